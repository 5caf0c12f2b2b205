//! The path integrator shared by the bake and the reference render.
//!
//! One eye sample: camera ray → eye hit x′ (region R′) → direct light at x′ for every value
//! the vertex BRDF gives → one (or more) indirect direction(s) → secondary hit x″ (region R₁)
//! → direct light at x″ for every value there → the product of the two goes to the pair of
//! slots. What "a value" is depends on [`VertexBrdf`]: one per basis of the region for the
//! bake, the one true BRDF for the reference. Random numbers are drawn in the same order
//! whatever the BRDF, so a relit bake and a reference with the same seed see the same paths.
//!
//! **Bounces beyond the first: the frozen tail.** With `bounces = n > 1`, light reaching the
//! secondary hit x″ after further bounces is traced too: one direction is drawn at x″ (the
//! region's cosine-and-lobes mixture), and along the path x‴, x⁗, … each vertex gets direct
//! light (next-event estimation, per emitter and light group, as at x″) and a continuation
//! drawn from its region's mixture, up to bounce n, with Russian roulette from bounce
//! [`RR_START`] on. Those later vertices are evaluated with [`VertexBrdf::tail`]: the
//! bake-time materials in the bake (editable regions included), the given materials in the
//! reference. The radiance that comes back is multiplied by the basis values at x″ and
//! added to the (eye slot, bounce slot) layers, so it stays linear in the coefficients of
//! the two keyed vertices and neither the stack's layout nor the relighter changes. It is
//! an approximation under edits: an edited region met at the third vertex or later still
//! reflects with its bake-time material (measured in `tests/engine/frozen_tail.rs`). Translucent
//! regions at later vertices reflect with their surface BRDF only, as at x″ (subsurface
//! light is gathered at the eye only). Roulette and direction choices depend on the
//! bake-time materials only, so the bake and a reference with other materials still trace
//! the same paths.
//!
//! **Direct light: two strategies.** Emitters are sampled at every vertex (next-event
//! estimation, per emitter and light group), and the BSDF-sampled rays a vertex traces
//! collect the light they meet — an area light's front face, an emissive surface, a point
//! or spot light's disk, a sun's cone, the world they escape to — both weighted by multiple importance sampling
//! ([`crate::bake::path::mis`]): the eye's light goes to its direct layers, a bounce vertex's to
//! the one-bounce layers. The weights use the pdfs of the sampling strategies, fixed before
//! the bake, never those of the edited materials, so the layers stay linear. A path's last
//! vertex traces a ray for this alone only where its region has a lobe; the paper's uniform
//! sampling at the eye keeps next-event estimation alone there.
//!
//! **Emitters seen directly.** A camera ray also collects the emitters it sees before (or
//! at) its first hit — area lights with camera visibility (front face), emissive surfaces
//! ([`crate::scene::Light::Emissive`]) — into the world layer of the emitter's light group:
//! that light depends on no material, so it relights as a constant scaled by the group's
//! gain. Emissive surfaces light the scene like any area light: uniform area sampling and
//! the BSDF rays that hit them, MIS-weighted.

use glam::{Vec2, Vec3};
use smallvec::{smallvec, SmallVec};
use std::f32::consts::PI;

use crate::bake::path::bounce_kinds::{BounceKinds, KindLimits};
use crate::bake::path::guide::GUIDE_WEIGHT;
use crate::bake::path::guide_tree::DirectionTree;
use crate::bake::path::mis::{
    emission_along, indirect_pdf, power_heuristic, traces_bsdf_ray, BsdfStrategy,
};
use crate::bake::path::mixture::DirectionMixture;
use crate::bake::path::tail_edits::{fold_bounce, TailEdits};
use crate::bake::prepare::context::{BakeContext, RegionModel};
use crate::geometry::bvh::SurfaceHit;
use crate::geometry::sampling::{cosine_hemisphere, to_world, uniform_hemisphere, SampleStream};
use crate::options::{IndirectSampling, MAX_BASES, MAX_GROUPS};
use crate::Rgb;

/// The BRDF values at a path vertex, one per slot of its region.
pub trait VertexBrdf: Sync {
    /// Writes the BRDF values (no cosine) for region `region` into `out` and returns the
    /// first slot they belong to and how many there are.
    fn eval(
        &self,
        region: u32,
        uv: Vec2,
        n: Vec3,
        wi: Vec3,
        wo: Vec3,
        out: &mut [Rgb; MAX_BASES],
    ) -> (u32, usize);

    /// Whether translucent regions add their subsurface layers at the eye (the bake's basis
    /// BRDF does; the reference renderer's true BRDF has no subsurface term).
    fn subsurface(&self) -> bool {
        false
    }

