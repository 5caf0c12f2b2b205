"""Time to error: Relume's preview bake against Cycles on the same machine.

    python3 scripts/cycles_time_to_error.py [--relume target/release/relume] [--out out/cycles]

Needs the `bpy` module (Blender as a Python module, `pip install bpy==5.0.1`, which
scripts/test.sh installs) and a release build of `relume`.

What it does, on a **diffuse variant** of the Cornell scene (Cycles has no Blinn–Phong BSDF,
so the glossy regions cannot be rendered the same way; every region becomes Lambertian with
Kd := Kd + Ks, the same albedo, and stays editable in Relume, so the bake keeps its layers):

1. `relume report VARIANT --presets preview`: bakes the preview preset from scratch, relights
   it at the bake-time materials and measures its relative L2 error against a converged
   reference of the true BRDF (other seeds; its noise measured and taken out in quadrature).
2. Imports the variant into Blender (meshes, Diffuse BSDF materials, the area light, black
   world, camera, resolution) and renders it with Cycles on the CPU at increasing samples
   per pixel: one bounce (max bounces 1: direct light and one indirect bounce, as the bake),
   box pixel filter of 1 px (Relume's jitter), no adaptive sampling, no clamping,
   the light invisible to the camera (as in Relume), `--threads` threads; once without
   denoising and once (`--denoised-spp`) with Cycles' OpenImageDenoise, since Relume's
   presets apply their own (linear) denoiser to the stack. Each render's
   wall time (scene sync, BVH build and path tracing; not Blender's start-up) and its error
   against the same reference are recorded.
3. The shown image (docs/denoise.md): the preview stack relit through OpenImageDenoise with
   the scene's albedo and normal features (`relume relight --denoise oidn --scene`, Blender's
   own OIDN from the bpy wheel), its error against the same reference, its time (bake plus
   features and OIDN), and Cycles' and Cycles + OIDN's times to that error. `--no-shown`
   skips it.
4. With `--adaptive-thresholds T1,T2`, bakes the preview again with per-tile adaptive sampling
   at each threshold (`relume report --adaptive-threshold`) and measures it as in 1 and 3
   against the same reference and the same Cycles ladders; `--repeats N` bakes each N times
   (min and median bake time). `--resolution WxH` sets the variant's resolution.
5. Prints and writes (OUT/cycles_time_to_error.json) Cycles' time to the preview's error,
   interpolated log–log between the two sample counts that bracket it, and Cycles' error at
   its highest sample count (the floor where the two renderers' models differ: smooth normals
   from Blender's own vertex normals, light sampling conventions).
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import pathlib
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent


def diffuse_variant(scene_path: pathlib.Path, out_path: pathlib.Path,
                    resolution: str | None = None) -> None:
    data = json.loads(scene_path.read_text())
    if resolution:
        w, h = (int(v) for v in resolution.lower().split("x"))
        data["resolution"] = {"width": w, "height": h}
    for region in data["regions"]:
        m = region["material"]
        if m["model"] != "blinn_phong":
            raise SystemExit(f"region {region['name']!r}: only Blinn–Phong regions are converted")
        m["kd"] = [min(1.0, kd + ks) for kd, ks in zip(m["kd"], m["ks"], strict=True)]
        m["ks"] = [0.0, 0.0, 0.0]
        m["ns"] = 1
    out_path.write_text(json.dumps(data))


def run_report(relume: str, variant: pathlib.Path, out: pathlib.Path, reference_spp: int,
               adaptive_threshold: float = 0.0) -> dict:
    cmd = [relume, "report", str(variant), "--presets", "preview", "--out", str(out / "report"),
           "--reference-spp", str(reference_spp), "--keep-stacks", "--json"]
    if adaptive_threshold:
        cmd += ["--adaptive-threshold", str(adaptive_threshold)]
    print("+", " ".join(cmd), file=sys.stderr)
    res = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, cwd=ROOT)
    return json.loads(res.stdout)


def bpy_lib_dir() -> str | None:
    """The bpy wheel's lib folder (Blender's OpenImageDenoise), found without importing bpy."""
    import importlib.util

    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        return None
    lib = pathlib.Path(list(spec.submodule_search_locations)[0]) / "lib"
    return str(lib) if lib.is_dir() else None


def run_shown(relume: str, stack: pathlib.Path, variant: pathlib.Path, out: pathlib.Path,
              name: str = "relume_preview_oidn.exr") -> dict:
    """The preview stack's shown image: relit through OIDN with the scene's features."""
    image = out / name
    env = dict(os.environ)
    lib = bpy_lib_dir()
    if lib and not env.get("RELUME_OIDN_LIBRARY"):
        env["RELUME_OIDN_LIBRARY"] = lib
    cmd = [relume, "relight", str(stack), "--scene", str(variant), "--denoise", "oidn",
           "--device", "cpu", "-o", str(image), "--json"]
    print("+", " ".join(cmd), file=sys.stderr)
    res = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, env=env, cwd=ROOT)
    data = json.loads(res.stdout)
    data["image"] = str(image)
    return data


# --- Blender side -------------------------------------------------------------------------

def build_blender_scene(path: pathlib.Path, threads: int):
    import bpy
    import mathutils

    bpy.ops.wm.read_factory_settings(use_empty=True)
    data = json.loads(path.read_text())
    scene = bpy.context.scene
    materials = []
    for region in data["regions"]:
        mat = bpy.data.materials.new(region["name"])
        mat.use_nodes = True
        tree = mat.node_tree
        for node in list(tree.nodes):
            if node.type != "OUTPUT_MATERIAL":
                tree.nodes.remove(node)
        out = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (*region["material"]["kd"], 1.0)
        diffuse.inputs["Roughness"].default_value = 0.0
        tree.links.new(diffuse.outputs["BSDF"], out.inputs["Surface"])
        materials.append(mat)
    for mesh_data in data["meshes"]:
        mesh = bpy.data.meshes.new(mesh_data["name"])
        mesh.from_pydata([tuple(p) for p in mesh_data["positions"]], [],
                         [tuple(t) for t in mesh_data["indices"]])
        mesh.materials.append(materials[mesh_data.get("region", 0)])
        if mesh_data.get("normals"):
            mesh.shade_smooth()
        mesh.update()
        obj = bpy.data.objects.new(mesh_data["name"], mesh)
        scene.collection.objects.link(obj)
    for i, light in enumerate(data["lights"]):
        if light["type"] != "area" or light["shape"] != "square":
            raise SystemExit("this script imports the Cornell scene's square area light only")
        ld = bpy.data.lights.new(f"Light {i}", "AREA")
        ld.shape = "SQUARE"
        ld.size = light["size_x"]
        ld.energy = light["power"]
        ld.color = light.get("color", [1, 1, 1])
        x = mathutils.Vector(light["axis_u"]).normalized()
        y = mathutils.Vector(light["axis_v"]).normalized()
        z = x.cross(y).normalized()
        m = mathutils.Matrix.Identity(4)
        for row in range(3):
            m[row][0], m[row][1], m[row][2], m[row][3] = x[row], y[row], z[row], light["position"][row]
        obj = bpy.data.objects.new(f"Light {i}", ld)
        obj.matrix_world = m
        obj.visible_camera = False  # Relume's lights are not seen by camera rays
        scene.collection.objects.link(obj)
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*data["world"]["color"], 1.0)
    bg.inputs["Strength"].default_value = data["world"].get("strength", 1.0)
    scene.world = world
    c = data["camera"]
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.type = "PERSP"
    cam_data.lens = c["lens_mm"]
    cam_data.sensor_width = c["sensor_width_mm"]
    cam_data.sensor_height = c["sensor_height_mm"]
    cam_data.sensor_fit = c["sensor_fit"].upper()
    cam_data.clip_start = c["clip_start"]
    cam_data.clip_end = c["clip_end"]
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.matrix_world = mathutils.Matrix(c["matrix_world"])
    scene.collection.objects.link(cam)
    scene.camera = cam
    r = scene.render
    r.resolution_x, r.resolution_y = data["resolution"]["width"], data["resolution"]["height"]
    r.resolution_percentage = 100
    r.engine = "CYCLES"
    r.threads_mode = "FIXED"
    r.threads = threads
    r.use_persistent_data = False  # every render syncs and builds its BVH from scratch
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.image_settings.exr_codec = "ZIP"
    r.use_compositing = False
    r.use_sequencer = False
    scene.view_settings.view_transform = "Standard"
    cy = scene.cycles
    cy.device = "CPU"
    cy.max_bounces = 1
    cy.diffuse_bounces = 1
    cy.glossy_bounces = 1
    cy.transmission_bounces = 0
    cy.volume_bounces = 0
    cy.transparent_max_bounces = 0
    cy.caustics_reflective = True
    cy.caustics_refractive = True
    cy.use_denoising = False
    cy.use_adaptive_sampling = False
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.pixel_filter_type = "BOX"
    cy.filter_width = 1.0
    cy.seed = 7
    cy.use_animated_seed = False
    cy.film_exposure = 1.0
    bpy.context.view_layer.update()
    return scene


def load_exr_rgb(path: pathlib.Path):
    """Linear RGB of an EXR, as a float64 numpy array (rows as Blender stores them)."""
    import bpy
    import numpy as np

    img = bpy.data.images.load(str(path), check_existing=False)
    img.colorspace_settings.name = "Non-Color"  # no view transform: the stored values
    w, h = img.size
    px = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    return w, h, px.reshape(h, w, 4)[:, :, :3].astype(np.float64)


def rel_l2(a, b) -> float:
    import numpy as np

    return float(np.sqrt(((a - b) ** 2).sum() / (b ** 2).sum()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--relume", default=str(ROOT / "target/release/relume"))
    ap.add_argument("--scene", default=str(ROOT / "assets/cornell.scene.json"))
    ap.add_argument("--out", default=str(ROOT / "out/cycles"))
    ap.add_argument("--spp", default="1,2,4,8,16,32,64,128,256",
                    help="Cycles samples per pixel, comma-separated, increasing")
    ap.add_argument("--reference-spp", type=int, default=256)
    ap.add_argument("--denoised-spp", default="1,2,4,8,16,32,64",
                    help="Cycles samples per pixel of a second series with Cycles' own "
                         "denoiser (OpenImageDenoise) on, since Relume's presets denoise too; "
                         "empty to skip")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--no-shown", action="store_true",
                    help="skip the shown image (the preview relit through OpenImageDenoise)")
    ap.add_argument("--resolution", default=None,
                    help="WIDTHxHEIGHT for the scene (Relume and Cycles alike); default: the scene's")
    ap.add_argument("--adaptive-thresholds", default="",
                    help="comma-separated adaptive sampling thresholds (the bake setting "
                         "adaptive_threshold) to bake the preview with besides the preset as it "
                         "is; each is measured like it and compared with the same Cycles ladders")
    ap.add_argument("--repeats", type=int, default=1,
                    help="bakes per Relume setting (the bake time is reported as min and median)")
    args = ap.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    variant = out / "cornell_diffuse.scene.json"
    diffuse_variant(pathlib.Path(args.scene), variant, args.resolution)

    def bake_and_show(threshold: float) -> tuple[dict, dict, dict | None]:
        """The preview baked `repeats` times at this adaptive threshold: the report, its
        row (bake times of every repeat added) and the shown image of the last."""
        times = []
        for _ in range(max(args.repeats, 1)):
            report = run_report(args.relume, variant, out, args.reference_spp, threshold)
            times.append(report["rows"][0]["bake_seconds"])
        row = dict(report["rows"][0])
        row["adaptive_threshold"] = threshold
        row["bake_seconds_all"] = times
        row["bake_seconds_min"] = min(times)
        row["bake_seconds_median"] = sorted(times)[len(times) // 2]
        stack = out / "report" / "stacks" / f"{variant.name.removesuffix('.scene.json')}.preview.relume.exr"
        if not stack.exists():
            stack = next((out / "report" / "stacks").glob("*.preview.relume.exr"))
        shown = None if args.no_shown else run_shown(
            args.relume, stack, variant, out, f"relume_preview_oidn_t{threshold:g}.exr")
        return report, row, shown

    report, row, shown = bake_and_show(0.0)
    adaptive_runs = [bake_and_show(float(t)) for t in args.adaptive_thresholds.split(",") if t]
    ref_info = report["references"][0]
    ref_path = pathlib.Path(ref_info["file"])
    if not ref_path.is_absolute():
        ref_path = ROOT / ref_path
    ref_noise = ref_info["noise_rel_l2"]
    target = row["rel_l2"]
    print(f"relume preview: bake {row['bake_seconds']:.2f} s, error {target * 100:.3f} % "
          f"(raw {row['rel_l2_raw'] * 100:.3f} %, reference noise {ref_noise * 100:.3f} %)",
          file=sys.stderr)

    import numpy as np  # noqa: F401  (bpy ships numpy)

    scene = build_blender_scene(variant, args.threads)
    import bpy

    _, _, ref = load_exr_rgb(ref_path)
    shown_target = None
    if shown is not None:
        _, _, img = load_exr_rgb(pathlib.Path(shown["image"]))
        raw = rel_l2(img, ref)
        shown_target = math.sqrt(max(raw * raw - ref_noise * ref_noise, 0.0))
        shown.update({"rel_l2": shown_target, "rel_l2_raw": raw,
                      "seconds_bake_plus_denoise": row["bake_seconds_min"] + shown["denoise"]["ms"] / 1e3})
        print(f"relume preview, shown ({shown['denoise']['summary']}): "
              f"error {shown_target * 100:.3f} % (raw {raw * 100:.3f} %)", file=sys.stderr)
    for _, arow, ashown in adaptive_runs:
        if ashown is not None:
            _, _, img = load_exr_rgb(pathlib.Path(ashown["image"]))
            raw = rel_l2(img, ref)
            ashown.update({"rel_l2": math.sqrt(max(raw * raw - ref_noise * ref_noise, 0.0)),
                           "rel_l2_raw": raw,
                           "seconds_bake_plus_denoise": arow["bake_seconds_min"]
                           + ashown["denoise"]["ms"] / 1e3})

    def series(spps: list[int], denoise: bool) -> list[dict]:
        scene.cycles.use_denoising = denoise
        if denoise:
            scene.cycles.denoiser = "OPENIMAGEDENOISE"
        points = []
        for spp in spps:
            scene.cycles.samples = spp
            exr = out / f"cycles_{spp:05d}spp{'_oidn' if denoise else ''}.exr"
            scene.render.filepath = str(exr)
            t = time.perf_counter()
            bpy.ops.render.render(write_still=True)
            seconds = time.perf_counter() - t
            _, _, img = load_exr_rgb(exr)
            raw = rel_l2(img, ref)
            err = math.sqrt(max(raw * raw - ref_noise * ref_noise, 0.0))
            points.append({"spp": spp, "seconds": seconds, "rel_l2": err, "rel_l2_raw": raw})
            print(f"cycles{' + OIDN' if denoise else ''} {spp:5d} spp: {seconds:7.2f} s, error "
                  f"{err * 100:.3f} % (raw {raw * 100:.3f} %)", file=sys.stderr)
        return points

    def time_to(points: list[dict], target: float = target) -> dict | None:
        """Time to `target` (the preview's error): log–log interpolation between the
        bracketing points."""
        for a, b in itertools.pairwise(points):
            if a["rel_l2"] > target >= b["rel_l2"]:
                f = math.log(a["rel_l2"] / target) / math.log(a["rel_l2"] / b["rel_l2"])
                return {
                    "seconds": math.exp(math.log(a["seconds"]) + f * math.log(b["seconds"] / a["seconds"])),
                    "spp": math.exp(math.log(a["spp"]) + f * math.log(b["spp"] / a["spp"])),
                    "interpolated_between_spp": [a["spp"], b["spp"]],
                }
        if points and points[0]["rel_l2"] <= target:
            return {"seconds": points[0]["seconds"], "spp": points[0]["spp"],
                    "note": "the lowest sample count already reaches the error"}
        return None

    points = series([int(s) for s in args.spp.split(",")], denoise=False)
    cycles_time = time_to(points)
    denoised_points, denoised_time, denoised_error = [], None, None
    if args.denoised_spp:
        try:
            denoised_points = series([int(s) for s in args.denoised_spp.split(",")], denoise=True)
            denoised_time = time_to(denoised_points)
        except (RuntimeError, TypeError) as e:  # a bpy build without OpenImageDenoise
            denoised_error = str(e)
            print(f"Cycles with OpenImageDenoise could not run: {e}", file=sys.stderr)
    result = {
        "date_utc": time.strftime("%Y-%m-%d", time.gmtime()),
        "blender": bpy.app.version_string,
        "threads": args.threads,
        "load_average": " ".join(pathlib.Path("/proc/loadavg").read_text().split()[:3]),
        "scene": "cornell, diffuse variant (every region Lambertian, Kd := Kd + Ks)",
        "relume_preview": row,
        "reference": ref_info,
        "cycles": points,
        "cycles_time_to_preview_error": cycles_time,
        "cycles_floor_rel_l2": points[-1]["rel_l2"] if points else None,
        "cycles_oidn": denoised_points,
        "cycles_oidn_time_to_preview_error": denoised_time,
        "cycles_oidn_error": denoised_error,
        "relume_preview_shown": shown,
        "cycles_time_to_shown_error": time_to(points, shown_target) if shown_target else None,
        "cycles_oidn_time_to_shown_error": (time_to(denoised_points, shown_target)
                                            if shown_target and denoised_points else None),
        "resolution": args.resolution,
        "relume_adaptive": [
            {"row": arow, "shown": ashown,
             "cycles_oidn_time_to_error": time_to(denoised_points, arow["rel_l2"]) if denoised_points else None,
             "cycles_oidn_time_to_shown_error": (time_to(denoised_points, ashown["rel_l2"])
                                                 if ashown and denoised_points else None)}
            for _, arow, ashown in adaptive_runs],
    }
    (out / "cycles_time_to_error.json").write_text(json.dumps(result, indent=2))
    if cycles_time:
        print(f"Cycles reaches the preview's {target * 100:.2f} % in {cycles_time['seconds']:.2f} s "
              f"(≈ {cycles_time['spp']:.0f} spp) against Relume's preview bake {row['bake_seconds']:.2f} s")
    else:
        print(f"Cycles does not reach the preview's {target * 100:.2f} % within {points[-1]['spp']} spp "
              f"(its error there: {points[-1]['rel_l2'] * 100:.2f} %)")
    if denoised_time:
        print(f"Cycles + OpenImageDenoise reaches it in {denoised_time['seconds']:.2f} s "
              f"(≈ {denoised_time['spp']:.0f} spp)")
    if shown_target is not None:
        t_oidn = result["cycles_oidn_time_to_shown_error"]
        print(f"Relume preview + OIDN: {shown_target * 100:.2f} % in "
              f"{shown['seconds_bake_plus_denoise']:.2f} s; Cycles + OIDN reaches that in "
              + (f"{t_oidn['seconds']:.2f} s (≈ {t_oidn['spp']:.0f} spp)" if t_oidn else "none of its sample counts"))
    runs = [(row, shown, result["cycles_oidn_time_to_shown_error"])] + [
        (a["row"], a["shown"], a["cycles_oidn_time_to_shown_error"]) for a in result["relume_adaptive"]]
    print("| adaptive threshold | bake min / median s | mean spp | relit % | shown (OIDN) % "
          "| Cycles + OIDN to the shown error |")
    for r, sh, t in runs:
        a = r.get("adaptive") or {}
        times = r.get("bake_seconds_all", [r["bake_seconds"]])
        print(f"| {r.get('adaptive_threshold', 0.0):g} | {min(times):.1f} / {sorted(times)[len(times) // 2]:.1f} "
              f"| {a.get('mean_spp', r['spp']):.1f} | {r['rel_l2'] * 100:.2f} "
              f"| {sh['rel_l2'] * 100 if sh else float('nan'):.2f} "
              + (f"| {t['seconds']:.1f} s (≈ {t['spp']:.0f} spp) |" if t else "| — |"))
    print(f"→ {out / 'cycles_time_to_error.json'}")


if __name__ == "__main__":
    main()
