//! The pivoted Cholesky factor of a symmetric positive semi-definite matrix.

/// Pivoted Cholesky `G ≈ R Rᵀ` of a symmetric PSD `l×l` matrix (row-major), stopped once the
/// largest remaining diagonal is below 1e-15 of the trace: the columns of R, each of length
/// l. Families of smooth functions (lobes, profiles) have Gram matrices of low numerical
/// rank, so R has far fewer columns than `l` and every later step works on that rank.
/// Pivoting on the largest remaining diagonal keeps the factor stable without a threshold
/// tuned per matrix.
pub fn pivoted_cholesky(g: &[f64], l: usize) -> Vec<Vec<f64>> {
    let trace: f64 = (0..l).map(|j| g[j * l + j]).sum();
    let mut diag: Vec<f64> = (0..l).map(|j| g[j * l + j]).collect();
    let mut cols: Vec<Vec<f64>> = vec![];
    let mut used = vec![false; l];
    while cols.len() < l {
        let Some((p, dp)) = diag
            .iter()
            .enumerate()
            .filter(|(j, _)| !used[*j])
            .map(|(j, &d)| (j, d))
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            break;
        };
        if !(dp > 1e-15 * trace) {
            break;
        }
        used[p] = true;
        let sq = dp.sqrt();
        let mut col: Vec<f64> = (0..l).map(|i| g[i * l + p]).collect();
        for c in &cols {
            let cp = c[p];
            for i in 0..l {
                col[i] -= c[i] * cp;
            }
        }
        for (i, x) in col.iter_mut().enumerate() {
            *x /= sq;
            diag[i] -= *x * *x;
        }
        cols.push(col);
    }
    cols
}