    /// The one BRDF value at a vertex beyond the first bounce (the frozen tail, no cosine).
    fn tail(&self, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> Rgb;

    /// [`Self::tail`] of an editable region as its diffuse and glossy parts, with the
    /// region's editable index, for the tail-edit layers
    /// ([`crate::bake::path::tail_edits`]); `None` for a fixed region and for BRDFs that
    /// keep no such layers (the reference renderer's).
    fn tail_parts(
        &self,
        _region: u32,
        _uv: Vec2,
        _n: Vec3,
        _wi: Vec3,
        _wo: Vec3,
    ) -> Option<(u16, [Rgb; 2])> {
        None
    }

    /// [`Self::tail`] and [`Self::tail_parts`] of one vertex, for BRDFs that get both from
    /// one evaluation (the bake's: a tail-edit vertex needs both, and a BRDF is the costly
    /// part of a tail vertex after its rays).
    #[inline]
    fn tail_with_parts(
        &self,
        region: u32,
        uv: Vec2,
        n: Vec3,
        wi: Vec3,
        wo: Vec3,
    ) -> (Rgb, Option<(u16, [Rgb; 2])>) {
        (
            self.tail(region, uv, n, wi, wo),
            self.tail_parts(region, uv, n, wi, wo),
        )
    }

    /// Whether [`Self::tail`] is the bake-time material ([`crate::bake::path::frozen::frozen_value`])
    /// itself, so that Russian roulette can reuse its value instead of evaluating it again;
    /// not for the reference renderer, whose tail has the edited materials.
    #[inline]
    fn tail_is_frozen(&self) -> bool {
        false
    }

    /// The probability that a bounce leaving region `region` along `wi` is a glossy one, for
    /// Cycles' per-kind light path limits ([`crate::bake::path::bounce_kinds`]): the glossy
    /// part of the tail BRDF there over the whole. Only called when such a limit binds.
    fn glossy_share(&self, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> f32;

    /// [`Self::tail`] and, when a per-kind limit binds (`share`), [`Self::glossy_share`] of
    /// one vertex (0 otherwise): BRDFs that get both from one evaluation of the material
    /// override it, since a tail vertex past the first needs both and the material's
    /// evaluation is its costliest part after its rays.
    #[inline]
    fn tail_and_share(
        &self,
        region: u32,
        uv: Vec2,
        n: Vec3,
        wi: Vec3,
        wo: Vec3,
        share: bool,
    ) -> (Rgb, f32) {
        let value = self.tail(region, uv, n, wi, wo);
        let share = if share {
            self.glossy_share(region, uv, n, wi, wo)
        } else {
            0.0
        };
        (value, share)
    }

    /// [`Self::tail_with_parts`] and, when `share`, [`Self::glossy_share`] of one vertex,
    /// the same way.
    #[inline]
    #[allow(clippy::too_many_arguments, clippy::type_complexity)]
    fn tail_with_parts_and_share(
        &self,
        region: u32,
        uv: Vec2,
        n: Vec3,
        wi: Vec3,
        wo: Vec3,
        share: bool,
    ) -> (Rgb, Option<(u16, [Rgb; 2])>, f32) {
        let (value, parts) = self.tail_with_parts(region, uv, n, wi, wo);
        let share = if share {
            self.glossy_share(region, uv, n, wi, wo)
        } else {
            0.0
        };
        (value, parts, share)
    }

    /// The last bounce a path reaches, for a bake of `baked` bounces: the bake's own and
    /// the reference renderer's stop there; a refinement's edited tail goes on to the
    /// bake's cap (the bounces a bounce budget left out at the bake-time materials).
    #[inline]
    fn bounces(&self, baked: u32) -> u32 {
        baked
    }
}

/// A vertex beyond the first bounce: [`VertexBrdf::tail`] as a one-slot BRDF, so
/// [`direct_light`] serves it too. When the path keeps a tail-edit record (`.1`), an
/// editable region's value also gives its diffuse and glossy parts in slots 1 and 2.
struct TailBrdf<'a, B: VertexBrdf>(&'a B, bool);

impl<B: VertexBrdf> VertexBrdf for TailBrdf<'_, B> {
    #[inline]
    fn eval(
        &self,
        region: u32,
        uv: Vec2,
        n: Vec3,
        wi: Vec3,
        wo: Vec3,
        out: &mut [Rgb; MAX_BASES],
    ) -> (u32, usize) {
        if !self.1 {
            out[0] = self.0.tail(region, uv, n, wi, wo);
            return (0, 1);
        }
        let (value, parts) = self.0.tail_with_parts(region, uv, n, wi, wo);
        out[0] = value;
        if let Some((_, [d, g])) = parts {
            out[1] = d;
            out[2] = g;
            return (0, 3);
        }
        (0, 1)
    }
    #[inline]
    fn tail(&self, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> Rgb {
        self.0.tail(region, uv, n, wi, wo)
    }
    #[inline]
    fn glossy_share(&self, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> f32 {
        self.0.glossy_share(region, uv, n, wi, wo)
    }
}

/// The bounce from which the frozen tail plays Russian roulette: the path continues with
/// probability min(1, luminance of its bake-time throughput), at least [`RR_MIN_SURVIVAL`].
pub const RR_START: u32 = 4;
/// Lowest survival probability of the roulette (keeps paths whose bake-time throughput is
/// black but whose edited one is not, so the reference stays unbiased).
pub const RR_MIN_SURVIVAL: f32 = 0.05;

/// The slot of value `k` of the eye vertex whose values start at slot `first` on scene region
/// `region`: a translucent region's diffuse basis has its own slot at the eye (weighted by
/// `Kd·(1 − w)`, see [`crate::bssrdf::coefficients`]).
#[inline]
fn eye_slot(ctx: &BakeContext, region: u32, first: u32, k: usize) -> u32 {
    if k == 0 {
        ctx.eye_diffuse_slot[region as usize]
    } else {
        first + k as u32
    }
}

/// Where the integrator puts radiance, by light group.
pub trait PathSink {
    /// The world (of light group `group`) seen directly through the pixel.
    fn world(&mut self, group: usize, value: Rgb);
    /// Direct light of group `group` reflected at the eye vertex through slot `slot`.
    fn direct(&mut self, group: usize, slot: u32, value: Rgb);
    /// Light of group `group` reflected at the bounce vertex through `bounce_slot`, then at
    /// the eye vertex through `eye_slot`.
    fn bounce(&mut self, group: usize, eye_slot: u32, bounce_slot: u32, value: Rgb);
    /// The eye ray hit region `region` at `position` with shading normal `normal` (what the
    /// bake's denoiser steers by; nothing by default).
    #[inline]
    fn eye_hit(&mut self, _region: u32, _normal: Vec3, _position: Vec3) {}
    /// Whether this sink keeps tail-edit layers (then the integrator labels tail vertices
    /// and calls [`Self::tail_edit`]; the bake's sinks do, nothing else needs to).
    #[inline]
    fn tail_edits(&self) -> bool {
        false
    }
    /// Tail light of group `group` for the tail-edit layer of eye part `eye` (0: the fixed
    /// region, 1 + 2r + p: part p of editable region r), tail region `region` and bin `bin`
    /// (a monomial of the region's part scales, the bounce vertex folded in); see
    /// [`crate::bake::path::tail_edits`].
    #[inline]
    fn tail_edit(&mut self, _group: usize, _eye: usize, _region: usize, _bin: usize, _value: Rgb) {}
}

/// Ray queries, counted (and recordable for throughput measurements).
pub trait Tracer {
    fn intersect(
        &mut self,
        ctx: &BakeContext,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<SurfaceHit>;
    fn occluded(&mut self, ctx: &BakeContext, origin: Vec3, dir: Vec3, tmax: f32) -> bool;
}

/// The plain tracer: counts rays.
#[derive(Default, Clone, Copy, Debug)]
pub struct CountingTracer {
    pub rays: u64,
}

impl Tracer for CountingTracer {
    #[inline]
    fn intersect(
        &mut self,
        ctx: &BakeContext,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<SurfaceHit> {
        self.rays += 1;
        ctx.geometry.intersect(origin, dir, tmin, tmax)
    }
    #[inline]
    fn occluded(&mut self, ctx: &BakeContext, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.rays += 1;
        ctx.geometry.occluded(origin, dir, tmax)
    }
}

/// Passes on only finite contributions: a NaN or infinite one (a degenerate pdf, a
/// throughput that overflowed) is discarded and counted, as Cycles discards such samples,
/// so one bad path never poisons a pixel's sum, its denoiser window or the stack.
struct FiniteOnly<'a, S> {
    inner: &'a mut S,
    discarded: u32,
}

impl<S: PathSink> FiniteOnly<'_, S> {
    #[inline]
    fn keep(&mut self, v: Rgb) -> bool {
        let finite = v.is_finite();
        self.discarded += u32::from(!finite);
        finite
    }
}

impl<S: PathSink> PathSink for FiniteOnly<'_, S> {
    #[inline]
    fn world(&mut self, group: usize, value: Rgb) {
        if self.keep(value) {
            self.inner.world(group, value);
        }
    }
    #[inline]
    fn direct(&mut self, group: usize, slot: u32, value: Rgb) {
        if self.keep(value) {
            self.inner.direct(group, slot, value);
        }
    }
    #[inline]
    fn bounce(&mut self, group: usize, eye_slot: u32, bounce_slot: u32, value: Rgb) {
        if self.keep(value) {
            self.inner.bounce(group, eye_slot, bounce_slot, value);
        }
    }
    #[inline]
    fn eye_hit(&mut self, region: u32, normal: Vec3, position: Vec3) {
        if normal.is_finite() && position.is_finite() {
            self.inner.eye_hit(region, normal, position);
        }
    }
    #[inline]
    fn tail_edits(&self) -> bool {
        self.inner.tail_edits()
    }
    #[inline]
    fn tail_edit(&mut self, group: usize, eye: usize, region: usize, bin: usize, value: Rgb) {
        if self.keep(value) {
            self.inner.tail_edit(group, eye, region, bin, value);
        }
    }
}

/// Traces eye sample number `sample` of pixel (`px`, `py`) into `sink`, which receives only
/// finite contributions; returns how many were discarded for a NaN or infinite channel
/// (for [`crate::bake::non_finite`]'s count).
pub fn trace_eye_sample<B: VertexBrdf, S: PathSink, T: Tracer>(
    ctx: &BakeContext,
    brdf: &B,
    sink: &mut S,
    tracer: &mut T,
    px: u32,
    py: u32,
    sample: u32,
) -> u32 {
    let mut finite = FiniteOnly {
        inner: sink,
        discarded: 0,
    };
    trace_path(ctx, brdf, &mut finite, tracer, px, py, sample);
    finite.discarded
}

/// The path of [`trace_eye_sample`], into any sink.
fn trace_path<B: VertexBrdf, S: PathSink, T: Tracer>(
    ctx: &BakeContext,
    brdf: &B,
    sink: &mut S,
    tracer: &mut T,
    px: u32,
    py: u32,
    sample: u32,
) {
    let settings = &ctx.settings;
    let pixel = py as u64 * ctx.resolution.width as u64 + px as u64;
    let mut stream = SampleStream::new(settings.seed, pixel, sample);
    let (jx, jy) = stream.next2();
    let (origin, dir) = ctx.camera.ray(px as f32 + jx, py as f32 + jy);
    let hit = tracer.intersect(ctx, origin, dir, 0.0, ctx.clip_end);
    // Emitters the camera sees (visible area lights, emissive surfaces): constant light,
    // independent of every material, so it goes to the world layer of the emitter's group.
    ctx.lights.seen_directly(
        origin,
        dir,
        hit.as_ref().map(|h| (h.t, h.region)),
        |g, v| sink.world(g, v),
    );
    let Some(hit) = hit else {
        sink.world(
            ctx.lights.world_group(),
            ctx.lights.environment.radiance(dir),
        );
        return;
    };
    sink.eye_hit(hit.region, hit.shading_normal, hit.position);
    let groups = ctx.lights.groups.len();
    let wo = -dir;
    let region = &ctx.regions[hit.region as usize];
    let guide = ctx.guide.as_ref().and_then(|g| g.sampler(px, py));
    // The eye weighs its light samples against its BSDF rays when those follow the region's
    // lobes (not the paper's uniform directions, `mis` module docs); it traces them for its
    // bounce, or (no bounce) for the light a lobe meets.
    let eye_mis = settings.sampling != IndirectSampling::Uniform
        && (settings.bounces > 0 || traces_bsdf_ray(&region.mixture));
    let eye_rays = settings.bounces > 0 || eye_mis;
    let eye_strategy = eye_mis.then_some(BsdfStrategy {
        sampling: settings.sampling,
        mixture: &region.mixture,
        guide,
        count: settings.indirect_samples,
    });
    let mut values = [Rgb::ZERO; MAX_BASES];
    let mut eye_light = group_light(groups);
    let (first, count) = direct_light(
        ctx,
        brdf,
        tracer,
        &hit,
        wo,
        eye_strategy.as_ref(),
        true,
        &mut stream,
        &mut values,
        &mut eye_light,
    );
    for g in 0..groups {
        for (k, v) in eye_light[g * MAX_BASES..].iter().enumerate().take(count) {
            if *v != Rgb::ZERO {
                sink.direct(g, eye_slot(ctx, hit.region, first, k), *v);
            }
        }
    }
    if brdf.subsurface() {
        if let Some(t) = &ctx.translucent[hit.region as usize] {
            let k_count = t.basis.count();
            let mut acc = [Rgb::ZERO; MAX_GROUPS * crate::bssrdf::MAX_SSS_BASES];
            let acc = &mut acc[..groups * k_count];
            crate::bake::prepare::subsurface::gather_at(
                t,
                hit.position,
                hit.shading_normal,
                wo,
                acc,
            );
            for g in 0..groups {
                for (k, v) in acc[g * k_count..(g + 1) * k_count].iter().enumerate() {
                    if *v != Rgb::ZERO {
                        sink.direct(g, t.first_slot + k as u32, *v);
                    }
                }
            }
        }
    }
    if !eye_rays {
        return;
    }
    let n = hit.shading_normal;
    let inv_indirect = 1.0 / settings.indirect_samples as f32;
    let limits = KindLimits::of(settings, brdf.bounces(settings.bounces));
    let mut eye_values = [Rgb::ZERO; MAX_BASES];
    let mut bounce_light = group_light(groups);
    let indirect = stream.branch();
    for i in 0..settings.indirect_samples {
        let mut stream = indirect.child(i, settings.indirect_samples);
        let Some((wi, pdf)) = sample_indirect(
            settings.sampling,
            &region.mixture,
            guide,
            n,
            wo,
            &mut stream,
        ) else {
            continue;
        };
        let cos_i = n.dot(wi);
        if cos_i <= 0.0 || hit.geometric_normal.dot(wi) <= 0.0 || !(pdf > 0.0) {
            continue;
        }
        let hit2 = tracer.intersect(
            ctx,
            ctx.geometry.offset(hit.position, hit.geometric_normal),
            wi,
            0.0,
            f32::INFINITY,
        );
        let (eye_first, eye_count) = brdf.eval(hit.region, hit.uv, n, wi, wo, &mut eye_values);
        let weight = cos_i / pdf * inv_indirect;
        // Cycles' per-kind limits: the path's split of its bounces after the eye's one.
        let kinds = limits.map(|l| {
            let mut k = BounceKinds::new(l);
            k.bounce(brdf.glossy_share(hit.region, hit.uv, n, wi, wo));
            k
        });
        // The light this BSDF ray meets is direct light at the eye (the second strategy).
        let mut emitted = [Rgb::ZERO; MAX_GROUPS];
        let density = settings.indirect_samples as f32 * pdf;
        if eye_mis
            && emission_along(
                ctx,
                &hit,
                wi,
                density,
                hit2.as_ref(),
                true,
                &mut emitted[..groups],
            )
        {
            for (e, value) in eye_values.iter().enumerate().take(eye_count) {
                let fe = *value * weight;
                for (g, l) in emitted[..groups].iter().enumerate() {
                    if fe != Rgb::ZERO && *l != Rgb::ZERO {
                        sink.direct(g, eye_slot(ctx, hit.region, eye_first, e), fe * *l);
                    }
                }
            }
        }
        if settings.bounces == 0 {
            continue;
        }
        let Some(hit2) = hit2 else {
            continue;
        };
        // The bounce vertex traces a BSDF ray when the path goes on, or for a lobe's light.
        let mixture2 = &ctx.regions[hit2.region as usize].mixture;
        let bounce_rays = brdf.bounces(settings.bounces) >= 2 || traces_bsdf_ray(mixture2);
        let bounce_strategy = bounce_rays.then(|| BsdfStrategy::mixture(ctx, hit2.region));
        let (mut bounce_first, mut bounce_count) = direct_light(
            ctx,
            brdf,
            tracer,
            &hit2,
            -wi,
            bounce_strategy.as_ref(),
            false,
            &mut stream,
            &mut values,
            &mut bounce_light,
        );
        if let Some(within) = kinds.as_ref().map(BounceKinds::within) {
            if within < 1.0 {
                for g in 0..groups {
                    for l in &mut bounce_light[g * MAX_BASES..g * MAX_BASES + bounce_count] {
                        *l *= within;
                    }
                }
            }
        }
        if bounce_rays {
            let mut tail = stream.branch();
            let mut edits =
                (settings.bounces >= 2 && sink.tail_edits()).then(|| TailEdits::new(groups));
            let bounce_parts = frozen_tail(
                ctx,
                brdf,
                tracer,
                &hit2,
                -wi,
                &mut tail,
                &mut values,
                &mut bounce_light,
                (&mut bounce_first, &mut bounce_count),
                edits.as_mut(),
                kinds,
            );
            if let (Some(edits), Some(bounce_parts)) = (&edits, bounce_parts) {
                emit_tail_edits(sink, brdf, &hit, wi, wo, weight, edits, &bounce_parts);
            }
        }
        for (e, value) in eye_values.iter().enumerate().take(eye_count) {
            let fe = *value * weight;
            if fe == Rgb::ZERO {
                continue;
            }
            for g in 0..groups {
                for (b, light) in bounce_light[g * MAX_BASES..]
                    .iter()
                    .enumerate()
                    .take(bounce_count)
                {
                    if *light != Rgb::ZERO {
                        sink.bounce(
                            g,
                            eye_slot(ctx, hit.region, eye_first, e),
                            bounce_first + b as u32,
                            fe * *light,
                        );
                    }
                }
            }
        }
    }
}

/// Direct light at `hit` towards `wo`: for every emitter and light sample, every BRDF value
/// of the vertex times cos θ times radiance/pdf, averaged over the light samples, summed per
/// light group and slot into `light[group · MAX_BASES + slot]` (cleared first). Returns the
/// vertex's first slot and slot count (count 0 when no sample arrived). Takes one branch of
/// `stream` per emitter, whose children are the light samples, always. With `bsdf` (the
/// vertex also traces BSDF rays that collect light, [`crate::bake::path::mis`]) each light sample
/// an emitter can also be met by carries its multiple-importance weight against that
/// strategy; with `None` every light sample has full weight. `eye` says whether `hit` is
/// the eye's vertex, which takes its own count
/// ([`crate::bake::settings::BakeSettings::light_samples_at`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn direct_light<B: VertexBrdf, T: Tracer>(
    ctx: &BakeContext,
    brdf: &B,
    tracer: &mut T,
    hit: &SurfaceHit,
    wo: Vec3,
    bsdf: Option<&BsdfStrategy>,
    eye: bool,
    stream: &mut SampleStream,
    values: &mut [Rgb; MAX_BASES],
    light: &mut [Rgb],
) -> (u32, usize) {
    let mut first = 0u32;
    let mut count = 0usize;
    let n = hit.shading_normal;
    let ng = hit.geometric_normal;
    let samples = ctx.settings.light_samples_at(eye);
    let inv = 1.0 / samples as f32;
    let origin = ctx.geometry.offset(hit.position, ng);
    for emitter in 0..ctx.lights.len() {
        let base = stream.branch();
        for j in 0..samples {
            let (u1, u2) = base.child(j, samples).next2();
            let Some(s) = ctx.lights.sample(emitter, hit.position, n, u1, u2) else {
                continue;
            };
            let cos = n.dot(s.wi);
            if cos <= 0.0 || ng.dot(s.wi) <= 0.0 || s.radiance_over_pdf == Rgb::ZERO {
                continue;
            }
            let tmax = if s.distance.is_finite() {
                s.distance * (1.0 - 1e-4)
            } else {
                f32::INFINITY
            };
            if tracer.occluded(ctx, origin, s.wi, tmax) {
                continue;
            }
            let (f, c) = brdf.eval(hit.region, hit.uv, n, s.wi, wo, values);
            if count == 0 {
                (first, count) = (f, c);
                for g in 0..ctx.lights.groups.len() {
                    light[g * MAX_BASES..g * MAX_BASES + c].fill(Rgb::ZERO);
                }
            }
            let mis = match (bsdf, s.pdf) {
                (Some(b), Some(pdf)) => {
                    power_heuristic(samples as f32 * pdf, b.density(n, wo, s.wi))
                }
                _ => 1.0,
            };
            let li = s.radiance_over_pdf * (cos * inv * mis);
            let g = ctx.lights.group_of(emitter);
            for (l, v) in light[g * MAX_BASES..]
                .iter_mut()
                .zip(values.iter())
                .take(count)
            {
                *l += *v * li;
            }
        }
    }
    (first, count)
}

