//! Solving a small symmetric positive definite system in place: the unpivoted Cholesky
//! factor and its two triangular solves, for the lattice fits' normal equations (full
//! rank by their ridge, so no pivoting is needed; a pivot that rounding leaves below a
//! floor is raised to it, so a nearly singular system still gives finite coefficients).

/// In-place lower Cholesky factor of the symmetric positive definite `n × n` matrix `m`
/// (row-major); a pivot below `pivot_floor` (rounding on a singular matrix) is raised to it
/// so the solve stays finite.
pub fn cholesky_in_place(m: &mut [f64], n: usize, pivot_floor: f64) {
    for j in 0..n {
        let mut d = m[j * n + j];
        for k in 0..j {
            d -= m[j * n + k] * m[j * n + k];
        }
        let d = d.max(pivot_floor).sqrt();
        m[j * n + j] = d;
        for i in j + 1..n {
            let mut v = m[i * n + j];
            for k in 0..j {
                v -= m[i * n + k] * m[j * n + k];
            }
            m[i * n + j] = v / d;
        }
        for i in 0..j {
            m[i * n + j] = 0.0;
        }
    }
}

/// Solves `L Lᵀ x = b` in place for the factor `l` of [`cholesky_in_place`].
pub fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut v = b[i];
        for k in 0..i {
            v -= l[i * n + k] * b[k];
        }
        b[i] = v / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut v = b[i];
        for k in i + 1..n {
            v -= l[k * n + i] * b[k];
        }
        b[i] = v / l[i * n + i];
    }
}
