//! The GPU relighter of one stack: the engine's relight bookkeeping
//! ([`RelightBookkeeping`]: the weights, the checks, the incremental edits and the periodic
//! full re-sum, exactly as on the CPU), with the kernel as its [`LayerSum`].
//!
//! Weight semantics are therefore the engine's: layer `l` adds
//! `layer_weight(key, coefs) · group factor · scale · value` — grey layers to R, G and B,
//! RGB layers channel by channel — into an RGBA f32 image with alpha 1, rows top-down. The
//! image stays on the GPU between edits, so an incremental edit sends only the weight
//! changes of the layers its region appears in.

use std::sync::Arc;
use std::time::Instant;

use relume_engine::relight::{LayerSum, RelightBookkeeping, RelightStats};
use relume_engine::stack::TransferStack;
use relume_engine::Rgb;

use crate::device::adapter_label;
use crate::error::GpuError;
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

/// The kernel as the bookkeeping's sum: the layers on the GPU and the host copy of the image.
struct KernelSum {
    kernel: Kernel,
    image: Vec<f32>,
    timings: GpuTimings,
}

impl KernelSum {
    /// Adds the listed layers (those of non-zero weight) on the GPU, after clearing the
    /// image when `reset`, and reads the image back.
    fn submit(
        &mut self,
        layers: impl Iterator<Item = usize>,
        effective: &[Rgb],
        reset: bool,
    ) -> Result<RelightStats, GpuError> {
        let adds: Vec<(u32, Rgb)> = layers
            .filter(|&l| effective[l] != Rgb::ZERO)
            .map(|l| (l as u32, effective[l]))
            .collect();
        let t = Instant::now();
        let kernel_ms = self.kernel.run(&adds, reset, &mut self.image)?;
        self.timings = GpuTimings {
            edit_to_image_ms: t.elapsed().as_secs_f64() * 1e3,
            kernel_ms,
        };
        Ok(RelightStats {
            layers_summed: adds.len(),
            bytes_read: adds
                .iter()
                .map(|&(l, _)| self.kernel.read_bytes[l as usize])
                .sum(),
            incremental: false,
        })
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
    stack: Arc<TransferStack>,
    book: RelightBookkeeping,
    sum: KernelSum,
}

impl GpuRelighter {
    /// Checks the stack as the CPU relighter does, opens a device on `adapter` and uploads
    /// the layers.
    pub fn new(
        stack: Arc<TransferStack>,
        adapter: &wgpu::Adapter,
        options: GpuOptions,
    ) -> Result<GpuRelighter, GpuError> {
        let book = RelightBookkeeping::new(&stack)?;
        let kernel = Kernel::new(adapter, &stack, options)?;
        let (width, height) = book.shape().size();
        let mut image = vec![0.0f32; width * height * 4];
        image.chunks_exact_mut(4).for_each(|p| p[3] = 1.0);
        Ok(GpuRelighter {
            stack,
            book,
            sum: KernelSum {
                kernel,
                image,
                timings: GpuTimings::default(),
            },
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

    /// Time to create the GPU buffers and copy the layers in, ms.
    pub fn upload_ms(&self) -> f64 {
        self.sum.kernel.upload_ms
    }

    /// Bytes of layers on the GPU, and in how many storage buffers.
    pub fn layer_bytes_and_chunks(&self) -> (u64, usize) {
        let layout = &self.sum.kernel.layout;
        (layout.bytes(), layout.chunk_words.len())
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

    pub fn stack(&self) -> &Arc<TransferStack> {
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
