"""Measures a BRDF basis built from Cycles' Principled lobes (issue 15), numpy only.

What it measures (docs/principled_basis_study.md has the figures and the decision):

1. Basis size against error. The lobes are Cycles' Principled specular reflection as
   `core/engine/src/brdf/cycles_principled/` evaluates it (ported here: GGX, α = r², the
   height-correlated Smith G, Schlick / exact dielectric Fresnel, Kulla-Conty multiple
   scattering `1 + Fms·(1 − E(μo))/E(μo)` with E from the same half-vector quadrature and
   48-node μ table), for 96 roughness values uniform in ln r over [0.1, 1]. Families: metals
   (Schlick, F0 = base colour; trained on F0 ∈ {0, .25, .5, .75, 1}, tested also at 0.1 and
   0.9) and dielectrics (exact Fresnel, Specular IOR Level 0.5, IOR 1.5; tested at 1.33 and
   1.8). PCA without mean subtraction, the constant `1/π` in the fit (its own slot, counted in
   N_b, as the engine's default), lobes normalised to unit norm, unit and Lawson-capped lobe
   weights. Reported: the mean and worst relative L2 error ‖f − Pf‖/‖f‖ of every lobe over
   N_b = 4…16, under the cos-weighted measure `cos θi cos θo dωi dωo` and under the uniform
   measure `dθi dθo dφ`. And the best single Blinn–Phong `Kd/π + Ks·(ns+2)/(8π) cos^ns δ`
   (ns on a log scan, Kd, Ks by least squares, free or with Kd, Ks ≥ 0, Kd + Ks ≤ 1) against
   the same lobes under the cos-weighted measure.
2. Linearity: coefficients c_k(r) of a lobe tabulated on 256 nodes (uniform in r, √r or
   ln r), linearly interpolated, against the direct projection at the midpoints.
3. f16 risk: the cancellation factor Σ|c_k ρ̃_k(ω)| / |Σ c_k ρ̃_k(ω)| of the roughness-0.1
   lobe at mirror, near-mirror and grazing configurations, against the Blinn–Phong PCA basis
   over ns ∈ [1, 22 809] at the same count.
4. Table cost: the φd dependence of the bases, and the nodes of a trilinear (θh, θd, φd)
   table (θh on the engine's warp of √(1 − cos θh)) that reach an interpolation error below
   1e-3 of the basis RMS.
5. Other table parametrisations, measured as part 4 (same bases, quantity ρ̃_k·cos θi·cos θo,
   trilinear, same error columns): (θh, θd, φd) with θd warped (uniform in 1 − cos θd, in
   1 − √(1 − sin θd), or in a rational warp of cos θd dense at 90°); θd measured from the
   horizon (the horizon a table face); the "lune" (θh, ψ, η), ωd's position in h's frame, in
   which both horizons are faces; θh on the engine's warp or blended half-and-half with
   uniform θh; (θi, θo, φ) on cos-warped axes. Each is checked first (round trip of the
   quadrature's directions through its coordinates; a table of a product of affine functions
   of its coordinates, which trilinear must reproduce to rounding). Then a size sweep of the
   best. `--tables-only` builds the metal basis and runs parts 4 and 5 alone (about 5 min).

The integrals run on a product quadrature in Rusinkiewicz's (θh, θd, φd) with a graded θh
mesh (the continuum limit of the (θi, θo, φ) grid; a uniform grid of cell centres does not
resolve a roughness-0.1 lobe, which part 0 shows on 32×32×64 and 64×64×128 grids). `--check`
doubles the quadrature to show convergence.

Run (about 10 minutes on one busy core; `--check` adds a few):

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 nice -n 10 python3 scripts/principled_basis_study.py \
        [--check] [--json out.json]
"""

import argparse
import json
import time

import numpy as np

PI = np.pi
HALF_PI = 0.5 * np.pi

# ---------------------------------------------------------------------------------------
# Port of core/engine/src/brdf/cycles_principled/ggx.rs


def ggx_d(alpha, cos_h):
    a2 = alpha * alpha
    t = 1.0 + (a2 - 1.0) * cos_h * cos_h
    return np.where(cos_h > 0.0, a2 / (PI * t * t), 0.0)


def ggx_lambda(alpha, cos_t):
    c2 = np.maximum(cos_t * cos_t, 1e-300)
    tan2 = np.maximum(1.0 / c2 - 1.0, 0.0)
    return 0.5 * (np.sqrt(1.0 + alpha * alpha * tan2) - 1.0)


def ggx_single(alpha, cos_i, cos_o, cos_h):
    """`D·G/(4 cos θi cos θo)` with Fresnel 1; 0 below the surface."""
    ok = (cos_i > 0.0) & (cos_o > 0.0)
    ci = np.where(ok, cos_i, 1.0)
    co = np.where(ok, cos_o, 1.0)
    g = 1.0 / (1.0 + ggx_lambda(alpha, ci) + ggx_lambda(alpha, co))
    return np.where(ok, ggx_d(alpha, cos_h) * g / (4.0 * ci * co), 0.0)


def fresnel_dielectric(cos, eta):
    c = np.abs(cos)
    g2 = eta * eta - 1.0 + c * c
    g = np.sqrt(np.maximum(g2, 0.0))
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return np.where(g2 <= 0.0, 1.0, 0.5 * a * a * (1.0 + b * b))


def f0_from_ior(eta):
    r = (eta - 1.0) / (eta + 1.0)
    return r * r


def fresnel_dielectric_average(eta):
    return (eta - 1.0) / (4.08567 + 1.00071 * eta)


def schlick_weight(cos):
    """`(1 − cos)⁵`: Schlick's F = F0·(1 − w) + w."""
    s = np.clip(1.0 - cos, 0.0, 1.0)
    return s**5


def fresnel_schlick_average(f0):
    return f0 + (1.0 - f0) / 21.0


def multiscatter_fresnel(f_avg, e_avg):
    return f_avg * e_avg / (1.0 - f_avg * (1.0 - e_avg))


def dielectric_fresnel(cos_d, eta):
    """Cycles' Principled dielectric Fresnel at Specular IOR Level 0.5 (= the exact one)."""
    f0 = f0_from_ior(eta)
    s = np.clip((fresnel_dielectric(cos_d, eta) - f0) / max(1.0 - f0, 1e-12), 0.0, 1.0)
    return f0 + (1.0 - f0) * s


# ---------------------------------------------------------------------------------------
# Port of quadrature.rs (incident_nodes, Resolution::FINE) and mod.rs's MuTable

MU_NODES = 48
MU = (np.arange(MU_NODES) + 0.5) / MU_NODES


def incident_nodes(cos_o, width, fine=160, coarse=96, nphi=48):
    """Half-vector quadrature over ωi for each view in `cos_o` (array): cos_i, cos_h, cos_d,
    dω_i (0 where the Rust code skips the node), each `(len(cos_o), nodes)`."""
    co = np.clip(np.asarray(cos_o, float), 1e-6, 1.0)[:, None]
    so = np.sqrt(np.maximum(1.0 - co * co, 0.0))
    split = min(12.0 * max(width, 1e-4), HALF_PI * 0.5)
    dphi = PI / nphi
    ths, dths = [], []
    for lo, hi, n in ((0.0, split, fine), (split, HALF_PI, coarse)):
        d = (hi - lo) / n
        ths.append(lo + (np.arange(n) + 0.5) * d)
        dths.append(np.full(n, d))
    th = np.concatenate(ths)
    dth = np.concatenate(dths)
    phi = (np.arange(nphi) + 0.5) * dphi
    sth = np.repeat(np.sin(th), nphi)[None, :]
    cth = np.repeat(np.cos(th), nphi)[None, :]
    dth = np.repeat(dth, nphi)[None, :]
    cphi = np.tile(np.cos(phi), th.size)[None, :]
    cos_d = so * sth * cphi + co * cth
    cos_i = 2.0 * cos_d * cth - co
    ok = (cos_d > 0.0) & (cos_i > 0.0)
    d_omega = np.where(ok, 4.0 * cos_d * sth * dth * 2.0 * dphi, 0.0)
    return cos_i, np.broadcast_to(cth, cos_i.shape), cos_d, d_omega


