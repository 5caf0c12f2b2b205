//! One pixel's stack of partial records while its eye samples are traced, summed in the
//! canonical tree of [`super::blocks`], touching only the layers the samples reached.
//!
//! Why sparse: a record holds every layer of the bake, and a bake with editable materials
//! in a large basis has thousands of layers (a slot per basis function, light group, bounce
//! and region), of which one eye sample reaches a few dozen. Clearing and merging whole
//! records made the bake's bookkeeping cost more than its rays. Each record therefore keeps
//! the list of layers it holds (with a bit per layer, so a layer is listed once), a free
//! record is all zeros, and a merge adds, and then clears, only the listed layers.
//!
//! The bits are those of the dense sums: a layer a record does not list holds +0.0, adding
//! +0.0 to a sum changes no bit (no sum is ever −0.0: [`super::blocks`]), and every listed
//! layer is added by the same operation, in the same tree, as before.

use std::ops::Range;

use super::blocks::siblings;
use crate::bake::finish::denoise::{EyeFeatures, FEATURE_STRIDE};
use crate::{Result, Rgb};

/// The leaf of the eye sample being traced: its layer sums (RGB per layer) and its
/// features, as the integrator's sink fills them.
pub struct Leaf<'a> {
    values: &'a mut [f32],
    marks: &'a mut [u64],
    touched: &'a mut Vec<u32>,
    /// The pixel's eye-hit record for the denoiser ([`EyeFeatures`]).
    pub features: &'a mut [f32],
}

impl Leaf<'_> {
    /// Adds `v` to layer `layer`.
    #[inline]
    pub fn add(&mut self, layer: usize, v: Rgb) {
        mark(self.marks, self.touched, layer as u32);
        let i = layer * 3;
        self.values[i] += v.x;
        self.values[i + 1] += v.y;
        self.values[i + 2] += v.z;
    }
}

/// Lists `layer` in a record unless its bit says it is listed already.
#[inline]
fn mark(marks: &mut [u64], touched: &mut Vec<u32>, layer: u32) {
    let (word, bit) = ((layer / 64) as usize, 1u64 << (layer % 64));
    if marks[word] & bit == 0 {
        marks[word] |= bit;
        touched.push(layer);
    }
}

/// The per-pixel stack: push a leaf per sample, fill it, [`PixelTree::close_leaf`]; the
/// stack then holds the blocks of [`super::blocks::dyadic_blocks`] for the samples pushed.
pub struct PixelTree {
    /// Floats per record: the layer sums, then [`FEATURE_STRIDE`] features.
    record: usize,
    layer_floats: usize,
    /// u64 words of one record's layer bits.
    words: usize,
    buf: Vec<f32>,
    marks: Vec<u64>,
    /// The layers each record holds, in the order they were first reached.
    touched: Vec<Vec<u32>>,
    nodes: Vec<Range<u32>>,
}

impl PixelTree {
    /// For records of `layers` layers.
    pub fn new(layers: usize) -> Result<PixelTree> {
        let record = layers * 3 + FEATURE_STRIDE;
        let words = layers.div_ceil(64).max(1);
        let slots = 8;
        Ok(PixelTree {
            record,
            layer_floats: layers * 3,
            words,
            buf: crate::memory::try_zeroed(record * slots, "a pixel's sample tree")?,
            marks: crate::memory::try_zeroed(words * slots, "a pixel's sample tree")?,
            touched: (0..slots).map(|_| Vec::new()).collect(),
            nodes: Vec::with_capacity(64),
        })
    }

    /// Empties the stack for the next pixel (its records back to zeros).
    pub fn clear(&mut self) {
        for k in 0..self.nodes.len() {
            self.clear_slot(k);
        }
        self.nodes.clear();
    }

