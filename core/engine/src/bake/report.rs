//! What a bake reports: the whole bake ([`BakeReport`]) and each pass of a progressive one
//! ([`PassReport`]), for the command line's JSON and the add-on's status.

use std::time::Instant;

use serde::Serialize;

use super::{
    finish::drop,
    prepare::{bounce_budget, estimate},
    NonFiniteReport,
};
use crate::scene::validate::ValidationReport;

/// What a bake did, for the command line's JSON and the add-on's status.
#[derive(Clone, Debug, Serialize)]
pub struct BakeReport {
    /// Whole bake, wall clock.
    pub seconds: f64,
    /// Validation, basis and BVH build.
    pub setup_seconds: f64,
    /// Path tracing and layer assembly.
    pub trace_seconds: f64,
    /// Part of `trace_seconds` spent on per-layer work: filtering, finalising tiles into the
    /// stack and finishing it (interleaved with a one-pass bake's tracing: the rest of
    /// `trace_seconds` is tracing).
    pub assembly_seconds: f64,
    /// Part of `assembly_seconds` spent denoising ([`denoise`]; 0 when the settings ask for none).
    pub denoise_seconds: f64,
    /// Rays per second of `trace_seconds`.
    pub rays: u64,
    pub rays_per_second: f64,
    pub width: u32,
    pub height: u32,
    pub triangles: usize,
    pub degenerate_triangles: usize,
    pub warnings: Vec<String>,
    /// Layers the slots allow (world + slots + slot pairs).
    pub layers_possible: usize,
    pub layers_grey: usize,
    pub layers_rgb: usize,
    /// Layers no path reached (e.g. a region never seen from another): not stored.
    pub layers_empty: usize,
    /// Bytes of samples the stack would hold in the dense layout (every kept layer a full
    /// frame): what `dense_bytes` says, kept under its old name.
    pub sample_bytes: usize,
    /// (Tile, layer) entries of the tiled stack.
    pub tile_entries: usize,
    /// Bytes of samples the tiled stack holds (only the layers present per tile).
    pub stored_bytes: usize,
    /// Bytes the kept layers would hold as full frames (the dense layout).
    pub dense_bytes: usize,
    /// Relative L2 error of the image at the bake-time materials that storing bounce
    /// layers as lattice entries costs (‖Σ w (L − L̃)‖ / ‖Σ w L‖ over the frame, measured
    /// before negligible layers are dropped); 0 when the settings' compression is off.
    pub compression_error: f64,
    /// Bytes of values the lattice entries saved against per-pixel entries (before
    /// dropping).
    pub compression_saved_bytes: usize,
    /// The largest number of bytes the bake's own accounting held at once in its layer
    /// buffers: the stack so far plus the band in flight, and for a progressive bake's pass
    /// the per-tile sums it keeps for the next passes.
    pub peak_accounted_bytes: usize,
    /// Layers kept and left out, per region, and what leaving them out costs.
    pub layers: drop::DropReport,
    /// The memory forecast made before tracing (compare with the measured peak).
    pub estimate: Option<estimate::BakeEstimate>,
    /// Bounces baked (the header's `bounces`) and, when the settings asked for what the
    /// scene needs, what the pre-pass measured ([`bounces`]).
    pub bounces: u32,
    pub bounce_estimate: Option<bounce_budget::BounceEstimate>,
    /// Values that were not finite, per stage, and what was done with each (all 0 in a
    /// clean bake; otherwise `warnings` says so too).
    pub non_finite: NonFiniteReport,
    /// What adaptive sampling did; absent when it was off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub adaptive: Option<AdaptiveReport>,
}

/// What per-tile adaptive sampling did ([`super::schedule::adaptive`]).
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveReport {
    pub threshold: f32,
    /// Samples of a tile's first check.
    pub first_check_spp: u32,
    /// The most samples a tile takes (the bake's `spp`).
    pub max_spp: u32,
    pub tiles: usize,
    /// Tiles that stopped before `max_spp`.
    pub tiles_stopped: usize,
    /// Eye samples per pixel over the frame, on average (pixel-weighted).
    pub mean_spp: f64,
    /// The eye samples the bake took, as a share of `max_spp` everywhere.
    pub sample_share: f64,
    /// Eye samples per pixel of every tile, raster order (16 × 16 tiles).
    #[serde(skip)]
    pub tile_spp: Vec<u32>,
}

impl AdaptiveReport {
    /// The report of a bake of `resolution` whose tiles took `tile_spp` samples.
    pub(crate) fn new(
        settings: &super::BakeSettings,
        resolution: crate::scene::Resolution,
        tile_spp: Vec<u32>,
    ) -> AdaptiveReport {
        let tiles = super::schedule::tiles::tiles(resolution);
        let spp = settings.spp;
        let pixels: usize = tiles.iter().map(|t| t.pixels()).sum();
        let samples: f64 = tiles
            .iter()
            .zip(&tile_spp)
            .map(|(t, n)| t.pixels() as f64 * *n as f64)
            .sum();
        let mean_spp = samples / pixels.max(1) as f64;
        AdaptiveReport {
            threshold: settings.adaptive.threshold,
            first_check_spp: settings.adaptive.first_check(spp),
            max_spp: spp,
            tiles: tiles.len(),
            tiles_stopped: tile_spp.iter().filter(|n| **n < spp).count(),
            mean_spp,
            sample_share: mean_spp / spp.max(1) as f64,
            tile_spp,
        }
    }
}

/// One pass of a progressive bake.
#[derive(Clone, Debug, Serialize)]
pub struct PassReport {
    pub pass: usize,
    /// Eye samples per pixel so far.
    pub spp: u32,
    /// Seconds since the bake started, when this pass's stack was ready.
    pub seconds: f64,
    /// Estimated relative L2 noise of the image at the bake-time materials after this pass
    /// (from the change since the previous pass: for cumulative sample counts n₋ < n, the
    /// noise is ‖I − I₋‖·√(r/(1 − r)) with r = n₋/n); `None` for the first pass.
    pub estimated_rel_error: Option<f64>,
}

/// What the preparation hands to the report of every pass: when the bake started, how
/// long its set-up took, the scene's validation and the memory forecast.
pub(crate) struct SetupFacts {
    pub start: Instant,
    pub setup_seconds: f64,
    pub validation: ValidationReport,
    pub forecast: estimate::BakeEstimate,
}

impl SetupFacts {
    /// Fills in what `report` says of the whole bake: times, rays, triangles, the
    /// warnings and the forecast.
    pub(crate) fn finish_report(&self, report: &mut BakeReport, rays: u64) {
        report.seconds = self.start.elapsed().as_secs_f64();
        report.setup_seconds = self.setup_seconds;
        report.trace_seconds = report.seconds - self.setup_seconds;
        report.rays = rays;
        report.rays_per_second = rays as f64 / report.trace_seconds.max(1e-9);
        report.triangles = self.validation.triangles;
        report.degenerate_triangles = self.validation.degenerate_triangles;
        // The validation's warnings first, then those of the bake itself.
        let own = std::mem::take(&mut report.warnings);
        report.warnings = self
            .validation
            .warnings
            .iter()
            .cloned()
            .chain(own)
            .collect();
        report.estimate = Some(self.forecast.clone());
    }
}
