//! `relume report`: the measured preset table and chart.
//!
//! For every scene and preset it bakes from scratch (no cache: the bake time is the figure),
//! relights the stack at the bake-time materials on the CPU, and compares that image — and
//! the shown one, the relit image through OpenImageDenoise with the scene's albedo and
//! normals — with a converged reference of the *true* Blinn–Phong BRDF rendered with other
//! seeds. The
//! reference is rendered once per scene and resolution and cached under `OUT/references/`
//! (keyed by the scene's hash and the reference settings). Its own noise is measured — it is
//! rendered as two halves with different seeds, and ‖A − B‖ / ‖A + B‖ estimates the relative
//! L2 noise of their mean — and the table gives both the raw error and the error with the
//! reference's noise taken out in quadrature (√(e² − n²), an approximation that assumes the
//! two are independent).
//!
//! Writes `OUT/presets.md`, `OUT/presets.json` and the chart (`OUT/presets.png`, or
//! `--chart`): error against bake time, log–log, one line per scene, points = presets.

mod chart;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use relume_engine::bake::presets::Preset;
use relume_engine::bake::reference::{render_reference, ReferenceBrdf};
use relume_engine::bake::to_file::bake_to_file;
use relume_engine::bake::{BakeSettings, IndirectSampling};
use relume_engine::image_io::{compare_rgb, read_rgb_exr, write_atomic, write_rgba_exr};
use relume_engine::materials::{resolve_materials, MaterialsFile};
use relume_engine::relight::CpuRelighter;
use relume_engine::scene::{file::load_scene, hash::scene_hash, Resolution, Scene};
use relume_engine::stack::{bases::StackBases, RegionInfo};
use relume_engine::RelumeError;
use serde_json::{json, Value};

use crate::options::{parse_resolution, scale_resolution, PresetArg};
use crate::progress_bar::with_progress;

/// Version of the reference cache's key: bump when the reference's meaning changes.
const REFERENCE_CACHE_VERSION: u32 = 1;

