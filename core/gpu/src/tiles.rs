//! Which tiles of each layer hold a non-zero sample, so the kernel skips the rest unread.
//!
//! A tile is the [`TILE_PIXELS`] consecutive pixels (row-major) of one workgroup, so the
//! skip is the same for every invocation of a workgroup and costs no divergence. Layers of
//! a path that starts at a region cover only that region's pixels, so the CPU relight reads
//! a fraction of the stack's bytes, and the tiles let the GPU skip about as much (its
//! granularity is 256 pixels, the CPU's a span per row). The masks cost one bit per tile
//! and layer.

use relume_engine::stack::{Layer, LayerSamples};

/// Pixels per tile: the workgroup size of `kernel.wgsl`.
pub const TILE_PIXELS: usize = 256;

/// Words of mask per layer for an image of `pixels` pixels.
pub fn mask_words(pixels: usize) -> usize {
    pixels.div_ceil(TILE_PIXELS).div_ceil(32).max(1)
}

/// Bit `t` of the mask is set when tile `t` of `layer` holds a non-zero sample (negative
/// zero counts as zero). Writes [`mask_words`] words into `out` and returns the number of
/// tiles set.
pub fn layer_mask(layer: &Layer, pixels: usize, out: &mut [u32]) -> usize {
    out.fill(0);
    let ch = layer.channels as usize;
    let mut set = 0;
    for t in 0..pixels.div_ceil(TILE_PIXELS) {
        let range = t * TILE_PIXELS * ch..((t + 1) * TILE_PIXELS).min(pixels) * ch;
        let any = match &layer.samples {
            LayerSamples::F16(v) => v[range].iter().any(|h| h.to_bits() & 0x7fff != 0),
            LayerSamples::F32(v) => v[range].iter().any(|&x| x != 0.0),
        };
        if any {
            out[t / 32] |= 1 << (t % 32);
            set += 1;
        }
    }
    set
}

#[cfg(test)]
mod tests {
    use super::*;
    use relume_engine::bake::signature::LayerKey;
    use relume_engine::stack::Precision;

    #[test]
    fn only_tiles_with_a_non_zero_sample_are_set() {
        // 40 tiles and a partial 41st: two mask words. RGB, so tile t spans samples
        // [768 t, 768 (t + 1)).
        let pixels = 40 * TILE_PIXELS + 7;
        let mut v = vec![0.0f32; pixels * 3];
        v[3 * TILE_PIXELS * 2 + 5] = 1.0; // tile 2, last channel of a pixel
        v[3 * TILE_PIXELS * 33] = -2.0; // first sample of tile 33
        v[pixels * 3 - 1] = 0.5; // the partial last tile, 40
        v[3 * TILE_PIXELS * 5] = -0.0; // negative zero is zero
        for precision in [Precision::F16, Precision::F32] {
            let layer = Layer::from_f32(LayerKey::new(vec![]), 3, &v, precision);
            let mut mask = vec![0u32; mask_words(pixels)];
            assert_eq!(mask.len(), 2);
            assert_eq!(layer_mask(&layer, pixels, &mut mask), 3, "{precision:?}");
            assert_eq!(mask, [1 << 2, (1 << 1) | (1 << 8)], "{precision:?}");
        }
    }
}