/// Adds to `light` (laid out as [`direct_light`]'s, whose `(first, count)` it updates when
/// that found nothing) the light that leaves the first-bounce vertex `hit` towards `wo`
/// along one direction drawn from the region's mixture: the emitters that direction meets
/// (MIS-weighted against the vertex's light samples) and, with bounces ≥ 2, the light of
/// bounces 2..=n ([`tail_radiance`]), times each basis value of the vertex, cos θ over the
/// pdf.
#[allow(clippy::too_many_arguments)]
fn frozen_tail<B: VertexBrdf, T: Tracer>(
    ctx: &BakeContext,
    brdf: &B,
    tracer: &mut T,
    hit: &SurfaceHit,
    wo: Vec3,
    stream: &mut SampleStream,
    values: &mut [Rgb; MAX_BASES],
    light: &mut [Rgb],
    (first, count): (&mut u32, &mut usize),
    edits: Option<&mut TailEdits>,
    kinds: Option<BounceKinds>,
) -> Option<BounceParts> {
    let n = hit.shading_normal;
    let (wi, cos, pdf) = continuation(ctx, hit, wo, stream)?;
    // With tail-edit layers the bounce vertex's value, parts and glossy share come from one
    // evaluation of its material. Where a per-kind limit binds, the share is needed before
    // the tail is traced, so that evaluation comes first; otherwise it waits until the tail
    // has found light, and a tail that finds none costs no evaluation.
    let tracked = edits.is_some();
    let record = |labelled: bool| {
        let (value, parts, share) =
            brdf.tail_with_parts_and_share(hit.region, hit.uv, n, wi, wo, labelled);
        let bounce = BounceParts {
            parts,
            value,
            weight: cos / pdf,
        };
        (bounce, share)
    };
    let early = (tracked && kinds.is_some()).then(|| record(true));
    let kinds = kinds.map(|k| {
        let share = match &early {
            Some((_, share)) => *share,
            None => brdf.glossy_share(hit.region, hit.uv, n, wi, wo),
        };
        (k, share)
    });
    let groups = ctx.lights.groups.len();
    let mut radiance = [Rgb::ZERO; MAX_GROUPS];
    if !tail_radiance(
        ctx,
        brdf,
        tracer,
        hit,
        wi,
        pdf,
        stream,
        &mut radiance[..groups],
        edits,
        kinds,
    ) {
        return None;
    }
    let (f, c) = brdf.eval(hit.region, hit.uv, n, wi, wo, values);
    if *count == 0 {
        (*first, *count) = (f, c);
        for g in 0..groups {
            light[g * MAX_BASES..g * MAX_BASES + c].fill(Rgb::ZERO);
        }
    }
    let w = cos / pdf;
    for (g, r) in radiance[..groups].iter().enumerate() {
        if *r == Rgb::ZERO {
            continue;
        }
        for (l, v) in light[g * MAX_BASES..].iter_mut().zip(values.iter()).take(c) {
            *l += *v * *r * w;
        }
    }
    match early {
        Some((bounce, _)) => Some(bounce),
        None => tracked.then(|| record(false).0),
    }
}

