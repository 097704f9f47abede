//! Volumetric compensation of a whole program (CONTRACT v1.1 "Compensated programs"): every
//! programmed tool-tip point p (machine frame: after work offset and tool length, where the
//! map was fitted) becomes p − e(p), written back in the program's own frame and units.
//!
//! - G0: the end point only. G1: the end point; where e varies along the segment by more
//!   than the tolerance from linear between the compensated ends, the segment becomes G1
//!   points (bisection until every piece is within tolerance).
//! - G2/G3 (any plane, IJK or R, helices): kept as an arc with shifted end and centre when e
//!   is constant along it within the tolerance; otherwise G1 points within the tolerance of
//!   the compensated arc (chord error and variation of e together, [`super::paths`]).
//! - Canned cycles (G90): the hole bottom X Y Z is compensated, and the R plane's Z at the
//!   hole; the drill axis stays parallel to Z and pecks are not modelled (a warning).
//! - What the service cannot place (G28/G30/G53, unknown positions, RTCP tool-tip frames, G91
//!   cycles) is copied unchanged with a warning naming the lines.
//!
//! The error field is the machine's volumetric map (Xiang et al. 2019; Wang, Dai & Hong),
//! queried as its predict route does (outside the box: the nearest point of the box, and a
//! warning naming the lines).

use super::emit::{Emitter, LineInfo, LinePlan, PathPiece, rounding_mm};
use super::error::Error;
use super::field::ErrorField;
use super::paths::{Shifter, arc_directions, arc_pieces, arc_point, arc_reversals, linear_points};
use super::reversals::Reversals;
use crate::motion::ReadOptions;
use crate::motion::gcode::{LineFrame, parse_traced};
use crate::motion::program::{Block, Feed, Motion};
use crate::numeric::vec3::{norm, sub};

/// Smallest `tolerance_mm` accepted, mm.
pub const MIN_TOLERANCE_MM: f64 = 1e-5;
/// Largest `tolerance_mm` accepted, mm.
pub const MAX_TOLERANCE_MM: f64 = 0.1;
/// Default `tolerance_mm`, mm.
pub const DEFAULT_TOLERANCE_MM: f64 = 0.001;
/// Most lines written in one answer.
pub const MAX_OUTPUT_BLOCKS: usize = 2_000_000;

/// A compensated program.
#[derive(Clone, Debug, PartialEq)]
pub struct Compensated {
    /// The program text, same line endings as the source.
    pub gcode: String,
    /// Warnings of the reader and of the compensation, one sentence each.
    pub warnings: Vec<String>,
    /// Largest |e(p)| applied, mm.
    pub max_shift_mm: f64,
    /// Lines (blocks) in the answer.
    pub blocks: usize,
    /// 1-based source line of every output line.
    pub source_lines: Vec<usize>,
    /// 1-based output lines that are backlash take-up moves ([`super::reversals`]): a later
    /// pass writes them as they are.
    pub takeups: Vec<usize>,
}

/// Checks `tolerance_mm` against [[`MIN_TOLERANCE_MM`], [`MAX_TOLERANCE_MM`]].
pub fn check_tolerance(tolerance_mm: f64) -> Result<(), Error> {
    if (MIN_TOLERANCE_MM..=MAX_TOLERANCE_MM).contains(&tolerance_mm) {
        Ok(())
    } else {
        Err(Error::Tolerance {
            got: tolerance_mm,
            min: MIN_TOLERANCE_MM,
            max: MAX_TOLERANCE_MM,
        })
    }
}

/// Lines of a list named in one warning, at most this many.
const LINES_NAMED: usize = 20;

/// `lines` as "1, 2, 3" (at most [`LINES_NAMED`], then "and N more").
pub(super) fn line_list(lines: &[usize]) -> String {
    let mut s: Vec<String> = lines
        .iter()
        .take(LINES_NAMED)
        .map(|l| l.to_string())
        .collect();
    if lines.len() > LINES_NAMED {
        s.push(format!("and {} more", lines.len() - LINES_NAMED));
    }
    s.join(", ")
}