def mu_table_at(table, mu):
    """MuTable::at for tables `(..., 48)` and views `mu` (array): linear, clamped."""
    x = np.clip(np.clip(mu, 0.0, 1.0) * MU_NODES - 0.5, 0.0, MU_NODES - 1.0)
    i = np.minimum(np.floor(x).astype(int), MU_NODES - 2)
    t = x - i
    return table[..., i] * (1.0 - t) + table[..., i + 1] * t


def energy_table(alpha):
    """`E(μo)` at the 48 μ nodes (single-scattering GGX albedo, Fresnel 1) and its
    cosine-weighted mean `Eavg`, as CyclesPrincipled::new computes them."""
    ci, ch, _, dw = incident_nodes(MU, alpha)
    e = np.sum(ggx_single(alpha, ci, MU[:, None], ch) * ci * dw, axis=1)
    e = np.clip(e, 1e-6, 1.0)
    return e, float(np.sum(2.0 * MU * e) / MU_NODES)


class Energy:
    """E(μ; r) and Eavg(r) on a fine grid uniform in ln r, linear in ln r between nodes
    (exact at the training roughness values, which are nodes)."""

    def __init__(self, r_lo, r_hi, nodes):
        self.lr = np.linspace(np.log(r_lo), np.log(r_hi), nodes)
        rows = [energy_table(np.exp(lr) ** 2) for lr in self.lr]
        self.e = np.array([r[0] for r in rows])
        self.eavg = np.array([r[1] for r in rows])

    def at(self, r):
        x = (np.log(r) - self.lr[0]) / (self.lr[1] - self.lr[0])
        i = int(np.clip(np.floor(x + 1e-9), 0, len(self.lr) - 2))
        t = float(np.clip(x - i, 0.0, 1.0))
        if t < 1e-9:
            return self.e[i], self.eavg[i]
        return self.e[i] * (1 - t) + self.e[i + 1] * t, self.eavg[i] * (1 - t) + self.eavg[i + 1] * t


# ---------------------------------------------------------------------------------------
# Lobes


def lobe_columns(energy, rs, fams, ci, co, ch, cd):
    """Matrix `(points, len(rs)·len(fams))`, column r-major: Cycles' Principled specular
    lobe for roughness r and family `("metal", F0)` / `("diel", η)`, incl. multiscatter."""
    out = np.empty((ci.size, len(rs) * len(fams)))
    sw = schlick_weight(cd)
    fd = {f[1]: dielectric_fresnel(cd, f[1]) for f in fams if f[0] == "diel"}
    for a, r in enumerate(rs):
        alpha = r * r
        single = ggx_single(alpha, ci, co, ch)
        etab, eavg = energy.at(r)
        e = mu_table_at(etab, co)
        miss = (1.0 - e) / e
        for b, (kind, p) in enumerate(fams):
            if kind == "metal":
                fr = p * (1.0 - sw) + sw
                fms = multiscatter_fresnel(fresnel_schlick_average(p), eavg)
            else:
                fr = fd[p]
                fms = multiscatter_fresnel(fresnel_dielectric_average(p), eavg)
            out[:, a * len(fams) + b] = single * fr * (1.0 + fms * miss)
    return out


def bp_lobe(ns, cos_h):
    c = np.clip(cos_h, 1e-300, 1.0)
    return np.where(cos_h > 0, (ns + 2.0) / (8.0 * PI) * np.exp(ns * np.log(c)), 0.0)


# ---------------------------------------------------------------------------------------
# Quadrature over (θh, θd, φd)


class Quad:
    """Product midpoint rule in Rusinkiewicz coordinates: θh on a graded mesh
    `s(e^{βu} − 1)`, θd and φd ∈ [0, π] uniform (φd → −φd symmetry). `dωi dωo =
    4 cos θd dωh dωd`. Only nodes with both directions above the surface are kept. Weights:
    `w_cos` ∝ cos θi cos θo dωi dωo, `w_uni` ∝ dθi dθo dφ = dωi dωo/(sin θi sin θo); each
    normalised to total 1 (inner products are means, as in the engine)."""

    def __init__(self, n_h, n_d, n_phi, s=0.0015):
        beta = np.log1p(HALF_PI / s)
        e = s * np.expm1(beta * np.arange(n_h + 1) / n_h)
        th, dth = 0.5 * (e[1:] + e[:-1]), np.diff(e)
        td = (np.arange(n_d) + 0.5) * HALF_PI / n_d
        pd = (np.arange(n_phi) + 0.5) * PI / n_phi
        TH, TD, PD = np.meshgrid(th, td, pd, indexing="ij")
        DTH = np.broadcast_to(dth[:, None, None], TH.shape)
        sh, chh, sd, cdd, cp = np.sin(TH), np.cos(TH), np.sin(TD), np.cos(TD), np.cos(PD)
        ci = chh * cdd - sh * sd * cp
        co = chh * cdd + sh * sd * cp
        vol = 4.0 * cdd * sh * sd * DTH * (HALF_PI / n_d) * (PI / n_phi) * 2.0 * 2.0 * PI
        ok = (ci > 0) & (co > 0)
        self.th, self.td, self.pd = TH[ok], TD[ok], PD[ok]
        self.ci, self.co, self.ch, self.cd = ci[ok], co[ok], chh[ok], cdd[ok]
        self.vol = vol[ok]
        si = np.sqrt(1 - self.ci**2)
        so = np.sqrt(1 - self.co**2)
        self.total_cos = float(np.sum(self.vol * self.ci * self.co))  # exact: π²
        self.total_uni = float(np.sum(self.vol / (si * so)))  # exact: π⁴
        self.w = {
            "cos": self.vol * self.ci * self.co / self.total_cos,
            "uni": self.vol / (si * so) / self.total_uni,
        }
        self.n = self.ci.size

    def args(self):
        return self.ci, self.co, self.ch, self.cd


def grid_points(gi, go, gp):
    """Cell centres of the (θi, θo, φ) grid, φ ∈ [0, π]: cos_i, cos_o, cos_h, cos_d and the
    cos / uniform weights (normalised)."""
    ti = (np.arange(gi) + 0.5) * HALF_PI / gi
    to = (np.arange(go) + 0.5) * HALF_PI / go
    ph = (np.arange(gp) + 0.5) * PI / gp
    TI, TO, PH = np.meshgrid(ti, to, ph, indexing="ij")
    ci, co = np.cos(TI).ravel(), np.cos(TO).ravel()
    dot = (np.sin(TI) * np.sin(TO) * np.cos(PH)).ravel() + ci * co
    hl = np.sqrt(np.maximum(2.0 + 2.0 * dot, 1e-300))
    ch = (ci + co) / hl
    cd = np.sqrt(np.maximum((1.0 + dot) / 2.0, 0.0))
    wc = ci * co * np.sin(TI).ravel() * np.sin(TO).ravel()
    return ci, co, ch, cd, {"cos": wc / wc.sum(), "uni": np.full(ci.size, 1.0 / ci.size)}


# ---------------------------------------------------------------------------------------
# PCA on Gram matrices (no mean subtraction; constant in the fit)