/// The bounce vertex's bake-time BRDF along the tail's first direction, for the tail-edit
/// layers: its parts when editable, its value, and cos θ over the direction's pdf.
pub(crate) struct BounceParts {
    parts: Option<(u16, [Rgb; 2])>,
    value: Rgb,
    weight: f32,
}

/// Hands the tail-edit record of one indirect sample to `sink`: each (group, region, bin)
/// light of `edits` times the eye vertex's bake-time BRDF, split by its part, and the bounce
/// vertex's, folded into the monomial bins by its part when it lies on that region
/// ([`fold_bounce`]; `eye_weight` is that sample's cos θ over pdf and sample count).
#[allow(clippy::too_many_arguments)]
fn emit_tail_edits<B: VertexBrdf, S: PathSink>(
    sink: &mut S,
    brdf: &B,
    hit: &SurfaceHit,
    wi: Vec3,
    wo: Vec3,
    eye_weight: f32,
    edits: &TailEdits,
    bounce: &BounceParts,
) {
    let n = hit.shading_normal;
    let mut eyes = [(0usize, Rgb::ZERO); 2];
    let eye_count = match brdf.tail_parts(hit.region, hit.uv, n, wi, wo) {
        Some((r, [d, g])) => {
            eyes = [(1 + 2 * r as usize, d), (2 + 2 * r as usize, g)];
            2
        }
        None => {
            eyes[0] = (0, brdf.tail(hit.region, hit.uv, n, wi, wo));
            1
        }
    };
    edits.for_each(|group, region, bin, light| {
        let light = light * (bounce.weight * eye_weight);
        // The bounce vertex's BRDF parts when it lies on the tail's region.
        let on = match bounce.parts {
            Some((r, parts)) if r == region => Some(parts),
            _ => None,
        };
        for &(eye, f) in &eyes[..eye_count] {
            fold_bounce(bin, light * f, on, bounce.value, |b, v| {
                if v != Rgb::ZERO {
                    sink.tail_edit(group, eye, region as usize, b, v);
                }
            });
        }
    });
}

