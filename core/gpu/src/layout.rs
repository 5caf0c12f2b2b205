//! Where every layer lives on the GPU: which storage buffer ("chunk") and at which 32-bit
//! word, and how its samples are packed into words.
//!
//! **Packing.** f16 layers go up as they are stored, two halves per `u32` (low half first,
//! what WGSL's `unpack2x16float` reads as `.x`): the GPU converts them exactly as the CPU
//! does, so the two relights differ only by summation order (≈ 1e-6 relative). f32 layers
//! go up as f32 bits, one word per sample, *not* converted to f16: an f32 layer carries
//! scale 1 and any magnitude, so converting would need a new scale and would add up to
//! 2⁻¹² relative error per sample — on basis layers of both signs that cancel, enough to
//! break the 1e-3 agreement with the CPU. A stack baked in f32 costs twice the GPU memory,
//! as it does on the CPU.
//!
//! **Chunks.** A storage binding may not exceed the adapter's
//! `max_storage_buffer_binding_size` (128 MiB by default, the paper's 84 layers at 512² in
//! f16 are 74 MB), so layers are laid out greedily, whole, into chunks of at most that many
//! bytes; one layer is never split. [`CHUNKS_PER_GROUP`] chunks share one bind group; a
//! stack that needs more chunks gets one dispatch per group in the same compute pass.

use relume_engine::stack::{Layer, LayerSamples};

/// Chunk bindings in the shader (`chunk0` … `chunk3` in `kernel.wgsl`). With the image,
/// the layer list and the parameters that is 6 storage buffers per stage, within the
/// default limit of 8; four chunks of the default 128 MiB hold 512 MiB of layers (≈ 7× the
/// paper's stack) in one dispatch.
pub const CHUNKS_PER_GROUP: usize = 4;

/// Sample encoding of a layer on the GPU (the `format` field of an entry in the shader).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Two f16 per word, low half first.
    F16Pairs = 0,
    /// One f32 per word.
    F32 = 1,
}

/// One layer's place on the GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Placement {
    pub chunk: u32,
    /// First word of the layer in its chunk.
    pub offset_words: u32,
    pub words: u64,
    pub format: Format,
    /// 1 (grey) or 3 (RGB interleaved), as in the stack.
    pub channels: u32,
}

/// The layout of a whole stack.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layout {
    pub placements: Vec<Placement>,
    /// Words of each chunk.
    pub chunk_words: Vec<u64>,
}

impl Layout {
    /// Lays `layers` out in chunks of at most `max_chunk_bytes` (rounded down to whole
    /// words). Errors (as a message) if one layer alone is larger than a chunk, or if a
    /// chunk would hold more than 2³² words (offsets are u32 in the shader).
    pub fn new(layers: &[Layer], max_chunk_bytes: u64) -> Result<Layout, String> {
        let cap = (max_chunk_bytes / 4).min(1u64 << 32);
        let mut placements = Vec::with_capacity(layers.len());
        let mut chunk_words: Vec<u64> = Vec::new();
        for layer in layers {
            let (format, words) = match &layer.samples {
                LayerSamples::F16(v) => (Format::F16Pairs, v.len().div_ceil(2) as u64),
                LayerSamples::F32(v) => (Format::F32, v.len() as u64),
            };
            if words > cap {
                return Err(format!(
                    "layer {} needs {} bytes on the GPU, more than one storage binding may hold \
                     ({} bytes, the adapter's max_storage_buffer_binding_size)",
                    layer.key.layer_name(),
                    words * 4,
                    cap * 4
                ));
            }
            let n_chunks = chunk_words.len();
            match chunk_words.last_mut() {
                Some(used) if *used + words <= cap => {
                    placements.push(Placement {
                        chunk: (n_chunks - 1) as u32,
                        offset_words: *used as u32,
                        words,
                        format,
                        channels: layer.channels,
                    });
                    *used += words;
                }
                _ => {
                    placements.push(Placement {
                        chunk: chunk_words.len() as u32,
                        offset_words: 0,
                        words,
                        format,
                        channels: layer.channels,
                    });
                    chunk_words.push(words);
                }
            }
        }
        Ok(Layout {
            placements,
            chunk_words,
        })
    }

    /// Bind groups needed: one per [`CHUNKS_PER_GROUP`] chunks, at least one.
    pub fn groups(&self) -> usize {
        self.chunk_words.len().div_ceil(CHUNKS_PER_GROUP).max(1)
    }

