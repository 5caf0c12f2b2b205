//! The GPU side of the relight: device, pipeline, the tiled stack uploaded once, and one
//! submission per edit (write the weights, dispatch, read the image back).
//!
//! Built once per stack, like wgpu's `repeated_compute` example: per edit the host writes
//! only the per-layer weights (16 bytes a layer) and a 32-byte parameter block per bind
//! group, records one compute pass (one dispatch per group of
//! [`CHUNKS_PER_GROUP`](crate::layout::CHUNKS_PER_GROUP) value chunks; one for any stack
//! up to 4 × the binding limit), copies the RGBA f32 image (16 bytes a pixel) into a
//! mappable buffer and maps it. The image stays on the GPU
//! between edits, so an incremental edit adds its weight changes to it.
//!
//! Failures are values: the upload runs inside out-of-memory and validation error scopes,
//! [`Health`] records device loss and uncaptured errors, and every submission checks it.

use std::sync::{mpsc, Arc};
use std::time::Instant;

use relume_engine::stack::tiled::TiledStack;

use crate::device::adapter_label;
use crate::error::GpuError;
use crate::gpu_memory::GpuMemory;
use crate::health::Health;
use crate::lattice::check_and_count;
use crate::layout::Layout;
use crate::pipeline::{self, Bindings, Dispatch, Params};
use crate::tiles::{entries_at, table_words};
use crate::upload::{upload_tables, upload_values};

/// Bytes of one layer's weight (`vec4<f32>`).
pub(crate) const WEIGHT_BYTES: u64 = 16;
/// Two u64 timestamps: start and end of the compute pass.
const TIMESTAMP_BYTES: u64 = 16;

/// Options of the GPU context.
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuOptions {
    /// Upper bound on the bytes of one value chunk, below the adapter's storage binding
    /// limit (tests use a few KiB to exercise several chunks and bind groups).
    pub max_chunk_bytes: Option<u64>,
    /// Time the compute pass with timestamp queries when the adapter has
    /// `Features::TIMESTAMP_QUERY` (benchmarks; costs 16 bytes more of read-back).
    pub timestamps: bool,
}

struct Timestamps {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    /// Nanoseconds per timestamp tick.
    period_ns: f64,
}

/// The uploaded stack and the objects of the pipeline.
pub(crate) struct Kernel {
    pub adapter: wgpu::AdapterInfo,
    pub layout: Layout,
    pub memory: GpuMemory,
    /// Wall time of creating the buffers and copying the stack into them.
    pub upload_ms: f64,
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    dispatches: Vec<Dispatch>,
    weights: wgpu::Buffer,
    image: wgpu::Buffer,
    readback: wgpu::Buffer,
    timestamps: Option<Timestamps>,
    health: Arc<Health>,
    pixels: u64,
    max_workgroups: u32,
}

impl Kernel {
    /// Opens a device on `adapter` with the adapter's own limits, and uploads the stack.
    pub fn new(
        adapter: &wgpu::Adapter,
        stack: &TiledStack,
        options: GpuOptions,
    ) -> Result<Kernel, GpuError> {
        let info = adapter.get_info();
        let label = adapter_label(&info);
        let limits = adapter.limits();
        let timed =
            options.timestamps && adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("relume relight"),
            required_features: if timed {
                wgpu::Features::TIMESTAMP_QUERY
            } else {
                wgpu::Features::empty()
            },
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::RequestDevice {
            adapter: label.clone(),
            message: e.to_string(),
        })?;
        let health = Health::watch(&device);

        let binding_limit = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        let too_large = |message: String| GpuError::TooLarge {
            adapter: label.clone(),
            message,
        };
        let max_chunk = options
            .max_chunk_bytes
            .map_or(binding_limit, |m| m.min(binding_limit));
        let layout = Layout::new(stack, max_chunk).map_err(too_large)?;
        let entries = stack.entry_count();
        let lattice_words = check_and_count(stack).map_err(too_large)?;
        let table_bytes = table_words(stack.tiles.len(), entries, lattice_words) * 4;
        // Word indices into the tables are u32 in the kernel.
        if table_bytes > binding_limit.min(u32::MAX as u64 * 4) {
            return Err(too_large(format!(
                "the tile and entry tables ({} entries) are {table_bytes} bytes, over the \
                 {binding_limit}-byte storage binding limit",
                entries
            )));
        }
        let (width, height) = (stack.header.width, stack.header.height);
        let pixels = width as u64 * height as u64;
        let image_bytes = pixels * 16;
        if image_bytes > binding_limit {
            return Err(too_large(format!(
                "the {width}×{height} RGBA f32 image is {image_bytes} bytes, over the \
                 {binding_limit}-byte storage binding limit"
            )));
        }
        let weight_bytes = (stack.layers.len() as u64 * WEIGHT_BYTES).max(WEIGHT_BYTES);
        let readback_bytes = image_bytes + if timed { TIMESTAMP_BYTES } else { 0 };