class Family:
    """Unit-normalised lobes' Gram `G`, their means `m = ⟨f̂, 1⟩` and the residual Gram
    `R = G − m mᵀ` (the constant takes its own slot), for training columns `train` of a set
    of columns (any other columns are tested against the training PCA)."""

    def __init__(self, gram, mean, train):
        self.g, self.m, self.train = gram, mean, np.asarray(train)
        self.r = gram - np.outer(mean, mean)

    def factor(self):
        """Low-rank factor `R_tt = L Lᵀ` of the training residuals' Gram (eigenvalues above
        1e-13 of the largest): every weighting's PCA is then a small eigenproblem."""
        if not hasattr(self, "_l"):
            t = self.train
            lam, u = np.linalg.eigh(self.r[np.ix_(t, t)])
            keep = lam > 1e-13 * lam.max()
            self._l = u[:, keep] * np.sqrt(lam[keep])[None, :]
        return self._l

    def pca(self, weights, nspec):
        d = np.sqrt(weights)
        dl = d[:, None] * self.factor()
        lam, y = np.linalg.eigh(dl.T @ dl)
        order = np.argsort(lam)[::-1][:nspec]
        lam, y = np.maximum(lam[order], 1e-300), y[:, order]
        v = dl @ y / np.sqrt(lam)[None, :]  # unit eigenvectors of D R D
        # φ_k = Σ_j coef[j, k] r_j over training residuals r_j (orthonormal).
        return d[:, None] * v / np.sqrt(lam)[None, :]

    def errors(self, coef, cols=None):
        """Relative L2 errors of columns `cols` (all by default) with constant + bases."""
        cols = np.arange(len(self.m)) if cols is None else np.asarray(cols)
        proj = self.r[np.ix_(cols, self.train)] @ coef
        e2 = np.diag(self.r)[cols] - np.sum(proj**2, axis=1)
        return np.sqrt(np.maximum(e2, 0.0))

    def capped(self, nspec, iters=40):
        """Lawson reweighting toward the minimax of the training lobes' errors (the engine's
        `capped_scale` with the cap at each round's RMS error): the best maximum seen."""
        w = np.ones(len(self.train))
        best = None
        for _ in range(iters):
            coef = self.pca(w, nspec)
            e = self.errors(coef, self.train)
            if best is None or e.max() < best[0]:
                best = (e.max(), coef)
            cap = np.sqrt(np.mean(e**2))
            w = w * np.where(e > cap, (e / cap) ** 2, 1.0)
            w /= w.max()
        return best[1]


def gram_of(cols, weights):
    """`(G, m)` of unit-normalised columns under `weights` (sum 1)."""
    fw = cols * np.sqrt(weights)[:, None]
    g = fw.T @ fw
    norm = np.sqrt(np.diag(g))
    m = (weights @ cols) / norm
    return g / np.outer(norm, norm), m, norm


def eval_basis(cols_train, norm, mean_train, coef):
    """Basis values `(points, 1 + nspec)` at the points where `cols_train` (raw training
    lobes) were evaluated: column 0 the constant 1 (unit norm), then φ_k."""
    res = cols_train / norm[None, :] - mean_train[None, :]
    return np.hstack([np.ones((cols_train.shape[0], 1)), res @ coef])


# ---------------------------------------------------------------------------------------
# Experiments


T0 = time.time()


def log(msg):
    print(f"[{time.time() - T0:7.1f}s] {msg}", flush=True)


def cross_checks(energy):
    """The Rust tests' figures (cycles_principled/tests.rs)."""
    out = {}
    e1, _ = energy_table(1.0)
    out["E(alpha=1, mu=1) vs 1-ln2"] = [float(mu_table_at(e1, 1.0)), 1.0 - np.log(2.0)]
    furnace = {}
    mus = np.array([1.0, 0.7, 0.4, 0.15, 0.05])
    for r in (0.1, 0.3, 0.5, 0.8, 1.0):
        etab, eavg = energy_table(r * r)
        ci, ch, cd, dw = incident_nodes(mus, r * r)
        e = mu_table_at(etab, mus)[:, None]
        fms = multiscatter_fresnel(fresnel_schlick_average(1.0), eavg)
        f = ggx_single(r * r, ci, mus[:, None], ch) * (1.0 + fms * (1.0 - e) / e)
        furnace[r] = np.sum(f * ci * dw, axis=1).round(4).tolist()
    out["white metal directional albedo at mu (1, .7, .4, .15, .05)"] = furnace
    # Smooth limit (r = 0.05): metal F0 0.5 albedo = Schlick, dielectric black = Fresnel.
    smooth = []
    etab, eavg = energy_table(0.0025)
    for mu in (0.9, 0.5, 0.2):
        ci, ch, cd, dw = incident_nodes(np.array([mu]), 0.0025)
        e = mu_table_at(etab, np.array([mu]))[:, None]
        s = ggx_single(0.0025, ci, mu, ch)
        fm = multiscatter_fresnel(fresnel_schlick_average(0.5), eavg)
        metal = np.sum(s * (0.5 * (1 - schlick_weight(cd)) + schlick_weight(cd)) * (1 + fm * (1 - e) / e) * ci * dw)
        smooth.append([mu, float(metal), float(0.5 + 0.5 * (1 - mu) ** 5)])
    out["r=0.05 metal F0=0.5 albedo vs Schlick (mu, albedo, Schlick)"] = smooth
    return out


def best_blinn_phong(q, cols, w):
    """Per column: the best `Kd/π + Ks·bp(ns)` under weights `w`, free and constrained
    (Kd, Ks ≥ 0, Kd + Ks ≤ 1): (rel L2 free, ns, rel L2 constrained, ns, Kd, Ks)."""
    ns_grid = np.exp(np.linspace(np.log(1e-3), np.log(1e6), 241))
    tt = w @ (cols * cols)
    t1 = w @ cols
    res = np.full((cols.shape[1], 6), np.inf)
    for ns in ns_grid:
        b = bp_lobe(ns, q.ch)
        bb, b1 = w @ (b * b), w @ b
        bt = (w * b) @ cols
        # ‖Kd u + Ks b − t‖², u = 1/π: quadratic form in (Kd, Ks).
        a11, a12, a22 = 1.0 / PI**2, b1 / PI, bb
        y1, y2 = t1 / PI, bt

        def obj(kd, ks, y1=y1, y2=y2, a12=a12, a22=a22, a11=a11):
            return tt - 2 * (kd * y1 + ks * y2) + kd * kd * a11 + 2 * kd * ks * a12 + ks * ks * a22

        det = a11 * a22 - a12 * a12
        kd_f = (y1 * a22 - y2 * a12) / det
        ks_f = (y2 * a11 - y1 * a12) / det
        e_free = np.sqrt(np.maximum(obj(kd_f, ks_f), 0) / tt)
        # Constrained: interior, edges Kd = 0, Ks = 0, Kd + Ks = 1, vertices.
        cands = []
        ok = (kd_f >= 0) & (ks_f >= 0) & (kd_f + ks_f <= 1)
        cands.append((np.where(ok, kd_f, 0), np.where(ok, ks_f, 0), ok))
        ks0 = np.clip(y2 / a22, 0, 1)
        cands.append((np.zeros_like(ks0), ks0, np.ones_like(ok)))
        kd0 = np.clip(y1 / a11, 0, 1)
        cands.append((kd0, np.zeros_like(kd0), np.ones_like(ok)))
        # Kd = 1 − Ks: minimise over Ks ∈ [0, 1].
        c2 = a11 - 2 * a12 + a22
        c1 = (y2 - y1) - (a12 - a11)
        ks_e = np.clip(c1 / c2, 0, 1)
        cands.append((1 - ks_e, ks_e, np.ones_like(ok)))
        best_c = np.full(cols.shape[1], np.inf)
        kd_c = np.zeros(cols.shape[1])
        ks_c = np.zeros(cols.shape[1])
        for kd, ks, valid in cands:
            o = np.where(valid, obj(kd, ks), np.inf)
            better = o < best_c
            best_c = np.where(better, o, best_c)
            kd_c = np.where(better, kd, kd_c)
            ks_c = np.where(better, ks, ks_c)
        e_con = np.sqrt(np.maximum(best_c, 0) / tt)
        upd = e_free < res[:, 0]
        res[upd, 0], res[upd, 1] = e_free[upd], ns
        upd = e_con < res[:, 2]
        res[upd, 2], res[upd, 3], res[upd, 4], res[upd, 5] = e_con[upd], ns, kd_c[upd], ks_c[upd]
    return res


METAL_TRAIN = (0.0, 0.25, 0.5, 0.75, 1.0)
FAMS = [("metal", f) for f in METAL_TRAIN] + [("metal", 0.1), ("metal", 0.9)] + [("diel", e) for e in (1.5, 1.33, 1.8)]
COUNTS = list(range(4, 25))


def columns_of(nr, pred):
    """Column indices (r-major layout of `lobe_columns` over FAMS) whose family passes."""
    return np.array([a * len(FAMS) + b for a in range(nr) for b, f in enumerate(FAMS) if pred(f)])


