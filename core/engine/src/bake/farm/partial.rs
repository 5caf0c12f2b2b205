//! A partial stack: what one partition of a farm bake hands to the merge — per tile and per
//! layer non-zero there the *sums* of its eye samples (not averages), in the aligned sample
//! blocks of the canonical summation tree ([`crate::bake::schedule::blocks`]), with the
//! denoiser's per-pixel feature sums and everything the merge checks: scene hash, settings
//! fingerprint, seed, the sample range, the guide it was traced with and the engine version.
//!
//! It is sparse and tiled like the stack the one-machine bake streams: a layer is stored
//! only on the 16×16 tiles where a sample of the block reached it, on one channel where its
//! sums are grey over the tile, so a part's size follows the data, not layers × frame.
//! Partitions write their tiles as they are traced and the merge reads them tile by tile
//! ([`PartialReader`]), so neither holds a full frame of any layer.
//!
//! File: the farm container ([`crate::bake::farm::farm_file`]: magic, JSON header,
//! little-endian payload, checksum). Payload, tile by tile in raster order
//! ([`crate::bake::schedule::tiles::tiles`]), block by block within a tile:
//!
//! ```text
//! n: u64 | n × u64 (layer id | channels << 32) | features: pixels × FEATURE_STRIDE f32
//!        | per entry: pixels × channels f32 sums
//! ```
//!
//! Version 1 (full-frame sums per block) is refused by name: re-bake its partitions.

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::bake::farm::farm_file::{self, PayloadReader};
use crate::bake::finish::denoise::FEATURE_STRIDE;
use crate::bake::settings::BakeSettings;
use crate::{RelumeError, Result};

const MAGIC: &[u8; 8] = b"RLMPART1";

/// Version of the partial stack layout (2: sparse tiles; 1 was full-frame sums).
pub const PARTIAL_FORMAT_VERSION: u32 = 2;

/// What a partial stack says about itself.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PartialHeader {
    pub format_version: u32,
    /// Engine version that traced it: another build may trace other paths.
    pub engine_version: String,
    pub scene_hash: String,
    /// The scene file the partition read, as it named it (the merge's default scene).
    pub scene_path: Option<PathBuf>,
    /// The bake's settings (threads and memory budget cleared: they change no result).
    pub settings: BakeSettings,
    /// [`crate::bake::farm::partition::settings_fingerprint`] of `settings`.
    pub settings_hash: String,
    /// Eye samples of the whole bake.
    pub spp: u32,
    /// The eye samples this part holds: `[start, end)`.
    pub samples: [u32; 2],
    /// `[i, N]` of `--partition i/N` (for messages; coverage is checked on `samples`).
    pub partition: [u32; 2],
    /// Checksum of the guide file the part was traced with (`None`: not guided).
    pub guide_hash: Option<String>,
    pub width: u32,
    pub height: u32,
    /// Dense layer count of the bake (layer keys follow from the scene and settings).
    pub layer_count: u32,
    /// The sample blocks every tile holds, in order (`[start, end)` each).
    pub blocks: Vec<[u32; 2]>,
    /// Layers some sample of the part reached somewhere.
    pub layers_reached: u32,
    /// (tile, layer) entries of all blocks, and the largest tile's bytes in the payload
    /// (what the merge holds per part while it sums a tile).
    pub tile_entries: u64,
    pub largest_tile_bytes: u64,
    /// The one-machine bake's forecast peak for these settings (the partition's probe):
    /// the merge finalises as that bake does, so it is the merge's forecast too.
    pub bake_peak_bytes: u64,
    /// Rays the partition traced and its wall time.
    pub rays: u64,
    pub seconds: f64,
}

pub use crate::bake::schedule::tile_sums::TileSums;

/// Writes a partial stack as its tiles are traced. The tiles go to a scratch file beside
/// the output (`.payload.tmp`); [`PartialWriter::finish`] writes the file atomically, its
/// header first (what it says is known only at the end), and removes the scratch file.
pub struct PartialWriter {
    path: PathBuf,
    scratch: PathBuf,
    out: std::io::BufWriter<std::fs::File>,
    written: u64,
    entries: u64,
    largest_tile: u64,
    reached: Vec<bool>,
}