/// The radiance, per light group, that arrives at `from` along `dir` (drawn there from its
/// region's mixture with pdf `pdf`): the emitters met along each segment, MIS-weighted
/// against the light samples of the vertex the segment leaves, and the light of the
/// vertices at bounces 2..=[`VertexBrdf::bounces`] evaluated with [`VertexBrdf::tail`]
/// (next-event estimation at each, mixture continuation, Russian roulette from
/// [`RR_START`] driven by the bake-time throughput). The last vertex traces one more
/// segment, for emitters only, where its region has a lobe ([`crate::bake::path::mis`]). Adds
/// into `out` (one entry per group); returns whether anything arrived.
#[allow(clippy::too_many_arguments)]
pub(crate) fn tail_radiance<B: VertexBrdf, T: Tracer>(
    ctx: &BakeContext,
    brdf: &B,
    tracer: &mut T,
    from: &SurfaceHit,
    dir: Vec3,
    pdf: f32,
    stream: &mut SampleStream,
    out: &mut [Rgb],
    mut edits: Option<&mut TailEdits>,
    kinds: Option<(BounceKinds, f32)>,
) -> bool {
    let tail = TailBrdf(brdf, edits.is_some());
    // Cycles' per-kind limits: the probability the path is within them at the vertex the
    // current segment leaves (`leaving`), and the split of its bounces after that segment.
    let (mut kinds, mut leaving) = match kinds {
        Some((mut k, share)) => {
            let leaving = k.within();
            k.bounce(share);
            (Some(k), leaving)
        }
        None => (None, 1.0),
    };
    let max_bounce = brdf.bounces(ctx.settings.bounces);
    let mut values = [Rgb::ZERO; MAX_BASES];
    let mut light = group_light(ctx.lights.groups.len());
    let mut emitted = [Rgb::ZERO; MAX_GROUPS];
    let mut throughput = Rgb::ONE;
    let mut frozen = Rgb::ONE;
    let mut vertex = *from;
    let mut dir = dir;
    let mut pdf = pdf;
    let mut any = false;
    // The bounce of the vertex the current segment leads to.
    let mut bounce = 2u32;
    loop {
        let origin = ctx
            .geometry
            .offset(vertex.position, vertex.geometric_normal);
        let next = tracer.intersect(ctx, origin, dir, 0.0, f32::INFINITY);
        let emitted = &mut emitted[..out.len()];
        emitted.fill(Rgb::ZERO);
        if leaving > 0.0 && emission_along(ctx, &vertex, dir, pdf, next.as_ref(), false, emitted) {
            for (g, (o, e)) in out.iter_mut().zip(emitted.iter()).enumerate() {
                if *e != Rgb::ZERO {
                    let e = throughput * *e * leaving;
                    *o += e;
                    any = true;
                    if let Some(edits) = edits.as_deref_mut() {
                        edits.record(g, e);
                    }
                }
            }
        }
        let Some(hit) = next else {
            break;
        };
        if bounce > max_bounce {
            break; // the last vertex's segment, for emitters only
        }
        let here = kinds.as_ref().map_or(1.0, BounceKinds::within);
        if here <= 0.0 {
            break; // past a per-kind limit on every split: nothing more reaches the image
        }
        let wo = -dir;
        let last = bounce == max_bounce;
        let rays = !last || traces_bsdf_ray(&ctx.regions[hit.region as usize].mixture);
        let strategy = rays.then(|| BsdfStrategy::mixture(ctx, hit.region));
        let (_, c) = direct_light(
            ctx,
            &tail,
            tracer,
            &hit,
            wo,
            strategy.as_ref(),
            false,
            stream,
            &mut values,
            &mut light,
        );
        if c > 0 {
            let throughput = throughput * here;
            for (g, o) in out.iter_mut().enumerate() {
                let l = light[g * MAX_BASES];
                if l != Rgb::ZERO {
                    *o += throughput * l;
                    any = true;
                    if let Some(edits) = edits.as_deref_mut() {
                        match ctx.regions[hit.region as usize].model {
                            RegionModel::Editable { index, .. } if c == 3 => edits.record_at(
                                g,
                                index,
                                [
                                    throughput * light[g * MAX_BASES + 1],
                                    throughput * light[g * MAX_BASES + 2],
                                ],
                            ),
                            _ => edits.record(g, throughput * l),
                        }
                    }
                }
            }
        }
        if !rays {
            break;
        }
        let n = hit.shading_normal;
        let Some((wi, cos, next_pdf)) = continuation(ctx, &hit, wo, stream) else {
            break;
        };
        let w = cos / next_pdf;
        let labelled = kinds.is_some();
        let (value, share) = match edits.as_deref_mut() {
            Some(edits) => {
                let (value, parts, share) =
                    brdf.tail_with_parts_and_share(hit.region, hit.uv, n, wi, wo, labelled);
                if let Some((index, parts)) = parts {
                    edits.label(index, parts);
                }
                (value, share)
            }
            None => brdf.tail_and_share(hit.region, hit.uv, n, wi, wo, labelled),
        };
        if let Some(k) = kinds.as_mut() {
            leaving = here;
            k.bounce(share);
        }
        throughput *= value * w;
        let bake_time = if brdf.tail_is_frozen() {
            value
        } else {
            crate::bake::path::frozen::frozen_value(ctx, hit.region, hit.uv, n, wi, wo)
        };
        frozen *= bake_time * w;
        bounce += 1;
        if bounce >= RR_START && bounce <= max_bounce {
            let q = crate::luminance(frozen).clamp(RR_MIN_SURVIVAL, 1.0);
            let u = stream.next();
            if u >= q {
                break;
            }
            throughput /= q;
            frozen /= q;
        }
        if throughput == Rgb::ZERO {
            break;
        }
        vertex = hit;
        dir = wi;
        pdf = next_pdf;
    }
    any
}

