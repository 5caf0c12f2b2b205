//! How the streaming bake ([`super::stream`]) walks the frame: the tile rows its denoiser
//! reads around the row it finalises, and how many rows it traces at once. Shared with the
//! memory forecast ([`crate::bake::prepare::estimate`]).

use super::tiles::TILE;
use crate::bake::finish::denoise::footprint_radius;
use crate::bake::settings::Denoise;
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
/// `threads` busy, and at least twice the `apron` (the rows of a band are finalised on one
/// denoiser window, which reads `apron` more rows on each side).
pub fn default_band_rows(width: u32, threads: usize, apron: usize) -> usize {
    let threads = if threads == 0 {
        rayon::current_num_threads()
    } else {
        threads
    };
    (2 * threads)
        .div_ceil(tiles_along(width).max(1) as usize)
        .max(2 * apron)
        .max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_apron_covers_the_larger_filter_footprint() {
        let apron = |direct, bounce| {
            apron_rows(&Denoise {
                direct_iterations: direct,
                bounce_iterations: bounce,
            })
        };
        assert_eq!(apron(0, 0), 0);
        // Footprint radii 2·(2^k − 1): 2, 6, 14, 30, 62 pixels.
        assert_eq!(apron(1, 0), 1);
        assert_eq!(apron(1, 3), 1);
        assert_eq!(apron(4, 2), 2);
        assert_eq!(apron(1, 5), 4);
        assert!(default_band_rows(40, 3, 0) >= 2);
        assert_eq!(default_band_rows(1920, 8, 0), 1);
        assert_eq!(default_band_rows(1920, 8, 2), 4);
    }
}