def sets(nr):
    """The PCA sets: (name, training columns, {group name: reported columns})."""
    metal = columns_of(nr, lambda f: f[0] == "metal" and f[1] in METAL_TRAIN)
    metal_all = columns_of(nr, lambda f: f[0] == "metal")
    metal_test = columns_of(nr, lambda f: f[0] == "metal" and f[1] not in METAL_TRAIN)
    d15 = columns_of(nr, lambda f: f == ("diel", 1.5))
    d_other = columns_of(nr, lambda f: f[0] == "diel" and f[1] != 1.5)
    d_all = columns_of(nr, lambda f: f[0] == "diel")
    return [
        ("metal", metal, {"metal F0 0..1 (train)": metal, "metal F0 0.1, 0.9 (test)": metal_test}),
        ("dielectric 1.5", d15, {"IOR 1.5": d15, "IOR 1.33, 1.8 (test)": d_other}),
        ("joint", np.concatenate([metal, d_all]), {"metal (all F0)": metal_all, "dielectric (all IOR)": d_all}),
    ]


def basis_size(q, cols, nr, label):
    """Part 1: mean / worst relative L2 per N_b, per set, weighting and measure."""
    res = {}
    fams = {}
    for meas in ("cos", "uni"):
        g, m, norm = gram_of(cols, q.w[meas])
        for name, train, groups in sets(nr):
            fam = Family(g, m, train)
            fams[(meas, name)] = (fam, norm)
            for weighting in ("unit", "capped"):
                rows = {}
                for nb in COUNTS:
                    coef = fam.pca(np.ones(len(train)), nb - 1) if weighting == "unit" else fam.capped(nb - 1)
                    e = fam.errors(coef)
                    rows[nb] = {k: [float(e[c].mean()), float(e[c].max())] for k, c in groups.items()}
                res[f"{label} {meas} {name} {weighting}"] = rows
        log(f"basis size, {label}, {meas}")
    return res, fams


def print_sizes(res):
    for key, rows in res.items():
        print(f"  {key}")
        for nb, groups in rows.items():
            txt = "  ".join(f"{k}: {a * 100:6.2f}% / {b * 100:6.2f}%" for k, (a, b) in groups.items())
            print(f"    N_b {nb:2d}  {txt}")


def shipped_count(rows, group, avg=0.01, worst=0.03):
    for nb, groups in rows.items():
        a, b = groups[group]
        if a <= avg and b <= worst:
            return int(nb)
    return None