/// Per light group, the light a vertex gathers for each of its basis values, `MAX_BASES`
/// apart ([`direct_light`]'s layout). On the stack for one light group, the usual case, and
/// on the heap for several: a buffer sized for every possible group would be zeroed at each
/// eye sample and bounce vertex, which the bake's profile showed as time in `memset`.
pub(crate) type GroupLight = SmallVec<[Rgb; MAX_BASES]>;

/// A zeroed [`GroupLight`] for `groups` light groups.
pub(crate) fn group_light(groups: usize) -> GroupLight {
    smallvec![Rgb::ZERO; groups.max(1) * MAX_BASES]
}

/// The direction a path continues in from vertex `hit` (seen from `wo`) beyond the first
/// bounce: one draw from the region's cosine-and-lobes mixture, kept only above both the
/// shading and the geometric surface and with a positive pdf. Returns the direction, its
/// cosine to the shading normal and its pdf. One function for the bake's frozen tail and
/// the bounce pre-pass, so both consume the random stream alike.
#[inline]
pub(crate) fn continuation(
    ctx: &BakeContext,
    hit: &SurfaceHit,
    wo: Vec3,
    stream: &mut SampleStream,
) -> Option<(Vec3, f32, f32)> {
    let n = hit.shading_normal;
    let region = &ctx.regions[hit.region as usize];
    let (wi, pdf) = sample_indirect(
        IndirectSampling::Mixture,
        &region.mixture,
        None,
        n,
        wo,
        stream,
    )?;
    let cos = n.dot(wi);
    if cos <= 0.0 || hit.geometric_normal.dot(wi) <= 0.0 || !(pdf > 0.0) {
        return None;
    }
    Some((wi, cos, pdf))
}

