//! Jerk-limited (S-curve) feed profile along one planning unit's path parameter: a block, or
//! a chain of straight blocks the interpolator's look-ahead joins (`interpolate::chain`).
//!
//! Hand-written (no crate offers a plain-f64 S-curve with closed-form distances): each
//! speed change is a symmetric jerk-limited ramp that starts and ends at zero acceleration,
//! so units join with continuous velocity and acceleration.

/// One polynomial piece of the path parameter: `s(τ) = s0 + v0 τ + a0 τ²/2 + j τ³/6`
/// for `τ ∈ [0, dur]`, starting at global time `t0` (s) in block `block`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece {
    /// Global start time, s.
    pub t0: f64,
    /// Duration, s.
    pub dur: f64,
    /// Path parameter at the start, mm along the block.
    pub s0: f64,
    /// Speed at the start, mm/s.
    pub v0: f64,
    /// Acceleration at the start, mm/s².
    pub a0: f64,
    /// Constant jerk over the piece, mm/s³.
    pub j: f64,
    /// Index of the block, or the interpolator's planning unit, this piece belongs to.
    pub block: usize,
}

impl Piece {
    /// Path parameter (mm) at global time `t` (clamped into the piece).
    pub fn s_at(&self, t: f64) -> f64 {
        let tau = (t - self.t0).clamp(0.0, self.dur);
        self.s0 + tau * (self.v0 + tau * (0.5 * self.a0 + tau * self.j / 6.0))
    }
}

/// Duration (s) of a jerk-limited speed change of `dv` ≥ 0 (mm/s) with acceleration cap
/// `a` (mm/s²) and jerk `j` (mm/s³), zero acceleration at both ends:
/// `2√(dv/j)` if `dv ≤ a²/j` (triangular acceleration), else `dv/a + a/j` (trapezoidal).
pub fn ramp_time(dv: f64, a: f64, j: f64) -> f64 {
    if dv <= a * a / j {
        2.0 * (dv / j).sqrt()
    } else {
        dv / a + a / j
    }
}

/// Distance (mm) covered by the ramp from `v0` to `v1` (mm/s): `(v0 + v1)/2 · ramp_time`,
/// exact because a symmetric ramp's velocity is point-symmetric about its midpoint.
pub fn ramp_distance(v0: f64, v1: f64, a: f64, j: f64) -> f64 {
    0.5 * (v0 + v1) * ramp_time((v1 - v0).abs(), a, j)
}

/// Largest speed (mm/s) reachable from `v0` within `dist` mm with caps `a`, `j`
/// (by bisection on the monotone [`ramp_distance`]; relative accuracy 1e-12).
pub fn max_reachable_speed(v0: f64, dist: f64, a: f64, j: f64) -> f64 {
    let mut lo = v0;
    let mut hi = v0 + 1.0;
    let mut guard = 0;
    while ramp_distance(v0, hi, a, j) < dist && guard < 200 {
        hi = v0 + 2.0 * (hi - v0);
        guard += 1;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if ramp_distance(v0, mid, a, j) <= dist {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi.max(1e-9) {
            break;
        }
    }
    lo
}

/// Appends the pieces of a ramp v0 → v1; returns the state (t, s, v, a) after it.
fn push_ramp(
    out: &mut Vec<Piece>,
    block: usize,
    state: (f64, f64, f64, f64),
    v1: f64,
    a: f64,
    j: f64,
) -> (f64, f64, f64, f64) {
    let (t, s, v, acc) = state;
    let dv = (v1 - v).abs();
    if dv <= 0.0 {
        return state;
    }
    let sign = if v1 > v { 1.0 } else { -1.0 };
    let phases: [(f64, f64); 3] = if dv <= a * a / j {
        let tj = (dv / j).sqrt();
        [(tj, sign * j), (tj, -sign * j), (0.0, 0.0)]
    } else {
        let ta = a / j;
        [(ta, sign * j), (dv / a - a / j, 0.0), (ta, -sign * j)]
    };
    let mut st = (t, s, v, acc);
    for (dur, jerk) in phases {
        if dur <= 0.0 {
            continue;
        }
        let p = Piece {
            t0: st.0,
            dur,
            s0: st.1,
            v0: st.2,
            a0: st.3,
            j: jerk,
            block,
        };
        out.push(p);
        st = (
            st.0 + dur,
            p.s_at(st.0 + dur),
            st.2 + st.3 * dur + 0.5 * jerk * dur * dur,
            st.3 + jerk * dur,
        );
    }
    // Land exactly on the target to stop rounding from drifting across blocks.
    (st.0, st.1, v1, 0.0)
}

/// What one block's feed profile must satisfy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockLimits {
    /// Path length, mm.
    pub len: f64,
    /// Entry speed, mm/s.
    pub v0: f64,
    /// Exit speed, mm/s.
    pub v1: f64,
    /// Cruise cap ≥ max(v0, v1), mm/s.
    pub vcap: f64,
    /// Acceleration cap, mm/s².
    pub a: f64,
    /// Jerk cap, mm/s³.
    pub j: f64,
}

/// Plans one block of length `len` (mm) entered at `v0` and left at `v1` (mm/s) with cruise
/// cap `vcap` ≥ max(v0, v1), acceleration cap `a` and jerk cap `j`: ramp up, cruise, ramp
/// down, lowering the peak by bisection when the block is too short to reach `vcap`.
/// Requires `ramp_distance(v0, v1) ≤ len` (guaranteed by the look-ahead passes).
/// Appends pieces starting at global time `t0`; returns the block's end time (s).
pub fn plan_block(out: &mut Vec<Piece>, block: usize, t0: f64, lim: BlockLimits) -> f64 {
    let BlockLimits {
        len,
        v0,
        v1,
        vcap,
        a,
        j,
    } = lim;
    if len <= 0.0 {
        return t0;
    }
    let need = |vp: f64| ramp_distance(v0, vp, a, j) + ramp_distance(vp, v1, a, j);
    let vp = if need(vcap) <= len {
        vcap
    } else {
        let (mut lo, mut hi) = (v0.max(v1), vcap);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if need(mid) <= len {
                lo = mid;
            } else {
                hi = mid;
            }
            if hi - lo <= 1e-13 * hi.max(1e-9) {
                break;
            }
        }
        lo
    };
    let st = push_ramp(out, block, (t0, 0.0, v0, 0.0), vp, a, j);
    let cruise_len = len - need(vp);
    let mut st = st;
    if cruise_len > 0.0 && vp > 0.0 {
        let dur = cruise_len / vp;
        out.push(Piece {
            t0: st.0,
            dur,
            s0: st.1,
            v0: vp,
            a0: 0.0,
            j: 0.0,
            block,
        });
        st = (st.0 + dur, st.1 + cruise_len, vp, 0.0);
    }
    let st = push_ramp(out, block, st, v1, a, j);
    st.0
}

#[cfg(test)]
mod tests;