        let start = Instant::now();
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let invalid = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let buffer = |label: &str, size: u64, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let chunks: Vec<wgpu::Buffer> = layout
            .chunks
            .iter()
            .map(|c| {
                buffer(
                    "relume values",
                    layout.format.buffer_bytes(c.samples),
                    storage,
                )
            })
            .collect();
        let tables = buffer("relume tables", table_bytes, storage);
        let placeholder = buffer("relume unused chunk slot", 4, wgpu::BufferUsages::STORAGE);
        let weights = buffer("relume weights", weight_bytes, storage);
        let image = buffer(
            "relume image",
            image_bytes,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        );
        let readback = buffer(
            "relume read-back",
            readback_bytes,
            wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        );
        let uploaded = upload_values(&device, &queue, stack, &layout, &chunks)
            .and_then(|_| upload_tables(&device, &queue, stack, &layout, &tables));
        queue.submit(Vec::<wgpu::CommandBuffer>::new());
        let scope_errors = [
            pollster::block_on(invalid.pop()),
            pollster::block_on(oom.pop()),
        ];
        if let Some(e) = scope_errors.into_iter().flatten().next() {
            return Err(match e {
                wgpu::Error::OutOfMemory { .. } => GpuError::OutOfMemory {
                    adapter: label,
                    bytes: layout.value_bytes() + table_bytes,
                    message: e.to_string(),
                },
                other => GpuError::Backend {
                    during: "the stack upload".into(),
                    message: other.to_string(),
                },
            });
        }
        uploaded?;
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Backend {
                during: "the stack upload".into(),
                message: e.to_string(),
            })?;
        health.check("the stack upload")?;
        let upload_ms = start.elapsed().as_secs_f64() * 1e3;

        let timestamps = timed.then(|| Timestamps {
            set: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("relume relight pass time"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("relume timestamps"),
                size: TIMESTAMP_BYTES,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            period_ns: queue.get_timestamp_period() as f64,
        });

        let invalid = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let base = Params {
            width,
            height,
            tiles_x: stack.tiles_x(),
            first_tile: 0,
            tile_count: 0,
            reset: 1,
            format: layout.format as u32,
            entries_at: entries_at(stack.tiles.len()) as u32,
        };
        let bindings = Bindings {
            image: &image,
            weights: &weights,
            tables: &tables,
            chunks: &chunks,
            placeholder: &placeholder,
        };
        let (pipeline, dispatches) = pipeline::build(&device, &layout, &bindings, base);
        if let Some(e) = pollster::block_on(invalid.pop()) {
            return Err(GpuError::Backend {
                during: "building the relight pipeline".into(),
                message: e.to_string(),
            });
        }
        let memory = GpuMemory {
            values: chunks.iter().map(|c| c.size()).sum(),
            tables: tables.size(),
            image: image.size(),
            weights: weights.size(),
            readback: readback.size(),
            other: placeholder.size()
                + dispatches
                    .iter()
                    .map(|d| d.params_buffer.size())
                    .sum::<u64>()
                + timestamps.as_ref().map_or(0, |t| t.resolve.size()),
        };
        Ok(Kernel {
            adapter: info,
            layout,
            memory,
            upload_ms,
            device,
            queue,
            pipeline,
            dispatches,
            weights,
            image,
            readback,
            timestamps,
            health,
            pixels,
            max_workgroups: limits.max_compute_workgroups_per_dimension.max(1),
        })
    }

    /// Whether the compute pass is timed.
    pub fn timed(&self) -> bool {
        self.timestamps.is_some()
    }

    /// Sums the stack with `weights` (one RGB weight per layer, packed as 16-byte
    /// `vec4<f32>`s) into the image on the GPU — written when `reset`, added to it
    /// otherwise — and reads the image back into `out` (RGBA f32). Returns the compute
    /// pass time in ms when timed.
    pub fn run(
        &mut self,
        weights: &[[f32; 4]],
        reset: bool,
        out: &mut [f32],
    ) -> Result<Option<f64>, GpuError> {
        self.health.check("the previous relight")?;
        if !weights.is_empty() {
            self.queue
                .write_buffer(&self.weights, 0, bytemuck::cast_slice(weights));
        }
        for d in &mut self.dispatches {
            d.write_params(&self.queue, reset);
        }
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("relume relight"),
                timestamp_writes: self.timestamps.as_ref().map(|t| {
                    wgpu::ComputePassTimestampWrites {
                        query_set: &t.set,
                        beginning_of_pass_write_index: Some(0),
                        end_of_pass_write_index: Some(1),
                    }
                }),
            });
            pass.set_pipeline(&self.pipeline);
            for d in &self.dispatches {
                let [x, y] = fold(d.params.tile_count, self.max_workgroups);
                pass.set_bind_group(0, &d.bind_group, &[]);
                pass.dispatch_workgroups(x, y, 1);
            }
        }
        let image_bytes = self.pixels * 16;
        encoder.copy_buffer_to_buffer(&self.image, 0, &self.readback, 0, image_bytes);
        let timed = self.timestamps.as_ref().map(|t| {
            encoder.resolve_query_set(&t.set, 0..2, &t.resolve, 0);
            encoder.copy_buffer_to_buffer(
                &t.resolve,
                0,
                &self.readback,
                image_bytes,
                TIMESTAMP_BYTES,
            );
            t.period_ns
        });
        self.queue.submit([encoder.finish()]);
        let ticks = self.map_read(out, timed.is_some())?;
        Ok(timed
            .zip(ticks)
            .map(|(period, [t0, t1])| t1.saturating_sub(t0) as f64 * period / 1e6))
    }

    /// Copies the current image on the GPU into `out` (what [`run`](Self::run) does after
    /// its dispatch, alone: the bench's read-back figure).
    pub fn read_back(&mut self, out: &mut [f32]) -> Result<(), GpuError> {
        self.health.check("the previous relight")?;
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        encoder.copy_buffer_to_buffer(&self.image, 0, &self.readback, 0, self.pixels * 16);
        self.queue.submit([encoder.finish()]);
        self.map_read(out, false).map(|_| ())
    }

    /// Maps the read-back buffer, copies the image into `out`, and returns the two
    /// timestamps after it when `with_ticks`.
    fn map_read(&self, out: &mut [f32], with_ticks: bool) -> Result<Option<[u64; 2]>, GpuError> {
        let image_bytes = self.pixels as usize * 16;
        let len = image_bytes as u64 + if with_ticks { TIMESTAMP_BYTES } else { 0 };
        let (tx, rx) = mpsc::channel();
        self.readback
            .map_async(wgpu::MapMode::Read, 0..len, move |r| {
                let _ = tx.send(r);
            });
        let failed = |message: String| GpuError::Backend {
            during: "the image read-back".into(),
            message,
        };
        if let Err(e) = self.device.poll(wgpu::PollType::wait_indefinitely()) {
            self.health.check("the relight")?;
            return Err(failed(e.to_string()));
        }
        match rx.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => {
                self.health.check("the relight")?;
                return Err(failed(e.to_string()));
            }
            Err(_) => return Err(failed("the map callback never ran".into())),
        }
        let ticks = {
            let view = self
                .readback
                .get_mapped_range(0..len)
                .map_err(|e| failed(e.to_string()))?;
            // f32 → bytes always casts (no alignment to meet on that side).
            bytemuck::cast_slice_mut::<f32, u8>(out).copy_from_slice(&view[..image_bytes]);
            with_ticks.then(|| {
                let tick = |i: usize| {
                    let at = image_bytes + 8 * i;
                    u64::from_le_bytes(view[at..at + 8].try_into().unwrap_or([0; 8]))
                };
                [tick(0), tick(1)]
            })
        };
        self.readback.unmap();
        self.health.check("the relight")?;
        Ok(ticks)
    }
}

/// Workgroups `[x, y]` for `tiles` tiles when one dimension holds at most `max`: rows of
/// `max` tiles (the kernel skips the surplus of the last row).
fn fold(tiles: u32, max: u32) -> [u32; 2] {
    let tiles = tiles.max(1);
    if tiles <= max {
        [tiles, 1]
    } else {
        [max, tiles.div_ceil(max)]
    }
}

#[cfg(test)]
mod tests {
    use super::fold;

    #[test]
    fn dispatches_fold_into_rows_within_the_limit() {
        assert_eq!(fold(10, 65535), [10, 1]);
        assert_eq!(fold(0, 65535), [1, 1]);
        let [x, y] = fold(129_600, 65535);
        assert_eq!([x, y], [65535, 2]);
        assert!(x as u64 * y as u64 >= 129_600);
    }
}