#[derive(clap::Args)]
pub struct Args {
    /// Scene files [default: every assets/*.scene.json, in name order].
    pub scenes: Vec<PathBuf>,
    /// Presets to bake, cheapest first.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "draft,preview,final"
    )]
    pub presets: Vec<PresetArg>,
    /// Output folder: presets.md, presets.json, presets.png, references/ (the cache).
    #[arg(long, default_value = "out/report")]
    pub out: PathBuf,
    /// Where to write the chart [default: OUT/presets.png].
    #[arg(long)]
    pub chart: Option<PathBuf>,
    /// Replace every scene's resolution (e.g. 16x16 for a quick check); the presets'
    /// resolution scales apply to it.
    #[arg(long)]
    pub resolution: Option<String>,
    /// Eye samples per pixel of the reference (two halves of different seeds). The default
    /// leaves ≈ 2.4 % noise on the Cornell scene (measured, printed, and taken out of every
    /// error in quadrature); more spp tighten the estimate at 2.5 min per 128 spp at 512² on
    /// 2 cores.
    #[arg(long, default_value_t = 128)]
    pub reference_spp: u32,
    /// Samples per light of the reference.
    #[arg(long, default_value_t = 4)]
    pub reference_light_samples: u32,
    /// Indirect directions per eye hit of the reference.
    #[arg(long, default_value_t = 4)]
    pub reference_indirect_samples: u32,
    /// Seed of the reference's first half (the second uses seed + 1); the bakes use seed 0.
    #[arg(long, default_value_t = 1_000_003)]
    pub reference_seed: u64,
    /// Timed full relights per stack (the median is reported).
    #[arg(long, default_value_t = 20)]
    pub relight_repeats: usize,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Bakes every preset with per-tile adaptive sampling at this noise threshold (the
    /// bake setting `adaptive_threshold`; 0: the presets as they are).
    #[arg(long, default_value_t = 0.0)]
    pub adaptive_threshold: f32,
    /// Keep the baked stacks in OUT/stacks/ (they are deleted after measuring otherwise).
    #[arg(long)]
    pub keep_stacks: bool,
    /// Bake nothing: redraw OUT/presets.md and the chart from an existing OUT/presets.json
    /// (docs/measurements.md's: `--redraw --out docs/report --chart docs/images/presets.png`).
    #[arg(long)]
    pub redraw: bool,
    /// Print the JSON report on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Seed of every bake of the report (the reference uses others).
const BAKE_SEED: u64 = 0;

pub fn run(args: Args) -> Result<(), RelumeError> {
    if args.redraw {
        let path = args.out.join("presets.json");
        check_report_outputs(&args, &[(&path, "the report being redrawn")], false)?;
        let text = std::fs::read_to_string(&path).map_err(|e| RelumeError::io(&path, e))?;
        let report: Value = serde_json::from_str(&text)
            .map_err(|e| RelumeError::invalid("--redraw", format!("{}: {e}", path.display())))?;
        return write_outputs(&args, &report, false);
    }
    let started = Instant::now();
    let load_before = load_average();
    let scenes = if args.scenes.is_empty() {
        default_scenes()?
    } else {
        args.scenes.clone()
    };
    if args.presets.is_empty() {
        return Err(RelumeError::invalid("--presets", "no preset named"));
    }
    let scene_inputs: Vec<(&Path, &str)> =
        scenes.iter().map(|p| (p.as_path(), "a scene")).collect();
    check_report_outputs(&args, &scene_inputs, true)?;
    let resolution = args
        .resolution
        .as_deref()
        .map(parse_resolution)
        .transpose()?;
    let refs_dir = args.out.join("references");
    let stacks_dir = args.out.join("stacks");
    for d in [&args.out, &refs_dir, &stacks_dir] {
        std::fs::create_dir_all(d).map_err(|e| RelumeError::io(d, e))?;
    }
    let mut rows = Vec::new();
    let mut references = Vec::new();
    for path in &scenes {
        let mut scene = load_scene(path)?;
        if let Some(r) = resolution {
            scene.resolution = r;
        }
        let name = scene_name(path);
        let reference = reference_for(&scene, &name, &args, &refs_dir)?;
        eprintln!(
            "report: {name}: reference {}×{}, {} spp, noise {:.3} % ({})",
            reference.resolution.width,
            reference.resolution.height,
            args.reference_spp,
            reference.noise * 100.0,
            if reference.cached {
                "cached".to_string()
            } else {
                format!("rendered in {:.1} s", reference.seconds)
            }
        );
        for preset in &args.presets {
            let preset = preset.preset();
            let row = measure_preset(&scene, &name, preset, &reference, &args, &stacks_dir)?;
            eprintln!(
                "report: {name} {}: bake {:.2} s, error {:.3} % (raw {:.3} %), {:.1} MB, relight {:.2} ms",
                preset.name(),
                row["bake_seconds"].as_f64().unwrap_or(f64::NAN),
                row["rel_l2"].as_f64().unwrap_or(f64::NAN) * 100.0,
                row["rel_l2_raw"].as_f64().unwrap_or(f64::NAN) * 100.0,
                row["stack_file_bytes"].as_f64().unwrap_or(f64::NAN) / 1e6,
                row["relight_ms"].as_f64().unwrap_or(f64::NAN),
            );
            rows.push(row);
        }
        references.push(json!({
            "scene": name,
            "file": reference.path,
            "width": reference.resolution.width,
            "height": reference.resolution.height,
            "spp": args.reference_spp,
            "light_samples": args.reference_light_samples,
            "indirect_samples": args.reference_indirect_samples,
            "sampling": "mixture",
            "seeds": [args.reference_seed, args.reference_seed + 1],
            "noise_rel_l2": reference.noise,
            "render_seconds": reference.seconds,
            "cached": reference.cached,
        }));
    }
    if !args.keep_stacks {
        let _ = std::fs::remove_dir(&stacks_dir);
    }
    let report = json!({
        "command": "report",
        "date_utc": utc_date(),
        "machine": machine(),
        "threads": rayon::current_num_threads(),
        "load_average_before": load_before,
        "load_average_after": load_average(),
        "seconds": started.elapsed().as_secs_f64(),
        "bake_seed": BAKE_SEED,
        "error_measure": "relative L2 (RGB) of the relit image at the bake-time materials against a converged reference of the true Blinn–Phong BRDF, at the bake's resolution (the reference box-filtered down for a preset's resolution scale); rel_l2 has the reference's own noise taken out in quadrature, rel_l2_raw does not; rel_l2_shown is the shown image's (the relit image through OpenImageDenoise with the scene's albedo and normals; shown_denoise says what ran), its reference noise taken out too",
        "bake_time": "wall clock of the bake from scratch: scene validation, basis, BVH, path tracing, layer assembly (not writing the file: write_seconds)",
        "relight_time": "median full CPU relight at the bake-time materials (relume bench relight)",
        "references": references,
        "rows": rows,
    });
    write_outputs(&args, &report, true)
}

/// The chart's path: `--chart`, else OUT/presets.png.
fn chart_path(args: &Args) -> PathBuf {
    args.chart
        .clone()
        .unwrap_or_else(|| args.out.join("presets.png"))
}

/// Refuses report outputs (presets.json when `write_json`, presets.md, the chart) that are
/// `inputs`, one another, or existing non-regular files, before any work.
fn check_report_outputs(
    args: &Args,
    inputs: &[(&Path, &str)],
    write_json: bool,
) -> Result<(), RelumeError> {
    let (json_path, md_path, chart) = (
        args.out.join("presets.json"),
        args.out.join("presets.md"),
        chart_path(args),
    );
    let mut outputs: Vec<(&Path, &str)> = vec![(&md_path, "the table"), (&chart, "the chart")];
    if write_json {
        outputs.push((&json_path, "the JSON report"));
    }
    relume_engine::output_path::check_outputs(&outputs, inputs)
}

/// Writes presets.json (when `write_json`), presets.md and the chart, and prints the summary.
fn write_outputs(args: &Args, report: &Value, write_json: bool) -> Result<(), RelumeError> {
    let json_path = args.out.join("presets.json");
    if write_json {
        let text = serde_json::to_string_pretty(report)
            .map_err(|e| RelumeError::invalid("report", format!("JSON encoding: {e}")))?;
        write_atomic(&json_path, |w| {
            use std::io::Write;
            w.write_all(text.as_bytes())
                .map_err(|e| RelumeError::io(&json_path, e))
        })?;
    }
    let md_path = args.out.join("presets.md");
    let md = markdown(report);
    write_atomic(&md_path, |w| {
        use std::io::Write;
        w.write_all(md.as_bytes())
            .map_err(|e| RelumeError::io(&md_path, e))
    })?;
    let chart_path = chart_path(args);
    if let Some(dir) = chart_path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| RelumeError::io(dir, e))?;
    }
    chart_of(report).draw(960, 600)?.write_png(&chart_path)?;
    if args.json {
        super::print_json(report);
    } else {
        print!("{md}");
        println!(
            "report: {} rows in {:.0} s → {}, {}, {}",
            report["rows"].as_array().map_or(0, |r| r.len()),
            report["seconds"].as_f64().unwrap_or(0.0),
            md_path.display(),
            json_path.display(),
            chart_path.display()
        );
    }
    Ok(())
}

