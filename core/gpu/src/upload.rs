//! Writing the tiled stack into its GPU buffers: the values chunk by chunk and the tables,
//! streamed from the stack the host already holds, in bounded pieces.
//!
//! Host memory during the upload is the stack (shared, not copied) plus [`PIECE_BYTES`] of
//! pending bytes and what wgpu stages for the writes queued since the last submission,
//! which [`SUBMIT_EVERY_BYTES`] bounds: the upload never holds a second copy of the stack,
//! as mapping every buffer at creation would on a discrete GPU.

use relume_engine::stack::tiled::{TileValues, TiledStack};

use crate::error::GpuError;
use crate::lattice::{block, block_words, gpu_order};
use crate::layout::{Layout, CHUNKS_PER_GROUP};
use crate::tiles::{entry_flags, entry_record, lattices_at, EntryKind};

/// Bytes gathered on the host before one `write_buffer`.
pub(crate) const PIECE_BYTES: usize = 4 << 20;
/// Bytes of queued writes after which the queue is submitted and drained, so that wgpu's
/// staging memory is released.
pub(crate) const SUBMIT_EVERY_BYTES: u64 = 64 << 20;

/// Appends bytes to one buffer from offset 0, in whole-word writes.
struct StagedWriter<'a> {
    device: &'a wgpu::Device,
    queue: &'a wgpu::Queue,
    buffer: &'a wgpu::Buffer,
    /// Bytes written so far.
    at: u64,
    pending: Vec<u8>,
    /// Bytes queued since the last submission.
    queued: u64,
}

impl<'a> StagedWriter<'a> {
    fn new(device: &'a wgpu::Device, queue: &'a wgpu::Queue, buffer: &'a wgpu::Buffer) -> Self {
        StagedWriter {
            device,
            queue,
            buffer,
            at: 0,
            pending: Vec::new(),
            queued: 0,
        }
    }

    /// Appends `values`, each as the little-endian bytes `bytes` gives.
    fn push<T: Copy, const N: usize>(
        &mut self,
        values: &[T],
        bytes: impl Fn(T) -> [u8; N],
    ) -> Result<(), GpuError> {
        for part in values.chunks(PIECE_BYTES / N) {
            self.pending
                .extend(part.iter().flat_map(|&v| bytes(v).into_iter()));
            if self.pending.len() >= PIECE_BYTES {
                self.write_whole_words()?;
            }
        }
        Ok(())
    }

    /// Writes the pending whole words; keeps the last 0–3 bytes pending.
    fn write_whole_words(&mut self) -> Result<(), GpuError> {
        let n = self.pending.len() / 4 * 4;
        if n == 0 {
            return Ok(());
        }
        self.queue
            .write_buffer(self.buffer, self.at, &self.pending[..n]);
        self.pending.drain(..n);
        self.at += n as u64;
        self.queued += n as u64;
        if self.queued >= SUBMIT_EVERY_BYTES {
            self.queue.submit(Vec::<wgpu::CommandBuffer>::new());
            self.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| GpuError::Backend {
                    during: "the stack upload".into(),
                    message: e.to_string(),
                })?;
            self.queued = 0;
        }
        Ok(())
    }

    /// Pads the last word with zeros and writes it; returns the bytes queued since the
    /// last submission (the next writer continues the count).
    fn finish(mut self) -> Result<u64, GpuError> {
        let padded = self.pending.len().div_ceil(4) * 4;
        self.pending.resize(padded, 0);
        self.write_whole_words()?;
        Ok(self.queued)
    }
}

/// Writes every tile's values into its chunk (`chunks[c]` for `layout.chunks[c]`), back
/// to back in tile order, f16 as their bits.
pub(crate) fn upload_values(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    stack: &TiledStack,
    layout: &Layout,
    chunks: &[wgpu::Buffer],
) -> Result<(), GpuError> {
    let mut queued = 0;
    for (chunk, buffer) in layout.chunks.iter().zip(chunks) {
        let mut w = StagedWriter::new(device, queue, buffer);
        w.queued = queued;
        let tiles = &stack.tiles[chunk.first_tile as usize..][..chunk.tiles as usize];
        for tile in tiles {
            match &tile.values {
                TileValues::F16(v) => w.push(v, |h| h.to_bits().to_le_bytes())?,
                TileValues::F32(v) => w.push(v, |x: f32| x.to_le_bytes())?,
            }
        }
        queued = w.finish()?;
    }
    Ok(())
}

/// Writes the tables (`tiles.rs`): the tile starts, one record per entry with its offset
/// in its chunk (a tile's entries in [`gpu_order`]), the lattice pointers, then the lattice
/// blocks (`lattice.rs`).
pub(crate) fn upload_tables(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    stack: &TiledStack,
    layout: &Layout,
    buffer: &wgpu::Buffer,
) -> Result<(), GpuError> {
    let le = |v: u32| v.to_le_bytes();
    let mut w = StagedWriter::new(device, queue, buffer);
    let mut start = 0u32;
    w.push(&[start], le)?;
    for tile in &stack.tiles {
        // The entry count was checked to fit u32 before the upload.
        start += tile.entries.len() as u32;
        w.push(&[start], le)?;
    }
    for (c, chunk) in layout.chunks.iter().enumerate() {
        let slot = (c % CHUNKS_PER_GROUP) as u32;
        // The layout caps a chunk at 2³² samples, so every offset in it fits u32.
        let mut tile_start = 0u64;
        let tiles = &stack.tiles[chunk.first_tile as usize..][..chunk.tiles as usize];
        for tile in tiles {
            for e in gpu_order(tile) {
                let kind = if e.segments == 0 {
                    EntryKind::Values
                } else {
                    EntryKind::Lattice
                };
                let flags = entry_flags(e.channels, kind, slot);
                let offset = (tile_start + u64::from(e.offset)) as u32;
                w.push(&entry_record(e.layer, flags, e.scale, offset), le)?;
            }
            tile_start += tile.values.len() as u64;
        }
    }
    // The table's size was checked to fit u32 word indices before the upload.
    let mut block_at =
        lattices_at(stack.tiles.len(), stack.entry_count()) + stack.tiles.len() as u64;
    for tile in &stack.tiles {
        let words = block_words(tile) as u64;
        w.push(&[if words == 0 { 0 } else { block_at as u32 }], le)?;
        block_at += words;
    }
    for tile in &stack.tiles {
        w.push(&block(tile), le)?;
    }
    w.finish().map(|_| ())
}
