//! Probe flyers: points of a measurement that are off by far more than the rest (a chip
//! under the stylus, a coolant drop, a missed or double trigger).
//!
//! Why this exists: every later stage is a least-squares method (VMD's Wiener filters, the
//! GCV smoother, the carrier fit), so one 2 mm flyer among 3 µm noise spreads over its
//! whole neighbourhood and, through GCV's choice of λ, over the whole field: before this
//! screen a single flyer on the 41 × 41 demo surface moved 1,367 of 1,681 compensation
//! offsets, by up to 0.2 mm. A compensation that follows a chip gouges the part.
//!
//! The rule is Hampel's identifier on a local median (Hampel 1974; Davies & Gather 1993), with
//! the flyers then imputed from the decomposition itself (see docs/REFERENCES.md):
//! 1. a local median of the neighbours (5 × 5 on a grid, ±4 samples in 1-D) gives a first
//!    systematic surface that a few flyers cannot pull; points whose residual exceeds
//!    `k` robust standard deviations (σ̂ = 1.4826 · MAD) are suspects;
//! 2. the decomposition runs on the signal with the suspects replaced by a fill (first the
//!    local median, then the systematic part of the previous round), so they are left out
//!    of the systematic part and their own systematic value comes from their neighbours;
//! 3. step 2 repeats with the new fill until it settles (a few rounds; see [`robust`] for
//!    why the decomposition's own residual does not decide who is a flyer).
//!
//! On clean data nothing is flagged and the decomposition is the plain one, bit for bit.
//! `k` defaults to 10: Gaussian noise exceeds 10σ with probability 1.5e-23, so a clean
//! point is not named even on a million-sample signal, while a flyer of 50σ (the goal) is
//! five times over the line. A floor (`min_mm`, default 0.002 mm) keeps noise-free
//! synthetic data, whose σ̂ is ~1e-9 mm, from having its rounding named.
//!
//! Known bad cases: a real sharp feature narrower than the median window (a 1-point ridge,
//! a step edge the smoother cannot follow) is indistinguishable from a flyer and is named;
//! `flyers.enabled: false` turns the screen off. More than `max_fraction` of the points
//! over the line are not flyers but structure: then only the worst `max_fraction` are named.

use serde::{Deserialize, Serialize};

use super::error::Error;

/// Parameters of the flyer screen (JSON `params.flyers`; every field optional).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FlyerParams {
    /// Screen for flyers at all (default true).
    pub enabled: bool,
    /// Threshold in robust standard deviations of the random part (default 10).
    pub k: f64,
    /// Smallest residual (mm) ever named a flyer, whatever σ̂ (default 0.002 mm).
    pub min_mm: f64,
    /// Largest share of the points named (default 0.05): beyond it the worst are kept.
    pub max_fraction: f64,
}

impl Default for FlyerParams {
    fn default() -> Self {
        Self {
            enabled: true,
            k: 10.0,
            min_mm: 0.002,
            max_fraction: 0.05,
        }
    }
}

impl FlyerParams {
    /// Checks ranges; the sentence names the parameter.
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |name, reason: &str| {
            Err(Error::BadParam {
                name,
                reason: reason.into(),
            })
        };
        if !(self.k.is_finite() && (3.0..=1000.0).contains(&self.k)) {
            return bad(
                "flyers.k",
                "must be in [3, 1000] robust standard deviations (default 10)",
            );
        }
        if !(self.min_mm.is_finite() && (0.0..=10.0).contains(&self.min_mm)) {
            return bad("flyers.min_mm", "must be in [0, 10] mm (default 0.002)");
        }
        if !(self.max_fraction.is_finite() && self.max_fraction > 0.0 && self.max_fraction <= 0.5) {
            return bad("flyers.max_fraction", "must be in (0, 0.5] (default 0.05)");
        }
        Ok(())
    }
}

/// Half-width of the neighbour median window: 5 × 5 on a grid (holds up to 12 flyers in a
/// cluster), ±4 samples in 1-D (up to 4 adjacent flyers).
const HALF_2D: usize = 2;
const HALF_1D: usize = 4;