/// Compensates `text` against `field` (volumetric pre-compensation: each programmed
/// tool-tip point p, mm in the machine frame, becomes p − e(p); Xiang et al. 2019 §2, the
/// error map inverted to first order), read with `options` (work offsets, tool lengths,
/// home, strict), within `tolerance_mm` (mm, [1e-5, 0.1]) of the compensated path. Errors:
/// the reader's (line and word), a tolerance out of range, an answer over
/// [`MAX_OUTPUT_BLOCKS`] lines.
pub fn compensate_program(
    text: &str,
    options: &ReadOptions,
    field: &dyn ErrorField,
    tolerance_mm: f64,
) -> Result<Compensated, Error> {
    compensate_with_offsets(text, options, field, tolerance_mm, &Offsets::default())
}

/// What a pass corrects besides its error field: effects that are not functions of the
/// position alone.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Offsets {
    /// Play per axis X, Y, Z, mm ([`super::reversals`]).
    pub backlash_mm: [f64; 3],
    /// Drift (mm, X Y Z) at the end of each source line (index: line − 1), as the machine's
    /// thermal drift predicts it at the program's time there; every point of a line is
    /// written −drift further. Empty: none.
    pub drift_mm: Vec<[f64; 3]>,
}

/// [`compensate_program`] with `offsets` corrected too: every point offset by b/2 along its
/// axis' last direction with a take-up move at each reversal ([`super::reversals`]), and by
/// −drift at its line's time.
pub fn compensate_with_offsets(
    text: &str,
    options: &ReadOptions,
    field: &dyn ErrorField,
    tolerance_mm: f64,
    offsets: &Offsets,
) -> Result<Compensated, Error> {
    check_tolerance(tolerance_mm)?;
    let (program, reader_warnings, frames) = parse_traced(text, options)?;
    let raw_lines: Vec<&str> = text.lines().collect();
    let mut by_line: Vec<Vec<&Block>> = vec![Vec::new(); raw_lines.len() + 1];
    for b in &program.blocks {
        if let Some(v) = by_line.get_mut(b.line) {
            v.push(b);
        }
    }
    let mut warnings: Vec<String> = reader_warnings.iter().map(|w| w.to_string()).collect();
    let inch = frames.iter().any(|f| f.inch);
    let tol = (tolerance_mm - rounding_mm(inch)).max(0.5 * tolerance_mm);
    if tolerance_mm < 2.0 * rounding_mm(inch) {
        warnings.push(format!(
            "tolerance_mm {tolerance_mm} is close to the output resolution (±{:.5} mm): points \
             are within tolerance before rounding to the written decimals",
            rounding_mm(inch)
        ));
    }
    let mut shifter = Shifter::new(field);
    let mut em = Emitter::new();
    let mut notes = Notes::default();
    let mut whole = WholeMoves::default();
    let mut rev = Reversals::new(offsets.backlash_mm);
    let mut takeups = Vec::new();
    for (idx, raw) in raw_lines.iter().enumerate() {
        crate::numeric::stop::check();
        let line = idx + 1;
        let info = em.begin(raw);
        let frame = frames.get(idx).filter(|f| f.line == line);
        let keep_whole = whole.next(&info);
        let (plan, took) = match frame {
            Some(frame) => plan_line(
                line,
                &info,
                frame,
                &by_line[line],
                (
                    &mut shifter,
                    &mut rev,
                    offsets.drift_mm.get(idx).copied().unwrap_or([0.0; 3]),
                ),
                (tol, keep_whole),
                &mut notes,
            ),
            None => (LinePlan::Keep, Vec::new()),
        };
        // each piece of a take-up's plan is one line (the first on the source line)
        takeups.extend(took.into_iter().map(|i| em.len() + 1 + i));
        em.write(line, raw, &info, frame, plan);
        if em.len() > MAX_OUTPUT_BLOCKS {
            return Err(Error::TooLong {
                limit: MAX_OUTPUT_BLOCKS,
            });
        }
    }
    notes.into_warnings(&mut warnings, &shifter.out_of_box);
    let (lines, source_lines) = em.finish();
    let eol = if text.contains("\r\n") { "\r\n" } else { "\n" };
    let mut gcode = lines.join(eol);
    if text.ends_with('\n') {
        gcode.push_str(eol);
    }
    Ok(Compensated {
        gcode,
        warnings,
        max_shift_mm: shifter.max_shift_mm,
        blocks: lines.len(),
        source_lines,
        takeups,
    })
}

