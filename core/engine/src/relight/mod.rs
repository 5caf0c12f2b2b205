//! The CPU relight: the weighted sum of the layers of a transfer stack for the current
//! materials, and the reference the GPU relight must match.
//!
//! For coefficients `c[region][basis]` (RGB, from the BRDF basis; this module does not
//! compute them), every layer gets the weight [`layer_weight`] — the product of the
//! coefficients along its path signature, 1 for a fixed vertex and for the empty path
//! (world seen directly) — and the image is `Σ weight · layer`, RGBA f32 with alpha 1.
//!
//! **Cost.** The sum is memory-bound: the paper's 55 grey + 29 RGB layers at 512×512 in f16
//! are 74 MB, ≥ 4.6 ms at the ≈ 16 GB/s two threads read here ([`bandwidth`]). So the work
//! is arranged to read each needed sample once and nothing else:
//! - **Row bands in parallel.** The image is cut in bands of [`BAND_ROWS`] rows, one rayon
//!   task each; inside a band every layer touching it is added row by row into the band's
//!   RGBA output (16 rows × 512 px × 16 B = 128 KiB, which stays in L2 while 16 KiB–48 KiB
//!   of each layer streams through).
//! - **Zero spans skipped.** When the relighter is built, each layer row gets the span
//!   `[x0, x1)` of its non-zero pixels; rows that are all zero are skipped, and so are the
//!   zero ends of the others. A layer whose path starts at a region that covers a quarter
//!   of the frame costs about a quarter of its bytes.
//! - **Zero weights skipped.** A layer whose weight is 0 (say every specular basis of a
//!   region with `Ks = 0`) is not read at all.
//! - **Fast inner loops** (`kernels.rs`): AVX2 + FMA + F16C where the CPU has them
//!   (detected at run time), converting f16 in registers.
//!
//!
//! **Measured** (2-core AMD EPYC VM, release build, machine idle, `tests/relight_perf.rs`):
//! 84 f16 layers at 512² (56 grey + 28 RGB, 73.4 MB) take 5.0–5.6 ms for a full relight
//! (≈ 14 GB/s of layers), 183 layers (160 MB) 12.3–14.2 ms; an incremental edit of a region
//! on 69 of the 84 layers 4.0–4.5 ms, proportionally less for a region on fewer layers.
//! [`bandwidth::measure_read_bandwidth`] gives 25–32 GB/s on the idle machine (the 16 GB/s
//! of the project notes under load), so the relight is at 1.1–1.2× the 16 GB/s bound and
//! 2.0–2.5× the best measured one. Summing a stack that fits in L3 runs at ≈ 9 GB/s per
//! core, so the remaining gap is the kernels (one RGBA accumulator load and store per
//! layer and pixel pair), not DRAM. In the test profile (debug assertions on) the
//! intrinsics carry UB checks and the same sum is ≈ 3× slower: time release builds only.
//!
//! **Incremental relight.** When one region's material changes, only layers whose key
//! contains that region change weight: [`CpuRelighter::relight_region`] adds
//! `(w_new − w_old) · layer` for those layers to the current image. Each such update
//! rounds once more per pixel (relative ≈ 2⁻²⁴ of the largest term summed), so error grows
//! with the number of edits; every [`FULL_RESUM_EVERY`]-th edit is a full re-sum instead,
//! which keeps the drift below ≈ 64 · 6·10⁻⁸ ≈ 4·10⁻⁶ of the pixel's terms — a hundred times
//! under the f16 quantisation of the layers themselves (2⁻¹¹ ≈ 4.9·10⁻⁴).

pub mod bandwidth;
pub(crate) mod kernels;
mod packed;
pub mod tiled_sum;

use std::sync::Arc;

use rayon::prelude::*;

use crate::bake::signature::LayerKey;
use crate::stack::{LayerSamples, TransferStack};
use crate::{RelumeError, Result, Rgb};
use kernels::Kernels;
use packed::PackedRows;

/// Rows per parallel task. 512 rows give 32 tasks: enough for rayon to balance two to
/// sixteen threads when the layers cover the frame unevenly, while each task still reads
/// 16 rows (16–48 KiB) of a layer in one contiguous stretch.
pub const BAND_ROWS: usize = 16;

/// Every this many incremental edits, [`CpuRelighter::relight_region`] re-sums everything
/// to bound float drift (see the module notes: ≈ 4·10⁻⁶ relative at most).
pub const FULL_RESUM_EVERY: usize = 64;

