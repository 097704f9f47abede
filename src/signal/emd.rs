//! Empirical mode decomposition (Huang et al. 1998) with cubic-spline envelopes, mirrored
//! extrema at both ends and the SD stopping criterion. Written here (no crate): the Rust
//! EMD crates lack end handling and a stopping rule we can state.

use super::error::{Error, check_signal};
use super::spline::CubicSpline;
use serde::{Deserialize, Serialize};

/// EMD parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EmdParams {
    /// Sifting stops when SD = Σ(h_{k-1} − h_k)² / Σ h_{k-1}² falls below this (Chen et al. 2024
    /// eq. 13, typically 0.2–0.3). Default 0.2.
    pub sd_threshold: f64,
    /// Cap on sifting iterations per IMF. Default 100.
    pub max_sift: usize,
    /// Cap on the number of IMFs (the residue is extra). Default ⌊log2 n⌋.
    pub max_imfs: Option<usize>,
    /// Extrema mirrored beyond each end for the envelopes. Default 2.
    pub mirrored_extrema: usize,
}

impl Default for EmdParams {
    fn default() -> Self {
        Self {
            sd_threshold: 0.2,
            max_sift: 100,
            max_imfs: None,
            mirrored_extrema: 2,
        }
    }
}

impl EmdParams {
    /// Checks ranges; the sentence names the parameter.
    pub fn validate(&self) -> Result<(), Error> {
        if !(self.sd_threshold.is_finite() && self.sd_threshold > 0.0 && self.sd_threshold < 1.0) {
            return Err(Error::BadParam {
                name: "sd_threshold",
                reason: "must be in (0, 1); Huang recommends 0.2..0.3".into(),
            });
        }
        if !(1..=10_000).contains(&self.max_sift) {
            return Err(Error::BadParam {
                name: "max_sift",
                reason: "must be between 1 and 10000".into(),
            });
        }
        if !(1..=8).contains(&self.mirrored_extrema) {
            return Err(Error::BadParam {
                name: "mirrored_extrema",
                reason: "must be between 1 and 8".into(),
            });
        }
        Ok(())
    }
}

/// Output of [`emd`]: IMFs from the highest frequency down, then the residue (trend);
/// Σ imfs + residue == x exactly.
#[derive(Clone, Debug, Serialize)]
pub struct EmdResult {
    /// Intrinsic mode functions, highest frequency first, each as long as the input.
    pub imfs: Vec<Vec<f64>>,
    /// What is left after the last IMF (the trend), in the input's unit.
    pub residue: Vec<f64>,
    /// Sifting iterations used per IMF.
    pub sifts: Vec<usize>,
}

/// Extrema as (position, value) pairs.
type Points = Vec<(f64, f64)>;

/// Local maxima and minima (positions, values); a plateau counts once at its middle.
fn extrema(h: &[f64]) -> (Points, Points) {
    let (mut maxs, mut mins) = (Vec::new(), Vec::new());
    extrema_into(h, &mut maxs, &mut mins);
    (maxs, mins)
}

/// [`extrema`] into reused vectors. Fast path: when no two neighbours are equal there is no
/// plateau, and an extremum is a sample above (below) both neighbours, at its own index;
/// otherwise the plateau-aware scan ([`reference_extrema`]). Same points either way
/// (`extrema_fast_path_matches_reference`).
fn extrema_into(h: &[f64], maxs: &mut Points, mins: &mut Points) {
    maxs.clear();
    mins.clear();
    let n = h.len();
    if n < 3 {
        return;
    }
    if h[0] != h[1] {
        let mut i = 1;
        while i + 1 < n {
            // Skip 8 samples at a time where h runs strictly up or down through each.
            if i + 9 <= n && !any_turn(&h[i - 1..i + 9]) {
                i += 8;
                continue;
            }
            let (a, b, c) = (h[i - 1], h[i], h[i + 1]);
            if b == c {
                break;
            }
            if b > a && b > c {
                maxs.push((i as f64, b));
            } else if b < a && b < c {
                mins.push((i as f64, b));
            }
            i += 1;
        }
        if i + 1 >= n {
            return;
        }
        maxs.clear();
        mins.clear();
    }
    reference_extrema(h, maxs, mins);
}