/// Draws an indirect direction at a vertex with normal `n`: uniform (the paper), the
/// region's cosine-and-lobes [`DirectionMixture`], or (guided, where the pixel's tile has a
/// guide tree) [`GUIDE_WEIGHT`] of the tree and the rest that mixture. The component is
/// picked by the first number of the pair, rescaled, so stratification survives inside each
/// component. Returns the direction and its solid-angle pdf (of the whole mixture);
/// consumes one dimension pair always.
pub fn sample_indirect(
    sampling: IndirectSampling,
    mixture: &DirectionMixture,
    guide: Option<&DirectionTree>,
    n: Vec3,
    wo: Vec3,
    stream: &mut SampleStream,
) -> Option<(Vec3, f32)> {
    let (u1, u2) = stream.next2();
    if sampling == IndirectSampling::Uniform {
        return Some((to_world(n, uniform_hemisphere(u1, u2)), 1.0 / (2.0 * PI)));
    }
    let guide = guide.filter(|_| sampling == IndirectSampling::Guided);
    let guide_weight = if guide.is_some() { GUIDE_WEIGHT } else { 0.0 };
    let wi = match guide {
        Some(g) if u1 < guide_weight => g.sample(u1 / guide_weight, u2),
        _ => {
            let u = ((u1 - guide_weight) / (1.0 - guide_weight)).clamp(0.0, 1.0 - f32::EPSILON);
            mixture.sample(u, u2, n, wo)
        }
    };
    if n.dot(wi) <= 0.0 {
        return None;
    }
    Some((wi, indirect_pdf(sampling, mixture, guide, n, wo, wi)))
}

