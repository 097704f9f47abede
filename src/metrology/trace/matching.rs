//! Matching the settled stops of the measured position to the command's approaches, by order
//! and position only: never by sample index, because the measuring device's clock need not be
//! the command's (a 3 % difference moves a reading by a whole target after a few cycles).
//!
//! The measured positions may carry the device's own constant offset (a laser zeroed at the
//! first target or at the start point); the offset is found as the shift that puts the most
//! stops on commanded positions, and used only for matching.

/// A commanded approach: the command holds one position for at least `min_dwell_s`.
#[derive(Clone, Debug, PartialEq)]
pub struct Visit {
    /// First command sample of the hold.
    pub start: usize,
    /// One past its last sample.
    pub end: usize,
    /// The commanded position held, mm.
    pub commanded_mm: f64,
    /// Index of its position in the sorted distinct commanded positions.
    pub position: usize,
    /// Direction of the last command motion before it: `Some(true)` positive, `None` when
    /// the command never moved before it (the start position).
    pub forward: Option<bool>,
}

/// The sorted distinct positions and the index of the one nearest `q`, with its distance.
pub fn nearest(positions: &[f64], q: f64) -> (usize, f64) {
    let i = positions.partition_point(|&p| p < q);
    let mut best = (usize::MAX, f64::INFINITY);
    for j in [i.wrapping_sub(1), i] {
        if let Some(p) = positions.get(j) {
            let d = (p - q).abs();
            if d < best.1 {
                best = (j, d);
            }
        }
    }
    best
}

/// How far a stop may sit from a commanded position and still be read as reaching it, mm: a
/// quarter of the smallest distance between two commanded positions (so no stop is near two),
/// infinite with a single position.
pub fn match_tolerance(positions: &[f64]) -> f64 {
    let gap = positions
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    0.25 * gap
}

/// Stops scored when searching the offset; more are subsampled evenly.
const OFFSET_SCORED: usize = 2048;
/// Stops (the first ones) whose distance to commanded positions is a candidate offset.
const OFFSET_SEEDS: usize = 8;
/// Commanded positions per seed stop tried, on each side of the position nearest it (an
/// ISO 230-2 run has tens of targets; this bounds the work on a log with many holds).
const OFFSET_REACH: usize = 128;

/// The constant offset of the measured positions from the commanded ones, mm, as the shift
/// that brings the most stops within `tol` of a commanded position (ties: the smallest shift).
///
/// Formula: o* = argmax_o #{k : min_p |y_k − o − p| ≤ tol}, o over y_k − p for the first
/// `OFFSET_SEEDS` stops k and every position p (the `OFFSET_REACH` nearest on each side
/// when there are more).
///
/// Known bad cases: evenly spaced targets and an offset of a whole spacing differ only at the
/// end targets and the overrun points; ISO 230-2:2014 §5.2 spaces targets unevenly, which
/// removes the ambiguity.
pub fn device_offset(stops_mm: &[f64], positions: &[f64], tol: f64) -> f64 {
    if stops_mm.is_empty() || positions.is_empty() {
        return 0.0;
    }
    let stride = stops_mm.len().div_ceil(OFFSET_SCORED).max(1);
    let score = |o: f64| {
        stops_mm
            .iter()
            .step_by(stride)
            .filter(|&&y| nearest(positions, y - o).1 <= tol)
            .count()
    };
    let mut best = (score(0.0), 0.0_f64);
    for &y in stops_mm.iter().take(OFFSET_SEEDS) {
        let near = positions.partition_point(|&p| p < y);
        let reach = near.saturating_sub(OFFSET_REACH)..(near + OFFSET_REACH).min(positions.len());
        for &p in &positions[reach] {
            let o = y - p;
            let s = score(o);
            if s > best.0 || (s == best.0 && o.abs() < best.1.abs()) {
                best = (s, o);
            }
        }
    }
    best.1
}

/// What became of a stop.
#[derive(Clone, Debug, PartialEq)]
pub enum Matched {
    /// It answers this visit (index into the visits).
    Visit(usize),
    /// It is not used, and why.
    Unused(String),
}

/// The visits (indices, in time order) of each commanded position.
pub fn visits_by_position(visits: &[Visit], positions: usize) -> Vec<Vec<usize>> {
    let mut by_position: Vec<Vec<usize>> = vec![Vec::new(); positions];
    for (v, visit) in visits.iter().enumerate() {
        by_position[visit.position].push(v);
    }
    by_position
}

/// Matches stops to visits (`by_position` from [`visits_by_position`]) in time order: each stop goes to the next visit (after the last one
/// matched) of the commanded position within `tol` of the stop's position less `offset_mm`.
/// Visits without a stop are skipped (an overrun passed without a pause, an approach the axis
/// never finished).
///
/// Known bad cases: a stop at a target the command does not visit next (the log misses a move)
/// skips the visits between; the cycle counts then fall short and the run is refused.
pub fn match_stops(
    stops_mm: &[f64],
    by_position: &[Vec<usize>],
    positions: &[f64],
    offset_mm: f64,
    tol: f64,
) -> Vec<Matched> {
    let mut next = 0;
    stops_mm
        .iter()
        .map(|&y| {
            let (g, d) = nearest(positions, y - offset_mm);
            if positions.is_empty() {
                return Matched::Unused("the command holds no position".into());
            }
            if d > tol {
                return Matched::Unused(format!(
                    "the axis stopped at {y} mm, {d:.4} mm from the nearest commanded position \
                     (more than the matching tolerance {tol:.4} mm, with the measured offset \
                     {offset_mm} mm): a stop between targets"
                ));
            }
            let list = &by_position[g];
            let i = list.partition_point(|&v| v < next);
            match list.get(i) {
                Some(&v) => {
                    next = v + 1;
                    Matched::Visit(v)
                }
                None => Matched::Unused(format!(
                    "the command approaches {} mm no more after the previous reading",
                    positions[g]
                )),
            }
        })
        .collect()
}