/// The weight of a layer: the product of the coefficients along its path, per RGB channel.
/// A [`crate::bake::signature::PathVertex::Fixed`] vertex contributes 1 (its BRDF was baked in), and the empty path
/// (the world seen directly, layer `World`) has weight 1. A [`crate::bake::signature::PathVertex::Subsurface`] vertex
/// weighs like an editable one: its `basis` is the region's coefficient slot. The light group is not part of
/// the weight (light scaling is applied elsewhere).
///
/// # Panics
/// If a vertex names a region or basis outside `coefs`; [`CpuRelighter`] checks shapes
/// before calling it.
pub fn layer_weight(key: &LayerKey, coefs: &[Vec<Rgb>]) -> Rgb {
    key.path.iter().fold(Rgb::ONE, |w, v| match v.slot() {
        None => w,
        Some((region, basis)) => w * coefs[region as usize][basis as usize],
    })
}

/// The factor of every layer-key light group (index 0: all lights; g + 1: group g): the
/// colour factored out of its layers at bake time, times the group's live `gains` (one per
/// group of the header, unit when `None`). Checks that every layer names a group the header
/// has. Shared by the CPU and GPU relights: a layer's weight is
/// `layer_weight(key, coefs) · factors[key.light_group]`.
pub fn group_factors(stack: &TransferStack, gains: Option<&[Rgb]>) -> Result<Vec<Rgb>> {
    let header = &stack.header;
    if let Some(g) = gains {
        if g.len() != header.light_groups.len() {
            return Err(RelumeError::invalid(
                "light group gains",
                format!(
                    "{} gains for {} light groups",
                    g.len(),
                    header.light_groups.len()
                ),
            ));
        }
    }
    let mut factors = vec![Rgb::from(header.light_tint)];
    for (k, group) in header.light_groups.iter().enumerate() {
        factors.push(Rgb::from(group.tint) * gains.map_or(Rgb::ONE, |g| g[k]));
    }
    if let Some(bad) = factors
        .iter()
        .find(|t| !t.is_finite() || t.min_element() < 0.0)
    {
        return Err(RelumeError::StackFormat {
            path: Default::default(),
            message: format!("light group factor {bad} is not a finite non-negative colour"),
        });
    }
    if let Some(l) = stack
        .layers
        .iter()
        .find(|l| l.key.light_group as usize >= factors.len())
    {
        return Err(RelumeError::StackFormat {
            path: Default::default(),
            message: format!(
                "layer {} names light group {} of {}",
                l.key.layer_name(),
                l.key.light_group,
                header.light_groups.len()
            ),
        });
    }
    Ok(factors)
}

/// What the last relight did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RelightStats {
    /// Layers actually added (zero-weight and zero-delta layers are not).
    pub layers_summed: usize,
    /// Bytes of layer samples read (non-zero spans only).
    pub bytes_read: usize,
    /// Whether it was an incremental (delta) update.
    pub incremental: bool,
}

/// Per-layer preparation.
struct LayerPlan {
    /// Per row, the span `[x0, x1)` of pixels with a non-zero sample; `x0 == x1` if none.
    spans: Vec<[u32; 2]>,
}

/// The CPU relighter of one stack. Build it once per loaded stack (the build scans every
/// sample, ≈ the cost of one relight), then call [`relight`](Self::relight) and
/// [`relight_region`](Self::relight_region) per edit.
pub struct CpuRelighter {
    stack: Arc<TransferStack>,
    width: usize,
    height: usize,
    editable_names: Vec<String>,
    basis_counts: Vec<usize>,
    /// The non-zero samples in row order (what the sums read).
    packed: PackedRows,
    /// Per editable region, whether each layer's key contains it.
    region_member: Vec<Vec<bool>>,
    /// Per editable region, the layers whose key contains it.
    region_layers: Vec<Vec<u32>>,
    /// Coefficients of the current image.
    coefs: Vec<Vec<Rgb>>,
    /// Weight of every layer for `coefs` (without the layer's scale).
    weights: Vec<Rgb>,
    /// Scratch: per-layer weight × scale handed to the sum.
    effective: Vec<Rgb>,
    image: Vec<f32>,
    has_image: bool,
    edits_since_full: usize,
    stats: RelightStats,
    kernels: Kernels,
    /// Per layer-key light group (0: all lights; g + 1: group g), the colour factored out
    /// of its layers at bake time times the group's live gain.
    group_factor: Vec<Rgb>,
}