/// Every `assets/*.scene.json` under the current folder, in name order.
fn default_scenes() -> Result<Vec<PathBuf>, RelumeError> {
    let dir = Path::new("assets");
    let entries = std::fs::read_dir(dir).map_err(|e| RelumeError::io(dir, e))?;
    let mut out: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.to_string_lossy().ends_with(".scene.json"))
        .collect();
    out.sort();
    if out.is_empty() {
        return Err(RelumeError::invalid(
            "report",
            "no scene given and no assets/*.scene.json in the current folder",
        ));
    }
    Ok(out)
}

/// "cornell" for "assets/cornell.scene.json".
fn scene_name(path: &Path) -> String {
    let file = path
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    file.strip_suffix(".scene.json")
        .or_else(|| file.strip_suffix(".json"))
        .unwrap_or(&file)
        .to_string()
}

/// A converged reference image of a scene.
struct Reference {
    path: PathBuf,
    resolution: Resolution,
    /// RGBA f32.
    rgba: Vec<f32>,
    /// Estimated relative L2 noise.
    noise: f64,
    seconds: f64,
    cached: bool,
}

/// The editable regions' bake-time materials as Blinn–Phong (what the reference renders).
fn bake_time_materials(scene: &Scene) -> Result<Vec<relume_engine::brdf::BlinnPhong>, RelumeError> {
    let infos: Vec<RegionInfo> = scene
        .regions
        .iter()
        .map(|r| RegionInfo::from_region(r, None))
        .collect();
    Ok(resolve_materials(&infos, &MaterialsFile::default())?
        .iter()
        .map(|m| m.to_blinn_phong())
        .collect())
}

