//! Tiled, parallel, cancellable execution of per-pixel work. Each tile's result depends
//! only on its pixels, so the output is the same for any thread count.

use rayon::prelude::*;

use crate::progress::Progress;
use crate::scene::Resolution;
use crate::{RelumeError, Result};

/// Tile edge in pixels.
pub const TILE: u32 = 16;

/// A rectangle of pixels.
#[derive(Clone, Copy, Debug)]
pub struct Tile {
    pub index: usize,
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub height: u32,
}

impl Tile {
    /// Pixels in the tile.
    pub fn pixels(&self) -> usize {
        (self.width * self.height) as usize
    }
}

/// The tiles covering `res`, in raster order.
pub fn tiles(res: Resolution) -> Vec<Tile> {
    let mut out = Vec::new();
    for y0 in (0..res.height).step_by(TILE as usize) {
        for x0 in (0..res.width).step_by(TILE as usize) {
            out.push(Tile {
                index: out.len(),
                x0,
                y0,
                width: TILE.min(res.width - x0),
                height: TILE.min(res.height - y0),
            });
        }
    }
    out
}

/// Runs `work` on every tile in a pool of `threads` threads (0: all cores), advancing
/// `progress` by `weight` per tile (the caller has started it with the total) and stopping
/// with [`RelumeError::Cancelled`] when it is cancelled. `work` gets the tile and returns
/// `false` if it saw the cancel flag midway.
pub fn run_tiles<F>(
    res: Resolution,
    threads: usize,
    progress: &Progress,
    weight: u64,
    work: F,
) -> Result<()>
where
    F: Fn(&Tile) -> bool + Sync,
{
    let all = tiles(res);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| RelumeError::invalid("threads", e.to_string()))?;
    pool.install(|| {
        all.par_iter().for_each(|tile| {
            if progress.is_cancelled() {
                return;
            }
            if work(tile) {
                progress.advance(weight);
            }
        })
    });
    if progress.is_cancelled() {
        return Err(RelumeError::Cancelled);
    }
    Ok(())
}
