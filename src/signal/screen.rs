//! Pearson correlation screening of components (Chen et al. 2024 §2.2, eqs. 2 and 18).

/// Pearson correlation coefficient r of two equally long series (Chen et al. 2024 eq. 2). Returns 0
/// when either series is constant (r is undefined there; a constant component carries no
/// correlated variation) or the lengths differ.
pub fn pearson(a: &[f64], b: &[f64]) -> f64 {
    if a.len() != b.len() || a.is_empty() {
        return 0.0;
    }
    let n = a.len() as f64;
    let ma = a.iter().sum::<f64>() / n;
    let mb = b.iter().sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        let (dx, dy) = (x - ma, y - mb);
        sab += dx * dy;
        saa += dx * dx;
        sbb += dy * dy;
    }
    if saa <= 0.0 || sbb <= 0.0 {
        return 0.0;
    }
    sab / (saa.sqrt() * sbb.sqrt())
}

/// Screens components against a reference: r_i = pearson(component_i, reference) and
/// strong_i = |r_i| > threshold (Chen et al. 2024: 0.3, Cohen's "weak correlation" bound).
pub fn screen(components: &[Vec<f64>], reference: &[f64], threshold: f64) -> (Vec<f64>, Vec<bool>) {
    let r: Vec<f64> = components.iter().map(|c| pearson(c, reference)).collect();
    let strong = r.iter().map(|v| v.abs() > threshold).collect();
    (r, strong)
}

/// Sum of the selected components (zeros of length `n` when none is selected).
pub fn sum_selected(components: &[Vec<f64>], select: &[bool], n: usize) -> Vec<f64> {
    let mut out = vec![0.0; n];
    for (c, &s) in components.iter().zip(select) {
        if s {
            for (o, v) in out.iter_mut().zip(c) {
                *o += v;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests;