/// Median of `v` (reorders it); NaN-free input. 0 for an empty slice.
fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    let hi = *m;
    if v.len() % 2 == 1 {
        hi
    } else {
        let lo = v[..mid].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lo + hi)
    }
}

/// Robust standard deviation 1.4826 · median(|r − median(r)|) of the residuals `r` (mm).
/// 1.4826 makes it σ for Gaussian noise.
///
/// Reference: Hampel (1974); Rousseeuw & Croux (1993) eq. 1.
pub fn robust_sigma(r: &[f64]) -> f64 {
    let mut v = r.to_vec();
    let m = median(&mut v);
    for x in &mut v {
        *x = (*x - m).abs();
    }
    1.4826 * median(&mut v)
}

/// [`median`] of exactly 8 values, by Batcher's odd-even merge sort network (19
/// compare-exchanges in [`f64::total_cmp`] order, no branches to mispredict): the mean of
/// the 4th and 5th smallest, the same values and so the same bits as [`median`]'s selection
/// (`median_of_8_matches_median`). The interior of [`neighbour_median`] in 1-D: a
/// selection on 8 values branches unpredictably on every sample (the 1-D flyer screen took
/// 1.4 ms of a 20,000-sample decomposition, BENCHMARKS.md issue 41 item 8).
fn median_of_8(mut v: [f64; 8]) -> f64 {
    const NET: [(usize, usize); 19] = [
        (0, 1),
        (2, 3),
        (4, 5),
        (6, 7),
        (0, 2),
        (1, 3),
        (4, 6),
        (5, 7),
        (1, 2),
        (5, 6),
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7),
        (2, 4),
        (3, 5),
        (1, 2),
        (3, 4),
        (5, 6),
    ];
    // Each value as the integer whose order is f64::total_cmp's (its own inverse), so each
    // compare-exchange is an integer min and max.
    let key = |x: f64| {
        let b = x.to_bits() as i64;
        b ^ (((b >> 63) as u64) >> 1) as i64
    };
    let mut k = v.map(key);
    for (a, b) in NET {
        let (p, q) = (k[a], k[b]);
        k[a] = p.min(q);
        k[b] = p.max(q);
    }
    v = k.map(|b| f64::from_bits((b ^ (((b >> 63) as u64) >> 1) as i64) as u64));
    0.5 * (v[0..4].iter().copied().fold(f64::NEG_INFINITY, f64::max) + v[4])
}

/// Samples between two looks at the should-stop check in [`neighbour_median`] (1-D).
const STOP_EVERY: usize = 1 << 16;

/// The median of each sample's neighbours, the sample itself left out (mm): 5 × 5 on a
/// `(nu, nv)` grid (k = iv·nu + iu; windows clipped at the edges), ±4 samples in 1-D.
pub fn neighbour_median(x: &[f64], grid: Option<(usize, usize)>) -> Vec<f64> {
    let mut buf = Vec::with_capacity(32);
    match grid {
        Some((nu, nv)) => (0..nv)
            .flat_map(|iv| (0..nu).map(move |iu| (iu, iv)))
            .map(|(iu, iv)| {
                if iu == 0 {
                    crate::numeric::stop::check();
                }
                buf.clear();
                for jv in iv.saturating_sub(HALF_2D)..(iv + HALF_2D + 1).min(nv) {
                    for ju in iu.saturating_sub(HALF_2D)..(iu + HALF_2D + 1).min(nu) {
                        if (ju, jv) != (iu, iv) {
                            buf.push(x[jv * nu + ju]);
                        }
                    }
                }
                median(&mut buf)
            })
            .collect(),
        None => (0..x.len())
            .map(|k| {
                if k % STOP_EVERY == 0 {
                    crate::numeric::stop::check();
                }
                if k >= HALF_1D && k + HALF_1D < x.len() {
                    // A full window: the 8 neighbours through a sorting network.
                    let w = &x[k - HALF_1D..=k + HALF_1D];
                    return median_of_8([w[0], w[1], w[2], w[3], w[5], w[6], w[7], w[8]]);
                }
                buf.clear();
                let hi = (k + HALF_1D + 1).min(x.len());
                buf.extend(x[k.saturating_sub(HALF_1D)..k].iter());
                buf.extend(x[k + 1..hi].iter());
                median(&mut buf)
            })
            .collect(),
    }
}

