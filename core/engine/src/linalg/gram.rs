//! Gram matrices `G = Σ_q w_q f_q f_qᵀ` of sampled functions.

/// Accumulates `G = Σ_q w_q f_q f_qᵀ` (`l×l`, row-major) one sample `f_q` at a time, so a
/// caller that generates its samples on the fly (the subsurface profiles) never holds them
/// all. Only the lower triangle is summed; [`Self::finish`] mirrors it, which keeps `G`
/// exactly symmetric.
///
/// Samples are added [`BLOCK`] at a time: a row of `G` is updated by every sample of the
/// block while it is in the L1 cache, instead of the whole triangle (larger than the L2
/// cache for the Principled basis' lobes) going through memory once per sample. Each element
/// still gets its samples' products in sample order, each a multiply and an add (never
/// fused), so the sum is the same bit for bit as one sample at a time, on every CPU.
pub struct GramAccumulator {
    l: usize,
    g: Vec<f64>,
    /// The block's samples: `w·f` and `f`, sample-major.
    weighted: Vec<f64>,
    samples: Vec<f64>,
}

/// Samples per pass over the triangle.
const BLOCK: usize = 16;
/// Elements of a row summed in registers at a time: eight 512-bit vectors, enough
/// independent sums to keep the adds' latency hidden (four on AVX2, whose sixteen registers
/// then spill a little).
const CHUNK: usize = 64;

impl GramAccumulator {
    /// An empty `l×l` sum.
    pub fn new(l: usize) -> GramAccumulator {
        GramAccumulator {
            l,
            g: vec![0.0; l * l],
            weighted: Vec::with_capacity(BLOCK * l),
            samples: Vec::with_capacity(BLOCK * l),
        }
    }

    /// Adds `w·f fᵀ` (`f.len() == l`). Zero entries of `w·f` are skipped: sampled lobes and
    /// profiles are zero over much of their domain.
    ///
    /// # Panics
    /// If `f.len() != l`.
    pub fn add(&mut self, w: f64, f: &[f64]) {
        assert_eq!(f.len(), self.l, "Gram sample of {} values", self.l);
        self.weighted.extend(f.iter().map(|x| w * x));
        self.samples.extend_from_slice(f);
        if self.samples.len() == BLOCK * self.l {
            self.flush();
        }
    }

    /// Adds the block's samples into the triangle and empties the block, with the widest
    /// vectors the CPU has: the loop over a row is a multiply and an add per element, never
    /// fused, so every CPU gives the same bits.
    fn flush(&mut self) {
        #[cfg(target_arch = "x86_64")]
        {
            if is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F (checked just above).
                return unsafe { self.flush_avx512() };
            }
            if is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                return unsafe { self.flush_avx2() };
            }
        }
        self.flush_rows()
    }

    /// [`Self::flush`] compiled for AVX-512F (eight lanes per multiply and add).
    ///
    /// # Safety
    /// The CPU has AVX-512F.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn flush_avx512(&mut self) {
        self.flush_rows()
    }

    /// [`Self::flush`] compiled for AVX2 (four lanes per multiply and add).
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn flush_avx2(&mut self) {
        self.flush_rows()
    }

    /// The loops of [`Self::flush`], inlined into each compiled version: per row of the
    /// triangle, the block's samples that are not zero there, in order, added into
    /// [`CHUNK`] elements of the row at a time held in registers (one load and one store of
    /// the row per block, not per sample).
    #[inline(always)]
    fn flush_rows(&mut self) {
        let l = self.l;
        let count = self.samples.len() / l.max(1);
        let mut live = [0usize; BLOCK];
        for j in 0..l {
            let mut n = 0;
            for b in 0..count {
                if self.weighted[b * l + j] != 0.0 {
                    live[n] = b;
                    n += 1;
                }
            }
            if n == 0 {
                continue;
            }
            let live = &live[..n];
            let row = &mut self.g[j * l..j * l + j + 1];
            let mut chunks = row.chunks_exact_mut(CHUNK);
            let mut k0 = 0;
            for chunk in chunks.by_ref() {
                let mut acc = [0.0f64; CHUNK];
                acc.copy_from_slice(chunk);
                for &b in live {
                    let a = self.weighted[b * l + j];
                    let f = &self.samples[b * l + k0..b * l + k0 + CHUNK];
                    for i in 0..CHUNK {
                        acc[i] += a * f[i];
                    }
                }
                chunk.copy_from_slice(&acc);
                k0 += CHUNK;
            }
            let rest = chunks.into_remainder();
            for &b in live {
                let a = self.weighted[b * l + j];
                let f = &self.samples[b * l + k0..b * l + k0 + rest.len()];
                for (gk, &fk) in rest.iter_mut().zip(f) {
                    *gk += a * fk;
                }
            }
        }
        self.weighted.clear();
        self.samples.clear();
    }

    /// The full symmetric matrix.
    pub fn finish(mut self) -> Vec<f64> {
        self.flush();
        let l = self.l;
        for j in 0..l {
            for k in 0..j {
                self.g[k * l + j] = self.g[j * l + k];
            }
        }
        self.g
    }
}

