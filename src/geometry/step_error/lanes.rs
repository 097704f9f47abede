//! The exact step error of up to `L` segments at once, one segment per lane (uniform knots,
//! m >= 4, all lanes with the same m). The work is the scalar algorithm of
//! [`super::StepErrorSolver::solve`] written lane by lane: every chain of dependent operations
//! (the spline sweeps, the knot scan, Halley's iteration) runs for `L` segments side by side,
//! so their latencies overlap (and the compiler may use SIMD). `L = 1` is the single-segment
//! path, so a batch and a lone segment give bit-identical results.

use super::solver::{Prepared, SegmentRef, StepError, TOL_B, TOL_BRENT, TOL_HALLEY, all_finite};
use crate::numeric::brent;
use crate::numeric::vec3::{norm, normalize, scale, sub};

type V<const L: usize> = [f64; L];
type V3<const L: usize> = [[f64; L]; 3];

#[inline(always)]
fn lanes<const L: usize>(f: impl FnMut(usize) -> f64) -> V<L> {
    std::array::from_fn(f)
}

#[inline(always)]
fn map3<const L: usize>(mut f: impl FnMut(usize, usize) -> f64) -> V3<L> {
    std::array::from_fn(|d| std::array::from_fn(|l| f(d, l)))
}

/// `p_{k+1} - 2 p_k + p_{k-1}` over three consecutive knots.
#[inline(always)]
fn second_difference<const L: usize>(w: &[V3<L>]) -> V3<L> {
    map3(|d, l| w[2][d][l] - 2.0 * w[1][d][l] + w[0][d][l])
}

/// Work space for `L` lanes, kept between calls (no allocation per segment).
#[derive(Clone, Debug, Default)]
pub(super) struct Lanes<const L: usize> {
    /// Knot points `p[k][d][lane]`, mm.
    p: Vec<V3<L>>,
    /// `S_k = h^2 M_k / 6`: second derivatives in the pieces' local parameter over 6, mm.
    s: Vec<V3<L>>,
    /// Squared distances of the knots to the CL line, mm^2.
    kd: Vec<V<L>>,
}

/// The CL lines and mid normals of the lanes, transposed.
struct Frame<const L: usize> {
    a: V3<L>,
    u: V3<L>,
}

/// One spline piece per lane (`j[l]`): `Q(b) = Σ c_i b^i` and its part normal to the CL line
/// minus the line's point, `P(b) = Σ n_i b^i` (see [`super::Piece`]).
struct Pieces<const L: usize> {
    c: [V3<L>; 4],
    n: [V3<L>; 4],
}

/// Where a lane's extremum is: at its best knot, or inside piece `j` at `b`.
struct Found<const L: usize> {
    t: V<L>,
    d2: V<L>,
    point: [[f64; 3]; L],
}

impl<const L: usize> Pieces<L> {
    #[inline(always)]
    fn end_slopes(&self, s: &V<L>) -> (V<L>, V<L>) {
        let n = &self.n;
        let f0 = lanes(|l| {
            s[l] * (n[0][0][l] * n[1][0][l] + n[0][1][l] * n[1][1][l] + n[0][2][l] * n[1][2][l])
        });
        let p1: V3<L> = map3(|d, l| n[0][d][l] + n[1][d][l] + n[2][d][l] + n[3][d][l]);
        let d1: V3<L> = map3(|d, l| n[1][d][l] + 2.0 * n[2][d][l] + 3.0 * n[3][d][l]);
        let f1 =
            lanes(|l| s[l] * (p1[0][l] * d1[0][l] + p1[1][l] * d1[1][l] + p1[2][l] * d1[2][l]));
        (f0, f1)
    }

    /// `(g, g', g'')` per lane at `b` (see [`super::Piece::slope`]).
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // one index over coefficients and lanes
    fn slope(&self, b: &V<L>) -> (V<L>, V<L>, V<L>) {
        let n = &self.n;
        let (mut g, mut g1, mut g2) = ([0.0; L], [0.0; L], [0.0; L]);
        for d in 0..3 {
            for l in 0..L {
                let x = b[l];
                let p = ((n[3][d][l] * x + n[2][d][l]) * x + n[1][d][l]) * x + n[0][d][l];
                let p1 = (3.0 * n[3][d][l] * x + 2.0 * n[2][d][l]) * x + n[1][d][l];
                let p2 = 6.0 * n[3][d][l] * x + 2.0 * n[2][d][l];
                let p3 = 6.0 * n[3][d][l];
                g[l] += p * p1;
                g1[l] += p1 * p1 + p * p2;
                g2[l] += 3.0 * p1 * p2 + p * p3;
            }
        }
        (g, g1, g2)
    }

