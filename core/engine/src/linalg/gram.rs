//! Gram matrices `G = Σ_q w_q f_q f_qᵀ` of sampled functions.

/// Accumulates `G = Σ_q w_q f_q f_qᵀ` (`l×l`, row-major) one sample `f_q` at a time, so a
/// caller that generates its samples on the fly (the subsurface profiles) never holds them
/// all. Only the lower triangle is summed; [`Self::finish`] mirrors it, which keeps `G`
/// exactly symmetric.
pub struct GramAccumulator {
    l: usize,
    g: Vec<f64>,
    row: Vec<f64>,
}

impl GramAccumulator {
    /// An empty `l×l` sum.
    pub fn new(l: usize) -> GramAccumulator {
        GramAccumulator {
            l,
            g: vec![0.0; l * l],
            row: vec![0.0; l],
        }
    }

    /// Adds `w·f fᵀ` (`f.len() == l`). Zero entries of `w·f` are skipped: sampled lobes and
    /// profiles are zero over much of their domain.
    pub fn add(&mut self, w: f64, f: &[f64]) {
        let l = self.l;
        for (r, &x) in self.row.iter_mut().zip(f) {
            *r = w * x;
        }
        for j in 0..l {
            let a = self.row[j];
            if a == 0.0 {
                continue;
            }
            let gj = &mut self.g[j * l..j * l + j + 1];
            for (gjk, &fk) in gj.iter_mut().zip(&f[..=j]) {
                *gjk += a * fk;
            }
        }
    }

    /// The full symmetric matrix.
    pub fn finish(mut self) -> Vec<f64> {
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