/// Whether any of the 8 interior samples of `w` (10 samples) is not strictly between its
/// neighbours (an extremum, or equal to a neighbour). Branch-free, so the compiler
/// vectorises it.
#[inline(always)]
fn any_turn(w: &[f64]) -> bool {
    let w: &[f64; 10] = w.try_into().expect("10 samples");
    let mut any = false;
    for q in 1..9 {
        let (a, b, c) = (w[q - 1], w[q], w[q + 1]);
        any |= ((b > a) == (b > c)) | (b == a) | (b == c);
    }
    any
}

/// Local maxima and minima of `h` with plateaus (runs of equal samples) counted once at
/// their middle: the slow scan that [`extrema_into`]'s fast path must agree with.
fn reference_extrema(h: &[f64], maxs: &mut Points, mins: &mut Points) {
    let n = h.len();
    let mut i = 1;
    while i + 1 < n {
        if h[i] == h[i - 1] {
            i += 1;
            continue;
        }
        // Extend over a plateau.
        let mut j = i;
        while j + 1 < n && h[j + 1] == h[i] {
            j += 1;
        }
        if j + 1 >= n {
            break;
        }
        let mid = (i + j) as f64 / 2.0;
        if h[i] > h[i - 1] && h[i] > h[j + 1] {
            maxs.push((mid, h[i]));
        } else if h[i] < h[i - 1] && h[i] < h[j + 1] {
            mins.push((mid, h[i]));
        }
        i = j + 1;
    }
}

/// Zero crossings of `h`: neighbours of opposite sign, or a zero followed by a non-zero.
fn zero_crossings(h: &[f64]) -> usize {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports the feature the function is compiled for.
        return unsafe { zero_crossings_avx2(h) };
    }
    zero_crossings_portable(h)
}

/// [`zero_crossings`], the loop.
#[inline(always)]
fn zero_crossings_portable(h: &[f64]) -> usize {
    h.windows(2)
        .map(|w| usize::from((w[0] * w[1] < 0.0) | ((w[0] == 0.0) & (w[1] != 0.0))))
        .sum()
}

/// [`zero_crossings_portable`] compiled for AVX2 (4 pairs per instruction).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn zero_crossings_avx2(h: &[f64]) -> usize {
    zero_crossings_portable(h)
}

/// One sift: h ← h − m with m = (e_max + e_min)/2 at every sample, in place; returns
/// (Σ m², Σ h²) (h before the step) for SD = Σ m² / Σ h² (Chen et al. 2024 eq. 13).
///
/// The sums are four interleaved partial sums (sample i in lane i mod 4, the tail in lane 0,
/// added lane 0 first), so that the loop runs 4 samples per AVX2 instruction instead of
/// waiting on one addition per sample; SD differs from the sample-order sum by rounding
/// only, and only decides when sifting stops (`emd_matches_reference_bit_for_bit`: the same
/// IMFs as the sample-order sums).
fn sift_step(h: &mut [f64], upper: &[f64], lower: &[f64]) -> (f64, f64) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports the feature the function is compiled for.
        return unsafe { sift_step_avx2(h, upper, lower) };
    }
    sift_step_portable(h, upper, lower)
}

/// [`sift_step`], the loop (the same operations on any path, so the same bits).
#[inline(always)]
fn sift_step_portable(h: &mut [f64], upper: &[f64], lower: &[f64]) -> (f64, f64) {
    let n = h.len().min(upper.len()).min(lower.len());
    let full = n / 4 * 4;
    let (mut num, mut den) = ([0.0f64; 4], [0.0f64; 4]);
    for ((hc, uc), lc) in h[..full]
        .chunks_exact_mut(4)
        .zip(upper[..full].chunks_exact(4))
        .zip(lower[..full].chunks_exact(4))
    {
        for l in 0..4 {
            let mean = 0.5 * (uc[l] + lc[l]);
            num[l] += mean * mean;
            den[l] += hc[l] * hc[l];
            hc[l] -= mean;
        }
    }
    for i in full..n {
        let mean = 0.5 * (upper[i] + lower[i]);
        num[0] += mean * mean;
        den[0] += h[i] * h[i];
        h[i] -= mean;
    }
    (
        num[0] + num[1] + num[2] + num[3],
        den[0] + den[1] + den[2] + den[3],
    )
}

