//! The GPU relighter of one stack: the engine's relight bookkeeping
//! ([`RelightBookkeeping`]: the weights, the checks, the incremental edits and the periodic
//! full re-sum, exactly as on the CPU), with the kernel as its [`LayerSum`].
//!
//! Weight semantics are therefore the engine's: layer `l` adds
//! `layer_weight(key, coefs) · group factor · entry scale · value` — grey entries to R, G
//! and B, RGB entries channel by channel — into an RGBA f32 image with alpha 1, rows
//! top-down. The stack stays on the GPU in its tiled layout and the image between edits,
//! so an edit sends only the weights: every layer's for a full relight, the weight
//! changes of the edited region's layers (zero elsewhere) for an incremental one.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use relume_engine::relight::{LayerSum, RelightBookkeeping, RelightStats};
use relume_engine::stack::tiled::{validate::validate, TiledStack};
use relume_engine::Rgb;

use crate::device::adapter_label;
use crate::error::GpuError;
use crate::gpu_memory::GpuMemory;
use crate::kernel::{GpuOptions, Kernel};

/// Times of the last GPU relight.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuTimings {
    /// Weights write + dispatch + read-back, host clock.
    pub edit_to_image_ms: f64,
    /// The compute pass alone, from timestamp queries; `None` without
    /// `Features::TIMESTAMP_QUERY` or when [`GpuOptions::timestamps`] is off.
    pub kernel_ms: Option<f64>,
}

/// The kernel as the bookkeeping's sum: the stack on the GPU and the host copy of the image.
struct KernelSum {
    kernel: Kernel,
    image: Vec<f32>,
    /// Scratch: the weights written per relight, one `vec4<f32>` per layer.
    weights: Vec<[f32; 4]>,
    /// Bytes of stored values per layer id (what adding the layer reads), as the CPU
    /// sum counts them.
    layer_bytes: Vec<usize>,
    timings: GpuTimings,
}

impl KernelSum {
    /// Writes `weights` for `layers` (zero for the others), sums on the GPU — the whole
    /// image when `reset`, added to it otherwise — and reads the image back.
    fn submit(
        &mut self,
        layers: impl Iterator<Item = usize> + Clone,
        effective: &[Rgb],
        reset: bool,
    ) -> Result<RelightStats, GpuError> {
        self.weights.fill([0.0; 4]);
        let mut stats = RelightStats::default();
        for l in layers {
            let w = effective[l];
            self.weights[l] = [w.x, w.y, w.z, 0.0];
            // As the CPU counts: a layer of zero weight, or held by no tile, is not added.
            if w != Rgb::ZERO && self.layer_bytes[l] > 0 {
                stats.layers_summed += 1;
                stats.bytes_read += self.layer_bytes[l];
            }
        }
        let t = Instant::now();
        let kernel_ms = self.kernel.run(&self.weights, reset, &mut self.image)?;
        self.timings = GpuTimings {
            edit_to_image_ms: t.elapsed().as_secs_f64() * 1e3,
            kernel_ms,
        };
        Ok(stats)
    }
}

impl LayerSum for KernelSum {
    type Error = GpuError;

    fn full(&mut self, effective: &[Rgb]) -> Result<RelightStats, GpuError> {
        self.submit(0..effective.len(), effective, true)
    }

    fn incremental(&mut self, layers: &[u32], effective: &[Rgb]) -> Result<RelightStats, GpuError> {
        self.submit(layers.iter().map(|&l| l as usize), effective, false)
    }

    fn image(&self) -> &[f32] {
        &self.image
    }
}

/// The relight context of one stack on one GPU: build once per loaded stack.
pub struct GpuRelighter {
    stack: Arc<TiledStack>,
    book: RelightBookkeeping,
    sum: KernelSum,
}