/// The cached reference of `scene`, rendered (as two halves) when the cache has none.
fn reference_for(
    scene: &Scene,
    name: &str,
    args: &Args,
    dir: &Path,
) -> Result<Reference, RelumeError> {
    let half_spp = args.reference_spp.div_ceil(2).max(1);
    let key = format!(
        "v{REFERENCE_CACHE_VERSION}-{}-{}x{}-{}spp-{}ls-{}is-mixture-seed{}",
        scene_hash(scene),
        scene.resolution.width,
        scene.resolution.height,
        half_spp * 2,
        args.reference_light_samples,
        args.reference_indirect_samples,
        args.reference_seed
    );
    let tag = short_hash(&key);
    let path = dir.join(format!("{name}.{tag}.exr"));
    let meta_path = dir.join(format!("{name}.{tag}.json"));
    if let (Ok((w, h, rgb)), Ok(meta)) = (read_rgb_exr(&path), std::fs::read_to_string(&meta_path))
    {
        let meta: Value = serde_json::from_str(&meta).unwrap_or(Value::Null);
        if meta["key"] == key && (w, h) == (scene.resolution.width, scene.resolution.height) {
            let rgba = rgb
                .chunks_exact(3)
                .flat_map(|p| [p[0], p[1], p[2], 1.0])
                .collect();
            return Ok(Reference {
                path,
                resolution: scene.resolution,
                rgba,
                noise: meta["noise_rel_l2"].as_f64().unwrap_or(f64::NAN),
                seconds: meta["render_seconds"].as_f64().unwrap_or(f64::NAN),
                cached: true,
            });
        }
    }
    let materials = bake_time_materials(scene)?;
    let t = Instant::now();
    let mut halves = Vec::new();
    for k in 0..2u64 {
        let settings = BakeSettings {
            spp: half_spp,
            light_samples: args.reference_light_samples,
            indirect_samples: args.reference_indirect_samples,
            bounces: 1,
            sampling: IndirectSampling::Mixture,
            seed: args.reference_seed + k,
            resolution: None,
            threads: args.threads,
            ..BakeSettings::default()
        };
        let (scene, materials) = (scene.clone(), materials.clone());
        let label = format!("{name}: reference {}/2", k + 1);
        let image = with_progress(&label, move |p| {
            render_reference(&scene, &settings, &materials, ReferenceBrdf::True, &p)
        })?;
        halves.push(image.rgba);
    }
    let seconds = t.elapsed().as_secs_f64();
    let mean: Vec<f32> = halves[0]
        .iter()
        .zip(&halves[1])
        .map(|(a, b)| 0.5 * (a + b))
        .collect();
    // ‖A − B‖ / ‖A + B‖ = ‖A − B‖/2 / ‖mean‖: for independent halves of equal variance σ²,
    // ‖A − B‖² ≈ 2σ²·N while the mean's error is σ²/2·N.
    let d = compare_rgb(&halves[0], &halves[1], 4)?;
    let norm = |img: &[f32]| -> f64 {
        img.chunks_exact(4)
            .flat_map(|p| p[..3].iter().map(|v| (*v as f64).powi(2)))
            .sum::<f64>()
            .sqrt()
    };
    let diff_norm = d.rel_l2 * norm(&halves[1]);
    let noise = diff_norm / (2.0 * norm(&mean)).max(f64::MIN_POSITIVE);
    write_rgba_exr(
        &path,
        scene.resolution.width,
        scene.resolution.height,
        &mean,
    )?;
    let meta = json!({"key": key, "noise_rel_l2": noise, "render_seconds": seconds});
    write_atomic(&meta_path, |w| {
        use std::io::Write;
        w.write_all(meta.to_string().as_bytes())
            .map_err(|e| RelumeError::io(&meta_path, e))
    })?;
    Ok(Reference {
        path,
        resolution: scene.resolution,
        rgba: mean,
        noise,
        seconds,
        cached: false,
    })
}

