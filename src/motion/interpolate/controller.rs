//! The controller's limits on dense blocks ([`ControllerLimits`], the machine definition's
//! `"controller"`), applied to the planning segments: caps on each block's speed (LinuxCNC's
//! segment cap, a block-processing rate) and on each junction's speed (a look-ahead depth).
//! Sources and the JSON are in [`crate::motion::controller`].

use super::Seg;
use crate::motion::controller::ControllerLimits;
use crate::motion::gcode::Block;
use crate::motion::profile;

/// LinuxCNC's `TP_MIN_SEGMENT_CYCLES` (`src/emc/tp/tp_types.h`): a segment lasts at least
/// 1.02 trajectory cycles, "greater than 1 to ensure each segment is hit at least once".
pub const LINUXCNC_MIN_SEGMENT_CYCLES: f64 = 1.02;

/// Lowers each block's speed cap `vcap` (mm/s) by the controller's per-block limits:
///
/// - segment cap: `vcap ≤ L / (1.02 · period_s)` for a block of length `L` mm (LinuxCNC
///   `tpAddLine`; 20 µm at 1 ms: 19.6 mm/s);
/// - block rate `r` (blocks/s): `vcap ≤ L · r` (the controller cannot start more than `r`
///   blocks a second; 20 µm at 1000 blocks/s: 20 mm/s).
///
/// `L` is the block's path length as planned (a blend arc and the lines it trims count as
/// the segments they are, as in LinuxCNC's queue). Dwells carry no segment.
pub(super) fn cap_blocks(
    items: &mut [(&Block, Option<Seg>)],
    limits: &ControllerLimits,
    period_s: f64,
) {
    for seg in items.iter_mut().filter_map(|(_, s)| s.as_mut()) {
        if limits.segment_cap {
            seg.vcap = seg
                .vcap
                .min(seg.len / (LINUXCNC_MIN_SEGMENT_CYCLES * period_s));
        }
        if let Some(rate) = limits.block_rate_hz {
            seg.vcap = seg.vcap.min(seg.len * rate);
        }
    }
}

/// Lowers the junction speeds `v` (mm/s; `v[k]` enters item `k`) by the look-ahead depth: a
/// planner that sees `N` blocks ahead of the one it executes must be able to stop within
/// them, so at the end of item `k − 1`, with items `k .. k + N − 1` in view,
///
/// `v[k] ≤ v_stop(W_k)`, `W_k = Σ_{j=k}^{k+N−1} L_j`,
///
/// where `v_stop(W)` is the largest speed that stops within `W` mm with the smallest
/// acceleration and jerk caps of those blocks ([`profile::max_reachable_speed`] from rest;
/// a jerk-limited stop is time-symmetric to a start). A dwell counts as a block of length 0;
/// the window stops at the program's end, where the look-ahead passes stop the tool anyway.
/// Inside a block the speed stays within `v_stop` of what remains in view, since its
/// S-curve reaches `v[k]` with a ramp no shorter than that stop's (a jerk-limited ramp
/// split in two covers more path than one).
///
/// Reference: the planner-buffer limit on short segments (S. Jeon, grbl/grbl pull 498);
/// 5 blocks of 0.1 mm stop within 0.5 mm.
pub(super) fn cap_junctions(
    items: &[(&Block, Option<Seg>)],
    limits: &ControllerLimits,
    v: &mut [f64],
) {
    let Some(depth) = limits.lookahead_blocks else {
        return;
    };
    let n = items.len();
    for k in 1..n {
        let window = &items[k..(k + depth).min(n)];
        let (mut len, mut acc, mut jerk) = (0.0, f64::INFINITY, f64::INFINITY);
        for s in window.iter().filter_map(|(_, s)| s.as_ref()) {
            len += s.len;
            acc = acc.min(s.acc);
            jerk = jerk.min(s.jerk);
        }
        if len > 0.0 && acc.is_finite() && jerk.is_finite() {
            v[k] = v[k].min(profile::max_reachable_speed(0.0, len, acc, jerk));
        } else {
            v[k] = 0.0;
        }
    }
}

#[cfg(test)]
mod tests;