/// [`sift_step_portable`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn sift_step_avx2(h: &mut [f64], upper: &[f64], lower: &[f64]) -> (f64, f64) {
    sift_step_portable(h, upper, lower)
}

/// Reflects up to `k` points of `pts` (taken from `from`) about `axis`.
fn reflect(pts: &[(f64, f64)], from: usize, k: usize, axis: f64) -> Vec<(f64, f64)> {
    pts.iter()
        .skip(from)
        .take(k)
        .map(|&(t, v)| (2.0 * axis - t, v))
        .collect()
}

/// Mirrored extrema at the left end (Rilling, Flandrin & Gonçalves 2003): mirror about the
/// first extremum when the signal starts inside the first swing, else about the first sample,
/// which then counts as an extremum of the opposite kind.
fn left_mirror(x0: f64, maxs: &[(f64, f64)], mins: &[(f64, f64)], k: usize) -> (Points, Points) {
    let first_is_max = maxs[0].0 < mins[0].0;
    let (lmax, lmin) = if first_is_max {
        if x0 > mins[0].1 {
            let a = maxs[0].0;
            (reflect(maxs, 1, k, a), reflect(mins, 0, k, a))
        } else {
            let mut lmin = reflect(mins, 0, k.saturating_sub(1), 0.0);
            lmin.insert(0, (0.0, x0));
            (reflect(maxs, 0, k, 0.0), lmin)
        }
    } else if x0 < maxs[0].1 {
        let a = mins[0].0;
        (reflect(maxs, 0, k, a), reflect(mins, 1, k, a))
    } else {
        let mut lmax = reflect(maxs, 0, k.saturating_sub(1), 0.0);
        lmax.insert(0, (0.0, x0));
        (lmax, reflect(mins, 0, k, 0.0))
    };
    // Ascending order, and strictly left of the real extrema.
    let fix = |mut v: Vec<(f64, f64)>, first: f64| {
        v.retain(|p| p.0 < first);
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        v.dedup_by(|a, b| a.0 == b.0);
        v
    };
    (fix(lmax, maxs[0].0), fix(lmin, mins[0].0))
}

/// Upper and lower spline envelopes at every sample, written into `upper_out` and
/// `lower_out` (each as long as `h`), with mirrored extrema at both ends; returns how many
/// envelope knots have the wrong sign for an IMF (maxima ≤ 0, minima ≥ 0), or `None` when
/// there are too few extrema or a spline cannot be built.
/// `maxs`, `mins`: the extrema of `h` ([`extrema`]).
fn envelopes(
    h: &[f64],
    maxs: &[(f64, f64)],
    mins: &[(f64, f64)],
    k: usize,
    upper_out: &mut [f64],
    lower_out: &mut [f64],
) -> Option<usize> {
    let n = h.len();
    if maxs.len() < 2 || mins.len() < 2 {
        return None;
    }
    let (lmax, lmin) = left_mirror(h[0], maxs, mins, k);
    // The right end is the left end of the reversed signal.
    let rev = |v: &[(f64, f64)]| -> Vec<(f64, f64)> {
        v.iter()
            .rev()
            .map(|&(t, y)| ((n - 1) as f64 - t, y))
            .collect()
    };
    let (rmax_r, rmin_r) = left_mirror(h[n - 1], &rev(maxs), &rev(mins), k);
    let mut upper: Vec<(f64, f64)> = lmax;
    upper.extend_from_slice(maxs);
    upper.extend(rev(&rmax_r));
    let mut lower: Vec<(f64, f64)> = lmin;
    lower.extend_from_slice(mins);
    lower.extend(rev(&rmin_r));
    let build = |pts: &[(f64, f64)], out: &mut [f64]| -> Option<()> {
        let xs: Vec<f64> = pts.iter().map(|p| p.0).collect();
        let ys: Vec<f64> = pts.iter().map(|p| p.1).collect();
        CubicSpline::not_a_knot(&xs, &ys)
            .ok()
            .map(|s| s.eval_samples_into(out))
    };
    let wrong =
        upper.iter().filter(|p| p.1 <= 0.0).count() + lower.iter().filter(|p| p.1 >= 0.0).count();
    build(&upper, upper_out)?;
    build(&lower, lower_out)?;
    Some(wrong)
}