    /// Total bytes of layer data on the GPU.
    pub fn bytes(&self) -> u64 {
        self.chunk_words.iter().sum::<u64>() * 4
    }
}

/// Writes `layer`'s samples as words (little-endian bytes) into `out`, which is exactly
/// the layer's words long. Returns the index of the first non-finite sample, if any (the
/// CPU relighter refuses such a layer too).
pub fn pack_layer(layer: &Layer, out: &mut [u8]) -> Result<(), usize> {
    match &layer.samples {
        LayerSamples::F16(v) => {
            for (k, (pair, dst)) in v.chunks(2).zip(out.chunks_exact_mut(4)).enumerate() {
                let lo = pair[0].to_bits();
                let hi = pair.get(1).map_or(0, |h| h.to_bits());
                for (j, h) in [lo, hi].into_iter().enumerate() {
                    if h & 0x7c00 == 0x7c00 && 2 * k + j < v.len() {
                        return Err(2 * k + j);
                    }
                }
                dst.copy_from_slice(&(u32::from(lo) | u32::from(hi) << 16).to_le_bytes());
            }
        }
        LayerSamples::F32(v) => {
            for (i, (x, dst)) in v.iter().zip(out.chunks_exact_mut(4)).enumerate() {
                if !x.is_finite() {
                    return Err(i);
                }
                dst.copy_from_slice(&x.to_le_bytes());
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use relume_engine::bake::signature::LayerKey;
    use relume_engine::stack::Precision;

    fn layer(n: usize, precision: Precision) -> Layer {
        let v: Vec<f32> = (0..n).map(|i| i as f32 - 2.5).collect();
        Layer::from_f32(LayerKey::new(vec![]), 1, &v, precision)
    }

    #[test]
    fn layers_fill_chunks_whole_and_in_order() {
        // 5 halves → 3 words, 4 f32 → 4 words: a 10-word chunk takes the first three
        // layers exactly (3 + 4 + 3), and the fourth opens chunk 1.
        let layers = [
            layer(5, Precision::F16),
            layer(4, Precision::F32),
            layer(5, Precision::F16),
            layer(4, Precision::F32),
        ];
        let l = Layout::new(&layers, 40).unwrap();
        let got: Vec<(u32, u32, u64)> = l
            .placements
            .iter()
            .map(|p| (p.chunk, p.offset_words, p.words))
            .collect();
        assert_eq!(got, [(0, 0, 3), (0, 3, 4), (0, 7, 3), (1, 0, 4)]);
        assert_eq!(l.chunk_words, [10, 4]);
        assert_eq!((l.groups(), l.bytes()), (1, 56));
        // A chunk smaller than one layer is refused with the layer's name.
        let e = Layout::new(&layers, 12).unwrap_err();
        assert!(
            e.contains("World") && e.contains("max_storage_buffer_binding_size"),
            "{e}"
        );
    }

    #[test]
    fn f16_pairs_pack_low_half_first_and_pad_the_tail() {
        let l = layer(3, Precision::F16);
        let mut out = vec![0xffu8; 8];
        pack_layer(&l, &mut out).unwrap();
        let LayerSamples::F16(v) = &l.samples else {
            unreachable!("built as f16")
        };
        let w0 = u32::from_le_bytes(out[0..4].try_into().unwrap());
        let w1 = u32::from_le_bytes(out[4..8].try_into().unwrap());
        assert_eq!(w0 & 0xffff, u32::from(v[0].to_bits()));
        assert_eq!(w0 >> 16, u32::from(v[1].to_bits()));
        assert_eq!(w1, u32::from(v[2].to_bits()), "odd tail: high half zero");
    }

    #[test]
    fn non_finite_samples_are_found() {
        let mut l = layer(4, Precision::F32);
        if let LayerSamples::F32(v) = &mut l.samples {
            v[2] = f32::NAN;
        }
        assert_eq!(pack_layer(&l, &mut [0u8; 16]), Err(2));
        let mut h = layer(4, Precision::F16);
        if let LayerSamples::F16(v) = &mut h.samples {
            v[3] = half::f16::INFINITY;
        }
        assert_eq!(pack_layer(&h, &mut [0u8; 8]), Err(3));
    }
}