/// Indices whose residual `r[k]` (mm) exceeds max(k·σ̂, min_mm), σ̂ the robust standard
/// deviation of all the residuals; at most `max_fraction` of the points, the largest |r|
/// first. Sorted ascending.
pub fn over_the_line(r: &[f64], p: &FlyerParams) -> Vec<usize> {
    let sigma = robust_sigma(r);
    let line = (p.k * sigma).max(p.min_mm);
    let mut hits: Vec<usize> = (0..r.len()).filter(|&k| r[k].abs() > line).collect();
    let cap = ((p.max_fraction * r.len() as f64).floor() as usize).max(1);
    if hits.len() > cap {
        hits.sort_by(|&a, &b| r[b].abs().total_cmp(&r[a].abs()));
        hits.truncate(cap);
        hits.sort_unstable();
    }
    hits
}

/// The first, cheap screen (step 1 of the module doc): suspects against the neighbour
/// median, and that median as their fill. This is what an upload is checked with.
pub fn suspects(
    x: &[f64],
    grid: Option<(usize, usize)>,
    p: &FlyerParams,
) -> (Vec<usize>, Vec<f64>) {
    if !p.enabled || x.len() < 3 {
        return (Vec::new(), Vec::new());
    }
    let med = neighbour_median(x, grid);
    let r: Vec<f64> = x.iter().zip(&med).map(|(a, b)| a - b).collect();
    let hits = over_the_line(&r, p);
    (hits, med)
}

/// Largest number of decompositions the robust loop runs (the first included).
pub const MAX_ROUNDS: usize = 4;

/// Runs `decompose` (which returns the systematic part, mm, of the signal it is given)
/// robustly against flyers, as the module doc describes. Returns the flyers' indices and
/// the last decomposition's output (of the filled signal). With nothing flagged it is
/// exactly `decompose(x)`, one run.
///
/// Which points are flyers is decided by the neighbour-median screen alone, never by the
/// decomposition's residual: a baseline method that leaves structure in its random part
/// (EMD's screening often does, over hundreds of samples) would otherwise have that
/// structure named. The decomposition only supplies the fill: each round replaces the
/// flyers by the previous round's systematic value there, which converges to the value the
/// smoother gives a point it does not see (a fixed point; the error shrinks by the
/// smoother's leverage, < 1, each round). The loop ends when no fill moves by more than
/// 1e-6 mm, or after [`MAX_ROUNDS`].
pub fn robust<T>(
    x: &[f64],
    grid: Option<(usize, usize)>,
    p: &FlyerParams,
    mut decompose: impl FnMut(&[f64]) -> Result<T, Error>,
    systematic: impl Fn(&T) -> &[f64],
) -> Result<(Vec<usize>, T), Error> {
    let (flagged, med) = suspects(x, grid, p);
    if flagged.is_empty() {
        return Ok((flagged, decompose(x)?));
    }
    let mut y = x.to_vec();
    for &k in &flagged {
        y[k] = med[k];
    }
    let mut rounds = 0;
    loop {
        rounds += 1;
        crate::numeric::stop::check();
        let out = decompose(&y)?;
        let sys = systematic(&out);
        let moved = flagged
            .iter()
            .map(|&k| (sys[k] - y[k]).abs())
            .fold(0.0, f64::max);
        if moved <= 1e-6 || rounds >= MAX_ROUNDS {
            return Ok((flagged, out));
        }
        for &k in &flagged {
            y[k] = sys[k];
        }
    }
}

#[cfg(test)]
mod tests;