/// 16 hex digits of FNV-1a over `s` (a file-name tag; the full key is checked on load).
fn short_hash(s: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in s.bytes() {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// `rgba` (width × height) box-filtered down by an integer factor to `to`; `None` when the
/// sizes are not an integer multiple of each other.
fn downsample(rgba: &[f32], from: Resolution, to: Resolution) -> Option<Vec<f32>> {
    if from == to {
        return Some(rgba.to_vec());
    }
    let (w, h) = (from.width as usize, from.height as usize);
    let (tw, th) = (to.width as usize, to.height as usize);
    if tw == 0 || th == 0 || w % tw != 0 || h % th != 0 || w / tw != h / th {
        return None;
    }
    let k = w / tw;
    let inv = 1.0 / (k * k) as f32;
    let mut out = vec![0.0f32; tw * th * 4];
    for y in 0..th {
        for x in 0..tw {
            let o = (y * tw + x) * 4;
            for dy in 0..k {
                for dx in 0..k {
                    let i = ((y * k + dy) * w + x * k + dx) * 4;
                    for c in 0..4 {
                        out[o + c] += rgba[i + c] * inv;
                    }
                }
            }
        }
    }
    Some(out)
}

/// Bakes `scene` with `preset` from scratch and measures it.
fn measure_preset(
    scene: &Scene,
    name: &str,
    preset: Preset,
    reference: &Reference,
    args: &Args,
    stacks_dir: &Path,
) -> Result<Value, RelumeError> {
    let mut settings = BakeSettings {
        seed: BAKE_SEED,
        threads: args.threads,
        ..BakeSettings::default()
    };
    let scale = preset.apply(&mut settings);
    settings.adaptive.threshold = args.adaptive_threshold;
    let resolution = scale_resolution(scene.resolution, scale)?;
    settings.resolution = Some(resolution);
    let stack_path = stacks_dir.join(format!("{name}.{}.relume.exr", preset.name()));
    let baked = {
        let (scene, settings, path) = (scene.clone(), settings.clone(), stack_path.clone());
        let label = format!("{name}: {}", preset.name());
        with_progress(&label, move |p| {
            bake_to_file(&scene, &settings, 1, &path, &p, |_, _| {})
        })?
    };
    let stack = Arc::new(baked.stack);
    let materials = resolve_materials(&stack.header.regions, &MaterialsFile::default())?;
    let coefs = StackBases::from_header(&stack.header)?.coefficients(&materials)?;
    let mut relighter = CpuRelighter::from_tiled(stack.clone())?;
    let relit = relighter.relight(&coefs)?.to_vec();
    let bases: Vec<usize> = (0..relighter.editable_count())
        .map(|r| relighter.basis_count(r))
        .collect();
    drop(relighter);
    let target =
        downsample(&reference.rgba, reference.resolution, resolution).ok_or_else(|| {
            RelumeError::invalid(
                "report",
                format!(
                "{name} {}: the bake's {}×{} is not an integer fraction of the reference's {}×{}",
                preset.name(),
                resolution.width,
                resolution.height,
                reference.resolution.width,
                reference.resolution.height
            ),
            )
        })?;
    let d = compare_rgb(&relit, &target, 4)?;
    // Box-filtering k×k pixels divides the reference's noise variance by k².
    let k = (reference.resolution.width / resolution.width).max(1) as f64;
    let ref_noise = reference.noise / k;
    let without_noise = |e: f64| (e.powi(2) - ref_noise.powi(2)).max(0.0).sqrt();
    let corrected = without_noise(d.rel_l2);
    // What a user is shown: the relit image through OpenImageDenoise with the scene's
    // features (docs/denoise.md); the linear image, and a note, where OIDN is not found.
    let mut scene_at = scene.clone();
    scene_at.resolution = resolution;
    let (shown, denoise) = super::relight::shown_image(
        &relit,
        (resolution.width, resolution.height),
        relume_denoise::DenoiseMode::Oidn,
        Some(&scene_at),
        &materials,
    )?;
    let shown_error = compare_rgb(&shown, &target, 4)?.rel_l2;
    let relight = super::bench::cpu_relight_figures(
        stack.clone(),
        args.relight_repeats,
        "CPU: the report measures the CPU relight",
    )?;
    let r = &baked.report;
    let row = json!({
        "scene": name,
        "preset": preset.name(),
        "width": resolution.width,
        "height": resolution.height,
        "spp": settings.spp,
        "light_samples": settings.light_samples,
        "indirect_samples": settings.indirect_samples,
        "sampling": settings.sampling.name(),
        "basis_tolerance": preset.values().basis_tolerance,
        "denoise_bounce": settings.denoise.bounce_iterations,
        "denoise_direct": settings.denoise.direct_iterations,
        "bases_per_editable_region": bases,
        "bake_seconds": r.seconds,
        "trace_seconds": r.trace_seconds,
        "adaptive": r.adaptive,
        "write_seconds": baked.write_seconds,
        "rays": r.rays,
        "layers": stack.layers.len(),
        "layers_grey": r.layers_grey,
        "layers_rgb": r.layers_rgb,
        "stack_sample_bytes": stack.sample_bytes(),
        "stack_file_bytes": baked.file_bytes,
        "relight_ms": relight["full_ms"],
        "relight_bandwidth_bound_ms": relight["bandwidth_bound_ms"],
        "rel_l2": corrected,
        "rel_l2_raw": d.rel_l2,
        "rel_l2_shown": without_noise(shown_error),
        "shown_denoise": denoise.summary(),
        "reference_noise_at_this_resolution": ref_noise,
        "rmse": d.rmse,
    });
    if !args.keep_stacks {
        std::fs::remove_file(&stack_path).map_err(|e| RelumeError::io(&stack_path, e))?;
    }
    Ok(row)
}

/// The report as a Markdown table with its conditions.
fn markdown(report: &Value) -> String {
    let mut s = String::new();
    s.push_str(&format!(
        "Relume presets — measured {} on {} ({} threads; load average {} before, {} after), {:.0} s in all.\n\n",
        report["date_utc"].as_str().unwrap_or("?"),
        report["machine"].as_str().unwrap_or("?"),
        report["threads"],
        report["load_average_before"].as_str().unwrap_or("?"),
        report["load_average_after"].as_str().unwrap_or("?"),
        report["seconds"].as_f64().unwrap_or(0.0),
    ));
    s.push_str("| Scene | Preset | Resolution | spp × light × indirect | Denoise | N_b | Bake | Layers | Stack file | Relight (CPU) | Rel. L2 error | raw (ref. noise) | shown (OIDN) |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for row in report["rows"].as_array().into_iter().flatten() {
        let bases: Vec<String> = row["bases_per_editable_region"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|v| v.to_string())
            .collect();
        // Rows written before the denoiser was recorded: the preset's value.
        let denoise = row["denoise_bounce"].as_u64().unwrap_or_else(|| {
            row["preset"]
                .as_str()
                .and_then(Preset::parse)
                .map_or(0, |p| p.values().denoise.bounce_iterations as u64)
        });
        let denoise = if denoise == 0 {
            "off".to_string()
        } else {
            format!("bounce ×{denoise}")
        };
        s.push_str(&format!(
            "| {} | {} | {}×{} | {} × {} × {} | {} | {} | {:.2} s | {} | {:.1} MB | {:.2} ms | **{:.2} %** | {:.2} % ({:.2} %) | {} |\n",
            row["scene"].as_str().unwrap_or("?"),
            row["preset"].as_str().unwrap_or("?"),
            row["width"],
            row["height"],
            row["spp"],
            row["light_samples"],
            row["indirect_samples"],
            denoise,
            if bases.is_empty() { "–".to_string() } else { bases.join(", ") },
            row["bake_seconds"].as_f64().unwrap_or(f64::NAN),
            row["layers"],
            row["stack_file_bytes"].as_f64().unwrap_or(f64::NAN) / 1e6,
            row["relight_ms"].as_f64().unwrap_or(f64::NAN),
            row["rel_l2"].as_f64().unwrap_or(f64::NAN) * 100.0,
            row["rel_l2_raw"].as_f64().unwrap_or(f64::NAN) * 100.0,
            row["reference_noise_at_this_resolution"].as_f64().unwrap_or(f64::NAN) * 100.0,
            // Rows written before the shown image was measured have none.
            row["rel_l2_shown"]
                .as_f64()
                .map_or("–".to_string(), |e| format!("{:.2} %", e * 100.0)),
        ));
    }
    s.push_str("\nReferences (true Blinn–Phong BRDF, other seeds than the bakes'):\n\n");
    for r in report["references"].as_array().into_iter().flatten() {
        s.push_str(&format!(
            "- {}: {}×{}, {} spp × {} light × {} indirect samples, estimated noise {:.3} %{}\n",
            r["scene"].as_str().unwrap_or("?"),
            r["width"],
            r["height"],
            r["spp"],
            r["light_samples"],
            r["indirect_samples"],
            r["noise_rel_l2"].as_f64().unwrap_or(f64::NAN) * 100.0,
            if r["cached"].as_bool() == Some(true) {
                " (cached)".to_string()
            } else {
                format!(
                    ", rendered in {:.0} s",
                    r["render_seconds"].as_f64().unwrap_or(0.0)
                )
            }
        ));
    }
    s.push_str(&format!(
        "\nError: {}.\nBake time: {}.\nRelight: {}.\n",
        report["error_measure"].as_str().unwrap_or(""),
        report["bake_time"].as_str().unwrap_or(""),
        report["relight_time"].as_str().unwrap_or("")
    ));
    s
}

/// The chart of the report: one series per scene, x = bake seconds, y = error in %.
fn chart_of(report: &Value) -> chart::Chart {
    let mut series: Vec<chart::Series> = Vec::new();
    for row in report["rows"].as_array().into_iter().flatten() {
        let scene = row["scene"].as_str().unwrap_or("?").to_string();
        let point = (
            row["bake_seconds"].as_f64().unwrap_or(f64::NAN),
            row["rel_l2"].as_f64().unwrap_or(f64::NAN) * 100.0,
            row["preset"].as_str().unwrap_or("?").to_string(),
        );
        match series.iter_mut().find(|s| s.name == scene) {
            Some(s) => s.points.push(point),
            None => series.push(chart::Series {
                name: scene,
                points: vec![point],
            }),
        }
    }
    chart::Chart {
        title: "Relume presets: error against bake time".into(),
        subtitle: format!(
            "{}, {} threads, {}. Error: relit image vs converged true-BRDF reference.",
            report["date_utc"].as_str().unwrap_or("?"),
            report["threads"],
            report["machine"].as_str().unwrap_or("?"),
        ),
        x_label: "bake time (s)".into(),
        y_label: "relative L2 error (%)".into(),
        series,
        target: Some((1.0, "1 % (preview target, cornell)".into())),
    }
}

/// Today's date in UTC, YYYY-MM-DD (civil-from-days, H. Hinnant).
fn utc_date() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0);
    let z = secs.div_euclid(86_400) + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

/// The CPU's model name (Linux), or "unknown CPU".
fn machine() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".to_string())
}

/// The 1-, 5- and 15-minute load averages (Linux), to tell a shared, busy machine.
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|| "unknown".to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsample_averages_boxes() {
        let from = Resolution {
            width: 4,
            height: 2,
        };
        let to = Resolution {
            width: 2,
            height: 1,
        };
        let rgba: Vec<f32> = (0..8).flat_map(|i| [i as f32, 0.0, 0.0, 1.0]).collect();
        let out = downsample(&rgba, from, to).unwrap();
        assert_eq!(
            out,
            vec![
                (0.0 + 1.0 + 4.0 + 5.0) / 4.0,
                0.0,
                0.0,
                1.0,
                (2.0 + 3.0 + 6.0 + 7.0) / 4.0,
                0.0,
                0.0,
                1.0
            ]
        );
        assert!(downsample(
            &rgba,
            from,
            Resolution {
                width: 3,
                height: 1
            }
        )
        .is_none());
    }

    #[test]
    fn dates_and_names() {
        assert_eq!(utc_date().len(), 10);
        assert_eq!(
            scene_name(Path::new("assets/cornell.scene.json")),
            "cornell"
        );
        assert_ne!(short_hash("a"), short_hash("b"));
    }
}
