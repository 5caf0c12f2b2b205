//! The GPU relighter of one stack: the weights of the CPU relighter, summed by the kernel.
//!
//! Weight semantics are the engine's, exactly: layer `l` adds
//! `layer_weight(key, coefs) · light_tint · scale · value` — grey layers to R, G and B,
//! RGB layers channel by channel — into an RGBA f32 image with alpha 1, rows top-down.
//!
//! **Incremental edits** follow [`CpuRelighter::relight_region`]: only the layers whose
//! key holds the edited region are sent, with weight `(w_new − w_old) · scale`, and added
//! to the image kept on the GPU; every [`FULL_RESUM_EVERY`]-th edit re-sums everything, so
//! float drift stays below ≈ 4·10⁻⁶ relative as on the CPU.
//!
//! [`CpuRelighter::relight_region`]: relume_engine::relight::CpuRelighter::relight_region

use std::sync::Arc;
use std::time::Instant;

use relume_engine::relight::{layer_weight, RelightStats, FULL_RESUM_EVERY};
use relume_engine::stack::TransferStack;
use relume_engine::{RelumeError, Rgb};

use crate::device::adapter_label;
use crate::error::GpuError;
use crate::kernel::{GpuOptions, Kernel};
use crate::shape::StackShape;

/// Times of the last GPU relight.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuTimings {
    /// Weights write + dispatch + read-back, host clock.
    pub edit_to_image_ms: f64,
    /// The compute pass alone, from timestamp queries; `None` without
    /// `Features::TIMESTAMP_QUERY` or when [`GpuOptions::timestamps`] is off.
    pub kernel_ms: Option<f64>,
}

/// The relight context of one stack on one GPU: build once per loaded stack.
pub struct GpuRelighter {
    stack: Arc<TransferStack>,
    shape: StackShape,
    kernel: Kernel,
    coefs: Vec<Vec<Rgb>>,
    /// Weight × tint of every layer for `coefs` (without the layer's scale).
    weights: Vec<Rgb>,
    image: Vec<f32>,
    has_image: bool,
    edits_since_full: usize,
    stats: RelightStats,
    timings: GpuTimings,
}

impl GpuRelighter {
    /// Checks the stack as the CPU relighter does, opens a device on `adapter` and uploads
    /// the layers.
    pub fn new(
        stack: Arc<TransferStack>,
        adapter: &wgpu::Adapter,
        options: GpuOptions,
    ) -> Result<GpuRelighter, GpuError> {
        let shape = StackShape::new(&stack)?;
        let kernel = Kernel::new(adapter, &stack, options)?;
        let mut image = vec![0.0f32; shape.width * shape.height * 4];
        image.chunks_exact_mut(4).for_each(|p| p[3] = 1.0);
        Ok(GpuRelighter {
            weights: vec![Rgb::ZERO; stack.layers.len()],
            stack,
            shape,
            kernel,
            coefs: Vec::new(),
            image,
            has_image: false,
            edits_since_full: 0,
            stats: RelightStats::default(),
            timings: GpuTimings::default(),
        })
    }

    /// "name (backend)" of the adapter.
    pub fn adapter(&self) -> String {
        adapter_label(&self.kernel.adapter)
    }

    /// Whether the adapter is a real GPU (not lavapipe / llvmpipe).
    pub fn is_real_gpu(&self) -> bool {
        crate::device::is_real_gpu(self.kernel.adapter.device_type)
    }

    /// Time to create the GPU buffers and copy the layers in, ms.
    pub fn upload_ms(&self) -> f64 {
        self.kernel.upload_ms
    }

    /// Bytes of layers on the GPU, and in how many storage buffers.
    pub fn layer_bytes_and_chunks(&self) -> (u64, usize) {
        (
            self.kernel.layout.bytes(),
            self.kernel.layout.chunk_words.len(),
        )
    }

    /// Whether the compute pass is timed by timestamp queries.
    pub fn timed(&self) -> bool {
        self.kernel.timed()
    }

    pub fn editable_count(&self) -> usize {
        self.shape.editable_names.len()
    }

    /// Bases the layers of editable region `region` use (0 if none or out of range).
    pub fn basis_count(&self, region: usize) -> usize {
        self.shape.basis_counts.get(region).copied().unwrap_or(0)
    }

    pub fn size(&self) -> (usize, usize) {
        (self.shape.width, self.shape.height)
    }

    pub fn stack(&self) -> &Arc<TransferStack> {
        &self.stack
    }