    /// `|P(b)|^2` of lane `l`, mm^2.
    #[inline(always)]
    fn dist2(&self, l: usize, b: f64) -> f64 {
        let n = &self.n;
        let p: [f64; 3] = std::array::from_fn(|d| {
            ((n[3][d][l] * b + n[2][d][l]) * b + n[1][d][l]) * b + n[0][d][l]
        });
        p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
    }

    /// `Q(b)` of lane `l`, mm.
    #[inline(always)]
    fn point(&self, l: usize, b: f64) -> [f64; 3] {
        let c = &self.c;
        std::array::from_fn(|d| ((c[3][d][l] * b + c[2][d][l]) * b + c[1][d][l]) * b + c[0][d][l])
    }
}

impl<const L: usize> Lanes<L> {
    /// The step errors of `segs` (validated, uniform, all with the same m >= 4); `factors`:
    /// the Thomas factors `f_i` for at least m - 4 rows; `both`: compute the other branch for
    /// every lane.
    pub(super) fn solve(
        &mut self,
        factors: &[f64],
        r: f64,
        segs: &[Prepared<'_>; L],
        both: bool,
    ) -> [StepError; L] {
        self.solve_raw(factors, r, segs.map(|s| (s, None)), both)
            .expect("prepared segments")
    }

    /// Like [`Lanes::solve`] for segments not yet checked (`(cl, cc)`): checks them lane by
    /// lane first ([`prepare_lanes`]); None when any is invalid.
    pub(super) fn solve_unchecked(
        &mut self,
        factors: &[f64],
        r: f64,
        segs: &[SegmentRef<'_>; L],
        both: bool,
    ) -> Option<[StepError; L]> {
        let raw = segs.map(|(cl, cc)| {
            let p = Prepared {
                a: [0.0; 3],
                u: [0.0; 3],
                n_mid: [0.0; 3],
                cc,
            };
            (p, Some(cl))
        });
        self.solve_raw(factors, r, raw, both)
    }

    /// Dispatch to the AVX2 build when the CPU has it; `segs[l].1` = Some(cl): not prepared.
    fn solve_raw(
        &mut self,
        factors: &[f64],
        r: f64,
        segs: [(Prepared<'_>, Option<[[f64; 3]; 2]>); L],
        both: bool,
    ) -> Option<[StepError; L]> {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU supports AVX2 and FMA (checked just above).
                return unsafe { self.solve_avx2(factors, r, segs, both) };
            }
        }
        self.prepare_and_solve(factors, r, segs, both)
    }

    /// The same code compiled for AVX2 (4 lanes in one register). No FMA contraction happens
    /// (Rust never fuses a * b + c), so the results are bit-identical to the portable build.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn solve_avx2(
        &mut self,
        factors: &[f64],
        r: f64,
        segs: [(Prepared<'_>, Option<[[f64; 3]; 2]>); L],
        both: bool,
    ) -> Option<[StepError; L]> {
        self.prepare_and_solve(factors, r, segs, both)
    }

    #[inline(always)]
    fn prepare_and_solve(
        &mut self,
        factors: &[f64],
        r: f64,
        segs: [(Prepared<'_>, Option<[[f64; 3]; 2]>); L],
        both: bool,
    ) -> Option<[StepError; L]> {
        let prepared = if segs[0].1.is_some() {
            let raw = segs.map(|(p, cl)| (cl.unwrap_or([[0.0; 3]; 2]), p.cc));
            prepare_lanes(r, &raw)?
        } else {
            segs.map(|(p, _)| p)
        };
        Some(self.solve_lanes(factors, r, &prepared, both))
    }

    #[inline(always)]
    fn solve_lanes(
        &mut self,
        factors: &[f64],
        r: f64,
        segs: &[Prepared<'_>; L],
        both: bool,
    ) -> [StepError; L] {
        let m = segs[0].cc.len();
        debug_assert!(m >= 4 && segs.iter().all(|s| s.cc.len() == m));
        self.fit(factors, segs);
        let frame = Frame {
            a: map3(|d, l| segs[l].a[d]),
            u: map3(|d, l| segs[l].u[d]),
        };
        let n_mid: V3<L> = map3(|d, l| segs[l].n_mid[d]);
        // Convexity: the sign of Q''(1/2) · n_mid (S is M times a positive constant).
        let mid = 0.5 * (m - 1) as f64;
        let km = (mid as usize).min(m - 2);
        let (wb, s) = (mid - km as f64, &self.s);
        let wa = 1.0 - wb;
        let convex: [bool; L] = std::array::from_fn(|l| {
            let k: f64 = (0..3)
                .map(|d| (wa * s[km][d][l] + wb * s[km + 1][d][l]) * n_mid[d][l])
                .sum();
            k < 0.0
        });
        // The knots: squared distances to the CL line, curvature signs along n_mid.
        let (mut any_neg, mut any_pos) = ([false; L], [false; L]);
        let (mut dmin, mut dmax) = ([f64::INFINITY; L], [f64::NEG_INFINITY; L]);
        for ((g, p), c) in self.kd.iter_mut().zip(&self.p).zip(&self.s) {
            for l in 0..L {
                let q: [f64; 3] = std::array::from_fn(|d| p[d][l] - frame.a[d][l]);
                let u = [frame.u[0][l], frame.u[1][l], frame.u[2][l]];
                let w = [
                    q[1] * u[2] - q[2] * u[1],
                    q[2] * u[0] - q[0] * u[2],
                    q[0] * u[1] - q[1] * u[0],
                ];
                let g2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
                g[l] = g2;
                dmin[l] = if g2 < dmin[l] { g2 } else { dmin[l] };
                dmax[l] = if g2 > dmax[l] { g2 } else { dmax[l] };
                let k = c[0][l] * n_mid[0][l] + c[1][l] * n_mid[1][l] + c[2][l] * n_mid[2][l];
                any_neg[l] |= k < 0.0;
                any_pos[l] |= k > 0.0;
            }
        }
        let inflection: [bool; L] =
            std::array::from_fn(|l| if convex[l] { any_pos[l] } else { any_neg[l] });
        let (mut kmin, mut kmax) = ([0usize; L], [0usize; L]);
        for (k, g) in self.kd.iter().enumerate() {
            for l in 0..L {
                kmin[l] = if g[l] == dmin[l] { k } else { kmin[l] };
                kmax[l] = if g[l] == dmax[l] { k } else { kmax[l] };
            }
        }
        let sign = lanes(|l| if convex[l] { 1.0 } else { -1.0 });
        let kbest = std::array::from_fn(|l| if convex[l] { kmin[l] } else { kmax[l] });
        let best = self.extremum(&frame, &sign, &kbest);
        let want_other: [bool; L] = std::array::from_fn(|l| both || inflection[l]);
        let other = want_other.iter().any(|&w| w).then(|| {
            let sign = lanes(|l| -sign[l]);
            let k = std::array::from_fn(|l| if convex[l] { kmax[l] } else { kmin[l] });
            self.extremum(&frame, &sign, &k)
        });
        std::array::from_fn(|l| {
            let dist = best.d2[l].sqrt();
            let one_sided = |dist: f64, convex: bool| if convex { r - dist } else { dist - r };
            let other_side_mm = match &other {
                Some(o) if want_other[l] => one_sided(o.d2[l].sqrt(), !convex[l]),
                _ => f64::NAN,
            };
            StepError {
                error_mm: (r - dist).abs(),
                signed_mm: one_sided(dist, convex[l]),
                distance_mm: dist,
                t: best.t[l],
                point: best.point[l],
                convex: convex[l],
                inflection: inflection[l],
                other_side_mm,
            }
        })
    }

    /// The not-a-knot spline through every lane's points: `S_k` by the twisted Thomas
    /// elimination of [`crate::geometry::CubicSpline3`]'s uniform path, lane by lane.
    #[inline(always)]
    fn fit(&mut self, f: &[f64], segs: &[Prepared<'_>; L]) {
        let m = segs[0].cc.len();
        self.p.resize(m, [[0.0; L]; 3]);
        self.s.resize(m, [[0.0; L]; 3]);
        self.kd.resize(m, [0.0; L]);
        for (l, seg) in segs.iter().enumerate() {
            for (pk, c) in self.p.iter_mut().zip(seg.cc) {
                for d in 0..3 {
                    pk[d][l] = c[d];
                }
            }
        }
        let (p, s) = (&self.p[..m], &mut self.s[..m]);
        let q = m - 4;
        let f = &f[..q];
        let sixth = 1.0 / 6.0;
        let (d1, dl) = (second_difference(&p[0..3]), second_difference(&p[m - 3..m]));
        let s1: V3<L> = map3(|d, l| d1[d][l] * sixth);
        let sl: V3<L> = map3(|d, l| dl[d][l] * sixth);
        if q > 0 {
            let h = q / 2;
            let rows = &mut s[2..m - 2];
            let rhs = &p[1..m - 1];
            let mut y = s1;
            for (i, (out, &fi)) in rows[..h].iter_mut().zip(f).enumerate() {
                let r = second_difference(&rhs[i..i + 3]);
                y = map3(|d, l| (r[d][l] - y[d][l]) * fi);
                *out = y;
            }
            let mut z = sl;
            for (i, (out, &fi)) in rows[h + 1..].iter_mut().rev().zip(f).enumerate() {
                let r = second_difference(&rhs[q - 1 - i..q + 2 - i]);
                z = map3(|d, l| (r[d][l] - z[d][l]) * fi);
                *out = z;
            }
            let f_top = if h > 0 { f[h - 1] } else { 0.0 };
            let f_bot = if q - 1 - h > 0 { f[q - 2 - h] } else { 0.0 };
            let inv_mid = 1.0 / (4.0 - f_top - f_bot);
            let r = second_difference(&rhs[h..h + 3]);
            let xm: V3<L> = map3(|d, l| (r[d][l] - y[d][l] - z[d][l]) * inv_mid);
            rows[h] = xm;
            let mut x = xm;
            for (out, &fi) in rows[..h].iter_mut().rev().zip(f[..h].iter().rev()) {
                x = map3(|d, l| out[d][l] - fi * x[d][l]);
                *out = x;
            }
            let mut x = xm;
            let nb = q - 1 - h;
            for (out, &fi) in rows[h + 1..].iter_mut().zip(f[..nb].iter().rev()) {
                x = map3(|d, l| out[d][l] - fi * x[d][l]);
                *out = x;
            }
        }
        s[1] = s1;
        s[m - 2] = sl;
        let (s2, s3) = (s[2], s[m - 3]);
        s[0] = map3(|d, l| 2.0 * s1[d][l] - s2[d][l]);
        s[m - 1] = map3(|d, l| 2.0 * sl[d][l] - s3[d][l]);
    }

    /// Piece `j[l]` of every lane.
    #[inline(always)]
    fn pieces(&self, frame: &Frame<L>, j: &[usize; L]) -> Pieces<L> {
        let (p, s) = (&self.p, &self.s);
        let c: [V3<L>; 4] = [
            map3(|d, l| p[j[l]][d][l]),
            map3(|d, l| {
                p[j[l] + 1][d][l] - p[j[l]][d][l] - 2.0 * s[j[l]][d][l] - s[j[l] + 1][d][l]
            }),
            map3(|d, l| 3.0 * s[j[l]][d][l]),
            map3(|d, l| s[j[l] + 1][d][l] - s[j[l]][d][l]),
        ];
        let u = &frame.u;
        let perp = |v: V3<L>| -> V3<L> {
            let dot = lanes::<L>(|l| v[0][l] * u[0][l] + v[1][l] * u[1][l] + v[2][l] * u[2][l]);
            map3(|d, l| v[d][l] - dot[l] * u[d][l])
        };
        let c0a = map3(|d, l| c[0][d][l] - frame.a[d][l]);
        Pieces {
            n: [perp(c0a), perp(c[1]), perp(c[2]), perp(c[3])],
            c,
        }
    }

    /// Per lane, the minimum (`sign` 1) or maximum (-1) of the distance to the CL line, from
    /// the best knot `k`: the logic of [`super::extremum`], Halley's iterations in lockstep.
    #[inline(always)]
    fn extremum(&self, frame: &Frame<L>, sign: &V<L>, k: &[usize; L]) -> Found<L> {
        let m = self.p.len();
        let kd = &self.kd;
        let inv = 1.0 / (m - 1) as f64;
        let mut left: [bool; L] = std::array::from_fn(|l| {
            let (k, s) = (k[l], sign[l]);
            k + 1 == m || (k > 0 && s * kd[k - 1][l] < s * kd[k + 1][l])
        });
        let side =
            |left: &[bool; L]| std::array::from_fn(|l| if left[l] { k[l] - 1 } else { k[l] });
        let mut j: [usize; L] = side(&left);
        let mut pieces = self.pieces(frame, &j);
        let (mut f0, mut f1) = pieces.end_slopes(sign);
        let mut at_knot = [false; L];
        let mut switch = false;
        for l in 0..L {
            let at = if left[l] { f1[l] } else { f0[l] };
            if at == 0.0 {
                at_knot[l] = true;
            } else if (at < 0.0) == left[l] {
                if (left[l] && k[l] + 1 == m) || (!left[l] && k[l] == 0) {
                    at_knot[l] = true;
                } else {
                    left[l] = !left[l];
                    switch = true;
                }
            }
        }
        if switch {
            j = side(&left);
            pieces = self.pieces(frame, &j);
            (f0, f1) = pieces.end_slopes(sign);
        }
        // Halley from the secant root, all lanes in step; a lane stops as the scalar would.
        let mut searching: [bool; L] =
            std::array::from_fn(|l| !at_knot[l] && f0[l] <= 0.0 && f1[l] >= 0.0);
        let mut b = [0.0; L];
        for l in 0..L {
            if !at_knot[l] && !searching[l] {
                let s = sign[l];
                b[l] = brent::minimize(|x| s * pieces.dist2(l, x), 0.0, 1.0, TOL_BRENT, 100).0;
            }
        }
        let (mut lo, mut hi) = ([0.0f64; L], [1.0f64; L]);
        let mut x = lanes(|l| {
            if f1[l] > f0[l] {
                f0[l] / (f0[l] - f1[l])
            } else {
                0.5
            }
        });
        for _ in 0..64 {
            if !searching.iter().any(|&s| s) {
                break;
            }
            let (g, g1, g2) = pieces.slope(&x);
            for l in 0..L {
                if !searching[l] {
                    continue;
                }
                let s = sign[l];
                let (f, df, ddf) = (s * g[l], s * g1[l], s * g2[l]);
                let neg = f < 0.0;
                lo[l] = if neg { x[l] } else { lo[l] };
                hi[l] = if neg { hi[l] } else { x[l] };
                let mut next = x[l] - 2.0 * f * df / (2.0 * df * df - f * ddf);
                let mut tol = TOL_HALLEY;
                if !(next >= lo[l] && next <= hi[l]) {
                    next = 0.5 * (lo[l] + hi[l]);
                    tol = TOL_B;
                }
                if (next - x[l]).abs() <= tol || hi[l] - lo[l] <= TOL_B {
                    b[l] = next;
                    searching[l] = false;
                }
                x[l] = next;
            }
        }
        for l in 0..L {
            if searching[l] {
                b[l] = x[l];
            }
        }
        let mut found = Found {
            t: [0.0; L],
            d2: [0.0; L],
            point: [[0.0; 3]; L],
        };
        for l in 0..L {
            let kk = k[l];
            let d2 = if at_knot[l] {
                f64::NAN
            } else {
                pieces.dist2(l, b[l])
            };
            if at_knot[l] || sign[l] * d2 >= sign[l] * kd[kk][l] {
                found.t[l] = kk as f64 * inv;
                found.d2[l] = kd[kk][l];
                found.point[l] = [self.p[kk][0][l], self.p[kk][1][l], self.p[kk][2][l]];
            } else {
                let jj = j[l];
                let (t0, t1) = (jj as f64 * inv, (jj + 1) as f64 * inv);
                found.t[l] = t0 + b[l] * (t1 - t0);
                found.d2[l] = d2;
                found.point[l] = pieces.point(l, b[l]);
            }
        }
        found
    }
}

/// [`super::prepare`] for `L` segments at once (same arithmetic, so the same frames), or None
/// when any of them is invalid (the caller then checks them one by one for the error).
#[inline(always)]
fn prepare_lanes<'a, const L: usize>(
    r: f64,
    segs: &[SegmentRef<'a>; L],
) -> Option<[Prepared<'a>; L]> {
    if !(r.is_finite() && r > 0.0) {
        return None;
    }
    let mut finite = true;
    for (cl, cc) in segs {
        finite &= cc.len() >= 3 && all_finite(cl.as_flattened()) && all_finite(cc.as_flattened());
    }
    if !finite {
        return None;
    }
    let tol = 1e-3 * r + 1e-9;
    let mut out = [Prepared {
        a: [0.0; 3],
        u: [0.0; 3],
        n_mid: [0.0; 3],
        cc: segs[0].1,
    }; L];
    let mut ok = true;
    for (o, &(cl, cc)) in out.iter_mut().zip(segs) {
        let d = sub(cl[1], cl[0]);
        let len = norm(d);
        let (r0, r1) = (sub(cl[0], cc[0]), sub(cl[1], cc[cc.len() - 1]));
        ok &= !(len.is_nan() || len <= 1e-12 * r)
            & ((norm(r0) - r).abs() <= tol)
            & ((norm(r1) - r).abs() <= tol);
        *o = Prepared {
            a: cl[0],
            u: scale(d, 1.0 / len),
            n_mid: normalize([r0[0] + r1[0], r0[1] + r1[1], r0[2] + r1[2]]),
            cc,
        };
    }
    ok.then_some(out)
}