/// Lines copied unchanged, by reason.
#[derive(Default)]
struct Notes {
    machine_moves: Vec<usize>,
    unplaced: Vec<usize>,
    rtcp: Vec<usize>,
    incremental_cycles: Vec<usize>,
    holes: Vec<usize>,
    split: Vec<usize>,
    split_arcs: Vec<usize>,
    takeups: Vec<usize>,
    backlash_whole: Vec<usize>,
}

impl Notes {
    fn into_warnings(self, out: &mut Vec<String>, out_of_box: &[usize]) {
        let mut say = |lines: &[usize], what: &str| {
            if !lines.is_empty() {
                out.push(format!("lines {}: {what}", line_list(lines)));
            }
        };
        say(
            &self.machine_moves,
            "G28/G30/G53 move to machine positions: copied uncompensated",
        );
        say(
            &self.unplaced,
            "the service cannot place these blocks (unknown machine position): copied uncompensated",
        );
        say(
            &self.rtcp,
            "RTCP blocks are tool-tip points in the workpiece frame, not machine positions: copied uncompensated",
        );
        say(
            &self.incremental_cycles,
            "canned cycles in G91 are copied uncompensated: post the cycles in G90",
        );
        say(
            &self.holes,
            "canned-cycle holes: X Y Z compensated at the hole bottom and R at the hole; the drill \
             axis stays parallel to Z and pecks (Q) are not modelled",
        );
        say(
            &self.split,
            "split into straight pieces: the error varies along the move by more than \
             tolerance_mm (inserted lines carry no N number)",
        );
        say(
            &self.split_arcs,
            "split into sub-arcs of the same plane and direction: the error varies along the \
             arc by more than tolerance_mm (inserted lines carry no N number)",
        );
        say(
            &self.takeups,
            "backlash take-up moves inserted where an axis reverses or first moves (the motor \
             crosses the play while the table stands), and every point after offset by half \
             the play along the axis' direction (inserted lines carry no N number)",
        );
        say(
            &self.backlash_whole,
            "kept whole for cutter compensation or not backlash-corrected: no take-up move \
             inserted, so the play is crossed along the move (arcs: not offset)",
        );
        say(
            out_of_box,
            "points outside the volumetric map's box: compensated with the error at the nearest \
             point of the box (out_of_box, as the predict route)",
        );
    }
}

/// Which moves must come back as one block: a move that carries G40, G41 or G42, and the
/// first move after it (a controller starts or ends its cutter compensation on them, and
/// checks their lengths against the tool radius; a point inserted before their end moves
/// the tool centre by up to the radius).
#[derive(Default)]
pub(super) struct WholeMoves {
    /// Moves still to keep whole.
    pending: usize,
}

impl WholeMoves {
    /// Whether the line `info` (read in order) must stay one block.
    pub(super) fn next(&mut self, info: &LineInfo) -> bool {
        let comp = info
            .spans
            .iter()
            .any(|s| s.letter == 'G' && matches!((s.value * 10.0).round() as i64, 400 | 410 | 420));
        if comp {
            // On a move: this move and the next; alone on its line: the next two.
            self.pending = 2;
        }
        if info.moves && self.pending > 0 {
            self.pending -= 1;
            return true;
        }
        false
    }
}