impl GpuRelighter {
    /// Checks the stack as the CPU relighter does, and its tables and values as the stack
    /// reader does ([`validate`]: the upload and the kernel index by them), opens a device
    /// on `adapter` and uploads the stack. The stack is shared, not copied: the host keeps
    /// it, the image and a few numbers per layer.
    pub fn new(
        stack: Arc<TiledStack>,
        adapter: &wgpu::Adapter,
        options: GpuOptions,
    ) -> Result<GpuRelighter, GpuError> {
        let book = RelightBookkeeping::from_tiled(&stack)?;
        validate(Path::new(""), &stack)?;
        let (width, height) = book.shape().size();
        let mut image: Vec<f32> =
            relume_engine::memory::try_zeroed(width * height * 4, "GPU relight image")?;
        image.chunks_exact_mut(4).for_each(|p| p[3] = 1.0);
        let kernel = Kernel::new(adapter, &stack, options)?;
        Ok(GpuRelighter {
            sum: KernelSum {
                kernel,
                image,
                weights: vec![[0.0; 4]; stack.layers.len()],
                layer_bytes: stack.layer_bytes(),
                timings: GpuTimings::default(),
            },
            stack,
            book,
        })
    }

    /// "name (backend)" of the adapter.
    pub fn adapter(&self) -> String {
        adapter_label(&self.sum.kernel.adapter)
    }

    /// Whether the adapter is a real GPU (not lavapipe / llvmpipe).
    pub fn is_real_gpu(&self) -> bool {
        crate::device::is_real_gpu(self.sum.kernel.adapter.device_type)
    }

    /// Time to create the GPU buffers and copy the stack in, ms.
    pub fn upload_ms(&self) -> f64 {
        self.sum.kernel.upload_ms
    }

    /// Bytes of the stack's values on the GPU, and in how many storage buffers.
    pub fn layer_bytes_and_chunks(&self) -> (u64, usize) {
        (
            self.sum.kernel.memory.values,
            self.sum.kernel.layout.chunks.len(),
        )
    }

    /// Bytes of every buffer on the GPU, by purpose: the stack (values and tables), the
    /// image, the weights, the read-back copy.
    pub fn memory(&self) -> GpuMemory {
        self.sum.kernel.memory
    }

    /// Whether the compute pass is timed by timestamp queries.
    pub fn timed(&self) -> bool {
        self.sum.kernel.timed()
    }

    pub fn editable_count(&self) -> usize {
        self.book.shape().editable_count()
    }

    /// Bases the layers of editable region `region` use (0 if none or out of range).
    pub fn basis_count(&self, region: usize) -> usize {
        self.book.shape().basis_count(region)
    }

    pub fn size(&self) -> (usize, usize) {
        self.book.shape().size()
    }

    /// The stack relit (tiled, shared with the caller).
    pub fn stack(&self) -> &Arc<TiledStack> {
        &self.stack
    }

    /// The current image: RGBA f32, rows top-down, alpha 1 (black before the first relight).
    pub fn image(&self) -> &[f32] {
        self.sum.image()
    }

    pub fn last_stats(&self) -> RelightStats {
        self.book.last_stats()
    }

    pub fn last_timings(&self) -> GpuTimings {
        self.sum.timings
    }

    /// Full relight with `coefs[region][basis]` for every editable region.
    pub fn relight(&mut self, coefs: &[Vec<Rgb>]) -> Result<&[f32], GpuError> {
        self.book.relight(&mut self.sum, coefs)?;
        Ok(self.sum.image())
    }

    /// Incremental relight: only editable region `region` changed, to `coefs`. Needs a
    /// full [`relight`](Self::relight) first.
    pub fn relight_region(&mut self, region: usize, coefs: &[Rgb]) -> Result<&[f32], GpuError> {
        self.book.relight_region(&mut self.sum, region, coefs)?;
        Ok(self.sum.image())
    }

    /// Light groups' live gains (one per group of the stack), then a full re-sum; see
    /// `CpuRelighter::set_light_group_gains`.
    pub fn set_light_group_gains(&mut self, gains: &[Rgb]) -> Result<&[f32], GpuError> {
        self.book.set_light_group_gains(&mut self.sum, gains)?;
        Ok(self.sum.image())
    }

    /// Copies the image on the GPU to the host again and returns the time it took, ms
    /// (the read-back share of an edit; the image does not change).
    pub fn time_read_back(&mut self) -> Result<f64, GpuError> {
        let t = Instant::now();
        self.sum.kernel.read_back(&mut self.sum.image)?;
        Ok(t.elapsed().as_secs_f64() * 1e3)
    }
}