def grid_part(energy, rs, q_cols_norm, q):
    """Part 0: a uniform (θi, θo, φ) grid of cell centres against the graded quadrature for
    metal F0 = 1: the lobe norm on the grid over the continuum's, and the grid PCA's own
    figures (which look fine while the lobes are not resolved)."""
    out = {}
    fams = [("metal", 1.0)]
    for grid in ((32, 32, 64), (64, 64, 128)):
        ci, co, ch, cd, w = grid_points(*grid)
        cols = lobe_columns(energy, rs, fams, ci, co, ch, cd)
        ratio = np.sqrt(w["cos"] @ (cols * cols)) / q_cols_norm
        g, m, _ = gram_of(cols, w["cos"])
        fam = Family(g, m, np.arange(len(rs)))
        rows = {}
        for nb in (6, 8, 12, 16):
            e = fam.errors(fam.capped(nb - 1))
            rows[nb] = [float(e.mean()), float(e.max())]
        pick = [0, len(rs) // 4, len(rs) // 2, len(rs) - 1]
        out["x".join(map(str, grid))] = {
            "norm ratio grid/continuum at r": {f"{rs[i]:.3f}": float(ratio[i]) for i in pick},
            "grid PCA capped (mean, worst)": rows,
        }
        log(f"grid {grid}: {out['x'.join(map(str, grid))]}")
        del cols
    return out


def bp_part(q, energy):
    """Part 1b: the best single Blinn–Phong against the lobes (cos-weighted measure)."""
    rs = np.array([0.1, 0.15, 0.2, 0.3, 0.5, 0.8, 1.0])
    fams = [("metal", 1.0), ("metal", 0.5), ("diel", 1.5)]
    cols = lobe_columns(energy, rs, fams, *q.args())
    res = best_blinn_phong(q, cols, q.w["cos"])
    out = {}
    for a, r in enumerate(rs):
        for b, f in enumerate(fams):
            e = res[a * len(fams) + b]
            out[f"r {r} {f[0]} {f[1]}"] = {
                "free rel L2": float(e[0]), "free ns": float(e[1]),
                "constrained rel L2": float(e[2]), "ns": float(e[3]), "Kd": float(e[4]), "Ks": float(e[5]),
            }
    return out


def linearity_part(q, energy, basis_at_nodes, w, nodes=256):
    """Part 2: c_k(r) on `nodes` nodes (uniform in r, √r, ln r), linear interpolation at the
    midpoints against the direct projection; error as a relative L2 of the lobe."""
    fams = [("metal", 0.0), ("metal", 1.0), ("diel", 1.5)]
    phiw = basis_at_nodes * w[:, None]
    out = {}
    maps = {"r": (lambda r: r, lambda u: u), "sqrt r": (np.sqrt, np.square), "ln r": (np.log, np.exp)}
    for name, (fwd, inv) in maps.items():
        u = np.linspace(fwd(0.1), fwd(1.0), 2 * nodes - 1)
        r_all = inv(u)
        r_all[0], r_all[-1] = 0.1, 1.0
        coefs, norms = [], []
        for chunk in np.array_split(np.arange(len(r_all)), 16):
            c = lobe_columns(energy, r_all[chunk], fams, *q.args())
            coefs.append(c.T @ phiw)
            norms.append(np.sqrt(w @ (c * c)))
        coef = np.vstack(coefs).reshape(len(r_all), len(fams), -1)
        norm = np.concatenate(norms).reshape(len(r_all), len(fams))
        interp = 0.5 * (coef[0:-2:2] + coef[2::2])
        err = np.linalg.norm(interp - coef[1:-1:2], axis=2) / norm[1:-1:2]
        out[name] = {f"{f[0]} {f[1]}": [float(err[:, b].mean()), float(err[:, b].max())] for b, f in enumerate(fams)}
        # Where the worst one sits.
        out[name]["worst at r"] = float(r_all[1:-1:2][np.argmax(err.max(axis=1))])
    return out


def config_points():
    """Named configurations as (cos_i, cos_o, cos_h, cos_d) arrays."""
    names, pts = [], []

    def add(name, ti, to, phi):
        ti, to = np.radians(ti), np.radians(to)
        ci, co = np.cos(ti), np.cos(to)
        dot = np.sin(ti) * np.sin(to) * np.cos(phi) + ci * co
        hl = np.sqrt(2 + 2 * dot)
        names.append(name)
        pts.append([ci, co, (ci + co) / hl, np.sqrt((1 + dot) / 2)])

    for t in (0.5, 30, 60, 75, 85, 89):
        add(f"mirror θ={t}°", t, t, PI)
    for t in (30, 60, 85, 89):
        add(f"θi=θo={t}°, 1° off mirror in φ", t, t, PI - np.radians(1.0) / max(np.sin(np.radians(t)), 1e-3))
        add(f"θi={t - 1}°, θo={t}° in plane", t - 1, t, PI)
    for t in (80, 85, 89):
        add(f"θi=θo={t}°, φ=90° (off lobe)", t, t, HALF_PI)
    return names, np.array(pts).T


def cancellation(coef, basis):
    """Σ|c_k φ_k| / |Σ c_k φ_k| per point (basis `(points, N_b)`)."""
    terms = basis * coef[None, :]
    return np.sum(np.abs(terms), axis=1) / np.maximum(np.abs(terms.sum(axis=1)), 1e-300)


def weighted_quantiles(x, w, qs):
    o = np.argsort(x)
    c = np.cumsum(w[o]) / w.sum()
    return [float(x[o][min(np.searchsorted(c, qq), len(x) - 1)]) for qq in qs]


def f16_part(q, energy, rs, fam_norm, nb, meas, cols_train_q, names, cfg, cfg_train):
    """Part 3 for one Principled basis (`fam_norm` = (Family, norms), N_b = `nb`)."""
    fam, norm = fam_norm
    coef = fam.capped(nb - 1)
    w = q.w[meas]
    mtrain = fam.m[fam.train]
    basis_q = eval_basis(cols_train_q, norm[fam.train], mtrain, coef)
    basis_c = eval_basis(cfg_train, norm[fam.train], mtrain, coef)
    out = {}
    for f in (("metal", 1.0), ("metal", 0.5), ("diel", 1.5)):
        lobe = lobe_columns(energy, [0.1], [f], *q.args())[:, 0]
        c = basis_q.T @ (w * lobe)
        fc = lobe_columns(energy, [0.1], [f], *cfg)[:, 0]
        canc = cancellation(c, basis_c)
        rec = basis_c @ c
        cq = cancellation(c, basis_q)
        rms = np.sqrt(w @ lobe**2)
        abs_q = np.sum(np.abs(basis_q * c[None, :]), axis=1) / rms
        abs_c = np.sum(np.abs(basis_c * c[None, :]), axis=1) / rms
        out[f"{f[0]} {f[1]}"] = {
            "Σ|c_k ρ̃_k|/‖f‖ max over nodes, at configs": [
                float(abs_q.max()), dict(zip(names, abs_c.round(3).tolist(), strict=True))
            ],
            "lobe peak / ‖f‖": float(lobe.max() / rms),
            "Σ|c_k| / ‖c‖": float(np.abs(c).sum() / np.linalg.norm(c)),
            "configs": {n: [float(canc[i]), float(rec[i] / fc[i]) if fc[i] else None] for i, n in enumerate(names)},
            "lobe-energy-weighted quantiles 50/90/99/100 %": weighted_quantiles(cq, w * lobe**2, [0.5, 0.9, 0.99, 1.0]),
            "sum |c_k|": float(np.abs(c).sum()),
            "coefficients": c.round(4).tolist(),
        }
    return out


def bp_basis_f16(q, nb, meas, names, cfg, ns_top=22809.0):
    """Part 3, Blinn–Phong side: PCA over ns ∈ [1, ns_top] (128 lobes geometric, constant in
    the fit, capped) at N_b = `nb`, the ns_top lobe's cancellation."""
    ns = np.exp(np.linspace(0.0, np.log(ns_top), 128))
    cols = np.stack([bp_lobe(n, q.ch) for n in ns], axis=1)
    w = q.w[meas]
    g, m, norm = gram_of(cols, w)
    fam = Family(g, m, np.arange(len(ns)))
    coef = fam.capped(nb - 1)
    e = fam.errors(coef)
    basis_q = eval_basis(cols, norm, m, coef)
    cfg_cols = np.stack([bp_lobe(n, cfg[2]) for n in ns], axis=1)
    basis_c = eval_basis(cfg_cols, norm, m, coef)
    lobe = cols[:, -1]
    c = basis_q.T @ (w * lobe)
    canc = cancellation(c, basis_c)
    rec = basis_c @ c
    fc = cfg_cols[:, -1]
    rms = np.sqrt(w @ lobe**2)
    abs_q = np.sum(np.abs(basis_q * c[None, :]), axis=1) / rms
    abs_c = np.sum(np.abs(basis_c * c[None, :]), axis=1) / rms
    return {
        "Σ|c_k ρ̃_k|/‖f‖ max over nodes, at configs": [
            float(abs_q.max()), dict(zip(names, abs_c.round(3).tolist(), strict=True))
        ],
        "lobe peak / ‖f‖": float(lobe.max() / rms),
        "Σ|c_k| / ‖c‖": float(np.abs(c).sum() / np.linalg.norm(c)),
        "basis mean / worst rel L2": [float(e.mean()), float(e.max())],
        "configs": {n: [float(canc[i]), float(rec[i] / fc[i]) if fc[i] > 1e-12 else None] for i, n in enumerate(names)},
        "lobe-energy-weighted quantiles 50/90/99/100 %": weighted_quantiles(
            cancellation(c, basis_q), w * lobe**2, [0.5, 0.9, 0.99, 1.0]
        ),
        "sum |c_k|": float(np.abs(c).sum()),
    }


def warp_k(alpha):
    """The engine's table warp `v = u(1+k)/(u+k)`, `u = √(1 − cos θh)`, with k = √u at the
    half width of the narrowest GGX distribution (tan²θh = α²(√2 − 1))."""
    th = np.arctan(alpha * np.sqrt(np.sqrt(2.0) - 1.0))
    return float(np.sqrt(np.sqrt(1.0 - np.cos(th))))


def th_of_t(t, k):
    u = np.minimum(k * t / (1.0 + k - t), 1.0)
    return np.arccos(np.clip(1.0 - u * u, -1.0, 1.0))


def t_of_th(th, k):
    u = np.sqrt(np.maximum(1.0 - np.cos(th), 0.0))
    return u * (1.0 + k) / (u + k)


def rus_cosines(th, td, pd, floor=1e-6):
    sh, chh, sd, cdd, cp = np.sin(th), np.cos(th), np.sin(td), np.cos(td), np.cos(pd)
    ci = np.maximum(chh * cdd - sh * sd * cp, floor)
    co = np.maximum(chh * cdd + sh * sd * cp, floor)
    return ci, co, chh, cdd


def trilinear(tab, ti, td, tp):
    """Interpolates `tab (nh, nd, np, nb)` at table coordinates in [0, 1]."""
    out = 0.0
    idx, frac = [], []
    for t, n in ((ti, tab.shape[0]), (td, tab.shape[1]), (tp, tab.shape[2])):
        if n == 1:
            idx.append((np.zeros(t.shape, int), np.zeros(t.shape, int)))
            frac.append(np.zeros(t.shape))
            continue
        x = np.clip(t, 0.0, 1.0) * (n - 1)
        i = np.minimum(np.floor(x).astype(int), n - 2)
        idx.append((i, i + 1))
        frac.append(x - i)
    for a in (0, 1):
        wa = frac[0] if a else 1 - frac[0]
        for b in (0, 1):
            wb = frac[1] if b else 1 - frac[1]
            for c in (0, 1):
                wc = frac[2] if c else 1 - frac[2]
                out = out + (wa * wb * wc)[:, None] * tab[idx[0][a], idx[1][b], idx[2][c]]
    return out


def table_part(q, energy, rs, fam_norm, nb, meas, basis_q, master=(513, 129, 33)):
    """Part 4: trilinear (θh, θd, φd) tables subsampled from a master table; the error of
    each basis (weighted RMS over the quadrature nodes, relative to the basis' RMS) and of the
    r = 0.1 / 0.3 lobes rebuilt from the tabulated bases."""
    fam, norm = fam_norm
    coef = fam.capped(nb - 1)
    k = warp_k(rs[0] ** 2)
    th = th_of_t(np.linspace(0, 1, master[0]), k)
    td = np.linspace(0, HALF_PI, master[1])
    pd = np.linspace(0, PI, master[2])
    TH, TD, PD = np.meshgrid(th, td, pd, indexing="ij")
    pts = [a.ravel() for a in rus_cosines(TH, TD, PD)]
    vals = np.empty((pts[0].size, nb))
    for chunk in np.array_split(np.arange(pts[0].size), 64):
        cols = lobe_columns(energy, rs, FAMS, *(p[chunk] for p in pts))[:, fam.train]
        # Tabulated: ρ̃_k·cos θi·cos θo (bounded; ρ̃_k itself grows like 1/cos at grazing).
        cc = (pts[0][chunk] * pts[1][chunk])[:, None]
        vals[chunk] = eval_basis(cols, norm[fam.train], fam.m[fam.train], coef) * cc
    mtab = vals.reshape(*master, nb)
    log("table master evaluated")
    w = q.w[meas]
    tq = (t_of_th(q.th, k), q.td / HALF_PI, q.pd / PI)
    lobes = {}
    for r in (0.1, 0.3):
        f = lobe_columns(energy, [r], [("metal", 1.0)], *q.args())[:, 0]
        lobes[r] = (basis_q.T @ (w * f), np.sqrt(w @ f**2))
    res = {}
    for nh in (33, 65, 129, 257, 513):
        for nd in (17, 33, 65, 129):
            for nphi in (1, 3, 5, 9, 17, 33):
                sh, sd = (master[0] - 1) // (nh - 1), (master[1] - 1) // (nd - 1)
                if nphi == 1:
                    sub = mtab[::sh, ::sd].mean(axis=2, keepdims=True)  # the φd mean: a 2D table
                else:
                    sub = mtab[::sh, ::sd, :: (master[2] - 1) // (nphi - 1)]
                interp = trilinear(sub, *tq) / (q.ci * q.co)[:, None]
                d = interp - basis_q
                e = np.sqrt(w @ d**2) / np.sqrt(w @ basis_q**2)
                e[0] = 0.0  # the constant is not tabulated
                le = {r: float(np.sqrt(w @ (d @ c) ** 2) / n) for r, (c, n) in lobes.items()}
                res[(nh, nd, nphi)] = (float(e.max()), e.tolist(), le)
    log("table errors")
    out = {"warp k": k, "N_b": nb, "measure": meas, "rows": {}}
    for key, (emax, _e, le) in res.items():
        out["rows"]["x".join(map(str, key))] = {"worst basis": emax, "lobe r=0.1": le[0.1], "lobe r=0.3": le[0.3]}
    ok = [(np.prod(kk), kk) for kk, v in res.items() if v[0] < 1e-3]
    if ok:
        best = min(ok)[1]
        out["smallest table with every basis < 1e-3"] = {
            "nodes (θh, θd, φd)": list(best), "bytes per basis f16": int(np.prod(best)) * 2,
            "bytes all bases f16": int(np.prod(best)) * 2 * nb, "errors per basis": res[best][1],
        }
    return out


# ---------------------------------------------------------------------------------------
# Part 5: other table parametrisations


METAL_FAMS = [("metal", f) for f in METAL_TRAIN]


def rwarp(x, k):
    """The engine's rational warp `x(1+k)/(x+k)` on [0, 1]: its slope at 0 is (1+k)/k, so
    nodes uniform in the result are dense near x = 0 (spacing ≈ k/n there)."""
    return x * (1.0 + k) / (x + k)


def rwarp_inv(t, k):
    return k * t / (1.0 + k - t)


def rus_angles(ci, co, ch, cd):
    """(θh, θd, φd) from the four cosines (inverse of `rus_cosines` above the horizon)."""
    th = np.arccos(np.clip(ch, -1.0, 1.0))
    td = np.arccos(np.clip(cd, -1.0, 1.0))
    den = 2.0 * np.sin(th) * np.sin(td)
    cp = np.where(den > 1e-300, (co - ci) / np.where(den > 1e-300, den, 1.0), 1.0)
    return th, td, np.arccos(np.clip(cp, -1.0, 1.0))


def horizon_td(th, pd):
    """The θd at which the lower of cos θi, cos θo reaches 0 for given (θh, φd):
    `π/2 − atan(tan θh |cos φd|)` (min(cos θi, cos θo) = R cos(θd + β), β that atan)."""
    return HALF_PI - np.arctan2(np.sin(th) * np.abs(np.cos(pd)), np.cos(th))


class ThWarp:
    """θh → [0, 1]: `lam·v + (1 − lam)·θh/(π/2)`, v the engine's warp (`t_of_th`, constant k).
    lam = 1 is the engine's warp, which puts θh ∈ [60°, 90°] in the last 2.5 % of the nodes
    (k = 0.067); a blend keeps part of its density at the peak and gives large θh, where the
    rough lobes live at grazing, nodes of their own. Inverted by bisection."""

    def __init__(self, k, lam=1.0):
        self.k, self.lam = k, lam

    def fwd(self, th):
        return self.lam * t_of_th(th, self.k) + (1.0 - self.lam) * th / HALF_PI

    def inv(self, t):
        if self.lam == 1.0:
            return th_of_t(t, self.k)
        lo, hi = np.zeros_like(t), np.full_like(t, HALF_PI)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            below = self.fwd(mid) < t
            lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
        return 0.5 * (lo + hi)


class RusTable:
    """A (θh, θd, φd) table: θh through `thw` (a ThWarp), φd ∈ [0, π]
    uniform, θd through `td_fwd` / `td_inv` (angle → [0, 1] and back). With `fitted`, the θd
    coordinate is relative to the horizon: x = 1 − θd/θd_max(θh, φd) (0 at the horizon),
    then `t = 1 − rwarp(x, k_fit)`, so the horizon is the face t = 1 and nodes crowd there."""

    def __init__(self, name, thw, td_fwd=None, td_inv=None, k_fit=None):
        self.name, self.thw, self.k_fit = name, thw, k_fit
        self.td_fwd = td_fwd or (lambda td: td / HALF_PI)
        self.td_inv = td_inv or (lambda t: t * HALF_PI)

    def dirs(self, t0, t1, t2):
        th, pd = self.thw.inv(t0), t2 * PI
        if self.k_fit is not None:
            return rus_cosines(th, (1.0 - rwarp_inv(1.0 - t1, self.k_fit)) * horizon_td(th, pd), pd)
        return rus_cosines(th, self.td_inv(t1), pd)

    def coords(self, ci, co, ch, cd):
        th, td, pd = rus_angles(ci, co, ch, cd)
        if self.k_fit is None:
            t1 = self.td_fwd(td)
        else:
            tmax = horizon_td(th, pd)
            x = 1.0 - td / np.maximum(tmax, 1e-300)
            t1 = 1.0 - rwarp(np.clip(x, 0.0, 1.0), self.k_fit)
        return self.thw.fwd(th), t1, pd / PI


class InOutTable:
    """A (θi, θo, φ) table: each of cos θi, cos θo through `1 − rwarp(cos, k)` (nodes dense
    toward grazing), φ ∈ [0, π] (mirror at π) uniform or, with `k_phi`, through
    `1 − rwarp(1 − φ/π, k_phi)` (dense toward the mirror plane)."""

    def __init__(self, name, k, k_phi=None):
        self.name, self.k, self.k_phi = name, k, k_phi

    def dirs(self, t0, t1, t2):
        ci, co = rwarp_inv(1.0 - t0, self.k), rwarp_inv(1.0 - t1, self.k)
        phi = t2 * PI if self.k_phi is None else (1.0 - rwarp_inv(1.0 - t2, self.k_phi)) * PI
        si, so = np.sqrt(np.maximum(1 - ci * ci, 0)), np.sqrt(np.maximum(1 - co * co, 0))
        dot = si * so * np.cos(phi) + ci * co
        hl = np.sqrt(np.maximum(2.0 + 2.0 * dot, 1e-300))
        return np.maximum(ci, 1e-6), np.maximum(co, 1e-6), (ci + co) / hl, np.sqrt(np.maximum((1 + dot) / 2, 0))

    def coords(self, ci, co, ch, cd):
        si, so = np.sqrt(np.maximum(1 - ci * ci, 0)), np.sqrt(np.maximum(1 - co * co, 0))
        den = si * so
        cp = np.where(den > 1e-300, (2 * cd * cd - 1 - ci * co) / np.where(den > 1e-300, den, 1.0), 1.0)
        phi = np.arccos(np.clip(cp, -1.0, 1.0)) / PI
        t2 = phi if self.k_phi is None else 1.0 - rwarp(1.0 - phi, self.k_phi)
        return 1.0 - rwarp(ci, self.k), 1.0 - rwarp(co, self.k), t2


class LuneTable:
    """A table over θh and ωd's position in the half-vector frame, in which both horizons are
    faces. With ωd = (x, y, z) in h's frame (z = cos θd, x along the plane of n and h),
    cos θi = z cos θh − x sin θh and cos θo = z cos θh + x sin θh, so the directions above
    both horizons are the lune |x| < z cot θh. Write ωd = (cos η sin ψ, sin η, cos η cos ψ):
    then cos θi = cos η cos(θh + ψ), cos θo = cos η cos(θh − ψ), cos θd = cos η cos ψ, and the
    lune is |ψ| < π/2 − θh, η ∈ [0, π/2]. Coordinates: θh through `thw`; s = ψ/(π/2 − θh)
    ∈ [−1, 1], dense toward both ends through `rwarp(1 − |s|, k_s)` (s = ±1: θi or θo at the
    horizon); η through `1 − rwarp(cos η, k_eta)` (η = π/2: both at the horizon)."""

    def __init__(self, name, thw, k_s, k_eta):
        self.name, self.thw, self.k_s, self.k_eta = name, thw, k_s, k_eta

    def dirs(self, t0, t1, t2):
        th = self.thw.inv(t0)
        a = 2.0 * t1 - 1.0
        s = np.sign(a) * (1.0 - rwarp_inv(1.0 - np.abs(a), self.k_s))
        psi = s * (HALF_PI - th)
        ce = rwarp_inv(1.0 - t2, self.k_eta)
        ci = np.maximum(ce * np.cos(th + psi), 1e-6)
        co = np.maximum(ce * np.cos(th - psi), 1e-6)
        return ci, co, np.cos(th), ce * np.cos(psi)

    def coords(self, ci, co, ch, cd):
        th = np.arccos(np.clip(ch, -1.0, 1.0))
        sh = np.sin(th)
        x = np.where(sh > 1e-300, (co - ci) / (2.0 * np.where(sh > 1e-300, sh, 1.0)), 0.0)
        z = cd
        y = np.sqrt(np.maximum(1.0 - x * x - z * z, 0.0))
        psi = np.arctan2(x, z)
        ce = np.cos(np.arctan2(y, np.hypot(x, z)))
        s = np.clip(psi / np.maximum(HALF_PI - th, 1e-300), -1.0, 1.0)
        t1 = 0.5 + 0.5 * np.sign(s) * (1.0 - rwarp(1.0 - np.abs(s), self.k_s))
        return self.thw.fwd(th), t1, 1.0 - rwarp(ce, self.k_eta)


def table_params(k):
    """The parametrisations of part 5 (k: the engine's θh warp constant)."""
    eng, mix = ThWarp(k), ThWarp(k, 0.5)
    return {
        "θd uniform (part 4)": RusTable("θd uniform", eng),
        "θd: uniform in 1 − cos θd": RusTable(
            "1-cos", eng, lambda td: 1.0 - np.cos(td), lambda t: np.arccos(np.clip(1.0 - t, -1, 1))),
        "θd: uniform in 1 − √(1 − sin θd)": RusTable(
            "sqrt(1-sin)", eng, lambda td: 1.0 - np.sqrt(np.maximum(1.0 - np.sin(td), 0.0)),
            lambda t: np.arcsin(np.clip(1.0 - (1.0 - t) ** 2, -1, 1))),
        "θd: 1 − rwarp(cos θd, 0.02)": RusTable(
            "rwarp cos 0.02", eng, lambda td: 1.0 - rwarp(np.cos(td), 0.02),
            lambda t: np.arccos(np.clip(rwarp_inv(1.0 - t, 0.02), -1, 1))),
        "θd to the horizon, rwarp 0.01": RusTable("fitted 0.01", eng, k_fit=0.01),
        "θd to the horizon, rwarp 0.03": RusTable("fitted 0.03", eng, k_fit=0.03),
        "θd to the horizon, rwarp 0.1": RusTable("fitted 0.1", eng, k_fit=0.1),
        "θd to the horizon, rwarp 0.1, θh blend": RusTable("fitted 0.1 mix", mix, k_fit=0.1),
        "lune, k_s 0.03, k_η 0.03": LuneTable("lune", eng, 0.03, 0.03),
        "lune, k_s 0.1, k_η 0.1": LuneTable("lune", eng, 0.1, 0.1),
        "lune, k_s 0.03, k_η 0.03, θh blend": LuneTable("lune mix", mix, 0.03, 0.03),
        "lune, k_s 0.1, k_η 0.1, θh blend": LuneTable("lune mix", mix, 0.1, 0.1),
        "(θi, θo, φ), rwarp(cos, 0.02)": InOutTable("io", 0.02),
        "(θi, θo, φ), rwarp(cos, 0.02), φ rwarp 0.02": InOutTable("io phi", 0.02, 0.02),
    }


def part5_runs(k):
    """Part 5's tables: every parametrisation on a 1.1 MB-per-basis master and two coarser
    subsamples, then a size sweep of the best one on a larger master."""
    p = table_params(k)
    runs = []
    for name, param in p.items():
        if isinstance(param, InOutTable):
            runs.append((name, param, (129, 129, 65), [(65, 65, 33), (129, 129, 65)]))
        else:
            runs.append((name, param, (129, 65, 65), [(65, 33, 33), (129, 65, 33), (129, 65, 65)]))
    sweep = [(33, 17, 17), (65, 33, 33), (129, 65, 65), (257, 65, 65), (129, 129, 65), (129, 65, 129), (257, 129, 129)]
    best = "lune, k_s 0.1, k_η 0.1, θh blend"
    runs.append((f"sweep: {best}", p[best], (257, 129, 129), sweep))
    return runs


def basis_function(energy, rs, fam_norm, coef):
    """ρ̃_k at arbitrary cosines `(points, N_b)`, from the metal training lobes."""
    fam, norm = fam_norm
    nt, mt = norm[fam.train], fam.m[fam.train]

    def f(ci, co, ch, cd):
        return eval_basis(lobe_columns(energy, rs, METAL_FAMS, ci, co, ch, cd), nt, mt, coef)

    return f


def tabulate(param, shape, fn, nb, chunk=40000):
    """`fn(t0, t1, t2) → (points, nb)` on the node grid `shape` of `param` (t uniform)."""
    axes = [np.linspace(0.0, 1.0, n) for n in shape]
    grid = [a.ravel() for a in np.meshgrid(*axes, indexing="ij")]
    out = np.empty((grid[0].size, nb))
    for lo in range(0, grid[0].size, chunk):
        out[lo:lo + chunk] = fn(*(g[lo:lo + chunk] for g in grid))
    return out.reshape(*shape, nb)


def check_param(param, q):
    """Round trip of the quadrature's directions through the table coordinates (`coords`
    then `dirs`), and the trilinear interpolation, at the quadrature's table coordinates, of
    a table of a product of affine functions of the (warped) table coordinates, which
    trilinear reproduces exactly: both should be at rounding level."""
    tq = param.coords(*q.args())
    back = param.dirs(*tq)
    rt = max(float(np.abs(a - b).max()) for a, b in zip(back, q.args(), strict=True))

    def poly(t0, t1, t2):
        return ((1.0 + 2.0 * t0) * (3.0 - t1) * (0.5 + t2))[:, None]

    tab = tabulate(param, (9, 7, 5), poly, 1)
    err = float(np.abs(trilinear(tab, *tq) - poly(*tq)).max())
    in_range = min(float(t.min()) for t in tq) >= 0.0 and max(float(t.max()) for t in tq) <= 1.0
    return {"round trip max |Δcos|": rt, "trilinear on affine product max |Δ|": err, "coords in [0,1]": in_range}


def table_errors(sub, param_tq, q, w, basis_q, lobes):
    interp = trilinear(sub, *param_tq) / (q.ci * q.co)[:, None]
    d = interp - basis_q
    e = np.sqrt(w @ d**2) / np.sqrt(w @ basis_q**2)
    e[0] = 0.0  # the constant is not tabulated
    le = {r: float(np.sqrt(w @ (d @ c) ** 2) / n) for r, (c, n) in lobes.items()}
    return float(e.max()), e, le


def subsample(tab, master, shape):
    st = [(m - 1) // (n - 1) for m, n in zip(master, shape, strict=True)]
    return tab[:: st[0], :: st[1], :: st[2]]


def param_part(q, energy, rs, fam_norm, nb, meas, basis_q, runs):
    """Part 5: for each (parametrisation, master shape, sub-shapes), the worst basis' RMS
    error over its RMS and the r = 0.1 / 0.3 white-metal lobes' relative L2, as part 4."""
    fam, _ = fam_norm
    coef = fam.capped(nb - 1)
    fn = basis_function(energy, rs, fam_norm, coef)
    w = q.w[meas]
    lobes = {}
    for r in (0.1, 0.3):
        f = lobe_columns(energy, [r], [("metal", 1.0)], *q.args())[:, 0]
        lobes[r] = (basis_q.T @ (w * f), np.sqrt(w @ f**2))
    out = {}
    for name, param, master, shapes in runs:
        chk = check_param(param, q)
        t = time.time()

        def quantity(t0, t1, t2, param=param):
            ci, co, ch, cd = param.dirs(t0, t1, t2)
            return fn(ci, co, ch, cd) * (ci * co)[:, None]

        mtab = tabulate(param, master, quantity, nb)
        tq = param.coords(*q.args())
        rows = {}
        for shape in shapes:
            emax, e, le = table_errors(subsample(mtab, master, shape), tq, q, w, basis_q, lobes)
            rows["x".join(map(str, shape))] = {
                "nodes": int(np.prod(shape)), "MB per basis f16": np.prod(shape) * 2 / 1e6,
                "worst basis": emax, "worst basis index": int(np.argmax(e)),
                "lobe r=0.1": le[0.1], "lobe r=0.3": le[0.3],
            }
        out[name] = {"checks": chk, "master": list(master), "rows": rows}
        log(f"part 5, {name}: master {master} in {time.time() - t:.0f}s, checks {chk}")
        for key, v in rows.items():
            log(f"    {key:>14s} {v['MB per basis f16']:7.2f} MB  worst {v['worst basis']:.3g} "
                f"(#{v['worst basis index']})  r=0.1 {v['lobe r=0.1']:.3g}  r=0.3 {v['lobe r=0.3']:.3g}")
        del mtab
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="also run the refined quadrature (convergence)")
    ap.add_argument("--json", help="write the figures to this file")
    ap.add_argument("--roughness", type=int, default=96, help="roughness samples in [0.1, 1], uniform in ln r")
    ap.add_argument("--skip-tables", action="store_true", help="skip parts 4 and 5")
    ap.add_argument("--tables-only", action="store_true", help="build the metal basis, then run parts 4 and 5 only")
    args = ap.parse_args()
    out = {}
    nr = args.roughness
    rs = np.exp(np.linspace(np.log(0.1), np.log(1.0), nr))
    energy = Energy(0.1, 1.0, 2 * (nr - 1) + 1)
    log("energy tables")
    if args.tables_only:
        tables_only(args, rs, energy, Quad(96, 40, 48))
        return
    out["cross_checks"] = cross_checks(energy)
    log(f"cross checks {json.dumps(out['cross_checks'])}")

    q = Quad(96, 40, 48)
    log(f"quadrature: {q.n} nodes; Σ cos-weights {q.total_cos:.5f} (π² = {PI**2:.5f}), "
        f"Σ uniform {q.total_uni:.3f} (π⁴ = {PI**4:.3f})")
    out["quadrature"] = {"nodes": q.n, "total cos": q.total_cos, "total uniform": q.total_uni}
    cols = lobe_columns(energy, rs, FAMS, *q.args())
    # White metal under the cos measure: ∫∫ f cos cos = π·(mean albedo) ≈ π at every r.
    white = cols[:, columns_of(nr, lambda f: f == ("metal", 1.0))]
    furnace = (q.vol * q.ci * q.co) @ white / PI
    out["quadrature"]["white metal ∫∫f cos cos/π, min/max over r"] = [float(furnace.min()), float(furnace.max())]
    log(f"lobes evaluated; white-metal furnace on the quadrature {furnace.min():.4f}..{furnace.max():.4f}")

    sizes, fams = basis_size(q, cols, nr, "main")
    print_sizes(sizes)
    out["basis size"] = sizes
    if args.check:
        q2 = Quad(160, 64, 72)
        metal = columns_of(nr, lambda f: f[0] == "metal" and f[1] in METAL_TRAIN)
        cols2 = lobe_columns(energy, rs, [("metal", f) for f in METAL_TRAIN], *q2.args())
        log(f"check quadrature: {q2.n} nodes")
        chk = {}
        for meas in ("cos", "uni"):
            g, m, _ = gram_of(cols2, q2.w[meas])
            fam = Family(g, m, np.arange(cols2.shape[1]))
            chk[meas] = {}
            for nb in (6, 8, 10, 12, 16):
                e2 = fam.errors(fam.capped(nb - 1))
                fam1 = fams[(meas, "metal")][0]
                e1 = fam1.errors(fam1.capped(nb - 1), metal)
                chk[meas][nb] = {
                    "main": [float(e1.mean()), float(e1.max())],
                    "refined": [float(e2.mean()), float(e2.max())],
                }
        out["convergence (metal, capped)"] = chk
        log(f"convergence: {json.dumps(chk)}")
        del cols2, q2

    norm_cos = np.sqrt(q.w["cos"] @ white**2)
    out["grid"] = grid_part(energy, rs, norm_cos, q)
    out["blinn-phong best single lobe (cos measure)"] = bp_part(q, energy)
    log("blinn-phong: " + json.dumps(out["blinn-phong best single lobe (cos measure)"]))

    meas = "cos"
    key = f"main {meas} metal capped"
    nb_metal = shipped_count(sizes[key], "metal F0 0..1 (train)") or 16
    nb_joint = shipped_count(sizes[f"main {meas} joint capped"], "metal (all F0)") or 16
    out["chosen counts"] = {"metal": nb_metal, "joint": nb_joint}
    log(f"counts meeting 1 % mean / 3 % worst: metal {nb_metal}, joint {nb_joint}")

    fam, norm = fams[(meas, "metal")]
    coef = fam.capped(nb_metal - 1)
    basis_q = eval_basis(cols[:, fam.train], norm[fam.train], fam.m[fam.train], coef)
    gram_check = basis_q.T @ (q.w[meas][:, None] * basis_q)
    out["basis orthonormality |G − I| max"] = float(np.abs(gram_check - np.eye(nb_metal)).max())
    out["linearity"] = linearity_part(q, energy, basis_q, q.w[meas])
    log("linearity: " + json.dumps(out["linearity"]))

    names, cfg = config_points()
    cfg_cols = lobe_columns(energy, rs, FAMS, *cfg)
    f16 = {}
    for name, nb in (("metal", nb_metal), ("joint", nb_joint)):
        fam_j = fams[(meas, name)]
        f16[f"principled {name} basis, N_b {nb}, {meas}"] = f16_part(
            q, energy, rs, fam_j, nb, meas, cols[:, fam_j[0].train], names, cfg, cfg_cols[:, fam_j[0].train]
        )
    for nb in sorted({nb_metal, nb_joint}):
        for m2 in ("uni", "cos"):
            f16[f"blinn-phong [1, 22809], N_b {nb}, {m2}"] = bp_basis_f16(q, nb, m2, names, cfg)
    out["f16"] = f16
    log("f16: " + json.dumps(f16, indent=1))
    if not args.skip_tables:
        tables(out, q, energy, rs, fams[(meas, "metal")], nb_metal, meas, basis_q)
    write_json(out, args.json)


def tables(out, q, energy, rs, fam_norm, nb, meas, basis_q):
    """Parts 4 and 5."""
    out["tables"] = table_part(q, energy, rs, fam_norm, nb, meas, basis_q)
    log("tables: " + json.dumps(out["tables"], indent=1))
    runs = part5_runs(warp_k(rs[0] ** 2))
    out["table parametrisations"] = param_part(q, energy, rs, fam_norm, nb, meas, basis_q, runs)


def write_json(out, path):
    if path:
        with open(path, "w") as f:
            json.dump(out, f, indent=1, default=float)


def tables_only(args, rs, energy, q):
    """`--tables-only`: the cos-measure metal basis exactly as the full run builds it (same
    columns, Gram and capped PCA), then parts 4 and 5 alone."""
    nr = len(rs)
    out = {}
    cols = lobe_columns(energy, rs, FAMS, *q.args())
    meas = "cos"
    g, m, norm = gram_of(cols, q.w[meas])
    fam = Family(g, m, columns_of(nr, lambda f: f[0] == "metal" and f[1] in METAL_TRAIN))
    nb = 16
    for n in COUNTS:
        e = fam.errors(fam.capped(n - 1), fam.train)
        if e.mean() <= 0.01 and e.max() <= 0.03:
            nb = n
            break
    coef = fam.capped(nb - 1)
    basis_q = eval_basis(cols[:, fam.train], norm[fam.train], fam.m[fam.train], coef)
    del cols
    out["chosen counts"] = {"metal": nb}
    log(f"tables only: metal basis N_b {nb}")
    tables(out, q, energy, rs, (fam, norm), nb, meas, basis_q)
    write_json(out, args.json)


if __name__ == "__main__":
    main()