impl PartialWriter {
    /// Starts the partial stack `path` of a bake of `layer_count` layers.
    pub fn create(path: &Path, layer_count: usize) -> Result<PartialWriter> {
        let mut name = path.file_name().unwrap_or_default().to_os_string();
        name.push(".payload.tmp");
        let scratch = path.with_file_name(name);
        let file = std::fs::File::create(&scratch).map_err(|e| RelumeError::io(&scratch, e))?;
        Ok(PartialWriter {
            path: path.to_path_buf(),
            scratch,
            out: std::io::BufWriter::with_capacity(1 << 20, file),
            written: 0,
            entries: 0,
            largest_tile: 0,
            reached: vec![false; layer_count],
        })
    }

    fn bytes(&mut self, b: &[u8]) -> Result<()> {
        self.written += b.len() as u64;
        self.out
            .write_all(b)
            .map_err(|e| RelumeError::io(&self.scratch, e))
    }

    fn f32s(&mut self, values: &[f32]) -> Result<()> {
        let mut buf = Vec::with_capacity(4 * values.len());
        for v in values {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        self.bytes(&buf)
    }

    /// Appends the next tile (raster order): its blocks in sample order. A layer is written
    /// on one channel where its sums are equal in R, G and B at every pixel of the tile.
    pub fn tile(&mut self, blocks: &[TileSums]) -> Result<()> {
        let start = self.written;
        for block in blocks {
            let pixels = block.features.len() / FEATURE_STRIDE;
            let grey: Vec<bool> = block
                .layers
                .iter()
                .map(|(_, s)| s.chunks_exact(3).all(|c| c[0] == c[1] && c[1] == c[2]))
                .collect();
            let mut head = vec![block.layers.len() as u64];
            for ((id, _), g) in block.layers.iter().zip(&grey) {
                head.push(*id as u64 | (if *g { 1u64 } else { 3 }) << 32);
                if let Some(r) = self.reached.get_mut(*id as usize) {
                    *r = true;
                }
            }
            let head: Vec<u8> = head.iter().flat_map(|v| v.to_le_bytes()).collect();
            self.bytes(&head)?;
            self.f32s(&block.features)?;
            for ((_, sums), g) in block.layers.iter().zip(&grey) {
                if *g {
                    let one: Vec<f32> = sums.chunks_exact(3).map(|c| c[0]).collect();
                    debug_assert_eq!(one.len(), pixels);
                    self.f32s(&one)?;
                } else {
                    self.f32s(sums)?;
                }
            }
            self.entries += block.layers.len() as u64;
        }
        self.largest_tile = self.largest_tile.max(self.written - start);
        Ok(())
    }

    /// Fills in what the tiles told (`blocks`' layers reached, entries, largest tile) and
    /// writes the file; returns the header and the bytes written.
    pub fn finish(mut self, mut header: PartialHeader) -> Result<(PartialHeader, u64)> {
        self.out
            .flush()
            .map_err(|e| RelumeError::io(&self.scratch, e))?;
        header.layers_reached = self.reached.iter().filter(|r| **r).count() as u32;
        header.tile_entries = self.entries;
        header.largest_tile_bytes = self.largest_tile;
        let scratch = self.scratch.clone();
        let result = (|| {
            let mut from =
                std::fs::File::open(&scratch).map_err(|e| RelumeError::io(&scratch, e))?;
            farm_file::write(&self.path, MAGIC, &header, self.written, |w| {
                let mut buf = vec![0u8; 1 << 20];
                loop {
                    let n = std::io::Read::read(&mut from, &mut buf)
                        .map_err(|e| RelumeError::io(&scratch, e))?;
                    if n == 0 {
                        return Ok(());
                    }
                    w.raw(&self.path, &buf[..n])?;
                }
            })
        })();
        let _ = std::fs::remove_file(&scratch);
        Ok((header, result?))
    }
}

impl Drop for PartialWriter {
    fn drop(&mut self) {
        // A cancelled or failed partition leaves no scratch file (after `finish` it is gone).
        let _ = std::fs::remove_file(&self.scratch);
    }
}

/// Reads only the header of a partial stack (the merge checks every part's header before it
/// reads any sums). A partial of another format version is refused by name.
pub fn read_partial_header(path: &Path) -> Result<PartialHeader> {
    Ok(PartialReader::open(path)?.header)
}

/// Reads a partial stack tile by tile, in the order it was written.
pub struct PartialReader<'a> {
    pub header: PartialHeader,
    path: &'a Path,
    payload: PayloadReader<'a>,
}

