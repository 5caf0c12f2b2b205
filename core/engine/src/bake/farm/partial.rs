//! A partial stack: what one partition of a farm bake hands to the merge — per layer the
//! *sums* of its eye samples (not averages), in the aligned sample blocks of the canonical
//! summation tree ([`crate::bake::schedule::blocks`]), with the denoiser's per-pixel feature sums
//! and everything the merge checks: scene hash, settings fingerprint, seed, the sample range, the
//! guide it was traced with and the engine version.
//!
//! File: the farm container ([`crate::bake::farm::farm_file`]: magic `RLMPART1`, JSON header,
//! little-endian f32 payload, checksum). Payload, block by block: the features
//! (pixels × [`FEATURE_STRIDE`]), then each reached layer's RGB sums (pixels × 3), in the
//! order of the block's `layers` list. Layers no sample of the block reached are absent
//! (zeros). Sums are f32 as the bake holds them: a partial is ≈ 2× an f16 stack per block.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::bake::farm::farm_file;
use crate::bake::finish::denoise::FEATURE_STRIDE;
use crate::bake::schedule::blocks::Block;
use crate::bake::settings::BakeSettings;
use crate::{RelumeError, Result};

const MAGIC: &[u8; 8] = b"RLMPART1";

/// Version of the partial stack layout.
pub const PARTIAL_FORMAT_VERSION: u32 = 1;

/// One stored block: its samples and the layers (dense indices) it holds.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct BlockInfo {
    pub samples: [u32; 2],
    pub layers: Vec<u32>,
}

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
    pub blocks: Vec<BlockInfo>,
    /// Rays the partition traced and its wall time.
    pub rays: u64,
    pub seconds: f64,
}

/// A partial stack in memory.
pub struct PartialStack {
    pub header: PartialHeader,
    pub blocks: Vec<Block>,
}

/// Writes `part` to `path` atomically; returns the bytes written.
pub fn write_partial(path: &Path, part: &PartialStack) -> Result<u64> {
    let pixels = part.header.width as u64 * part.header.height as u64;
    let floats: u64 = part
        .header
        .blocks
        .iter()
        .map(|b| pixels * (FEATURE_STRIDE as u64 + 3 * b.layers.len() as u64))
        .sum();
    farm_file::write(path, MAGIC, &part.header, 4 * floats, |w| {
        for (info, block) in part.header.blocks.iter().zip(&part.blocks) {
            w.f32s(
                path,
                &block.features.lock().unwrap_or_else(|e| e.into_inner()),
            )?;
            for &l in &info.layers {
                let image = block.layers[l as usize]
                    .lock()
                    .unwrap_or_else(|e| e.into_inner());
                w.f32s(path, image.as_deref().unwrap_or_default())?;
            }
        }
        Ok(())
    })
}

/// Reads only the header of a partial stack (the merge checks every part's header before it
/// reads any sums, and then reads the parts one at a time).
pub fn read_partial_header(path: &Path) -> Result<PartialHeader> {
    let (header, _): (PartialHeader, _) = farm_file::read(path, MAGIC, "Relume partial stack")?;
    Ok(header)
}

/// Reads a partial stack, checking its layout against its header and its checksum.
pub fn read_partial(path: &Path) -> Result<PartialStack> {
    let (header, mut r): (PartialHeader, _) = farm_file::read(path, MAGIC, "Relume partial stack")?;
    let bad = |m: String| RelumeError::StackFormat {
        path: path.to_path_buf(),
        message: m,
    };
    if header.format_version != PARTIAL_FORMAT_VERSION {
        return Err(bad(format!(
            "partial stack format version {} (this build reads {PARTIAL_FORMAT_VERSION})",
            header.format_version
        )));
    }
    let pixels = crate::memory::checked_product(
        "a partial stack's images",
        &[header.width as u64, header.height as u64],
    )? as usize;
    let mut blocks = Vec::with_capacity(header.blocks.len().min(64));
    for info in &header.blocks {
        let block = Block::new(
            info.samples[0]..info.samples[1],
            header.layer_count as usize,
            0,
        )?;
        *block.features.lock().unwrap_or_else(|e| e.into_inner()) =
            r.f32s(pixels * FEATURE_STRIDE, "a partial stack's features")?;
        for &l in &info.layers {
            let slot = block
                .layers
                .get(l as usize)
                .ok_or_else(|| bad(format!("layer {l} of {} layers", header.layer_count)))?;
            *slot.lock().unwrap_or_else(|e| e.into_inner()) =
                Some(r.f32s(pixels * 3, "a partial stack's layer sums")?);
        }
        blocks.push(block);
    }
    r.finish()?;
    Ok(PartialStack { header, blocks })
}
