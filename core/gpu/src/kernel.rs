//! The GPU side of the relight: device, pipeline, the layers uploaded once, and one
//! submission per edit (write the layer list, dispatch, read the image back).
//!
//! Built once per stack, like wgpu's `repeated_compute` example: per edit the host writes
//! only the list of layers to add with their weights (32 bytes a layer, ≤ 2.7 KiB for the
//! paper's 84) and a 16-byte parameter block per bind group, records one compute pass (one
//! dispatch per group of [`CHUNKS_PER_GROUP`] chunks; one for any stack up to 4 × the
//! binding limit), copies the RGBA f32 image (16 bytes a pixel, 4 MiB at 512²) into a
//! mappable buffer and maps it. The image stays on the GPU between edits, so an
//! incremental edit adds its deltas to it. Each workgroup skips, unread, the layers that
//! are zero on its 256 pixels (`tiles.rs`).
//!
//! Failures are values: the upload runs inside out-of-memory and validation error scopes,
//! a device-lost callback and an uncaptured-error handler (wgpu's default one panics)
//! record what happened, and every submission checks them.

use std::borrow::Cow;
use std::sync::{mpsc, Arc, Mutex};
use std::time::Instant;

use relume_engine::stack::TransferStack;
use relume_engine::Rgb;

use crate::device::adapter_label;
use crate::error::GpuError;
use crate::layout::{pack_layer, Format, Layout, CHUNKS_PER_GROUP};
use crate::tiles::{layer_mask, mask_words, TILE_PIXELS};

/// Invocations per workgroup (`@workgroup_size` in `kernel.wgsl`).
const WORKGROUP: u32 = 256;
/// Bytes of one entry of the layer list (`struct Entry` in `kernel.wgsl`).
const ENTRY_BYTES: usize = 32;
/// Bytes of the parameter block (`struct Params`).
const PARAMS_BYTES: u64 = 16;
/// Two u64 timestamps: start and end of the compute pass.
const TIMESTAMP_BYTES: u64 = 16;

/// Options of the GPU context.
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuOptions {
    /// Upper bound on the bytes of one layer chunk, below the adapter's storage binding
    /// limit (tests use a few KiB to exercise several chunks and bind groups).
    pub max_chunk_bytes: Option<u64>,
    /// Time the compute pass with timestamp queries when the adapter has
    /// `Features::TIMESTAMP_QUERY` (benchmarks; costs 16 bytes more of read-back).
    pub timestamps: bool,
}

/// What the device-lost callback and the uncaptured-error handler saw.
#[derive(Default)]
struct Health {
    lost: Mutex<Option<String>>,
    error: Mutex<Option<String>>,
}

impl Health {
    fn check(&self, during: &str) -> Result<(), GpuError> {
        if let Some(why) = lock(&self.lost).clone() {
            return Err(GpuError::DeviceLost(why));
        }
        if let Some(message) = lock(&self.error).take() {
            return Err(GpuError::Backend {
                during: during.into(),
                message,
            });
        }
        Ok(())
    }
}

/// A poisoned lock only means a callback panicked; its value is still the best we have.
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
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
    /// Wall time of creating the buffers and copying the layers into them.
    pub upload_ms: f64,
    /// Per layer, the bytes a relight reads: those of its non-zero tiles.
    pub read_bytes: Vec<usize>,
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    bind_groups: Vec<wgpu::BindGroup>,
    params: Vec<wgpu::Buffer>,
    entries: wgpu::Buffer,
    image: wgpu::Buffer,
    readback: wgpu::Buffer,
    timestamps: Option<Timestamps>,
    health: Arc<Health>,
    pixels: u32,
    /// Words of tile mask per layer.
    mask_words: u32,
    workgroups: [u32; 2],
}