impl<'a> PartialReader<'a> {
    /// Opens `path` and checks its header's format version.
    pub fn open(path: &'a Path) -> Result<PartialReader<'a>> {
        let (value, payload): (serde_json::Value, _) =
            farm_file::read(path, MAGIC, "Relume partial stack")?;
        let bad = |m: String| RelumeError::StackFormat {
            path: path.to_path_buf(),
            message: m,
        };
        let version = value.get("format_version").and_then(|v| v.as_u64());
        if version != Some(PARTIAL_FORMAT_VERSION as u64) {
            return Err(bad(format!(
                "partial stack format version {} (this build reads version {PARTIAL_FORMAT_VERSION}, \
                 sparse tiles; version 1 held full-frame sums): bake its partitions again with this build",
                version.map_or("unknown".into(), |v| v.to_string())
            )));
        }
        let header: PartialHeader = serde_json::from_value(value)
            .map_err(|e| bad(format!("Relume partial stack header: {e}")))?;
        Ok(PartialReader {
            header,
            path,
            payload,
        })
    }

    /// The next tile's blocks (`pixels` pixels), RGB sums (grey entries widened).
    pub fn tile(&mut self, pixels: usize) -> Result<Vec<TileSums>> {
        let layer_count = self.header.layer_count as u64;
        let mut out = Vec::with_capacity(self.header.blocks.len());
        for _ in 0..self.header.blocks.len() {
            let n = self.payload.u64s(1)?[0];
            if n > layer_count {
                return Err(self.bad(format!("a tile claims {n} layers of {layer_count}")));
            }
            let entries = self.payload.u64s(n as usize)?;
            let features = self
                .payload
                .f32s(pixels * FEATURE_STRIDE, "a partial stack's features")?;
            let mut layers = Vec::with_capacity(entries.len());
            let mut last: Option<u32> = None;
            for e in entries {
                let (id, channels) = ((e & 0xffff_ffff) as u32, e >> 32);
                if id as u64 >= layer_count
                    || !(channels == 1 || channels == 3)
                    || last.is_some_and(|l| l >= id)
                {
                    return Err(self.bad(format!(
                        "a tile's entry (layer {id}, {channels} channels) of {layer_count} layers"
                    )));
                }
                last = Some(id);
                let v = self
                    .payload
                    .f32s(pixels * channels as usize, "a partial stack's layer sums")?;
                let rgb = if channels == 3 {
                    v
                } else {
                    v.iter().flat_map(|x| [*x; 3]).collect()
                };
                layers.push((id, rgb));
            }
            out.push(TileSums { features, layers });
        }
        Ok(out)
    }

    fn bad(&self, message: String) -> RelumeError {
        RelumeError::StackFormat {
            path: self.path.to_path_buf(),
            message,
        }
    }

    /// Checks that the payload was read to its end and its checksum.
    pub fn finish(self) -> Result<()> {
        self.payload.finish().map(|_| ())
    }
}

/// Reads a whole partial stack through, checking its layout and checksum (a copy's check;
/// the merge does the same as it reads). Returns its header.
pub fn verify_partial(path: &Path) -> Result<PartialHeader> {
    let mut r = PartialReader::open(path)?;
    let tiles = crate::bake::schedule::tiles::tiles(crate::scene::Resolution {
        width: r.header.width,
        height: r.header.height,
    });
    for t in &tiles {
        r.tile(t.pixels())?;
    }
    let header = r.header.clone();
    r.finish()?;
    Ok(header)
}