impl CpuRelighter {
    /// Prepares per-layer weights, per-editable-region layer lists, and per-layer non-zero
    /// row spans.
    ///
    /// Errors: a layer whose sample count is not width·height·channels, whose channel
    /// count is not 1 or 3, whose key names an editable region the header does not have,
    /// or which holds a non-finite sample or scale.
    pub fn new(stack: Arc<TransferStack>) -> Result<Self> {
        Self::with_kernels(stack, Kernels::detect())
    }

    pub(crate) fn with_kernels(stack: Arc<TransferStack>, kernels: Kernels) -> Result<Self> {
        let width = stack.header.width as usize;
        let height = stack.header.height as usize;
        let editable_names: Vec<String> = stack
            .header
            .regions
            .iter()
            .filter(|r| r.editable)
            .map(|r| r.name.clone())
            .collect();
        let n_edit = editable_names.len();
        let mut basis_counts = vec![0usize; n_edit];
        let mut region_layers = vec![Vec::new(); n_edit];
        for (i, layer) in stack.layers.iter().enumerate() {
            let name = layer.key.layer_name();
            if layer.channels != 1 && layer.channels != 3 {
                return Err(RelumeError::invalid(
                    format!("layer {name}"),
                    format!(
                        "{} channels; a layer has 1 (grey) or 3 (RGB)",
                        layer.channels
                    ),
                ));
            }
            let expect = width * height * layer.channels as usize;
            if layer.samples.len() != expect {
                return Err(RelumeError::invalid(
                    format!("layer {name}"),
                    format!(
                        "{} samples, expected {width}×{height}×{} = {expect}",
                        layer.samples.len(),
                        layer.channels
                    ),
                ));
            }
            if !layer.scale.is_finite() {
                return Err(RelumeError::NonFinite {
                    what: format!("scale of layer {name}"),
                });
            }
            for v in &layer.key.path {
                if let Some((region, basis)) = v.slot() {
                    let r = region as usize;
                    if r >= n_edit {
                        return Err(RelumeError::IndexOutOfRange {
                            what: format!("editable region of layer {name}"),
                            index: r as u64,
                            len: n_edit,
                        });
                    }
                    basis_counts[r] = basis_counts[r].max(basis as usize + 1);
                    if region_layers[r].last() != Some(&(i as u32)) {
                        region_layers[r].push(i as u32);
                    }
                }
            }
        }

        let plans = stack
            .layers
            .par_iter()
            .map(|l| plan_layer(l, width, height))
            .collect::<Result<Vec<_>>>()?;

        let packed = PackedRows::build(&stack, &plans, width, height);
        let region_member: Vec<Vec<bool>> = region_layers
            .iter()
            .map(|ls| {
                let mut m = vec![false; plans.len()];
                ls.iter().for_each(|&l| m[l as usize] = true);
                m
            })
            .collect();

        let n_layers = stack.layers.len();
        let mut image = vec![0.0f32; width * height * 4];
        image.chunks_exact_mut(4).for_each(|p| p[3] = 1.0);
        let mut group_factor = vec![Rgb::from(stack.header.light_tint)];
        group_factor.extend(stack.header.light_groups.iter().map(|g| Rgb::from(g.tint)));
        if let Some(bad) = group_factor
            .iter()
            .find(|t| !t.is_finite() || t.min_element() < 0.0)
        {
            return Err(RelumeError::StackFormat {
                path: Default::default(),
                message: format!("light tint {bad} is not a finite non-negative colour"),
            });
        }
        if let Some(l) = stack
            .layers
            .iter()
            .find(|l| l.key.light_group as usize >= group_factor.len())
        {
            return Err(RelumeError::StackFormat {
                path: Default::default(),
                message: format!(
                    "layer {} names light group {} of {}",
                    l.key.layer_name(),
                    l.key.light_group,
                    stack.header.light_groups.len()
                ),
            });
        }
        Ok(CpuRelighter {
            group_factor,
            stack,
            width,
            height,
            editable_names,
            basis_counts,
            packed,
            region_member,
            region_layers,
            coefs: Vec::new(),
            weights: vec![Rgb::ZERO; n_layers],
            effective: vec![Rgb::ZERO; n_layers],
            image,
            has_image: false,
            edits_since_full: 0,
            stats: RelightStats::default(),
            kernels,
        })
    }

    /// Number of editable regions (those of `stack.header.regions` with `editable`).
    pub fn editable_count(&self) -> usize {
        self.editable_names.len()
    }

    /// Number of bases the layers of editable region `region` use: the largest basis index
    /// in any key plus one (0 for a region no layer mentions or an index out of range).
    /// A relight accepts more coefficients than this, since a basis whose layers were all
    /// dropped as negligible leaves no key behind.
    pub fn basis_count(&self, region: usize) -> usize {
        self.basis_counts.get(region).copied().unwrap_or(0)
    }

