//! How the streaming bake ([`super::stream`]) walks the frame: the tile rows its denoiser
//! reads around the row it finalises, and how many rows it traces at once. Shared with the
//! memory forecast ([`super::estimate`]).

use super::denoise::footprint_radius;
use super::settings::Denoise;
use super::tiles::TILE;
use crate::stack::tiled::tiles_along;

/// Tile rows the denoiser needs on each side of the row it finalises (0: no denoising).
pub fn apron_rows(denoise: &Denoise) -> usize {
    let iterations = denoise.direct_iterations.max(denoise.bounce_iterations);
    if iterations == 0 {
        0
    } else {
        footprint_radius(iterations).div_ceil(TILE as usize)
    }
}

/// Tile rows a band traces at once when the caller does not say: enough tiles to keep
/// `threads` busy.
pub fn default_band_rows(width: u32, threads: usize) -> usize {
    let threads = if threads == 0 {
        rayon::current_num_threads()
    } else {
        threads
    };
    (2 * threads)
        .div_ceil(tiles_along(width).max(1) as usize)
        .max(1)
}
