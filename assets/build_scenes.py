#!/usr/bin/env python3
"""Builds Relume's demo and test scenes (scene file format v1, see docs/scene-format.md).

Python 3.11+, standard library only. Usage, from the repository root:

    python3 assets/build_scenes.py                         # every scene, then validate them
    python3 assets/build_scenes.py --out assets            # the same, explicit output folder
    python3 assets/build_scenes.py cornell ring            # only the scenes named
    python3 assets/build_scenes.py --check FILE [FILE ...] # only validate existing scene files
    python3 assets/build_scenes.py --list                  # list the scenes

Scenes (see assets/README.md):
    cornell     -> OUT/cornell.scene.json                 committed
    ring        -> OUT/ring.scene.json                    committed
    textured    -> OUT/textured.scene.json                committed
    hdri        -> OUT/hdri.scene.json                    committed
    throughput  -> OUT/generated/throughput.scene.json    ~70k triangles, gitignored

Every scene written is validated (the same checks as --check); the script exits non-zero
when a check fails. Output is deterministic: rerunning reproduces the committed files.
Floats are rounded to 6 significant digits (texels to 4) to keep the files small.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

# ---------------------------------------------------------------------------------------
# Small vector helpers (tuples of 3 floats).


def vadd(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def vsub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def vmul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def vdot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def vcross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def vlen(a):
    return math.sqrt(vdot(a, a))


def vnorm(a):
    n = vlen(a)
    return (a[0] / n, a[1] / n, a[2] / n)


def rot_z(v, angle):
    c, s = math.cos(angle), math.sin(angle)
    return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])


# ---------------------------------------------------------------------------------------
# Mesh building.


class MeshBuilder:
    """Accumulates one scene mesh (world space). Triangles are counter-clockwise seen from
    the side their normal points to: geometric normal = (b - a) x (c - a)."""

    def __init__(self, name, region, normals=False, uvs=False):
        self.name = name
        self.region = region
        self.positions = []
        self.normals = [] if normals else None
        self.uvs = [] if uvs else None
        self.indices = []
        self.tri_regions = []

    def vert(self, p, n=None, uv=None):
        self.positions.append(tuple(p))
        if self.normals is not None:
            self.normals.append(vnorm(n))
        if self.uvs is not None:
            self.uvs.append(tuple(uv))
        return len(self.positions) - 1

    def tri(self, a, b, c, region=None):
        self.indices.append((a, b, c))
        self.tri_regions.append(self.region if region is None else region)

    def quad(self, a, b, c, d, region=None):
        self.tri(a, b, c, region)
        self.tri(a, c, d, region)

    def flat_quad(self, center, n, u, hu, hv, region=None):
        """A rectangle centred at `center`, facing unit `n`, spanned by unit `u` (half size
        `hu`) and n x u (half size `hv`); uv (0,0)..(1,1) along u and n x u."""
        v = vcross(n, u)
        corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
        ids = []
        for su, sv in corners:
            p = vadd(center, vadd(vmul(u, su * hu), vmul(v, sv * hv)))
            ids.append(self.vert(p, n, ((su + 1) / 2, (sv + 1) / 2)))
        self.quad(*ids, region=region)

    def box(self, center, size, angle=0.0, regions=None):
        """An axis-aligned box of full `size` rotated by `angle` about Z; outward faces.
        `regions` optionally maps face names (+x -x +y -y +z -z) to regions."""
        hx, hy, hz = size[0] / 2, size[1] / 2, size[2] / 2
        faces = {
            "+x": ((1, 0, 0), (0, 1, 0), hy, hz, hx),
            "-x": ((-1, 0, 0), (0, -1, 0), hy, hz, hx),
            "+y": ((0, 1, 0), (-1, 0, 0), hx, hz, hy),
            "-y": ((0, -1, 0), (1, 0, 0), hx, hz, hy),
            "+z": ((0, 0, 1), (1, 0, 0), hx, hy, hz),
            "-z": ((0, 0, -1), (-1, 0, 0), hx, hy, hz),
        }
        for key, (n, u, hu, hv, off) in faces.items():
            nw = rot_z(n, angle)
            uw = rot_z(u, angle)
            c = vadd(center, vmul(nw, off))
            self.flat_quad(c, nw, uw, hu, hv, None if regions is None else regions.get(key))

    def triangle_count(self):
        return len(self.indices)

    def to_json(self):
        m = {"name": self.name, "positions": [list(p) for p in self.positions]}
        if self.normals is not None:
            m["normals"] = [list(n) for n in self.normals]
        if self.uvs is not None:
            m["uvs"] = [list(t) for t in self.uvs]
        m["indices"] = [list(t) for t in self.indices]
        if all(r == self.region for r in self.tri_regions):
            m["region"] = self.region
        else:
            m["triangle_regions"] = list(self.tri_regions)
        return m


def icosphere(subdivisions):
    """Unit icosphere: (vertices, faces), faces outward."""
    t = (1 + math.sqrt(5)) / 2
    verts = [vnorm(v) for v in [
        (-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0),
        (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
        (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(subdivisions):
        cache = {}

        def mid(a, b):
            key = (a, b) if a < b else (b, a)
            if key not in cache:
                verts.append(vnorm(vmul(vadd(verts[a], verts[b]), 0.5)))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    out = []
    for a, b, c in faces:
        n = vcross(vsub(verts[b], verts[a]), vsub(verts[c], verts[a]))
        centroid = vadd(vadd(verts[a], verts[b]), verts[c])
        out.append((a, b, c) if vdot(n, centroid) > 0 else (a, c, b))
    return verts, out


def smooth_normals(positions, faces):
    """Area-weighted vertex normals."""
    acc = [(0.0, 0.0, 0.0)] * len(positions)
    for a, b, c in faces:
        n = vcross(vsub(positions[b], positions[a]), vsub(positions[c], positions[a]))
        for i in (a, b, c):
            acc[i] = vadd(acc[i], n)
    return [vnorm(n) for n in acc]


def add_radial_mesh(mb, unit_verts, faces, radius_fn, transform):
    """Adds a star-shaped surface: unit direction d -> transform(d * radius_fn(d)), with
    smooth area-weighted normals."""
    pos = [transform(vmul(d, radius_fn(d))) for d in unit_verts]
    nrm = smooth_normals(pos, faces)
    base = len(mb.positions)
    for p, n in zip(pos, nrm):
        mb.vert(p, n, None)
    for a, b, c in faces:
        mb.tri(base + a, base + b, base + c)


def add_icosphere(mb, center, radius, subdivisions):
    verts, faces = icosphere(subdivisions)
    base = len(mb.positions)
    for d in verts:
        mb.vert(vadd(center, vmul(d, radius)), d, None)
    for a, b, c in faces:
        mb.tri(base + a, base + b, base + c)


def add_uv_sphere(mb, center, radius, segments, rings):
    """UV sphere with Blender-like uvs (u around +Z from +X, v = 1 at the north pole);
    the seam and the poles have their own vertices, poles are triangle fans."""
    grid = []
    for j in range(rings + 1):
        theta = math.pi * j / rings
        row = []
        for i in range(segments + 1):
            pole = j == 0 or j == rings
            u = (i + 0.5) / segments if pole else i / segments
            phi = 2 * math.pi * u
            if pole:
                d = (0.0, 0.0, 1.0 if j == 0 else -1.0)
            else:
                d = (math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))
            if pole and i == segments:
                row.append(None)
                continue
            row.append(mb.vert(vadd(center, vmul(d, radius)), d, (u, 1 - j / rings)))
        grid.append(row)
    for j in range(rings):
        for i in range(segments):
            if j == 0:
                mb.tri(grid[0][i], grid[1][i], grid[1][i + 1])
            elif j == rings - 1:
                mb.tri(grid[j][i], grid[j + 1][i], grid[j][i + 1])
            else:
                mb.quad(grid[j][i], grid[j + 1][i], grid[j + 1][i + 1], grid[j][i + 1])


# ---------------------------------------------------------------------------------------
# Scene pieces.


def blinn_phong(kd, ks, ns):
    kd = list(kd) if isinstance(kd, (list, tuple)) else [kd] * 3
    ks = list(ks) if isinstance(ks, (list, tuple)) else [ks] * 3
    return {"model": "blinn_phong", "kd": kd, "ks": ks, "ns": ns}


def region(name, material, editable=False, texture=None, ns_range=None):
    r = {"name": name, "editable": editable, "material": material}
    if texture is not None:
        r["albedo_texture"] = texture
    if ns_range is not None:
        r["ns_range"] = list(ns_range)
    return r


def look_at_camera(eye, target, lens_mm=50.0, sensor_width_mm=36.0, sensor_height_mm=24.0,
                   sensor_fit="auto", clip_start=0.01, clip_end=1000.0):
    """A perspective Blender camera at `eye` looking at `target`, world +Z up (no roll)."""
    f = vnorm(vsub(target, eye))
    x = vnorm(vcross(f, (0.0, 0.0, 1.0)))  # camera right
    z = vmul(f, -1.0)                         # camera looks along its local -Z
    y = vcross(z, x)                          # camera up
    m = [[x[i], y[i], z[i], eye[i]] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]
    return {
        "projection": "perspective",
        "matrix_world": m,
        "lens_mm": lens_mm,
        "sensor_width_mm": sensor_width_mm,
        "sensor_height_mm": sensor_height_mm,
        "sensor_fit": sensor_fit,
        "shift_x": 0.0,
        "shift_y": 0.0,
        "ortho_scale": 6.0,
        "clip_start": clip_start,
        "clip_end": clip_end,
    }


def scene_doc(meshes, regions, lights, world, camera, width, height, version=1):
    return {
        "format": "relume-scene",
        "version": version,
        "meshes": [m.to_json() for m in meshes],
        "regions": regions,
        "lights": lights,
        "world": world,
        "camera": camera,
        "resolution": {"width": width, "height": height},
    }


# ---------------------------------------------------------------------------------------
# The scenes.


def build_cornell():
    """Cornell box after Fig. 3 of the paper: box [-1,1]^3, open at y = -1, Z up."""
    R_WHITE, R_OBJECT, R_RED, R_GREEN, R_TALL = range(5)
    regions = [
        region("White walls", blinn_phong(0.3, 0.3, 5.0), editable=True),
        region("Object", blinn_phong(0.2, 0.4, 5.0), editable=True),
        region("Red wall", blinn_phong([0.63, 0.065, 0.05], 0.0, 1.0)),
        region("Green wall", blinn_phong([0.14, 0.45, 0.091], 0.0, 1.0)),
        region("Tall box", blinn_phong([0.6, 0.6, 0.58], 0.0, 1.0)),
    ]
    white = MeshBuilder("White walls", R_WHITE)
    white.flat_quad((0, 0, -1), (0, 0, 1), (1, 0, 0), 1, 1)    # floor
    white.flat_quad((0, 0, 1), (0, 0, -1), (1, 0, 0), 1, 1)    # ceiling
    white.flat_quad((0, 1, 0), (0, -1, 0), (1, 0, 0), 1, 1)    # back wall
    red = MeshBuilder("Red wall", R_RED)
    red.flat_quad((-1, 0, 0), (1, 0, 0), (0, 1, 0), 1, 1)
    green = MeshBuilder("Green wall", R_GREEN)
    green.flat_quad((1, 0, 0), (-1, 0, 0), (0, 1, 0), 1, 1)
    tall = MeshBuilder("Tall box", R_TALL)
    tall.box((0.42, 0.38, -1 + 0.6), (0.56, 0.56, 1.2), math.radians(-18))

    # The object: a smooth bunny-ish blob (body, head, ears, tail) standing on the floor.
    def bump(d, c, p):
        return max(0.0, vdot(d, vnorm(c))) ** p

    def radius(d):
        return (1.0 + 0.35 * bump(d, (0.55, 0, 0.75), 4) + 0.45 * bump(d, (0.28, 0.3, 1), 14)
                + 0.45 * bump(d, (0.28, -0.3, 1), 14) + 0.2 * bump(d, (-1, 0, 0.25), 10)
                - 0.12 * bump(d, (0, 0, -1), 2))

    scale = (0.42, 0.33, 0.34)
    yaw = math.radians(-120)   # head towards the camera's left-front
    verts, faces = icosphere(4)
    raw = [rot_z((d[0] * radius(d) * scale[0], d[1] * radius(d) * scale[1],
                  d[2] * radius(d) * scale[2]), yaw) for d in verts]
    zmin = min(p[2] for p in raw)
    offset = (-0.33, -0.2, -1.0 - zmin - 0.003)   # sinks 3 mm into the floor: no light gap
    obj = MeshBuilder("Object", R_OBJECT, normals=True)
    add_radial_mesh(
        obj, verts, faces, radius,
        lambda p: vadd(rot_z((p[0] * scale[0], p[1] * scale[1], p[2] * scale[2]), yaw), offset))

    light_size = 0.5
    lights = [{
        "type": "area",
        "position": [0.0, 0.0, 0.99],
        "axis_u": [1.0, 0.0, 0.0],
        "axis_v": [0.0, 1.0, 0.0],   # emits along -(u x v) = -Z, down
        "shape": "square",
        "size_x": light_size,
        "power": 60.0,               # radiance 60 / (pi * 0.25) = 76.4 W/(m^2 sr)
        "color": [1.0, 0.85, 0.65],
    }]
    world = {"type": "color", "color": [0.0, 0.0, 0.0], "strength": 1.0}
    # 50 mm on a 36 mm sensor: horizontal fov 39.6 deg, the opening at y = -1 just fills it.
    camera = look_at_camera((0.0, -3.9, 0.0), (0.0, 0.0, 0.0), lens_mm=50.0, clip_start=0.1,
                            clip_end=100.0)
    return scene_doc([white, red, green, tall, obj], regions, lights, world, camera, 512, 512)


def build_ring():
    """A metal napkin ring on a floor under a low point light: caustics (Fig. 4)."""
    R_RING, R_FLOOR = 0, 1
    regions = [
        region("Ring", blinn_phong(0.05, 0.9, 150.0), editable=True),
        region("Floor", blinn_phong(0.8, 0.0, 1.0), editable=True),
    ]
    floor = MeshBuilder("Floor", R_FLOOR)
    floor.flat_quad((0, 0, 0), (0, 0, 1), (1, 0, 0), 3, 3)

    ring = MeshBuilder("Ring", R_RING, normals=True)
    seg, hseg = 256, 3
    r_out, r_in, height = 1.0, 0.97, 0.6
    z0 = -0.002   # the ring's foot sits 2 mm below the floor

    def ring_vert(r, phi, z, n):
        return ring.vert((r * math.cos(phi), r * math.sin(phi), z), n, None)

    for r, sign in ((r_out, 1.0), (r_in, -1.0)):   # outer and inner surfaces
        rows = []
        for j in range(hseg + 1):
            z = z0 + (height - z0) * j / hseg
            rows.append([ring_vert(r, 2 * math.pi * i / seg, z,
                                   (sign * math.cos(2 * math.pi * i / seg),
                                    sign * math.sin(2 * math.pi * i / seg), 0.0))
                         for i in range(seg)])
        for j in range(hseg):
            for i in range(seg):
                a, b = rows[j][i], rows[j][(i + 1) % seg]
                c, d = rows[j + 1][(i + 1) % seg], rows[j + 1][i]
                if sign > 0:
                    ring.quad(a, b, c, d)
                else:
                    ring.quad(a, d, c, b)
    for z, nz in ((height, 1.0), (z0, -1.0)):   # top and bottom rims (flat annuli)
        inner = [ring_vert(r_in, 2 * math.pi * i / seg, z, (0, 0, nz)) for i in range(seg)]
        outer = [ring_vert(r_out, 2 * math.pi * i / seg, z, (0, 0, nz)) for i in range(seg)]
        for i in range(seg):
            k = (i + 1) % seg
            if nz > 0:
                ring.quad(inner[i], outer[i], outer[k], inner[k])
            else:
                ring.quad(inner[i], inner[k], outer[k], outer[i])

    lights = [{
        "type": "point",
        "position": [-4.5, 0.0, 1.6],    # low, beyond the floor: light over the near rim
        "power": 600.0,                  # reaches the far inner wall, which focuses it
        "color": [1.0, 1.0, 1.0],
        "radius": 0.02,
    }]
    world = {"type": "color", "color": [0.0, 0.0, 0.0], "strength": 1.0}
    camera = look_at_camera((0.5, -2.5, 4.6), (0.1, 0.1, 0.0), lens_mm=38.0, clip_start=0.1,
                            clip_end=100.0)
    return scene_doc([floor, ring], regions, lights, world, camera, 512, 512)


def checker_texture(n=64, cells=8):
    a, b = (0.85, 0.82, 0.75), (0.22, 0.26, 0.3)
    rgb = []
    for y in range(n):
        for x in range(n):
            rgb += a if ((x * cells // n) + (y * cells // n)) % 2 == 0 else b
    return {"width": n, "height": n, "rgb": rgb}


def hsv(h, s, v):
    i = int(h * 6) % 6
    f = h * 6 - math.floor(h * 6)
    p, q, t = v * (1 - s), v * (1 - s * f), v * (1 - s * (1 - f))
    return [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)][i]


def gradient_texture(n=64):
    """Hue ramp along u (around a sphere), brightness rising with v, plus thin stripes."""
    rgb = []
    for y in range(n):        # top row first: row 0 is v = 1
        v = 1 - (y + 0.5) / n
        for x in range(n):
            u = (x + 0.5) / n
            c = hsv(u, 0.65, 0.35 + 0.6 * v)
            if y % 16 == 8:
                c = (0.9, 0.9, 0.9)
            rgb += [ch ** 2.2 for ch in c]   # sRGB-ish display value -> linear
    return {"width": n, "height": n, "rgb": rgb}


def build_textured():
    """Several objects, albedo textures on an editable and a fixed region, sun + spot."""
    R_GROUND, R_PAINTED, R_GLOSSY, R_PLASTIC = range(4)
    regions = [
        region("Ground", blinn_phong(0.8, 0.0, 1.0), texture=checker_texture()),
        region("Painted", blinn_phong(0.8, 0.15, 30.0), editable=True,
               texture=gradient_texture(), ns_range=(1.0, 100.0)),
        region("Glossy", blinn_phong([0.05, 0.1, 0.3], 0.5, 60.0), editable=True),
        region("Plastic", {"model": "principled", "base_color": [0.8, 0.3, 0.1],
                           "metallic": 0.0, "roughness": 0.45, "ior": 1.5,
                           "specular_ior_level": 0.5}),
    ]
    ground = MeshBuilder("Ground", R_GROUND, normals=True, uvs=True)
    ground.flat_quad((0, 0, 0), (0, 0, 1), (1, 0, 0), 4, 4)
    painted = MeshBuilder("Painted sphere", R_PAINTED, normals=True, uvs=True)
    add_uv_sphere(painted, (-1.2, 0.3, 0.8), 0.8, 48, 24)
    glossy = MeshBuilder("Glossy sphere", R_GLOSSY, normals=True, uvs=True)
    add_uv_sphere(glossy, (1.3, -0.5, 0.6), 0.6, 48, 24)
    # A box with two material slots: glossy top, plastic sides (triangle_regions).
    two = MeshBuilder("Two-slot box", R_PLASTIC, normals=True, uvs=True)
    two.box((0.35, 1.5, 0.4), (0.8, 0.8, 0.8), math.radians(30), regions={"+z": R_GLOSSY})
    pillar = MeshBuilder("Pillar", R_PLASTIC, normals=True, uvs=True)
    pillar.box((2.3, 1.9, 0.8), (0.4, 0.4, 1.6), math.radians(10))

    el, az = math.radians(48), math.radians(55)   # towards the sun: behind, to the right
    to_sun = (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el))
    spot_pos = (-3.0, -2.6, 3.4)
    lights = [
        {"type": "sun", "direction": list(vmul(to_sun, -1.0)), "strength": 3.0,
         "color": [1.0, 0.95, 0.88], "angle": math.radians(0.5)},
        {"type": "spot", "position": list(spot_pos),
         "direction": list(vnorm(vsub((-0.8, 0.4, 0.4), spot_pos))),
         "power": 600.0, "color": [0.75, 0.85, 1.0], "radius": 0.05,
         "spot_size": math.radians(60), "spot_blend": 0.2},
    ]
    world = {"type": "color", "color": [0.05, 0.05, 0.05], "strength": 1.0}
    camera = look_at_camera((0.6, -6.6, 3.1), (0.1, 0.4, 0.55), lens_mm=35.0, clip_start=0.1,
                            clip_end=200.0)
    return scene_doc([ground, painted, glossy, two, pillar], regions, lights, world, camera,
                     640, 360)


def build_throughput():
    """~70k triangles: a smooth terrain and a 5 x 4 grid of spheres; for bake timings."""
    R_TERRAIN, R_SPH_A, R_SPH_B = range(3)
    regions = [
        region("Terrain", blinn_phong([0.45, 0.4, 0.3], 0.05, 10.0), editable=True),
        region("Spheres A", blinn_phong([0.1, 0.3, 0.6], 0.4, 40.0), editable=True),
        region("Spheres B", blinn_phong([0.7, 0.2, 0.15], 0.1, 20.0)),
    ]

    def h(x, y):
        return (0.35 * math.sin(0.7 * x) * math.cos(0.5 * y) + 0.15 * math.sin(1.3 * x + 0.8 * y)
                + 0.08 * math.cos(2.1 * y - 0.4 * x))

    def grad(x, y):
        hx = (0.35 * 0.7 * math.cos(0.7 * x) * math.cos(0.5 * y)
              + 0.15 * 1.3 * math.cos(1.3 * x + 0.8 * y) + 0.08 * 0.4 * math.sin(2.1 * y - 0.4 * x))
        hy = (-0.35 * 0.5 * math.sin(0.7 * x) * math.sin(0.5 * y)
              + 0.15 * 0.8 * math.cos(1.3 * x + 0.8 * y) - 0.08 * 2.1 * math.sin(2.1 * y - 0.4 * x))
        return hx, hy

    terrain = MeshBuilder("Terrain", R_TERRAIN, normals=True, uvs=True)
    n, half = 150, 6.0
    ids = []
    for j in range(n + 1):
        y = -half + 2 * half * j / n
        row = []
        for i in range(n + 1):
            x = -half + 2 * half * i / n
            hx, hy = grad(x, y)
            row.append(terrain.vert((x, y, h(x, y)), (-hx, -hy, 1.0), (i / n, j / n)))
        ids.append(row)
    for j in range(n):
        for i in range(n):
            terrain.quad(ids[j][i], ids[j][i + 1], ids[j + 1][i + 1], ids[j + 1][i])
    meshes = [terrain]
    k = 0
    for gy in range(4):
        for gx in range(5):
            x, y = -4.0 + 2.0 * gx, -3.0 + 2.0 * gy
            r = 0.45 + 0.1 * ((gx + gy) % 3)
            m = MeshBuilder(f"Sphere {k}", R_SPH_A if (gx + gy) % 2 == 0 else R_SPH_B,
                            normals=True)
            add_icosphere(m, (x, y, h(x, y) + r - 0.05), r, 3)
            meshes.append(m)
            k += 1
    lights = [
        {"type": "area", "position": [0.0, 0.0, 4.5], "axis_u": [1.0, 0.0, 0.0],
         "axis_v": [0.0, 1.0, 0.0], "shape": "disk", "size_x": 2.5, "power": 500.0,
         "color": [1.0, 0.95, 0.9]},
        {"type": "point", "position": [3.5, -3.5, 2.5], "power": 200.0,
         "color": [1.0, 0.8, 0.6], "radius": 0.05},
    ]
    world = {"type": "color", "color": [0.05, 0.07, 0.1], "strength": 1.0}
    camera = look_at_camera((0.0, -11.0, 6.5), (0.0, 0.0, 0.0), lens_mm=35.0, clip_start=0.1,
                            clip_end=500.0)
    return scene_doc(meshes, regions, lights, world, camera, 512, 512)


def sky_texture(width=128, height=64, sun_el=math.radians(40), sun_az=math.radians(-35),
                sun_radius=math.radians(4.0), sun_radiance=2000.0):
    """An equirect sky (Blender mapping: centre column faces +X, top row is the zenith): a dim
    blue gradient, a dark ground half and a small, very bright sun disc (~10 texels at
    128 x 64) that carries most of the irradiance, the case cosine sampling handles worst."""
    to_sun = (math.cos(sun_el) * math.cos(sun_az), math.cos(sun_el) * math.sin(sun_az),
              math.sin(sun_el))
    cos_r = math.cos(sun_radius)
    rgb = []
    for y in range(height):
        v = 1 - (y + 0.5) / height
        el = (v - 0.5) * math.pi
        for x in range(width):
            u = (x + 0.5) / width
            phi = (0.5 - u) * 2 * math.pi
            d = (math.cos(el) * math.cos(phi), math.cos(el) * math.sin(phi), math.sin(el))
            if el >= 0:
                t = math.sin(el)
                c = (0.25 + 0.15 * t, 0.35 + 0.2 * t, 0.55 + 0.35 * t)
            else:
                c = (0.08, 0.07, 0.06)
            if vdot(d, to_sun) >= cos_r:
                c = (sun_radiance, sun_radiance * 0.93, sun_radiance * 0.82)
            rgb += c
    return {"width": width, "height": height, "rgb": rgb}


def build_hdri():
    """Spheres and boxes on a plane lit only by an HDR world with a small bright sun."""
    R_GROUND, R_MATTE, R_GLOSSY, R_BOX = range(4)
    regions = [
        region("Ground", blinn_phong(0.6, 0.0, 1.0)),
        region("Matte", blinn_phong([0.7, 0.35, 0.2], 0.05, 10.0), editable=True,
               ns_range=(1.0, 50.0)),
        region("Glossy", blinn_phong([0.1, 0.15, 0.3], 0.5, 80.0), editable=True,
               ns_range=(20.0, 200.0)),
        region("Box", blinn_phong([0.5, 0.55, 0.5], 0.02, 5.0)),
    ]
    ground = MeshBuilder("Ground", R_GROUND, normals=True, uvs=True)
    ground.flat_quad((0, 0, 0), (0, 0, 1), (1, 0, 0), 5, 5)
    matte = MeshBuilder("Matte sphere", R_MATTE, normals=True, uvs=True)
    add_uv_sphere(matte, (-1.0, 0.2, 0.7), 0.7, 32, 16)
    glossy = MeshBuilder("Glossy sphere", R_GLOSSY, normals=True, uvs=True)
    add_uv_sphere(glossy, (0.9, -0.4, 0.55), 0.55, 32, 16)
    box = MeshBuilder("Box", R_BOX, normals=True, uvs=True)
    box.box((0.4, 1.4, 0.5), (0.9, 0.9, 1.0), math.radians(25), regions={"+z": R_GLOSSY})
    world = {"type": "equirect", "image": sky_texture(), "strength": 1.0}
    camera = look_at_camera((0.3, -5.8, 2.6), (0.0, 0.3, 0.5), lens_mm=35.0, clip_start=0.1,
                            clip_end=200.0)
    return scene_doc([ground, matte, glossy, box], regions, [], world, camera, 480, 270)


def build_translucent():
    """A wax sphere on a floor, lit from behind: light that enters its lit back scatters
    through 0.3 m of wax (mean free path 20, 10, 5 cm) and leaves on the side the camera sees (scene format 2)."""
    R_FLOOR, R_WAX = range(2)
    wax = {
        "model": "principled",
        "base_color": [0.9, 0.75, 0.55],
        "roughness": 0.4,
        "ior": 1.4,
        "subsurface_weight": 1.0,
        "subsurface_radius": [1.0, 0.5, 0.25],
        "subsurface_scale": 0.2,
    }
    regions = [
        region("Floor", blinn_phong(0.5, 0.0, 1.0)),
        region("Wax", wax, editable=True),
    ]
    regions[R_WAX]["subsurface"] = {"samples": 65536}
    floor = MeshBuilder("Floor", R_FLOOR)
    floor.flat_quad((0, 0, 0), (0, 0, 1), (1, 0, 0), 2, 2)
    sphere = MeshBuilder("Wax", R_WAX, normals=True)
    add_icosphere(sphere, (0.0, 0.0, 0.15), 0.15, 4)
    lights = [
        # Behind the sphere, hidden by it from the camera.
        {"type": "point", "position": [0.0, 0.45, 0.2], "power": 80.0, "color": [1.0, 0.9, 0.8],
         "radius": 0.02},
        # A dim fill from the camera's side.
        {"type": "point", "position": [-0.8, -0.9, 0.9], "power": 6.0, "color": [0.8, 0.9, 1.0],
         "radius": 0.05},
    ]
    world = {"type": "color", "color": [0.02, 0.02, 0.025], "strength": 1.0}
    camera = look_at_camera((0.0, -0.95, 0.28), (0.0, 0.0, 0.15), lens_mm=50.0, clip_start=0.05,
                            clip_end=100.0)
    return scene_doc([floor, sphere], regions, lights, world, camera, 256, 256, version=2)


SCENES = {
    "cornell": (build_cornell, "cornell.scene.json"),
    "translucent": (build_translucent, "translucent.scene.json"),
    "ring": (build_ring, "ring.scene.json"),
    "textured": (build_textured, "textured.scene.json"),
    "hdri": (build_hdri, "hdri.scene.json"),
    "throughput": (build_throughput, os.path.join("generated", "throughput.scene.json")),
}

# ---------------------------------------------------------------------------------------
# Writing: compact JSON, floats to 6 significant digits, one line per big array.


def fmt_float(x, digits=6):
    if not math.isfinite(x):
        raise ValueError(f"non-finite number {x}")
    s = repr(float(f"{x:.{digits}g}"))
    if s.endswith(".0"):
        s = s[:-2]
    if s == "-0":
        s = "0"
    return s


def dump(value, indent=0, key=None):
    pad = "  " * indent
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return fmt_float(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple)):
        digits = 4 if key == "rgb" else 6
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            return "[" + ",".join(fmt_float(v, digits) if isinstance(v, float) else str(v)
                                  for v in value) + "]"
        if all(isinstance(v, (list, tuple)) for v in value) and all(
                all(isinstance(c, (int, float)) for c in v) for v in value):
            if key == "matrix_world":
                return "[\n" + ",\n".join(pad + "  " + dump(v) for v in value) + "\n" + pad + "]"
            return "[" + ",".join(dump(v) for v in value) + "]"
        return "[\n" + ",\n".join(pad + "  " + dump(v, indent + 1) for v in value) + "\n" + pad + "]"
    if isinstance(value, dict):
        items = [pad + "  " + json.dumps(k) + ": " + dump(v, indent + 1, k) for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    raise TypeError(type(value))


def write_scene(doc, path):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8", newline="\n") as f:
        f.write(dump(doc))
        f.write("\n")
    os.replace(tmp, path)


# ---------------------------------------------------------------------------------------
# Validation (--check).

TOP_KEYS = {"format", "version", "meshes", "regions", "lights", "world", "camera", "resolution"}
CAMERA_KEYS = {"projection", "matrix_world", "lens_mm", "sensor_width_mm", "sensor_height_mm",
               "sensor_fit", "shift_x", "shift_y", "ortho_scale", "clip_start", "clip_end"}
LIGHT_KEYS = {
    "point": ({"position", "power"}, {"color", "radius"}),
    "spot": ({"position", "direction", "power", "spot_size"}, {"color", "radius", "spot_blend"}),
    "sun": ({"direction", "strength"}, {"color", "angle"}),
    "area": ({"position", "axis_u", "axis_v", "shape", "size_x", "power"}, {"size_y", "color"}),
}


class Checker:
    def __init__(self, path):
        self.path = path
        self.errors = []
        self.warnings = []

    def err(self, msg):
        self.errors.append(msg)

    def warn(self, msg):
        self.warnings.append(msg)

    def num(self, v, what, lo=None, hi=None, lo_open=False):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.err(f"{what}: not a finite number ({v!r})")
            return False
        if lo is not None and (v < lo or (lo_open and v == lo)):
            self.err(f"{what}: {v} below {'or at ' if lo_open else ''}{lo}")
            return False
        if hi is not None and v > hi:
            self.err(f"{what}: {v} above {hi}")
            return False
        return True

    def vec(self, v, n, what, lo=None):
        if not isinstance(v, list) or len(v) != n:
            self.err(f"{what}: expected an array of {n} numbers")
            return False
        return all([self.num(x, f"{what}[{i}]", lo) for i, x in enumerate(v)])

    def keys(self, obj, required, optional, what):
        if not isinstance(obj, dict):
            self.err(f"{what}: expected an object")
            return False
        for k in required:
            if k not in obj:
                self.err(f"{what}: missing key {k!r}")
        for k in obj:
            if k not in required and k not in optional:
                self.err(f"{what}: unknown key {k!r}")
        return all(k in obj for k in required)


def check_image(c, img, what):
    if not isinstance(img, dict):
        c.err(f"{what}: expected an object")
        return
    if "path" in img:
        c.keys(img, {"path"}, set(), what)
        if not isinstance(img["path"], str) or not img["path"]:
            c.err(f"{what}.path: expected a non-empty string")
        elif not os.path.isabs(img["path"]):
            full = os.path.join(os.path.dirname(os.path.abspath(c.path)), img["path"])
            if not os.path.exists(full):
                c.warn(f"{what}.path: {full} does not exist")
        return
    if not c.keys(img, {"width", "height", "rgb"}, set(), what):
        return
    w, h, rgb = img["width"], img["height"], img["rgb"]
    if not (isinstance(w, int) and isinstance(h, int) and w > 0 and h > 0):
        c.err(f"{what}: width/height must be positive integers")
        return
    if not isinstance(rgb, list) or len(rgb) != 3 * w * h:
        c.err(f"{what}.rgb: expected {3 * w * h} numbers")
        return
    bad = sum(1 for x in rgb if isinstance(x, bool) or not isinstance(x, (int, float))
              or not math.isfinite(x) or x < 0)
    if bad:
        c.err(f"{what}.rgb: {bad} values not finite and >= 0")


def check_material(c, m, what):
    if not isinstance(m, dict) or m.get("model") not in ("blinn_phong", "principled"):
        c.err(f"{what}: expected an object with \"model\": \"blinn_phong\" | \"principled\"")
        return
    if m["model"] == "blinn_phong":
        if not c.keys(m, {"model", "kd", "ks", "ns"}, set(), what):
            return
        if c.vec(m["kd"], 3, f"{what}.kd", 0) and c.vec(m["ks"], 3, f"{what}.ks", 0):
            for i in range(3):
                if m["kd"][i] + m["ks"][i] > 1 + 1e-6:
                    c.err(f"{what}: kd + ks > 1 in channel {i}")
        c.num(m["ns"], f"{what}.ns", 0, lo_open=True)
    else:
        if not c.keys(m, {"model", "base_color"},
                      {"metallic", "roughness", "ior", "specular_ior_level", "subsurface_weight",
                       "subsurface_radius", "subsurface_scale"}, what):
            return
        if "subsurface_weight" in m:
            c.num(m["subsurface_weight"], f"{what}.subsurface_weight", 0, 1)
        if "subsurface_radius" in m:
            c.vec(m["subsurface_radius"], 3, f"{what}.subsurface_radius", 0)
        if "subsurface_scale" in m:
            c.num(m["subsurface_scale"], f"{what}.subsurface_scale", 0)
        c.vec(m["base_color"], 3, f"{what}.base_color", 0)
        for k, lo, hi in (("metallic", 0, 1), ("roughness", 0, 1), ("ior", 1, None),
                          ("specular_ior_level", 0, 1)):
            if k in m:
                c.num(m[k], f"{what}.{k}", lo, hi)


def check_unit(c, v, what, tol=1e-3):
    if c.vec(v, 3, what) and abs(vlen(v) - 1) > tol:
        c.err(f"{what}: not unit length ({vlen(v):.6f})")


def check_scene(path):
    """Validates one scene file; returns (errors, warnings, stats)."""
    c = Checker(path)
    stats = {}
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except (OSError, ValueError) as e:
        c.err(f"cannot read JSON: {e}")
        return c.errors, c.warnings, stats
    if not c.keys(doc, {"format", "version", "meshes", "regions", "camera", "resolution"},
                  {"lights", "world"}, "scene"):
        return c.errors, c.warnings, stats
    if doc["format"] != "relume-scene":
        c.err(f"format: expected \"relume-scene\", got {doc['format']!r}")
    if doc["version"] not in (1, 2):
        c.err(f"version: expected 1 or 2, got {doc['version']!r}")

    regions = doc["regions"]
    if not isinstance(regions, list) or not regions:
        c.err("regions: expected a non-empty array")
        regions = []
    names = set()
    for i, r in enumerate(regions):
        w = f"regions[{i}]"
        if not c.keys(r, {"name", "material"},
                      {"editable", "albedo_texture", "ns_range", "subsurface"}, w):
            continue
        if "subsurface" in r:
            if doc["version"] < 2:
                c.err(f"{w}.subsurface: needs scene format version 2")
            ss = r["subsurface"]
            if c.keys(ss, set(), {"samples", "mfp_range", "ior_range", "bases", "tolerance"},
                      f"{w}.subsurface") and "samples" in ss:
                c.num(ss["samples"], f"{w}.subsurface.samples", 16, 4194304)
        if not isinstance(r["name"], str) or not r["name"]:
            c.err(f"{w}.name: expected a non-empty string")
        elif r["name"] in names:
            c.err(f"{w}.name: duplicate {r['name']!r}")
        names.add(r.get("name"))
        if "editable" in r and not isinstance(r["editable"], bool):
            c.err(f"{w}.editable: expected true/false")
        check_material(c, r["material"], f"{w}.material")
        if r.get("albedo_texture") is not None:
            check_image(c, r["albedo_texture"], f"{w}.albedo_texture")
        if r.get("ns_range") is not None:
            if c.vec(r["ns_range"], 2, f"{w}.ns_range", 0) and not (
                    0 < r["ns_range"][0] < r["ns_range"][1]):
                c.err(f"{w}.ns_range: expected 0 < min < max")
    textured = {i for i, r in enumerate(regions) if isinstance(r, dict) and r.get("albedo_texture")}

    meshes = doc["meshes"]
    if not isinstance(meshes, list) or not meshes:
        c.err("meshes: expected a non-empty array")
        meshes = []
    tri_total, vert_total = 0, 0
    used = [0] * len(regions)
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    for mi, m in enumerate(meshes):
        w = f"meshes[{mi}]"
        if not c.keys(m, {"positions", "indices"},
                      {"name", "normals", "uvs", "region", "triangle_regions"}, w):
            continue
        pos = m["positions"]
        nv = len(pos) if isinstance(pos, list) else 0
        ok = isinstance(pos, list) and nv > 0
        for k, p in enumerate(pos if ok else []):
            if not (isinstance(p, list) and len(p) == 3 and all(
                    isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                    for x in p)):
                c.err(f"{w}.positions[{k}]: expected 3 finite numbers")
                ok = False
                break
        if not ok:
            c.err(f"{w}.positions: invalid")
            continue
        for a in range(3):
            lo[a] = min(lo[a], min(p[a] for p in pos))
            hi[a] = max(hi[a], max(p[a] for p in pos))
        nrm = m.get("normals")
        if nrm is not None:
            if not isinstance(nrm, list) or len(nrm) != nv:
                c.err(f"{w}.normals: expected {nv} entries (one per vertex)")
                nrm = None
            else:
                bad = 0
                for n in nrm:
                    if not (isinstance(n, list) and len(n) == 3 and all(
                            isinstance(x, (int, float)) and math.isfinite(x) for x in n)
                            and abs(vlen(n) - 1) < 1e-3):
                        bad += 1
                if bad:
                    c.err(f"{w}.normals: {bad} not finite unit vectors")
                    nrm = None
        uvs = m.get("uvs")
        if uvs is not None:
            if not isinstance(uvs, list) or len(uvs) != nv or not all(
                    isinstance(t, list) and len(t) == 2 and all(
                        isinstance(x, (int, float)) and math.isfinite(x) for x in t)
                    for t in uvs):
                c.err(f"{w}.uvs: expected {nv} pairs of finite numbers")
                uvs = None
        idx = m["indices"]
        if not isinstance(idx, list) or not idx:
            c.err(f"{w}.indices: expected a non-empty array")
            continue
        nt = len(idx)
        tri_regs = m.get("triangle_regions")
        if tri_regs is not None:
            if not isinstance(tri_regs, list) or len(tri_regs) != nt or not all(
                    isinstance(r, int) and not isinstance(r, bool) and 0 <= r < len(regions)
                    for r in tri_regs):
                c.err(f"{w}.triangle_regions: expected {nt} region indices < {len(regions)}")
                tri_regs = None
        else:
            reg = m.get("region", 0)
            if not (isinstance(reg, int) and not isinstance(reg, bool) and 0 <= reg < len(regions)):
                c.err(f"{w}.region: {reg!r} is not a region index < {len(regions)}")
                reg = None
        bad_idx = degenerate = flipped = 0
        for t, tri in enumerate(idx):
            if not (isinstance(tri, list) and len(tri) == 3 and all(
                    isinstance(i, int) and not isinstance(i, bool) and 0 <= i < nv for i in tri)):
                bad_idx += 1
                continue
            a, b, cc = (pos[i] for i in tri)
            g = vcross(vsub(b, a), vsub(cc, a))
            area2 = vlen(g)
            scale = max(vlen(vsub(b, a)), vlen(vsub(cc, a)), vlen(vsub(cc, b)))
            if area2 <= 1e-10 * max(scale * scale, 1e-30) or area2 < 1e-14:
                degenerate += 1
                continue
            if nrm is not None:
                ns = vadd(vadd(nrm[tri[0]], nrm[tri[1]]), nrm[tri[2]])
                if vdot(ns, g) <= 0:
                    flipped += 1
            r = tri_regs[t] if tri_regs is not None else (
                None if "triangle_regions" in m else reg)
            if r is not None and 0 <= r < len(regions):
                used[r] += 1
                if r in textured and uvs is None:
                    c.err(f"{w}: triangle {t} is in textured region {r} but the mesh has no uvs")
                    textured.discard(r)
        if bad_idx:
            c.err(f"{w}.indices: {bad_idx} triangles with indices out of [0, {nv})")
        if degenerate:
            c.err(f"{w}: {degenerate} zero-area triangles")
        if flipped:
            c.err(f"{w}: {flipped} triangles whose winding disagrees with their vertex normals")
        tri_total += nt
        vert_total += nv
    for r, n in enumerate(used):
        if n == 0:
            c.warn(f"regions[{r}] ({regions[r].get('name')!r}) has no triangles")

    lights = doc.get("lights", [])
    if not isinstance(lights, list):
        c.err("lights: expected an array")
        lights = []
    if not lights and doc.get("world", {}).get("type", "color") == "color" and not any(
            doc.get("world", {}).get("color", [0, 0, 0])):
        c.warn("no lights and a black world: the image is black")
    for i, l in enumerate(lights):
        w = f"lights[{i}]"
        t = l.get("type") if isinstance(l, dict) else None
        if t not in LIGHT_KEYS:
            c.err(f"{w}.type: expected one of {sorted(LIGHT_KEYS)}")
            continue
        req, opt = LIGHT_KEYS[t]
        if not c.keys(l, req | {"type"}, opt, w):
            continue
        if "position" in l:
            c.vec(l["position"], 3, f"{w}.position")
        if "power" in l:
            c.num(l["power"], f"{w}.power", 0)
        if "color" in l:
            c.vec(l["color"], 3, f"{w}.color", 0)
        if "radius" in l:
            c.num(l["radius"], f"{w}.radius", 0)
        if t in ("spot", "sun"):
            check_unit(c, l["direction"], f"{w}.direction")
        if t == "spot":
            c.num(l["spot_size"], f"{w}.spot_size", 0, math.pi, lo_open=True)
            if "spot_blend" in l:
                c.num(l["spot_blend"], f"{w}.spot_blend", 0, 1)
        if t == "sun":
            c.num(l["strength"], f"{w}.strength", 0)
            if "angle" in l:
                c.num(l["angle"], f"{w}.angle", 0, math.pi)
        if t == "area":
            check_unit(c, l["axis_u"], f"{w}.axis_u")
            check_unit(c, l["axis_v"], f"{w}.axis_v")
            if (c.vec(l["axis_u"], 3, f"{w}.axis_u") and c.vec(l["axis_v"], 3, f"{w}.axis_v")
                    and abs(vdot(l["axis_u"], l["axis_v"])) > 1e-3):
                c.err(f"{w}: axis_u and axis_v are not orthogonal")
            if l["shape"] not in ("square", "rectangle", "disk", "ellipse"):
                c.err(f"{w}.shape: expected square | rectangle | disk | ellipse")
            c.num(l["size_x"], f"{w}.size_x", 0, lo_open=True)
            if l["shape"] in ("rectangle", "ellipse"):
                if l.get("size_y") is None:
                    c.err(f"{w}.size_y: required for shape {l['shape']!r}")
                else:
                    c.num(l["size_y"], f"{w}.size_y", 0, lo_open=True)

    world = doc.get("world", {"type": "color", "color": [0, 0, 0]})
    t = world.get("type") if isinstance(world, dict) else None
    if t == "color":
        if c.keys(world, {"type", "color"}, {"strength"}, "world"):
            c.vec(world["color"], 3, "world.color", 0)
    elif t == "equirect":
        if c.keys(world, {"type", "image"}, {"strength"}, "world"):
            check_image(c, world["image"], "world.image")
    else:
        c.err("world.type: expected \"color\" | \"equirect\"")
    if isinstance(world, dict) and "strength" in world:
        c.num(world["strength"], "world.strength", 0)

    cam = doc["camera"]
    if c.keys(cam, {"projection", "matrix_world"}, CAMERA_KEYS, "camera"):
        if cam["projection"] not in ("perspective", "orthographic"):
            c.err("camera.projection: expected \"perspective\" | \"orthographic\"")
        m = cam["matrix_world"]
        if (isinstance(m, list) and len(m) == 4 and all(
                c.vec(row, 4, f"camera.matrix_world[{i}]") for i, row in enumerate(m))):
            if [float(x) for x in m[3]] != [0.0, 0.0, 0.0, 1.0]:
                c.err("camera.matrix_world: last row must be [0, 0, 0, 1]")
            cols = [tuple(m[r][k] for r in range(3)) for k in range(3)]
            for a in range(3):
                for b in range(3):
                    want = 1.0 if a == b else 0.0
                    if abs(vdot(cols[a], cols[b]) - want) > 1e-4:
                        c.err("camera.matrix_world: rotation part is not orthonormal "
                              "(no scale or shear allowed)")
                        break
                else:
                    continue
                break
            if vdot(vcross(cols[0], cols[1]), cols[2]) < 0:
                c.err("camera.matrix_world: rotation part has determinant -1")
        else:
            c.err("camera.matrix_world: expected 4 rows of 4 numbers")
        for k, lo_, open_ in (("lens_mm", 0, True), ("sensor_width_mm", 0, True),
                              ("sensor_height_mm", 0, True), ("ortho_scale", 0, True),
                              ("clip_start", 0, True), ("clip_end", 0, True),
                              ("shift_x", None, False), ("shift_y", None, False)):
            if k in cam:
                c.num(cam[k], f"camera.{k}", lo_, lo_open=open_)
        if cam.get("sensor_fit", "auto") not in ("auto", "horizontal", "vertical"):
            c.err("camera.sensor_fit: expected \"auto\" | \"horizontal\" | \"vertical\"")
        if cam.get("clip_start", 1e-4) >= cam.get("clip_end", 1e30):
            c.err("camera: clip_start must be below clip_end")
    res = doc["resolution"]
    if c.keys(res, {"width", "height"}, set(), "resolution"):
        for k in ("width", "height"):
            if not (isinstance(res[k], int) and not isinstance(res[k], bool) and res[k] > 0):
                c.err(f"resolution.{k}: expected a positive integer")

    stats = {
        "triangles": tri_total,
        "vertices": vert_total,
        "meshes": len(meshes),
        "regions": len(regions),
        "editable": [r.get("name") for r in regions if isinstance(r, dict) and r.get("editable")],
        "lights": [l.get("type") for l in lights if isinstance(l, dict)],
        "bounds": [lo, hi],
        "bytes": os.path.getsize(path),
    }
    return c.errors, c.warnings, stats


def report(path):
    errors, warnings, s = check_scene(path)
    for w in warnings:
        print(f"  warning: {w}")
    for e in errors[:50]:
        print(f"  ERROR: {e}")
    if len(errors) > 50:
        print(f"  ... and {len(errors) - 50} more errors")
    if s:
        lo, hi = s["bounds"]
        print(f"  {path}: {s['triangles']} triangles, {s['vertices']} vertices, "
              f"{s['meshes']} meshes, {s['regions']} regions (editable: "
              f"{', '.join(s['editable']) or 'none'}), lights: {', '.join(s['lights']) or 'none'}, "
              f"bounds [{', '.join(f'{x:.3g}' for x in lo)}]..[{', '.join(f'{x:.3g}' for x in hi)}], "
              f"{s['bytes'] / 1e6:.2f} MB — {'OK' if not errors else 'INVALID'}")
    return not errors


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("scenes", nargs="*", metavar="SCENE",
                    help=f"scenes to build (default: all of {', '.join(SCENES)})")
    ap.add_argument("--out", default=os.path.dirname(os.path.abspath(__file__)),
                    help="output folder (default: the folder of this script, assets/)")
    ap.add_argument("--check", nargs="+", metavar="FILE",
                    help="only validate these scene files, build nothing")
    ap.add_argument("--list", action="store_true", help="list the scenes and exit")
    args = ap.parse_args(argv)

    if args.list:
        for name, (fn, rel) in SCENES.items():
            print(f"{name:12s} {rel:40s} {fn.__doc__.strip().splitlines()[0]}")
        return 0
    if args.check:
        ok = True
        for path in args.check:
            print(f"checking {path}")
            ok &= report(path)
        return 0 if ok else 1
    unknown = [s for s in args.scenes if s not in SCENES]
    if unknown:
        ap.error(f"unknown scene(s) {', '.join(unknown)}; choose from {', '.join(SCENES)}")
    ok = True
    for name in args.scenes or list(SCENES):
        fn, rel = SCENES[name]
        path = os.path.join(args.out, rel)
        print(f"building {name} -> {path}")
        write_scene(fn(), path)
        ok &= report(path)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