    /// Image width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The stack being relit.
    pub fn stack(&self) -> &Arc<TransferStack> {
        &self.stack
    }

    /// The current image: RGBA f32, rows top-down, alpha 1 (black before the first relight).
    pub fn image(&self) -> &[f32] {
        &self.image
    }

    /// What the last relight did.
    pub fn last_stats(&self) -> RelightStats {
        self.stats
    }

    /// Full relight: `coefs[region][basis]` RGB for every editable region. Returns the RGBA
    /// f32 image (alpha 1).
    ///
    /// Errors: not one coefficient list per editable region, fewer coefficients than the
    /// region's [`basis_count`](Self::basis_count), a non-finite coefficient.
    pub fn relight(&mut self, coefs: &[Vec<Rgb>]) -> Result<&[f32]> {
        if coefs.len() != self.editable_count() {
            return Err(RelumeError::invalid(
                "relight coefficients",
                format!(
                    "{} coefficient lists for {} editable regions ({})",
                    coefs.len(),
                    self.editable_count(),
                    self.editable_names.join(", ")
                ),
            ));
        }
        for (r, c) in coefs.iter().enumerate() {
            self.check_region_coefs(r, c)?;
        }
        self.coefs = coefs.to_vec();
        self.full_sum();
        Ok(&self.image)
    }

