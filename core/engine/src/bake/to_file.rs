//! A bake written to a stack file: the one place that turns [`bake_progressive_tiled`]
//! into files on disk, shared by `relume bake` and the Python bindings' `BakeJob`. The
//! file is the tiled stack (format v2): no pass holds the layers as full frames.
//!
//! With `passes > 1` the sample counts double up to `settings.spp` ([`doubling_passes`]) and
//! a complete stack replaces the file after every pass; each write is atomic (temp file,
//! fsync, rename: [`crate::image_io::write_atomic`]), so a cancel, an error or a crash
//! leaves either the previous complete stack or nothing — never a partial file and never a
//! temp file.

use std::path::Path;
use std::time::Instant;

use super::{bake_progressive_tiled, doubling_passes, BakeReport, BakeSettings, PassReport};
use crate::progress::Progress;
use crate::scene::Scene;
use crate::stack::tiled::file::write_tiled_cancellable;
use crate::stack::tiled::TiledStack;
use crate::Result;

/// Most progressive passes: each doubles the samples, so 16 spans a 65 536-fold range.
pub const MAX_PASSES: u32 = 16;

/// What [`bake_to_file`] did.
pub struct BakedFile {
    /// The final stack (the last pass's, as written: file format v2, tiled).
    pub stack: TiledStack,
    pub report: BakeReport,
    /// One per pass, with the estimated noise after each.
    pub passes: Vec<PassReport>,
    /// Size of the last file written.
    pub file_bytes: u64,
    /// Seconds the last write took.
    pub write_seconds: f64,
    /// Stacks written (one per pass).
    pub stacks_written: usize,
}

/// Bakes `scene` in `passes` doubling passes (1: one plain bake) and writes the stack to
/// `path` after each. `on_written(pass, bytes)` runs after every write (for a message or a
/// counter). `progress` reports over all passes and cancels: a cancel stops within a pixel
/// row and returns [`crate::RelumeError::Cancelled`] with the file as the last completed
/// pass (or the previous file) left it.
pub fn bake_to_file(
    scene: &Scene,
    settings: &BakeSettings,
    passes: u32,
    path: &Path,
    progress: &Progress,
    mut on_written: impl FnMut(&PassReport, u64),
) -> Result<BakedFile> {
    if !(1..=MAX_PASSES).contains(&passes) {
        return Err(crate::RelumeError::invalid(
            "passes",
            format!("{passes} asked; a bake has 1…{MAX_PASSES} passes"),
        ));
    }
    let counts = doubling_passes(settings.spp, passes);
    let mut file_bytes = 0;
    let mut write_seconds = 0.0;
    let mut stacks_written = 0;
    let (stack, report, passes) =
        bake_progressive_tiled(scene, settings, &counts, progress, |stack, _, pass| {
            let t = Instant::now();
            progress.set_stage(crate::progress::Stage::Writing);
            file_bytes = write_tiled_cancellable(path, stack, progress)?;
            write_seconds = t.elapsed().as_secs_f64();
            stacks_written += 1;
            on_written(pass, file_bytes);
            Ok(())
        })
        .map_err(|e| e.for_stack_file(path))?;
    Ok(BakedFile {
        stack,
        report,
        passes,
        file_bytes,
        write_seconds,
        stacks_written,
    })
}