/// `G = Fᵀ diag(w) F` for `F` stored sample-major (`F[q·l + j]` = function j at sample q).
pub fn gram_matrix(f: &[f64], w: &[f64], l: usize) -> Vec<f64> {
    let mut acc = GramAccumulator::new(l);
    for (q, &wq) in w.iter().enumerate() {
        acc.add(wq, &f[q * l..(q + 1) * l]);
    }
    acc.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sum one sample at a time, element by element: what the blocked, vectorised
    /// accumulator must equal bit for bit.
    fn one_at_a_time(samples: &[(f64, Vec<f64>)], l: usize) -> Vec<f64> {
        let mut g = vec![0.0; l * l];
        for (w, f) in samples {
            for j in 0..l {
                let a = w * f[j];
                if a == 0.0 {
                    continue;
                }
                for k in 0..=j {
                    g[j * l + k] += a * f[k];
                }
            }
        }
        for j in 0..l {
            for k in 0..j {
                g[k * l + j] = g[j * l + k];
            }
        }
        g
    }

    /// Samples with zeros (whole runs of them, as sampled lobes have), negative values, a
    /// zero weight and values of very different sizes, so that the order of the additions
    /// shows in the last bits.
    fn samples(count: usize, l: usize) -> Vec<(f64, Vec<f64>)> {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        (0..count)
            .map(|q| {
                let w = if q % 7 == 3 {
                    0.0
                } else {
                    (next() % 1000) as f64 / 997.0
                };
                let f = (0..l)
                    .map(|j| match next() % 5 {
                        0 | 1 if (j + q) % 3 != 0 => 0.0,
                        2 => -((next() % 10_000) as f64) * 1e-3,
                        _ => (next() % 10_000) as f64 * 10f64.powi((j % 9) as i32 - 4),
                    })
                    .collect();
                (w, f)
            })
            .collect()
    }

    #[test]
    fn blocked_sum_equals_one_sample_at_a_time_bit_for_bit() {
        for l in [1usize, 5, 16, 63, 64, 65, 130, 200] {
            for count in [0usize, 1, BLOCK - 1, BLOCK, BLOCK + 1, 3 * BLOCK + 5] {
                let s = samples(count, l);
                let mut acc = GramAccumulator::new(l);
                for (w, f) in &s {
                    acc.add(*w, f);
                }
                let got = acc.finish();
                let want = one_at_a_time(&s, l);
                let same = got
                    .iter()
                    .zip(&want)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same, "l {l}, {count} samples: the sums differ");
            }
        }
    }

    #[test]
    fn gram_matrix_of_two_functions() {
        // f0 = (1, 2), f1 = (3, 4) at two samples of weights 1 and 0.5.
        let f = [1.0, 3.0, 2.0, 4.0];
        let g = gram_matrix(&f, &[1.0, 0.5], 2);
        assert_eq!(
            g,
            vec![
                1.0 + 0.5 * 4.0,
                3.0 + 0.5 * 8.0,
                3.0 + 0.5 * 8.0,
                9.0 + 0.5 * 16.0
            ]
        );
    }
}