    /// Light groups' live strength × colour (one RGB gain per group of the stack's
    /// `light_groups`, 1 leaves the group as baked), then a full re-sum: every layer of a
    /// group scales by its gain, since radiance is linear in each light's emission.
    pub fn set_light_group_gains(&mut self, gains: &[Rgb]) -> Result<&[f32]> {
        let groups = &self.stack.header.light_groups;
        if gains.len() != groups.len() {
            return Err(RelumeError::invalid(
                "light group gains",
                format!(
                    "{} gains for {} light groups ({})",
                    gains.len(),
                    groups.len(),
                    groups
                        .iter()
                        .map(|g| g.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        if let Some(g) = gains.iter().find(|g| !g.is_finite()) {
            return Err(RelumeError::NonFinite {
                what: format!("light group gain {g}"),
            });
        }
        self.group_factor = group_factors(&self.stack, Some(gains))?;
        if !self.has_image {
            return Err(RelumeError::invalid(
                "light group gains",
                "there is no image yet: call relight with every region's coefficients first",
            ));
        }
        self.full_sum();
        Ok(&self.image)
    }

    /// Incremental relight: only editable region `region` changed, to `coefs` (its basis
    /// coefficients). Adds `(w_new − w_old) · layer` for the layers whose key contains the
    /// region and whose weight changed; every [`FULL_RESUM_EVERY`]-th call re-sums all
    /// layers instead to bound float drift. Needs a full [`relight`](Self::relight) first.
    pub fn relight_region(&mut self, region: usize, coefs: &[Rgb]) -> Result<&[f32]> {
        if region >= self.editable_count() {
            return Err(RelumeError::IndexOutOfRange {
                what: "editable region to relight".into(),
                index: region as u64,
                len: self.editable_count(),
            });
        }
        self.check_region_coefs(region, coefs)?;
        if !self.has_image {
            return Err(RelumeError::invalid(
                "incremental relight",
                "there is no image to update yet: call relight with every region's coefficients first",
            ));
        }
        self.coefs[region] = coefs.to_vec();
        self.edits_since_full += 1;
        if self.edits_since_full >= FULL_RESUM_EVERY {
            self.full_sum();
            return Ok(&self.image);
        }

        let mut layers_summed = 0;
        let mut bytes_read = 0;
        for &l in &self.region_layers[region] {
            let l = l as usize;
            let key = &self.stack.layers[l].key;
            let new = layer_weight(key, &self.coefs) * self.group_factor[key.light_group as usize];
            let delta = new - self.weights[l];
            self.weights[l] = new;
            self.effective[l] = delta * self.stack.layers[l].scale;
            if self.effective[l] != Rgb::ZERO && self.packed.layer_bytes(l) > 0 {
                layers_summed += 1;
                bytes_read += self.packed.layer_bytes(l);
            }
        }
        sum_bands(
            &mut self.image,
            self.width,
            &self.packed,
            &self.effective,
            Some(&self.region_member[region]),
            false,
            self.kernels,
        );
        self.stats = RelightStats {
            layers_summed,
            bytes_read,
            incremental: true,
        };
        Ok(&self.image)
    }

    fn check_region_coefs(&self, r: usize, c: &[Rgb]) -> Result<()> {
        let name = &self.editable_names[r];
        if c.len() < self.basis_counts[r] {
            return Err(RelumeError::invalid(
                format!("coefficients of editable region {r} ({name})"),
                format!(
                    "{} given, but the stack's layers use {} bases",
                    c.len(),
                    self.basis_counts[r]
                ),
            ));
        }
        if let Some(b) = c.iter().position(|v| !v.is_finite()) {
            return Err(RelumeError::NonFinite {
                what: format!(
                    "coefficient {b} of editable region {r} ({name}): {:?}",
                    c[b]
                ),
            });
        }
        Ok(())
    }

    /// Recomputes every weight from `self.coefs` and re-sums every layer.
    fn full_sum(&mut self) {
        let mut layers_summed = 0;
        let mut bytes_read = 0;
        for (l, layer) in self.stack.layers.iter().enumerate() {
            let w = layer_weight(&layer.key, &self.coefs)
                * self.group_factor[layer.key.light_group as usize];
            self.weights[l] = w;
            self.effective[l] = w * layer.scale;
            if self.effective[l] != Rgb::ZERO && self.packed.layer_bytes(l) > 0 {
                layers_summed += 1;
                bytes_read += self.packed.layer_bytes(l);
            }
        }
        sum_bands(
            &mut self.image,
            self.width,
            &self.packed,
            &self.effective,
            None,
            true,
            self.kernels,
        );
        self.has_image = true;
        self.edits_since_full = 0;
        self.stats = RelightStats {
            layers_summed,
            bytes_read,
            incremental: false,
        };
    }
}

/// Scans a layer: non-zero span of every row, and finiteness of every sample.
fn plan_layer(layer: &crate::stack::Layer, width: usize, height: usize) -> Result<LayerPlan> {
    let ch = layer.channels as usize;
    let row_len = width * ch;
    let mut spans = Vec::with_capacity(height);
    for y in 0..height {
        let row = y * row_len..(y + 1) * row_len;
        // (first, last) non-zero sample index in the row, or the first non-finite one.
        let scan = match &layer.samples {
            LayerSamples::F16(v) => scan_row(&v[row], |h| {
                let b = h.to_bits();
                (b & 0x7fff != 0, b & 0x7c00 != 0x7c00)
            }),
            LayerSamples::F32(v) => scan_row(&v[row], |&x| (x != 0.0, x.is_finite())),
        };
        let (first, last) = match scan {
            Ok(s) => s,
            Err(i) => {
                return Err(RelumeError::NonFinite {
                    what: format!(
                        "layer {}, pixel ({}, {y}) channel {}",
                        layer.key.layer_name(),
                        i / ch,
                        i % ch
                    ),
                })
            }
        };
        let span = match (first, last) {
            (Some(f), Some(l)) => [(f / ch) as u32, (l / ch + 1) as u32],
            _ => [0, 0],
        };
        spans.push(span);
    }
    Ok(LayerPlan { spans })
}

/// `Ok((first non-zero, last non-zero))` sample positions of a row, or `Err(position)` of
/// its first non-finite sample. `test` gives (non-zero, finite).
#[allow(clippy::type_complexity)]
fn scan_row<T>(
    row: &[T],
    test: impl Fn(&T) -> (bool, bool),
) -> Result<(Option<usize>, Option<usize>), usize> {
    let mut first = None;
    let mut last = None;
    for (i, s) in row.iter().enumerate() {
        let (nz, finite) = test(s);
        if !finite {
            return Err(i);
        }
        if nz {
            first.get_or_insert(i);
            last = Some(i);
        }
    }
    Ok((first, last))
}

/// Adds `weights[l] · layer l` for the layers listed per band into `image` (RGBA).
/// With `reset`, each band is first set to (0, 0, 0, 1).
#[allow(clippy::too_many_arguments)]
fn sum_bands(
    image: &mut [f32],
    width: usize,
    packed: &PackedRows,
    weights: &[Rgb],
    include: Option<&[bool]>,
    reset: bool,
    kernels: Kernels,
) {
    let band_len = (BAND_ROWS * width * 4).max(4);
    image
        .par_chunks_mut(band_len)
        .enumerate()
        .for_each(|(b, out)| {
            if reset {
                out.chunks_exact_mut(4)
                    .for_each(|p| p.copy_from_slice(&[0.0, 0.0, 0.0, 1.0]));
            }
            packed.add_rows(out, b * BAND_ROWS, weights, include, kernels);
        });
}

#[cfg(test)]
mod tests;