/// The plan of one line the reader read; `tol.0` is the tolerance (mm), `tol.1` asks for
/// one block ([`WholeMoves`]).
fn plan_line(
    line: usize,
    info: &LineInfo,
    frame: &LineFrame,
    blocks: &[&Block],
    (shifter, rev, drift): (&mut Shifter<'_>, &mut Reversals, [f64; 3]),
    (tol, whole): (f64, bool),
    notes: &mut Notes,
) -> (LinePlan, Vec<usize>) {
    let plan = |p: LinePlan| (p, Vec::new());
    if info.machine_move {
        notes.machine_moves.push(line);
        return plan(LinePlan::Keep);
    }
    if info.dwell || !info.moves {
        return plan(LinePlan::Keep);
    }
    if blocks.is_empty() {
        notes.unplaced.push(line);
        return plan(LinePlan::Keep);
    }
    if blocks.iter().any(|b| b.rtcp) {
        notes.rtcp.push(line);
        return plan(LinePlan::Keep);
    }
    if info.is_hole() {
        if frame.incremental {
            notes.incremental_cycles.push(line);
            return plan(LinePlan::Keep);
        }
        let Some(feed) = blocks
            .iter()
            .find(|b| b.feed != Feed::Rapid && b.motion == Motion::Linear)
        else {
            notes.unplaced.push(line);
            return plan(LinePlan::Keep);
        };
        notes.holes.push(line);
        // The first feed starts at R; the bottom is the deepest feed end (G73/G83 feed in
        // pecks, G74/G84/G85/G89 feed back out).
        let r_plane = feed.start.xyz;
        let bottom = blocks
            .iter()
            .filter(|b| b.feed != Feed::Rapid && b.motion == Motion::Linear)
            .map(|b| b.end.xyz)
            .fold(feed.end.xyz, |a, b| if b[2] < a[2] { b } else { a });
        // a cycle's moves are not followed for backlash: its points carry the drift alone
        shifter.bias = sub([0.0; 3], drift);
        let eb = shifter.error(line, bottom);
        let er = shifter.error(line, r_plane);
        let last_z = blocks.last().map(|b| b.end.xyz[2]).unwrap_or(r_plane[2]);
        return plan(LinePlan::Hole {
            xy_mm: [bottom[0] - eb[0], bottom[1] - eb[1]],
            r_z_mm: r_plane[2] - er[2],
            bottom_z_mm: bottom[2] - eb[2],
            at_r_after: (last_z - r_plane[2]).abs() < 1e-9,
        });
    }
    let [block] = blocks else {
        notes.unplaced.push(line);
        return plan(LinePlan::Keep);
    };
    let end = block.end.xyz;
    let start = block.start.xyz;
    // The drift of this line's time holds for its points, the play's offset as it turns.
    shifter.bias = sub(rev.bias(), drift);
    // A take-up smaller than the printed digits cannot be written: its offset still holds.
    let writable = |a: [f64; 3], b: [f64; 3]| norm(sub(a, b)) > 2.0 * rounding_mm(frame.inch);
    match block.motion {
        Motion::Dwell { .. } => plan(LinePlan::Keep),
        Motion::Linear if block.feed == Feed::Rapid => {
            rev.turn(sub(end, start));
            shifter.bias = sub(rev.bias(), drift);
            plan(LinePlan::Rapid {
                end_mm: shifter.compensate(line, end),
            })
        }
        Motion::Linear => {
            let before = shifter.comp(start);
            let turned = rev.turn(sub(end, start));
            if turned && whole {
                notes.backlash_whole.push(line);
            }
            shifter.bias = sub(rev.bias(), drift);
            let mut pts = linear_points(shifter, line, start, end, tol, whole);
            if pts.len() > 1 {
                notes.split.push(line);
            }
            let mut took = Vec::new();
            let at = shifter.comp(start);
            if turned && !whole && writable(at, before) {
                pts.insert(0, shifter.compensate(line, start));
                took.push(0);
                notes.takeups.push(line);
            }
            if pts.len() == 1 {
                (LinePlan::Move { end_mm: pts[0] }, took)
            } else {
                let feeds = inverse_time_feeds(block, &pts, before);
                let points = LinePlan::Points {
                    points_mm: pts,
                    feeds,
                    dwells_s: Vec::new(),
                };
                (points, took)
            }
        }
        Motion::Arc {
            plane,
            center,
            sweep_rad,
        } => {
            // Split where an axis of the plane reverses; each stretch takes its directions
            // (a take-up move where they change) and is written with their offsets.
            let cuts = if whole || !rev.any() {
                if whole && rev.any() {
                    notes.backlash_whole.push(line);
                }
                Vec::new()
            } else {
                arc_reversals(plane, block, center, sweep_rad)
            };
            let bounds: Vec<f64> = std::iter::once(0.0)
                .chain(cuts)
                .chain(std::iter::once(1.0))
                .collect();
            let first = shifter.comp(start);
            let mut pieces = Vec::new();
            let mut took = Vec::new();
            let mut split = false;
            for w in bounds.windows(2) {
                if !whole {
                    let before = shifter.comp(arc_point(block, plane, center, sweep_rad, w[0]));
                    let dirs = arc_directions(plane, block, center, sweep_rad, (w[0], w[1]));
                    if rev.turn(dirs) {
                        shifter.bias = sub(rev.bias(), drift);
                        let p = arc_point(block, plane, center, sweep_rad, w[0]);
                        if writable(shifter.comp(p), before) {
                            took.push(pieces.len());
                            pieces.push(PathPiece::Line(shifter.compensate(line, p)));
                        }
                    }
                }
                let arcs = arc_pieces(
                    shifter,
                    line,
                    block,
                    plane,
                    center,
                    sweep_rad,
                    tol,
                    whole,
                    (w[0], w[1]),
                );
                split |= arcs.len() > 1;
                pieces.extend(arcs.into_iter().map(PathPiece::Arc));
            }
            if split {
                notes.split_arcs.push(line);
            }
            let (p0, p1, _) = plane.axes();
            let r0 = (start[p0] - center[p0]).hypot(start[p1] - center[p1]);
            if took.is_empty() {
                let subs: Vec<_> = pieces
                    .iter()
                    .filter_map(|p| match p {
                        PathPiece::Arc(a) => Some(*a),
                        PathPiece::Line(_) => None,
                    })
                    .collect();
                let shares: Vec<f64> = subs.iter().map(|a| a.sweep_rad.abs()).collect();
                let feeds = inverse_time_shares(block, &shares);
                return (
                    LinePlan::Arcs {
                        pieces: subs,
                        plane,
                        feeds,
                    },
                    took,
                );
            }
            notes.takeups.push(line);
            let mut prev = first;
            let lengths: Vec<f64> = pieces
                .iter()
                .map(|p| match p {
                    PathPiece::Line(q) => {
                        let l = norm(sub(*q, prev));
                        prev = *q;
                        l
                    }
                    PathPiece::Arc(a) => {
                        prev = a.end_mm;
                        a.sweep_rad.abs() * r0
                    }
                })
                .collect();
            let feeds = inverse_time_shares(block, &lengths);
            (
                LinePlan::Path {
                    pieces,
                    plane,
                    feeds,
                },
                took,
            )
        }
    }
}

/// Under G93 every piece of a split block carries its own F: the block's F (1/min) over the
/// piece's share of the block (`shares`: any measure of each piece's length).
fn inverse_time_shares(block: &Block, shares: &[f64]) -> Option<Vec<f64>> {
    let Feed::InverseTime(f) = block.feed else {
        return None;
    };
    let total: f64 = shares.iter().sum();
    Some(
        shares
            .iter()
            .map(|l| if *l > 0.0 { f * total / l } else { f })
            .collect(),
    )
}

/// [`inverse_time_shares`] of straight pieces from `start` through `pts` (mm).
fn inverse_time_feeds(block: &Block, pts: &[[f64; 3]], start: [f64; 3]) -> Option<Vec<f64>> {
    let mut prev = start;
    let lens: Vec<f64> = pts
        .iter()
        .map(|p| {
            let l = crate::numeric::vec3::norm(crate::numeric::vec3::sub(*p, prev));
            prev = *p;
            l
        })
        .collect();
    inverse_time_shares(block, &lens)
}