impl Kernel {
    /// Opens a device on `adapter` with the adapter's own limits, and uploads the layers.
    pub fn new(
        adapter: &wgpu::Adapter,
        stack: &TransferStack,
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
        let health = Arc::new(Health::default());
        {
            let h = health.clone();
            device.set_device_lost_callback(move |reason, message| {
                *lock(&h.lost) = Some(format!("{reason:?}: {message}"));
            });
            let h = health.clone();
            device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
                lock(&h.error).get_or_insert_with(|| e.to_string());
            }));
        }

        let binding_limit = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        let max_chunk = options
            .max_chunk_bytes
            .map_or(binding_limit, |m| m.min(binding_limit));
        let layout =
            Layout::new(&stack.layers, max_chunk).map_err(|message| GpuError::TooLarge {
                adapter: label.clone(),
                message,
            })?;
        let pixels64 = stack.header.width as u64 * stack.header.height as u64;
        let image_bytes = pixels64 * 16;
        if image_bytes > binding_limit || pixels64 > u32::MAX as u64 {
            return Err(GpuError::TooLarge {
                adapter: label,
                message: format!(
                    "the {}×{} RGBA f32 image is {image_bytes} bytes, over the {binding_limit}-byte storage binding limit",
                    stack.header.width, stack.header.height
                ),
            });
        }
        let pixels = pixels64 as u32;
        let total_groups = pixels.div_ceil(WORKGROUP).max(1);
        let max_x = limits.max_compute_workgroups_per_dimension.max(1);
        let workgroups = if total_groups <= max_x {
            [total_groups, 1]
        } else {
            [max_x, total_groups.div_ceil(max_x)]
        };

        let start = Instant::now();
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let invalid = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let uploaded = upload(&device, stack, &layout, image_bytes, timed);
        let scope_errors = [
            pollster::block_on(invalid.pop()),
            pollster::block_on(oom.pop()),
        ];
        let upload_ms = start.elapsed().as_secs_f64() * 1e3;
        if let Some(e) = scope_errors.into_iter().flatten().next() {
            return Err(match e {
                wgpu::Error::OutOfMemory { .. } => GpuError::OutOfMemory {
                    adapter: label,
                    bytes: layout.bytes(),
                    message: e.to_string(),
                },
                other => GpuError::Backend {
                    during: "the layer upload".into(),
                    message: other.to_string(),
                },
            });
        }
        let (buffers, read_bytes) = uploaded?;
        health.check("the layer upload")?;

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
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("relume relight kernel"),
            source: wgpu::ShaderSource::Wgsl(Cow::Borrowed(include_str!("kernel.wgsl"))),
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
        let params: Vec<wgpu::Buffer> = (0..layout.groups())
            .map(|_| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("relume params"),
                    size: PARAMS_BYTES,
                    usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            })
            .collect();
        let bind_groups = (0..layout.groups())
            .map(|g| {
                let mut entries = vec![
                    bind(0, &buffers.image),
                    bind(1, &params[g]),
                    bind(2, &buffers.entries),
                    bind(7, &buffers.masks),
                ];
                for c in 0..CHUNKS_PER_GROUP {
                    let chunk = buffers
                        .chunks
                        .get(g * CHUNKS_PER_GROUP + c)
                        .unwrap_or(&buffers.empty);
                    entries.push(bind(3 + c as u32, chunk));
                }
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("relume layers"),
                    layout: &bind_layout,
                    entries: &entries,
                })
            })
            .collect();
        if let Some(e) = pollster::block_on(invalid.pop()) {
            return Err(GpuError::Backend {
                during: "building the relight pipeline".into(),
                message: e.to_string(),
            });
        }
        Ok(Kernel {
            adapter: info,
            layout,
            upload_ms,
            read_bytes,
            device,
            queue,
            pipeline,
            bind_groups,
            params,
            entries: buffers.entries,
            image: buffers.image,
            readback: buffers.readback,
            timestamps,
            health,
            pixels,
            mask_words: mask_words(pixels as usize) as u32,
            workgroups,
        })
    }

    /// Whether the compute pass is timed.
    pub fn timed(&self) -> bool {
        self.timestamps.is_some()
    }

    /// Adds `weight · layer` for every `(layer, weight)` of `adds` to the image on the GPU
    /// (to black when `reset`), and reads the image back into `out` (RGBA f32). Returns the
    /// compute pass time in ms when timed.
    pub fn run(
        &mut self,
        adds: &[(u32, Rgb)],
        reset: bool,
        out: &mut [f32],
    ) -> Result<Option<f64>, GpuError> {
        self.health.check("the previous relight")?;
        // Entries in group order; a group's entries are contiguous.
        let groups = self.layout.groups();
        let mut by_group: Vec<Vec<[u8; ENTRY_BYTES]>> = vec![Vec::new(); groups];
        for &(l, w) in adds {
            let p = self.layout.placements[l as usize];
            let g = p.chunk as usize / CHUNKS_PER_GROUP;
            let mut e = [0u8; ENTRY_BYTES];
            let fields = [
                w.x.to_bits(),
                w.y.to_bits(),
                w.z.to_bits(),
                l * self.mask_words,
                p.chunk % CHUNKS_PER_GROUP as u32,
                p.offset_words,
                p.channels,
                p.format as u32,
            ];
            for (dst, v) in e.chunks_exact_mut(4).zip(fields) {
                dst.copy_from_slice(&v.to_le_bytes());
            }
            by_group[g].push(e);
        }
        let mut bytes = Vec::with_capacity(adds.len() * ENTRY_BYTES);
        let mut dispatches = Vec::new();
        for (g, list) in by_group.iter().enumerate() {
            let first = (bytes.len() / ENTRY_BYTES) as u32;
            list.iter().for_each(|e| bytes.extend_from_slice(e));
            // A full relight always runs group 0, which clears the image.
            let first_of_full = reset && g == 0;
            if list.is_empty() && !first_of_full {
                continue;
            }
            let params = [self.pixels, first, list.len() as u32, first_of_full as u32];
            let params: Vec<u8> = params.iter().flat_map(|v| v.to_le_bytes()).collect();
            self.queue.write_buffer(&self.params[g], 0, &params);
            dispatches.push(g);
        }
        if !bytes.is_empty() {
            self.queue.write_buffer(&self.entries, 0, &bytes);
        }

        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        if !dispatches.is_empty() {
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
            for &g in &dispatches {
                pass.set_bind_group(0, &self.bind_groups[g], &[]);
                pass.dispatch_workgroups(self.workgroups[0], self.workgroups[1], 1);
            }
        }
        let image_bytes = self.pixels as u64 * 16;
        encoder.copy_buffer_to_buffer(&self.image, 0, &self.readback, 0, image_bytes);
        let timed = match &self.timestamps {
            Some(t) if !dispatches.is_empty() => {
                encoder.resolve_query_set(&t.set, 0..2, &t.resolve, 0);
                encoder.copy_buffer_to_buffer(
                    &t.resolve,
                    0,
                    &self.readback,
                    image_bytes,
                    TIMESTAMP_BYTES,
                );
                Some(t.period_ns)
            }
            _ => None,
        };
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
        encoder.copy_buffer_to_buffer(&self.image, 0, &self.readback, 0, self.pixels as u64 * 16);
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

fn bind(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

struct Buffers {
    chunks: Vec<wgpu::Buffer>,
    /// Bound to the chunk slots a group does not use (a binding cannot be left empty).
    empty: wgpu::Buffer,
    image: wgpu::Buffer,
    entries: wgpu::Buffer,
    masks: wgpu::Buffer,
    readback: wgpu::Buffer,
}

/// Creates every buffer; the chunks and the tile masks are filled while mapped at creation
/// (no staging copy). Also returns the bytes a relight reads of each layer.
fn upload(
    device: &wgpu::Device,
    stack: &TransferStack,
    layout: &Layout,
    image_bytes: u64,
    timed: bool,
) -> Result<(Buffers, Vec<usize>), GpuError> {
    let pixels = image_bytes as usize / 16;
    let words = mask_words(pixels);
    let mut masks = vec![0u32; words * stack.layers.len().max(1)];
    let mut read_bytes = Vec::with_capacity(stack.layers.len());
    let storage = |label: &str, size: u64, mapped: bool, extra: wgpu::BufferUsages| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: size.max(16),
            usage: wgpu::BufferUsages::STORAGE | extra,
            mapped_at_creation: mapped,
        })
    };
    let mut chunks: Vec<wgpu::Buffer> = layout
        .chunk_words
        .iter()
        .map(|&w| storage("relume layers", w * 4, true, wgpu::BufferUsages::empty()))
        .collect();
    let mut views = Vec::with_capacity(chunks.len());
    for c in &chunks {
        views.push(c.get_mapped_range_mut(..).map_err(|e| GpuError::Backend {
            during: "mapping a layer buffer for the upload".into(),
            message: e.to_string(),
        })?);
    }
    let mut scratch = Vec::new();
    for (layer, p) in stack.layers.iter().zip(&layout.placements) {
        scratch.clear();
        scratch.resize(p.words as usize * 4, 0);
        pack_layer(layer, &mut scratch).map_err(|i| {
            GpuError::Engine(relume_engine::RelumeError::NonFinite {
                what: format!("layer {}, sample {i}", layer.key.layer_name()),
            })
        })?;
        let tiles = layer_mask(
            layer,
            pixels,
            &mut masks[read_bytes.len() * words..][..words],
        );
        let sample_bytes = match p.format {
            Format::F16Pairs => 2,
            Format::F32 => 4,
        };
        read_bytes.push(tiles * TILE_PIXELS * p.channels as usize * sample_bytes);
        let at = p.offset_words as usize * 4;
        views[p.chunk as usize]
            .slice(at..at + scratch.len())
            .copy_from_slice(&scratch);
    }
    drop(views);
    chunks.iter_mut().for_each(|c| c.unmap());
    let entry_bytes = (stack.layers.len() * ENTRY_BYTES) as u64;
    let readback_bytes = image_bytes + if timed { TIMESTAMP_BYTES } else { 0 };
    let mask_buffer = storage(
        "relume tile masks",
        masks.len() as u64 * 4,
        true,
        wgpu::BufferUsages::empty(),
    );
    mask_buffer
        .get_mapped_range_mut(..)
        .map_err(|e| GpuError::Backend {
            during: "mapping the tile masks for the upload".into(),
            message: e.to_string(),
        })?
        .slice(..masks.len() * 4)
        .copy_from_slice(bytemuck::cast_slice(&masks));
    mask_buffer.unmap();
    let buffers = Buffers {
        masks: mask_buffer,
        chunks,
        empty: storage("relume empty chunk", 16, false, wgpu::BufferUsages::empty()),
        image: storage(
            "relume image",
            image_bytes,
            false,
            wgpu::BufferUsages::COPY_SRC,
        ),
        entries: storage(
            "relume layer list",
            entry_bytes,
            false,
            wgpu::BufferUsages::COPY_DST,
        ),
        readback: device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("relume read-back"),
            size: readback_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        }),
    };
    Ok((buffers, read_bytes))
}
