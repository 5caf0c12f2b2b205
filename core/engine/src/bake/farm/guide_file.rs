//! The guide pass of a farm bake as a file: the first task of a farm job runs the guide
//! pass once (`relume bake SCENE --guide-only -o GUIDE`) and every partition reads it
//! (`--guide GUIDE`) instead of tracing it again. The pass is deterministic, so a partition
//! that builds the guide itself gets the same trees; the file saves the N − 1 repeats.
//!
//! The file records the scene hash and the settings fingerprint ([`super::partition`]) it
//! was made for; a partition refuses a guide of another scene or other settings. Bakes that
//! do not sample guided get a guide file with no trees, so job templates need no branch.
//! Trees are stored as their nodes' (energy f64, first child u32) pairs, bit-exact.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::farm_file;
use crate::bake::path::guide::GuideField;
use crate::bake::path::guide_tree::DirectionTree;
use crate::bake::prepare::context::BakeContext;
use crate::bake::settings::{settings_fingerprint, BakeSettings};
use crate::progress::Progress;
use crate::scene::{hash::scene_hash, Scene};
use crate::{RelumeError, Result};

const MAGIC: &[u8; 8] = b"RLMGUID1";

/// What a guide file says about itself.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct GuideHeader {
    pub scene_hash: String,
    pub settings_hash: String,
    /// `None` when the settings do not sample guided: the partitions need no trees.
    pub field: Option<FieldInfo>,
}

/// Layout of a stored guide field.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FieldInfo {
    pub side: u32,
    pub tiles_x: u32,
    pub tiles_y: u32,
    /// Nodes per tile (0: no tree there).
    pub nodes: Vec<u32>,
    pub rays: u64,
    pub seconds: f64,
}

/// A guide read back (or just built), with its file checksum.
pub struct GuideFile {
    pub header: GuideHeader,
    pub field: Option<GuideField>,
    /// The file's checksum (hex), recorded in every partition made with it.
    pub hash: String,
}

/// Runs the guide pass of `scene` with `settings` (none when they do not sample guided).
pub fn build_guide(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
) -> Result<Option<GuideField>> {
    let (mut ctx, _) = BakeContext::prepare(scene, settings, progress)?;
    ctx.build_guide(scene, progress)?;
    Ok(ctx.guide)
}

/// Writes the guide of `scene` and `settings` to `path`; returns the bytes and the hash.
pub fn write_guide(
    path: &Path,
    scene: &Scene,
    settings: &BakeSettings,
    field: Option<&GuideField>,
) -> Result<(u64, String)> {
    let trees: Vec<Vec<(f64, u32)>> = field
        .map(|f| {
            f.parts()
                .3
                .iter()
                .map(|t| t.as_ref().map(|t| t.to_nodes()).unwrap_or_default())
                .collect()
        })
        .unwrap_or_default();
    let header = GuideHeader {
        scene_hash: scene_hash(scene),
        settings_hash: settings_fingerprint(settings),
        field: field.map(|f| {
            let (side, tiles_x, tiles_y, _) = f.parts();
            FieldInfo {
                side,
                tiles_x,
                tiles_y,
                nodes: trees.iter().map(|t| t.len() as u32).collect(),
                rays: f.rays,
                seconds: f.seconds,
            }
        }),
    };
    let nodes: usize = trees.iter().map(|t| t.len()).sum();
    let bytes = farm_file::write(path, MAGIC, &header, 16 * nodes as u64, |w| {
        for t in &trees {
            let words: Vec<u64> = t
                .iter()
                .flat_map(|(e, c)| [e.to_bits(), *c as u64])
                .collect();
            w.u64s(path, &words)?;
        }
        Ok(())
    })?;
    let read = read_guide(path)?;
    Ok((bytes, read.hash))
}

/// Reads a guide file.
pub fn read_guide(path: &Path) -> Result<GuideFile> {
    let (header, mut r): (GuideHeader, _) = farm_file::read(path, MAGIC, "Relume guide file")?;
    let bad = |m: String| RelumeError::StackFormat {
        path: path.to_path_buf(),
        message: m,
    };
    let field = match &header.field {
        None => None,
        Some(info) => {
            let mut trees = Vec::with_capacity(info.nodes.len().min(1 << 24));
            for &n in &info.nodes {
                if n == 0 {
                    trees.push(None);
                    continue;
                }
                let words = r.u64s(2 * n as usize)?;
                let nodes: Vec<(f64, u32)> = words
                    .chunks_exact(2)
                    .map(|w| (f64::from_bits(w[0]), w[1] as u32))
                    .collect();
                trees
                    .push(Some(DirectionTree::from_nodes(&nodes).ok_or_else(
                        || bad("a guide tree is not a valid tree".into()),
                    )?));
            }
            Some(
                GuideField::from_parts(
                    info.side,
                    info.tiles_x,
                    info.tiles_y,
                    trees,
                    info.rays,
                    info.seconds,
                )
                .ok_or_else(|| bad("tile count does not match the tiles across × down".into()))?,
            )
        }
    };
    let hash = format!("{:016x}", r.finish()?);
    Ok(GuideFile {
        header,
        field,
        hash,
    })
}