    /// Zeroes the listed layers and bits of record `k`. A word of bits is cleared whole:
    /// every bit set in it belongs to a listed layer, all of which are cleared here.
    fn clear_slot(&mut self, k: usize) {
        let values = &mut self.buf[k * self.record..k * self.record + self.layer_floats];
        let marks = &mut self.marks[k * self.words..(k + 1) * self.words];
        for &layer in &self.touched[k] {
            let i = layer as usize * 3;
            values[i..i + 3].fill(0.0);
            marks[layer as usize / 64] = 0;
        }
        self.touched[k].clear();
    }

    /// Starts the leaf of eye sample `sample` (all zeros, features empty) for the
    /// integrator's sink.
    pub fn push_leaf(&mut self, sample: u32) -> Leaf<'_> {
        let k = self.nodes.len();
        if self.touched.len() <= k {
            let slots = k + 2;
            self.buf.resize(slots * self.record, 0.0);
            self.marks.resize(slots * self.words, 0);
            self.touched.resize_with(slots, Vec::new);
        }
        self.nodes.push(sample..sample + 1);
        let rec = &mut self.buf[k * self.record..(k + 1) * self.record];
        let (values, features) = rec.split_at_mut(self.layer_floats);
        features.copy_from_slice(&EyeFeatures::EMPTY);
        Leaf {
            values,
            marks: &mut self.marks[k * self.words..(k + 1) * self.words],
            touched: &mut self.touched[k],
            features,
        }
    }

    /// Adds record `k` into record `k − 1` (their listed layers, and the features) and
    /// leaves record `k` all zeros.
    fn merge_into_left(&mut self, k: usize) {
        let right_touched = std::mem::take(&mut self.touched[k]);
        let (head, tail) = self.buf.split_at_mut(k * self.record);
        let left = &mut head[(k - 1) * self.record..];
        let right = &mut tail[..self.record];
        let (left_marks, right_marks) = self.marks.split_at_mut(k * self.words);
        let left_marks = &mut left_marks[(k - 1) * self.words..];
        let right_marks = &mut right_marks[..self.words];
        let left_touched = &mut self.touched[k - 1];
        for &layer in &right_touched {
            let i = layer as usize * 3;
            for c in i..i + 3 {
                left[c] += right[c];
                right[c] = 0.0;
            }
            right_marks[layer as usize / 64] = 0; // whole words: as in `clear_slot`
            mark(left_marks, left_touched, layer);
        }
        EyeFeatures::merge(&mut left[self.layer_floats..], &right[self.layer_floats..]);
        self.touched[k] = right_touched;
        self.touched[k].clear();
    }

    /// Ends the current leaf: merges it with its completed siblings up the tree.
    pub fn close_leaf(&mut self) {
        while self.nodes.len() >= 2 {
            let k = self.nodes.len() - 1;
            if !siblings(&self.nodes[k - 1], &self.nodes[k]) {
                break;
            }
            self.merge_into_left(k);
            let right = self.nodes.pop().expect("two nodes");
            self.nodes[k - 1].end = right.end;
        }
    }

    /// The blocks on the stack, in sample order.
    pub fn blocks(&self) -> &[Range<u32>] {
        &self.nodes
    }

    /// Record of block `k` of [`Self::blocks`], dense: layer sums (zero where no sample
    /// reached), then features.
    pub fn record(&self, k: usize) -> &[f32] {
        &self.buf[k * self.record..(k + 1) * self.record]
    }

    /// The layers block `k`'s record holds (every other layer of it is zero), unordered.
    pub fn touched(&self, k: usize) -> &[u32] {
        &self.touched[k]
    }

    /// Copies record `k` into `out` (one record's length, all zeros): its listed layers and
    /// its features.
    pub fn copy_record_into_zeros(&self, k: usize, out: &mut [f32]) {
        let rec = self.record(k);
        for &layer in self.touched(k) {
            let i = layer as usize * 3;
            out[i..i + 3].copy_from_slice(&rec[i..i + 3]);
        }
        out[self.layer_floats..].copy_from_slice(&rec[self.layer_floats..]);
    }

    /// Folds the stack from the right into block 0 (`b₀ + (b₁ + (…))`): the tree's root when
    /// the samples pushed are `[0, spp)`. Returns the record.
    pub fn fold(&mut self) -> &[f32] {
        for k in (1..self.nodes.len()).rev() {
            self.merge_into_left(k);
        }
        if let Some(last) = self.nodes.last().map(|r| r.end) {
            self.nodes.truncate(1);
            self.nodes[0].end = last;
        }
        self.record(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::schedule::blocks::combine;

    /// Per-sample, per-layer values whose sums round differently in other groupings; many
    /// layers are never reached by a sample.
    fn value(s: u32, layer: usize) -> f32 {
        let h = (s.wrapping_mul(2_654_435_761) ^ (layer as u32).wrapping_mul(40_503)) >> 8;
        if h.is_multiple_of(5) {
            0.0
        } else {
            (h % 9973) as f32 * 1.0e-3 * 10f32.powi((h % 7) as i32 - 3)
        }
    }

    /// The dense tree it replaces: every record whole, combined whole.
    fn dense(samples: Range<u32>, layers: usize, fold: bool) -> Vec<Vec<f32>> {
        let record = layers * 3 + FEATURE_STRIDE;
        let mut stack: Vec<(Range<u32>, Vec<f32>)> = Vec::new();
        for s in samples {
            let mut rec = vec![0.0f32; record];
            rec[layers * 3..].copy_from_slice(&EyeFeatures::EMPTY);
            for l in (0..layers).filter(|l| (s as usize + l).is_multiple_of(3)) {
                rec[l * 3] += value(s, l);
                rec[l * 3 + 2] += value(s + 1, l);
            }
            stack.push((s..s + 1, rec));
            while stack.len() >= 2 && siblings(&stack[stack.len() - 2].0, &stack[stack.len() - 1].0)
            {
                let (r, right) = stack.pop().unwrap();
                let left = stack.last_mut().unwrap();
                combine(&mut left.1, &right, layers * 3);
                left.0.end = r.end;
            }
        }
        if fold {
            while stack.len() >= 2 {
                let (_, right) = stack.pop().unwrap();
                let left = stack.last_mut().unwrap();
                combine(&mut left.1, &right, layers * 3);
            }
        }
        stack.into_iter().map(|(_, r)| r).collect()
    }

    /// The sparse tree gives the dense tree's records bit for bit, for several pixels in a
    /// row (each pixel's records start from zeros), folded or not.
    #[test]
    fn sparse_records_equal_the_dense_ones_bit_for_bit() {
        let layers = 150;
        let mut tree = PixelTree::new(layers).unwrap();
        for (samples, fold) in [
            (0..37u32, true),
            (5..29, false),
            (0..1, true),
            (3..64, false),
        ] {
            tree.clear();
            for s in samples.clone() {
                let mut leaf = tree.push_leaf(s);
                for l in (0..layers).filter(|l| (s as usize + l).is_multiple_of(3)) {
                    leaf.add(l, Rgb::new(value(s, l), 0.0, value(s + 1, l)));
                }
                tree.close_leaf();
            }
            if fold {
                tree.fold();
            }
            let want = dense(samples.clone(), layers, fold);
            assert_eq!(tree.blocks().len(), want.len());
            for (k, w) in want.iter().enumerate() {
                let got: Vec<u32> = tree.record(k).iter().map(|x| x.to_bits()).collect();
                let w: Vec<u32> = w.iter().map(|x| x.to_bits()).collect();
                assert_eq!(got, w, "{samples:?} block {k}");
                let mut out = vec![0.0f32; layers * 3 + FEATURE_STRIDE];
                tree.copy_record_into_zeros(k, &mut out);
                assert_eq!(out.iter().map(|x| x.to_bits()).collect::<Vec<_>>(), w);
            }
        }
    }
}
