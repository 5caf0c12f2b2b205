//! The compute pipeline of `kernel.wgsl` and its dispatches: one bind group per group of
//! [`CHUNKS_PER_GROUP`] value chunks, each with its parameter block and the tiles it
//! covers (`layout.rs`).

use std::borrow::Cow;

use crate::layout::{Layout, CHUNKS_PER_GROUP};

/// Bytes of the parameter block (`struct Params` in `kernel.wgsl`).
const PARAMS_BYTES: u64 = 32;

/// The kernel's parameter block (`struct Params` in `kernel.wgsl`), word for word.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Params {
    pub width: u32,
    pub height: u32,
    pub tiles_x: u32,
    pub first_tile: u32,
    pub tile_count: u32,
    /// 1: write the sum; 0: add it to the image.
    pub reset: u32,
    /// [`crate::layout::Format`] as a number.
    pub format: u32,
    /// Word of the tables where the entry records start.
    pub entries_at: u32,
}

impl Params {
    fn words(&self) -> [u32; 8] {
        [
            self.width,
            self.height,
            self.tiles_x,
            self.first_tile,
            self.tile_count,
            self.reset,
            self.format,
            self.entries_at,
        ]
    }
}

/// One dispatch: a bind group, its parameter buffer and its parameters.
pub(crate) struct Dispatch {
    pub bind_group: wgpu::BindGroup,
    pub params_buffer: wgpu::Buffer,
    pub params: Params,
}

impl Dispatch {
    /// Writes the parameters, with `reset`, for the next submission.
    pub fn write_params(&mut self, queue: &wgpu::Queue, reset: bool) {
        self.params.reset = reset as u32;
        let words = self.params.words();
        queue.write_buffer(&self.params_buffer, 0, bytemuck::cast_slice(&words));
    }
}

/// The buffers every dispatch binds.
pub(crate) struct Bindings<'a> {
    pub image: &'a wgpu::Buffer,
    pub weights: &'a wgpu::Buffer,
    pub tables: &'a wgpu::Buffer,
    pub chunks: &'a [wgpu::Buffer],
    /// Bound to the chunk slots a group does not use (a binding cannot be left empty).
    pub placeholder: &'a wgpu::Buffer,
}

/// `kernel.wgsl` with the constants it takes from the host side.
fn kernel_source() -> String {
    format!(
        "const BATCH: u32 = {}u;\n{}",
        crate::tiles::ENTRY_BATCH,
        include_str!("kernel.wgsl")
    )
}

/// Compiles the kernel and builds one dispatch per group of `layout`; `base` holds the
/// parameters shared by every dispatch. Validation errors surface through the caller's
/// error scope.
pub(crate) fn build(
    device: &wgpu::Device,
    layout: &Layout,
    buffers: &Bindings,
    base: Params,
) -> (wgpu::ComputePipeline, Vec<Dispatch>) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("relume relight kernel"),
        source: wgpu::ShaderSource::Wgsl(Cow::Owned(kernel_source())),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("relume relight"),
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let bind_layout = pipeline.get_bind_group_layout(0);
    let dispatches = (0..layout.groups())
        .map(|g| {
            let params_buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("relume params"),
                size: PARAMS_BYTES,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut entries = vec![
                bind(0, buffers.image),
                bind(1, &params_buffer),
                bind(2, buffers.weights),
                bind(3, buffers.tables),
            ];
            for slot in 0..CHUNKS_PER_GROUP {
                let chunk = buffers
                    .chunks
                    .get(g * CHUNKS_PER_GROUP + slot)
                    .unwrap_or(buffers.placeholder);
                entries.push(bind(4 + slot as u32, chunk));
            }
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("relume stack"),
                layout: &bind_layout,
                entries: &entries,
            });
            let (first_tile, tile_count) = layout.group_tiles(g);
            Dispatch {
                bind_group,
                params_buffer,
                params: Params {
                    first_tile,
                    tile_count,
                    ..base
                },
            }
        })
        .collect();
    (pipeline, dispatches)
}

fn bind(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}