    /// The current image: RGBA f32, rows top-down, alpha 1 (black before the first relight).
    pub fn image(&self) -> &[f32] {
        &self.image
    }

    pub fn last_stats(&self) -> RelightStats {
        self.stats
    }

    pub fn last_timings(&self) -> GpuTimings {
        self.timings
    }

    /// Full relight with `coefs[region][basis]` for every editable region.
    pub fn relight(&mut self, coefs: &[Vec<Rgb>]) -> Result<&[f32], GpuError> {
        self.shape.check_coefs(coefs)?;
        self.coefs = coefs.to_vec();
        self.full_sum()?;
        Ok(&self.image)
    }

    /// Incremental relight: only editable region `region` changed, to `coefs`. Needs a
    /// full [`relight`](Self::relight) first.
    pub fn relight_region(&mut self, region: usize, coefs: &[Rgb]) -> Result<&[f32], GpuError> {
        self.shape.check_region(region, coefs)?;
        if !self.has_image {
            return Err(RelumeError::invalid(
                "incremental relight",
                "there is no image to update yet: call relight with every region's coefficients first",
            )
            .into());
        }
        self.coefs[region] = coefs.to_vec();
        self.edits_since_full += 1;
        if self.edits_since_full >= FULL_RESUM_EVERY {
            self.full_sum()?;
            return Ok(&self.image);
        }
        let mut adds = Vec::new();
        let mut new_weights = Vec::new();
        for &l in &self.shape.region_layers[region] {
            let layer = &self.stack.layers[l as usize];
            let new = layer_weight(&layer.key, &self.coefs)
                * self.shape.group_factors[layer.key.light_group as usize];
            let delta = (new - self.weights[l as usize]) * layer.scale;
            new_weights.push((l, new));
            if delta != Rgb::ZERO {
                adds.push((l, delta));
            }
        }
        if let Err(e) = self.submit(&adds, false) {
            // The image on the GPU is now unknown: only a full relight may follow.
            self.has_image = false;
            return Err(e);
        }
        // The weights are the image's only once the GPU has added the deltas.
        for (l, w) in new_weights {
            self.weights[l as usize] = w;
        }
        self.stats.incremental = true;
        Ok(&self.image)
    }

    /// Light groups' live gains (one per group of the stack), then a full re-sum; see
    /// `CpuRelighter::set_light_group_gains`.
    pub fn set_light_group_gains(&mut self, gains: &[Rgb]) -> Result<&[f32], GpuError> {
        self.shape.group_factors = relume_engine::relight::group_factors(&self.stack, Some(gains))?;
        if !self.has_image {
            return Err(RelumeError::invalid(
                "light group gains",
                "there is no image yet: call relight with every region's coefficients first",
            )
            .into());
        }
        self.full_sum()?;
        Ok(&self.image)
    }

    /// Copies the image on the GPU to the host again and returns the time it took, ms
    /// (the read-back share of an edit; the image does not change).
    pub fn time_read_back(&mut self) -> Result<f64, GpuError> {
        let t = Instant::now();
        self.kernel.read_back(&mut self.image)?;
        Ok(t.elapsed().as_secs_f64() * 1e3)
    }

    fn full_sum(&mut self) -> Result<(), GpuError> {
        let mut adds = Vec::with_capacity(self.stack.layers.len());
        for (l, layer) in self.stack.layers.iter().enumerate() {
            let w = layer_weight(&layer.key, &self.coefs)
                * self.shape.group_factors[layer.key.light_group as usize];
            self.weights[l] = w;
            let effective = w * layer.scale;
            if effective != Rgb::ZERO {
                adds.push((l as u32, effective));
            }
        }
        self.has_image = false;
        self.submit(&adds, true)?;
        self.has_image = true;
        self.edits_since_full = 0;
        self.stats.incremental = false;
        Ok(())
    }

    fn submit(&mut self, adds: &[(u32, Rgb)], reset: bool) -> Result<(), GpuError> {
        let t = Instant::now();
        let kernel_ms = self.kernel.run(adds, reset, &mut self.image)?;
        self.timings = GpuTimings {
            edit_to_image_ms: t.elapsed().as_secs_f64() * 1e3,
            kernel_ms,
        };
        self.stats.layers_summed = adds.len();
        self.stats.bytes_read = adds
            .iter()
            .map(|&(l, _)| self.kernel.read_bytes[l as usize])
            .sum();
        Ok(())
    }
}
