#!/usr/bin/env python3
"""Quick sanity preview of a Relume scene file (format v1): ray casting, direct light only.

Python 3.11+, standard library only. Usage:

    python3 assets/preview.py assets/cornell.scene.json                 # -> cornell.preview.png
    python3 assets/preview.py SCENE --width 128 --out /tmp/p.png --exposure 1

It checks framing and light placement, not the look: diffuse albedo (Kd, or Principled
base colour) x direct irradiance from every light (point, spot, sun, area; with shadow
rays, area lights sampled on a 4 x 4 grid), plus the constant world as unoccluded
ambient, at exposure 0 (or --exposure EV), sRGB-encoded. Conventions are the scene
file's (docs/scene-format.md): Blender camera (local -Z forward, +Y up; sensor fit; shift
in units of the fitted image dimension), area lights one-sided along -(axis_u x axis_v),
visible to the camera. Back faces show magenta: a surface seen from behind means wrong
winding (or a camera outside a room). Lights are marked with a yellow cross.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import struct
import sys
import time
import zlib

INF = float("inf")


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a):
    n = math.sqrt(dot(a, a))
    return (a[0] / n, a[1] / n, a[2] / n) if n > 0 else a


# ---------------------------------------------------------------------------------------
# Triangles + a median-split BVH (flat arrays).


class Bvh:
    def __init__(self, tris):
        # tris: list of (p0, e1, e2) with e1 = p1 - p0, e2 = p2 - p0
        self.tris = tris
        n = len(tris)
        self.order = list(range(n))
        cent, lo, hi = [], [], []
        for p0, e1, e2 in tris:
            p1 = (p0[0] + e1[0], p0[1] + e1[1], p0[2] + e1[2])
            p2 = (p0[0] + e2[0], p0[1] + e2[1], p0[2] + e2[2])
            l = (min(p0[0], p1[0], p2[0]), min(p0[1], p1[1], p2[1]), min(p0[2], p1[2], p2[2]))
            h = (max(p0[0], p1[0], p2[0]), max(p0[1], p1[1], p2[1]), max(p0[2], p1[2], p2[2]))
            lo.append(l)
            hi.append(h)
            cent.append(((l[0] + h[0]) / 2, (l[1] + h[1]) / 2, (l[2] + h[2]) / 2))
        # node: [lox, loy, loz, hix, hiy, hiz, left_or_start, right_or_-count]
        self.nodes = []
        self._build(0, n, cent, lo, hi)

    def _build(self, start, end, cent, lo, hi):
        idx = self.order
        bl = [INF] * 3
        bh = [-INF] * 3
        for i in idx[start:end]:
            for a in range(3):
                if lo[i][a] < bl[a]:
                    bl[a] = lo[i][a]
                if hi[i][a] > bh[a]:
                    bh[a] = hi[i][a]
        node = len(self.nodes)
        self.nodes.append(None)
        if end - start <= 4:
            self.nodes[node] = (bl[0], bl[1], bl[2], bh[0], bh[1], bh[2], start, -(end - start))
            return node
        ext = [bh[a] - bl[a] for a in range(3)]
        axis = ext.index(max(ext))
        part = sorted(idx[start:end], key=lambda i: cent[i][axis])
        idx[start:end] = part
        mid = (start + end) // 2
        left = self._build(start, mid, cent, lo, hi)
        right = self._build(mid, end, cent, lo, hi)
        self.nodes[node] = (bl[0], bl[1], bl[2], bh[0], bh[1], bh[2], left, right)
        return node

    def intersect(self, o, d, tmax, any_hit=False):
        """Closest hit (t, tri, u, v) with t in (1e-6 .. tmax), or None."""
        ox, oy, oz = o
        dx, dy, dz = d
        ix = 1 / dx if dx != 0 else INF
        iy = 1 / dy if dy != 0 else INF
        iz = 1 / dz if dz != 0 else INF
        nodes, tris, order = self.nodes, self.tris, self.order
        best = None
        stack = [0]
        while stack:
            n = nodes[stack.pop()]
            t0 = (n[0] - ox) * ix
            t1 = (n[3] - ox) * ix
            if t0 > t1:
                t0, t1 = t1, t0
            s0 = (n[1] - oy) * iy
            s1 = (n[4] - oy) * iy
            if s0 > s1:
                s0, s1 = s1, s0
            if s0 > t0:
                t0 = s0
            if s1 < t1:
                t1 = s1
            s0 = (n[2] - oz) * iz
            s1 = (n[5] - oz) * iz
            if s0 > s1:
                s0, s1 = s1, s0
            if s0 > t0:
                t0 = s0
            if s1 < t1:
                t1 = s1
            if t0 > t1 or t1 < 0 or t0 > tmax:
                continue
            if n[7] < 0:
                for k in range(n[6], n[6] - n[7]):
                    ti = order[k]
                    p0, e1, e2 = tris[ti]
                    px = dy * e2[2] - dz * e2[1]
                    py = dz * e2[0] - dx * e2[2]
                    pz = dx * e2[1] - dy * e2[0]
                    det = e1[0] * px + e1[1] * py + e1[2] * pz
                    if -1e-14 < det < 1e-14:
                        continue
                    inv = 1 / det
                    tx, ty, tz = ox - p0[0], oy - p0[1], oz - p0[2]
                    u = (tx * px + ty * py + tz * pz) * inv
                    if u < 0 or u > 1:
                        continue
                    qx = ty * e1[2] - tz * e1[1]
                    qy = tz * e1[0] - tx * e1[2]
                    qz = tx * e1[1] - ty * e1[0]
                    v = (dx * qx + dy * qy + dz * qz) * inv
                    if v < 0 or u + v > 1:
                        continue
                    t = (e2[0] * qx + e2[1] * qy + e2[2] * qz) * inv
                    if 1e-6 < t < tmax:
                        tmax = t
                        best = (t, ti, u, v)
                        if any_hit:
                            return best
            else:
                stack.append(n[6])
                stack.append(n[7])
        return best


# ---------------------------------------------------------------------------------------
# Scene.


def load_image(img, scene_path):
    if "rgb" in img:
        return img
    print(f"note: image {img.get('path')} is not inline; previewing it as grey", file=sys.stderr)
    return None


def albedo_of(region):
    m = region["material"]
    if m["model"] == "blinn_phong":
        return tuple(m["kd"])
    base = m["base_color"]
    met = m.get("metallic", 0.0)
    return tuple(c * (1 - met) for c in base)


def sample_texture(img, u, v):
    w, h = img["width"], img["height"]
    x = int((u % 1.0) * w) % w              # repeat, nearest texel
    y = int((1.0 - (v % 1.0)) * h) % h      # row 0 is the top of the image (v = 1)
    k = 3 * (y * w + x)
    rgb = img["rgb"]
    return rgb[k], rgb[k + 1], rgb[k + 2]


class Scene:
    def __init__(self, path):
        with open(path, encoding="utf-8") as f:
            self.doc = doc = json.load(f)
        self.regions = doc["regions"]
        self.textures = [load_image(r["albedo_texture"], path) if r.get("albedo_texture")
                         else None for r in self.regions]
        self.tris = []      # (p0, e1, e2)
        self.info = []      # (mesh index, triangle index, region)
        self.meshes = doc["meshes"]
        for mi, m in enumerate(self.meshes):
            P = m["positions"]
            tr = m.get("triangle_regions")
            for t, (a, b, c) in enumerate(m["indices"]):
                p0 = tuple(P[a])
                self.tris.append((p0, sub(P[b], p0), sub(P[c], p0)))
                self.info.append((mi, t, tr[t] if tr else m.get("region", 0)))
        t0 = time.time()
        self.bvh = Bvh(self.tris)
        self.build_s = time.time() - t0
        self.lights = doc.get("lights", [])
        w = doc.get("world", {"type": "color", "color": [0, 0, 0]})
        if w["type"] == "color":
            s = w.get("strength", 1.0)
            self.ambient = tuple(c * s for c in w["color"])
        else:
            self.ambient = (0.2, 0.2, 0.2)
            print("note: equirect world previewed as constant 0.2", file=sys.stderr)
        self.area_samples = [self._area_points(l) for l in self.lights]

    def _area_points(self, l):
        if l["type"] != "area":
            return None
        sx = l["size_x"]
        sy = l.get("size_y") if l["shape"] in ("rectangle", "ellipse") else sx
        round_ = l["shape"] in ("disk", "ellipse")
        area = math.pi * sx * sy / 4 if round_ else sx * sy
        u, v, c = l["axis_u"], l["axis_v"], l["position"]
        pts = []
        k = 4
        for i in range(k):
            for j in range(k):
                a, b = (i + 0.5) / k - 0.5, (j + 0.5) / k - 0.5
                if round_ and a * a + b * b > 0.25:
                    continue
                pts.append(tuple(c[q] + u[q] * a * sx + v[q] * b * sy for q in range(3)))
        n_emit = norm(cross(u, v))
        n_emit = (-n_emit[0], -n_emit[1], -n_emit[2])
        return pts, area, n_emit, sx, sy, round_

    def visible(self, x, y):
        d = sub(y, x)
        dist = math.sqrt(dot(d, d))
        d = (d[0] / dist, d[1] / dist, d[2] / dist)
        return self.bvh.intersect(x, d, dist * (1 - 1e-4), any_hit=True) is None

    def shade_point(self, x, n):
        """Irradiance at x with normal n from all lights (W/m^2, RGB)."""
        E = [0.0, 0.0, 0.0]
        for l, area in zip(self.lights, self.area_samples):
            col = l.get("color", [1, 1, 1])
            t = l["type"]
            if t in ("point", "spot"):
                d = sub(l["position"], x)
                d2 = dot(d, d)
                ld = norm(d)
                cos = dot(n, ld)
                if cos <= 0:
                    continue
                e = l["power"] / (4 * math.pi * d2) * cos
                if t == "spot":
                    ca = dot(l["direction"], (-ld[0], -ld[1], -ld[2]))
                    ch = math.cos(l["spot_size"] / 2)
                    if ca <= ch:
                        continue
                    smooth = (1 - ch) * l.get("spot_blend", 0.0)
                    if ca - ch < smooth:
                        s = (ca - ch) / smooth
                        e *= s * s * (3 - 2 * s)
                if not self.visible(x, l["position"]):
                    continue
                E = [E[q] + e * col[q] for q in range(3)]
            elif t == "sun":
                ld = (-l["direction"][0], -l["direction"][1], -l["direction"][2])
                cos = dot(n, ld)
                if cos <= 0:
                    continue
                if self.bvh.intersect(x, ld, INF, any_hit=True) is not None:
                    continue
                E = [E[q] + l["strength"] * cos * col[q] for q in range(3)]
            elif t == "area":
                pts, A, ne, *_ = area
                L = l["power"] / (math.pi * A)
                dA = A / len(pts)
                for p in pts:
                    d = sub(p, x)
                    d2 = dot(d, d)
                    ld = norm(d)
                    cos = dot(n, ld)
                    cosl = -dot(ne, ld)
                    if cos <= 0 or cosl <= 0 or not self.visible(x, p):
                        continue
                    e = L * dA * cos * cosl / d2
                    E = [E[q] + e * col[q] for q in range(3)]
        return E

    def hit_light(self, o, d, tmax):
        """Radiance of a light the camera ray meets before tmax, or None."""
        best, rad = tmax, None
        for l, area in zip(self.lights, self.area_samples):
            col = l.get("color", [1, 1, 1])
            if l["type"] == "area":
                pts, A, ne, sx, sy, round_ = area
                denom = dot(d, ne)
                if denom >= 0:      # seen from behind: one-sided
                    continue
                t = dot(sub(l["position"], o), ne) / denom
                if not (0 < t < best):
                    continue
                p = tuple(o[q] + d[q] * t for q in range(3))
                r = sub(p, l["position"])
                a, b = dot(r, l["axis_u"]) / sx, dot(r, l["axis_v"]) / sy
                inside = (a * a + b * b <= 0.25) if round_ else (abs(a) <= 0.5 and abs(b) <= 0.5)
                if inside:
                    L = l["power"] / (math.pi * A)
                    best, rad = t, tuple(L * c for c in col)
            elif l["type"] in ("point", "spot") and l.get("radius", 0) > 0:
                oc = sub(o, l["position"])
                bq = dot(oc, d)
                cq = dot(oc, oc) - l["radius"] ** 2
                disc = bq * bq - cq
                if disc > 0:
                    t = -bq - math.sqrt(disc)
                    if 0 < t < best:
                        L = l["power"] / (4 * math.pi * math.pi * l["radius"] ** 2)
                        best, rad = t, tuple(L * c for c in col)
        return rad

    def shade(self, o, d, tmin, tmax):
        h = self.bvh.intersect(o, d, tmax)
        tl = h[0] if h else tmax
        lr = self.hit_light(o, d, tl)
        if lr is not None:
            return lr, True
        if h is None:
            return self.ambient, True
        t, ti, u, v = h
        if t < tmin:
            return (0.0, 0.0, 0.0), True
        p0, e1, e2 = self.tris[ti]
        ng = norm(cross(e1, e2))
        if dot(ng, d) > 0:
            return (1.0, 0.0, 1.0), False    # back face: magenta
        mi, tt, reg = self.info[ti]
        m = self.meshes[mi]
        ia, ib, ic = m["indices"][tt]
        w = 1 - u - v
        n = ng
        if m.get("normals"):
            N = m["normals"]
            n = norm(tuple(w * N[ia][q] + u * N[ib][q] + v * N[ic][q] for q in range(3)))
        alb = albedo_of(self.regions[reg])
        tex = self.textures[reg]
        if tex is not None and m.get("uvs"):
            UV = m["uvs"]
            uu = w * UV[ia][0] + u * UV[ib][0] + v * UV[ic][0]
            vv = w * UV[ia][1] + u * UV[ib][1] + v * UV[ic][1]
            tc = sample_texture(tex, uu, vv)
            alb = tuple(alb[q] * tc[q] for q in range(3))
        x = tuple(o[q] + d[q] * t + ng[q] * 1e-4 for q in range(3))
        E = self.shade_point(x, n)
        return tuple(alb[q] / math.pi * E[q] + alb[q] * self.ambient[q] for q in range(3)), True


# ---------------------------------------------------------------------------------------
# Camera (Blender conventions).


class Camera:
    def __init__(self, cam, width, height):
        M = cam["matrix_world"]
        self.R = [[M[r][c] for c in range(3)] for r in range(3)]
        self.eye = (M[0][3], M[1][3], M[2][3])
        self.w, self.h = width, height
        fit = cam.get("sensor_fit", "auto")
        if fit == "auto":
            horizontal = width >= height
            sensor = cam.get("sensor_width_mm", 36.0)
        elif fit == "horizontal":
            horizontal, sensor = True, cam.get("sensor_width_mm", 36.0)
        else:
            horizontal, sensor = False, cam.get("sensor_height_mm", 24.0)
        self.persp = cam["projection"] == "perspective"
        if self.persp:
            full = sensor / cam.get("lens_mm", 50.0)       # fitted extent at distance 1
        else:
            full = cam.get("ortho_scale", 6.0)
        if horizontal:
            self.half_w, self.half_h = full / 2, full / 2 * height / width
        else:
            self.half_w, self.half_h = full / 2 * width / height, full / 2
        self.sx, self.sy = cam.get("shift_x", 0.0) * full, cam.get("shift_y", 0.0) * full
        self.clip = (cam.get("clip_start", 1e-4), cam.get("clip_end", 1e30))

    def to_world(self, v):
        R = self.R
        return tuple(R[r][0] * v[0] + R[r][1] * v[1] + R[r][2] * v[2] for r in range(3))

    def ray(self, px, py):
        """Ray through pixel centre (px, py); py = 0 is the top row."""
        a = ((px + 0.5) / self.w * 2 - 1) * self.half_w + self.sx
        b = (1 - (py + 0.5) / self.h * 2) * self.half_h + self.sy
        if self.persp:
            d = self.to_world((a, b, -1.0))
            inv = 1 / math.sqrt(dot(d, d))
            # clip distances are depths along the view axis: convert to ray lengths
            return self.eye, norm(d), self.clip[0] / inv, self.clip[1] / inv
        o = self.to_world((a, b, 0.0))
        return (tuple(self.eye[q] + o[q] for q in range(3)), self.to_world((0, 0, -1.0)),
                self.clip[0], self.clip[1])

    def project(self, p):
        """Pixel coordinates of world point p, or None behind the camera."""
        d = sub(p, self.eye)
        R = self.R
        c = tuple(R[0][k] * d[0] + R[1][k] * d[1] + R[2][k] * d[2] for k in range(3))
        if self.persp:
            if c[2] >= 0:
                return None
            a, b = c[0] / -c[2], c[1] / -c[2]
        else:
            a, b = c[0], c[1]
        px = ((a - self.sx) / self.half_w + 1) / 2 * self.w
        py = (1 - (b - self.sy) / self.half_h) / 2 * self.h
        return px, py


# ---------------------------------------------------------------------------------------


def write_png(path, width, height, pixels):
    raw = b"".join(b"\x00" + bytes(pixels[y * width * 3:(y + 1) * width * 3]) for y in range(height))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))
    with open(path, "wb") as f:
        f.write(png)


def srgb(x):
    x = max(0.0, min(1.0, x))
    return 12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--width", type=int, default=96, help="preview width in pixels (default 96)")
    ap.add_argument("--exposure", type=float, default=0.0, help="exposure in EV (default 0)")
    ap.add_argument("--out", help="PNG path (default: SCENE with .preview.png)")
    args = ap.parse_args(argv)

    scene = Scene(args.scene)
    res = scene.doc["resolution"]
    W = args.width
    H = max(1, round(W * res["height"] / res["width"]))
    cam = Camera(scene.doc["camera"], W, H)
    scale = 2.0 ** args.exposure
    t0 = time.time()
    px = bytearray()
    back = 0
    lum = []
    for y in range(H):
        for x in range(W):
            o, d, tmin, tmax = cam.ray(x, y)
            c, front = scene.shade(o, d, tmin, tmax)
            back += not front
            lum.append(0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2])
            px += bytes(int(round(255 * srgb(v * scale))) for v in c)
    for l in scene.lights:            # yellow crosses on light positions
        if "position" not in l:
            continue
        p = cam.project(l["position"])
        if p is None:
            continue
        cx, cy = int(p[0]), int(p[1])
        for k in range(-2, 3):
            for (qx, qy) in ((cx + k, cy), (cx, cy + k)):
                if 0 <= qx < W and 0 <= qy < H:
                    px[3 * (qy * W + qx):3 * (qy * W + qx) + 3] = b"\xff\xd0\x00"
    out = args.out or (args.scene[:-5] if args.scene.endswith(".json") else args.scene) + ".preview.png"
    write_png(out, W, H, px)
    lum.sort()
    print(f"{args.scene}: {len(scene.tris)} triangles (BVH {scene.build_s:.1f} s), {W}x{H} in "
          f"{time.time() - t0:.1f} s; back-facing pixels {back}; luminance median "
          f"{lum[len(lum) // 2]:.3f}, 95% {lum[int(len(lum) * 0.95)]:.3f} -> {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