/// One sample of the guide pass ([`crate::bake::path::guide`]) for pixel (`px`, `py`): a
/// cosine-distributed indirect direction at the eye hit and the luminance of the radiance
/// that comes back along it (direct light reflected at the secondary hit by `brdf`, each
/// light group's tint applied) times the cosine at the eye hit over the direction's pdf,
/// i.e. π × luminance. `None` when the eye ray or the indirect ray escapes (escaping
/// indirect rays carry nothing in the bake either).
pub fn guide_sample<B: VertexBrdf, T: Tracer>(
    ctx: &BakeContext,
    brdf: &B,
    tracer: &mut T,
    px: u32,
    py: u32,
    sample: u32,
    seed: u64,
) -> Option<(Vec3, f32)> {
    let pixel = py as u64 * ctx.resolution.width as u64 + px as u64;
    let mut stream = SampleStream::new(seed, pixel, sample);
    let (jx, jy) = stream.next2();
    let (origin, dir) = ctx.camera.ray(px as f32 + jx, py as f32 + jy);
    let hit = tracer.intersect(ctx, origin, dir, 0.0, ctx.clip_end)?;
    let n = hit.shading_normal;
    let (u1, u2) = stream.next2();
    let local = cosine_hemisphere(u1, u2);
    let wi = to_world(n, local);
    if local.z <= 1e-6 || hit.geometric_normal.dot(wi) <= 0.0 {
        return None;
    }
    let hit2 = tracer.intersect(
        ctx,
        ctx.geometry.offset(hit.position, hit.geometric_normal),
        wi,
        0.0,
        f32::INFINITY,
    )?;
    let mut values = [Rgb::ZERO; MAX_BASES];
    let mut light = group_light(ctx.lights.groups.len());
    let (_, count) = direct_light(
        ctx,
        brdf,
        tracer,
        &hit2,
        -wi,
        None,
        false,
        &mut stream,
        &mut values,
        &mut light,
    );
    if count == 0 {
        return None;
    }
    let mut radiance = Rgb::ZERO;
    for (g, group) in ctx.lights.groups.iter().enumerate() {
        radiance += light[g * MAX_BASES] * group.tint;
    }
    Some((wi, crate::luminance(radiance) * PI))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Default)]
    struct Recorder(Vec<Rgb>);

    impl PathSink for Recorder {
        fn world(&mut self, _: usize, v: Rgb) {
            self.0.push(v);
        }
        fn direct(&mut self, _: usize, _: u32, v: Rgb) {
            self.0.push(v);
        }
        fn bounce(&mut self, _: usize, _: u32, _: u32, v: Rgb) {
            self.0.push(v);
        }
    }

    /// The path stage: a contribution with a NaN or an infinite channel is discarded and
    /// counted, whichever layer it was for; a subnormal one is kept as it is.
    #[test]
    fn non_finite_path_contributions_are_discarded_and_counted() {
        let mut recorder = Recorder::default();
        let mut sink = FiniteOnly {
            inner: &mut recorder,
            discarded: 0,
        };
        sink.world(0, Rgb::new(f32::NAN, 1.0, 1.0));
        sink.direct(0, 1, Rgb::new(1.0, f32::INFINITY, 1.0));
        sink.bounce(0, 1, 2, Rgb::new(1.0, 1.0, f32::NEG_INFINITY));
        sink.direct(0, 1, Rgb::splat(1e-40));
        sink.bounce(0, 1, 2, Rgb::splat(2.0));
        assert_eq!(sink.discarded, 3);
        assert_eq!(recorder.0, vec![Rgb::splat(1e-40), Rgb::splat(2.0)]);
    }
}