/// Empirical mode decomposition of `x` into IMFs and a residue.
///
/// Formula (Chen et al. 2024 eqs. 9–16): sift h ← h − (e_max + e_min)/2 with not-a-knot cubic
/// envelopes through the extrema (mirrored at the ends) until SD < `sd_threshold` and the
/// candidate's maxima are positive and minima negative, or `max_sift`; subtract the IMF and
/// repeat on the rest until it has fewer than two maxima or minima (the trend), or
/// `max_imfs`. Units: those of x.
///
/// Reference: Huang et al. 1998, Proc. R. Soc. A 454; end handling as Rilling et al. 2003.
/// Known bad cases: mode mixing (one IMF holding two scales, or one scale split over two
/// IMFs) on intermittent signals; fewer than 4 samples.
pub fn emd(x: &[f64], params: &EmdParams) -> Result<EmdResult, Error> {
    params.validate()?;
    check_signal("emd", x, 4)?;
    let n = x.len();
    let max_imfs = params
        .max_imfs
        .unwrap_or_else(|| (n as f64).log2().floor() as usize);
    let mut residue = x.to_vec();
    let mut imfs = Vec::new();
    let mut sifts = Vec::new();
    let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // The two envelopes of each sift, written in place.
    let (mut up, mut lo) = (vec![0.0; n], vec![0.0; n]);
    while imfs.len() < max_imfs {
        crate::numeric::stop::check();
        let (maxs, mins) = extrema(&residue);
        if maxs.len() + mins.len() < 3 || residue.iter().all(|v| v.abs() <= 1e-14 * scale) {
            break;
        }
        let mut h = residue.clone();
        let mut used = 0;
        let mut ok = false;
        // Extrema of the current h (each sift's are reused by the next one's envelopes).
        let (mut hmax, mut hmin) = (maxs, mins);
        for it in 0..params.max_sift {
            crate::numeric::stop::check();
            let Some(wrong_signs) =
                envelopes(&h, &hmax, &hmin, params.mirrored_extrema, &mut up, &mut lo)
            else {
                break;
            };
            ok = true;
            let (num, den) = sift_step(&mut h, &up, &lo);
            used = it + 1;
            let sd = if den > 0.0 { num / den } else { 0.0 };
            extrema_into(&h, &mut hmax, &mut hmin);
            let (mx, mn) = (&hmax, &hmin);
            // IMF definition (Chen et al. 2024 §2.3.2): maxima above and minima below zero (checked
            // on the envelope knots of the iterate that was sifted, end points included, as
            // PyEMD does), and as many extrema as zero crossings, give or take one.
            let crossings = zero_crossings(&h);
            // On long signals one riding wave anywhere breaks both conditions, so each may
            // fail at up to 2 % of the extrema (exact on signals with < 50 extrema, as PyEMD).
            let extrema_count = mx.len() + mn.len();
            let slack = extrema_count / 50;
            let proper = wrong_signs <= slack && extrema_count.abs_diff(crossings) <= 1.max(slack);
            if sd < params.sd_threshold && proper {
                break;
            }
        }
        if !ok {
            break;
        }
        for (r, v) in residue.iter_mut().zip(&h) {
            *r -= v;
        }
        imfs.push(h);
        sifts.push(used);
    }
    Ok(EmdResult {
        imfs,
        residue,
        sifts,
    })
}

#[cfg(test)]
mod tests;
