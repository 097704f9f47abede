//! Both readers' moves as LinuxCNC's canonical calls, and their comparison: every move's kind
//! (STRAIGHT_TRAVERSE, STRAIGHT_FEED, ARC_FEED), source line and end point; every arc's plane,
//! centre and turns (the sign is the direction); every feed move's feed rate in force
//! (mm/min; under G93 the rate that makes the block take 1/F minutes, programmed length × F).
//!
//! truecut's blocks map one to one: a G0 block is a traverse, a G1 or cycle feed a straight
//! feed, an arc (`Motion::Arc { plane, center, sweep_rad }`) an ARC_FEED with the centre's
//! plane components and turns = sign(sweep) × the turns begun (a full circle is ±1). Dwells
//! are not motion and not compared (and G4 P's unit is a dialect difference). Moves of zero
//! length other than arcs are dropped on both sides: they move nothing, and the two
//! interpreters differ in whether they emit them.
//!
//! Named adjustments (module docs of `main`): [`DIALECT_TAP_BORE_RETRACT`] and
//! [`DIALECT_G98_ACROSS`] on the oracle's side, and a zero-depth last peck counted once on
//! both sides ([`without_zero_pecks`]).

use std::collections::BTreeSet;
use std::f64::consts::TAU;

use truecut::motion::gcode::{Block, Feed, Motion, Plane, word_spans};

use crate::rs274::OracleMove;

/// G84/G74/G89 with G98: the oracle's feed-out is cut at the R plane and rapids on (Fanuc).
pub const DIALECT_TAP_BORE_RETRACT: &str = "G84/G74/G89 with G98: LinuxCNC feeds out to the \
     initial level, Fanuc (truecut) feeds out to R and rapids to the initial level";

/// A G98 hole line reached from below the clearance level (after G99 holes): the oracle's
/// rise during the move across is flattened to the level the tool is at.
pub const DIALECT_G98_ACROSS: &str = "a G98 hole after G99 holes: LinuxCNC rises to the \
     initial level while it moves across to the hole, Fanuc (truecut) moves across at the R \
     plane where the tool is and returns to the initial level after the hole";

/// An F on the line of a G20/G21: the oracle's feed is read in the line's new unit
/// (`rs274::parse`).
pub const DIALECT_F_WITH_UNITS: &str = "an F on the line of a G20/G21: LinuxCNC sets the feed \
     before it changes units (its order of execution), Fanuc (truecut) reads the F in the \
     line's new unit";

/// Under G93 LinuxCNC runs no block slower than 0.1 program units a minute.
pub const DIALECT_G93_FLOOR: &str = "G93 on a block so short that 1/F minutes is slower than 0.1 \
     units/min: LinuxCNC runs it at 0.1 units/min, Fanuc (truecut) takes the 1/F minutes";
/// The floor of [`DIALECT_G93_FLOOR`], program units per minute.
const G93_FLOOR_PER_MIN: f64 = 0.1;

/// Largest |difference| of two exact numbers, mm (or mm/min).
pub const TOLERANCE_MM: f64 = 1e-6;

/// What a move is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    Traverse,
    Feed,
    Arc,
}

/// An arc's plane, centre (mm, the plane's first and second axes) and turns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArcOf {
    pub plane: Plane,
    pub centre: [f64; 2],
    pub turns: i32,
}

/// One canonical move.
#[derive(Clone, Debug)]
pub struct Canon {
    pub line: usize,
    pub kind: Kind,
    pub end: [f64; 3],
    pub arc: Option<ArcOf>,
    /// Feed moves and arcs: the feed rate in force, mm/min.
    pub feed_mm_min: Option<f64>,
    /// mm per printed unit of the points and of the feed (1 on truecut's side: exact).
    pub unit_mm: f64,
    pub feed_unit_mm: f64,
}

pub fn same(a: &[f64; 3], b: &[f64; 3]) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() <= 1e-7)
}

/// truecut's blocks as canonical moves.
pub fn from_blocks(blocks: &[Block]) -> Vec<Canon> {
    let mut out = Vec::new();
    for b in blocks {
        let (kind, arc) = match b.motion {
            Motion::Dwell { .. } => continue,
            Motion::Linear if same(&b.start.xyz, &b.end.xyz) => continue,
            Motion::Linear if b.feed == Feed::Rapid => (Kind::Traverse, None),
            Motion::Linear => (Kind::Feed, None),
            Motion::Arc {
                plane,
                center,
                sweep_rad,
            } => {
                let (a0, a1, _) = plane.axes();
                let begun = ((sweep_rad.abs() / TAU) - 1e-9).ceil().max(1.0) as i32;
                let turns = if sweep_rad > 0.0 { begun } else { -begun };
                let centre = [center[a0], center[a1]];
                (
                    Kind::Arc,
                    Some(ArcOf {
                        plane,
                        centre,
                        turns,
                    }),
                )
            }
        };
        let feed_mm_min = match b.feed {
            Feed::Rapid => None,
            Feed::PerMinute(f) => Some(f),
            Feed::InverseTime(f) => Some(f * inverse_time_length_mm(b)),
        };
        out.push(Canon {
            line: b.line,
            kind,
            end: b.end.xyz,
            arc,
            feed_mm_min,
            unit_mm: 1.0,
            feed_unit_mm: 1.0,
        });
    }
    without_zero_pecks(out)
}

/// A block's length as LinuxCNC measures it for G93: an arc by its start radius
/// (`find_arc_length`; truecut's `xyz_length` takes the mean of the start and end radii, which
/// differ by the program's rounding), mm.
fn inverse_time_length_mm(b: &Block) -> f64 {
    match b.motion {
        Motion::Arc {
            plane,
            center,
            sweep_rad,
        } => {
            let (a0, a1, n) = plane.axes();
            let r = (b.start.xyz[a0] - center[a0]).hypot(b.start.xyz[a1] - center[a1]);
            (r * sweep_rad).hypot(b.end.xyz[n] - b.start.xyz[n])
        }
        _ => b.xyz_length(),
    }
}

/// The cycle lines the named adjustments look at.
#[derive(Clone, Debug, Default)]
pub struct CycleLines {
    /// G84/G74/G89 with G98 (see [`DIALECT_TAP_BORE_RETRACT`]).
    pub feed_out: BTreeSet<usize>,
    /// Every hole line under G98 (see [`DIALECT_G98_ACROSS`]).
    pub g98: BTreeSet<usize>,
}

/// The cycle lines of `text`.
pub fn cycle_lines(text: &str) -> CycleLines {
    let (mut cycle, mut g98) = (None, true);
    let mut out = CycleLines::default();
    for (i, raw) in text.lines().enumerate() {
        for w in word_spans(raw).iter().filter(|w| w.letter == 'G') {
            let g = (w.value * 10.0).round() as u32;
            match g {
                0 | 10 | 20 | 30 | 800 => cycle = None,
                730 | 740 | 810..=890 => cycle = Some(g),
                980 => g98 = true,
                990 => g98 = false,
                _ => {}
            }
        }
        if matches!(cycle, Some(740 | 840 | 890)) && g98 {
            out.feed_out.insert(i + 1);
        }
        if cycle.is_some() && g98 {
            out.g98.insert(i + 1);
        }
    }
    out
}

/// The oracle's moves as canonical moves, with the named dialect adjustments on the cycle
/// lines `cycles`: feed out to R, then a traverse on ([`DIALECT_TAP_BORE_RETRACT`]); across
/// at the level the tool is at ([`DIALECT_G98_ACROSS`]).
pub fn from_oracle(moves: &[OracleMove], cycles: &CycleLines) -> Vec<Canon> {
    let clip = &cycles.feed_out;
    let mut out = Vec::new();
    let mut at = [0.0; 3];
    let mut r_plane: Option<(usize, f64)> = None;
    let mut skip_next = false;
    for (i, m) in moves.iter().enumerate() {
        if std::mem::take(&mut skip_next) {
            at = m.xyz_mm;
            continue;
        }
        let line = m.n.unwrap_or(0);
        // A G98 hole reached from below the clearance level: LinuxCNC rises while it moves
        // across, then comes down to where the tool was; Fanuc moves across at that level.
        if !m.feed && cycles.g98.contains(&line) && m.xyz_mm[2] > at[2] {
            let next = moves.get(i + 1);
            if let Some(n) = next
                && !n.feed
                && n.n == m.n
                && n.xyz_mm[2] == at[2]
                && (n.xyz_mm[0], n.xyz_mm[1]) == (m.xyz_mm[0], m.xyz_mm[1])
                && (m.xyz_mm[0], m.xyz_mm[1]) != (at[0], at[1])
            {
                let mut across = m.xyz_mm;
                across[2] = at[2];
                out.push(Canon {
                    line,
                    kind: Kind::Traverse,
                    end: across,
                    arc: None,
                    feed_mm_min: None,
                    unit_mm: m.unit_mm,
                    feed_unit_mm: m.feed_unit_mm,
                });
                skip_next = true;
                at = m.xyz_mm;
                continue;
            }
        }
        let line = m.n.unwrap_or(0);
        let moved = m.arc || !same(&at, &m.xyz_mm);
        let kind = match (m.feed, m.arc) {
            (_, true) => Kind::Arc,
            (true, false) => Kind::Feed,
            (false, false) => Kind::Traverse,
        };
        let canon = |end: [f64; 3], kind: Kind| Canon {
            line,
            kind,
            end,
            arc: m.arc_geometry.map(|a| ArcOf {
                plane: a.plane,
                centre: a.centre_mm,
                turns: a.turns,
            }),
            feed_mm_min: (kind != Kind::Traverse).then_some(m.feed_mm_min),
            unit_mm: m.unit_mm,
            feed_unit_mm: m.feed_unit_mm,
        };
        if m.feed && !m.arc && clip.contains(&line) {
            match r_plane {
                Some((l, r)) if l == line && m.xyz_mm[2] > r => {
                    let mut to_r = m.xyz_mm;
                    to_r[2] = r;
                    if !same(&at, &to_r) {
                        out.push(canon(to_r, Kind::Feed));
                    }
                    if !same(&to_r, &m.xyz_mm) {
                        out.push(canon(m.xyz_mm, Kind::Traverse));
                    }
                    at = m.xyz_mm;
                    continue;
                }
                Some((l, _)) if l == line => {}
                _ => r_plane = Some((line, at[2])),
            }
        }
        if moved {
            out.push(canon(m.xyz_mm, kind));
        }
        at = m.xyz_mm;
    }
    without_zero_pecks(out)
}

/// A zero-depth last peck counted once: when Z − R is a whole number of pecks (G73/G83),
/// rounding decides whether an interpreter adds a peck of zero depth (rs274 compares floats
/// exactly, in program units). A feed on one line that ends where the last feed of that line
/// ended, with only traverses between, is dropped with those traverses.
pub fn without_zero_pecks(moves: Vec<Canon>) -> Vec<Canon> {
    let mut out: Vec<Canon> = Vec::with_capacity(moves.len());
    for m in moves {
        if m.kind == Kind::Feed {
            let last_feed = out.iter().rposition(|q| q.kind != Kind::Traverse);
            if let Some(i) = last_feed
                && out[i].kind == Kind::Feed
                && out[i].line == m.line
                && out[i + 1..].iter().all(|q| q.line == m.line)
                && same(&out[i].end, &m.end)
            {
                out.truncate(i + 1);
                continue;
            }
        }
        out.push(m);
    }
    out
}

/// How truecut's points are held against the oracle's printout.
#[derive(Clone, Copy, PartialEq, Debug)]
pub enum Match {
    /// End points within [`TOLERANCE_MM`] as they are (the generated programs: their
    /// numbers are exact in four decimals); arc centres and feeds as printed.
    Exact,
    /// Everything within half the printout's last digit (0.00005 of its unit: 0.05 µm in mm,
    /// 1.27 µm in inch) plus [`TOLERANCE_MM`]: numbers with more digits than rs274 prints.
    AsPrinted,
    /// [`Match::AsPrinted`], and source lines not compared: under cutter compensation rs274
    /// names a held move by the line that released it (see `rs274`).
    Compensated,
}

/// What a comparison counted.
#[derive(Clone, Copy, Debug, Default)]
pub struct Counts {
    pub moves: usize,
    pub traverses: usize,
    pub feeds: usize,
    pub arcs: usize,
    pub feed_rates: usize,
    /// Worst |difference| of an end point before the printout's rounding, mm.
    pub worst_mm: f64,
}

impl std::ops::AddAssign for Counts {
    fn add_assign(&mut self, o: Counts) {
        self.moves += o.moves;
        self.traverses += o.traverses;
        self.feeds += o.feeds;
        self.arcs += o.arcs;
        self.feed_rates += o.feed_rates;
        self.worst_mm = self.worst_mm.max(o.worst_mm);
    }
}

/// |a − b| beyond the allowed difference (0 when within): `slack` of printed rounding.
fn beyond(a: f64, b: f64, slack: f64) -> f64 {
    ((a - b).abs() - slack - TOLERANCE_MM).max(0.0)
}

/// Compares `want` (the oracle's) with `got` (truecut's), move by move.
pub fn compare(want: &[Canon], got: &[Canon], how: Match) -> Result<Counts, String> {
    let mut c = Counts::default();
    for (i, (w, g)) in want.iter().zip(got).enumerate() {
        let fail = |what: String| {
            Err(format!(
                "move {i}: {what}\n  rs274:   {w:?}\n  truecut: {g:?}"
            ))
        };
        if w.kind != g.kind {
            return fail("kinds differ".into());
        }
        if how != Match::Compensated && w.line != g.line {
            return fail("source lines differ".into());
        }
        let half = 0.5e-4 * w.unit_mm;
        let end_slack = if how == Match::Exact { 0.0 } else { half };
        for k in 0..3 {
            if beyond(w.end[k], g.end[k], end_slack) > 0.0 {
                return fail(format!("end points differ on axis {k}"));
            }
            c.worst_mm = c.worst_mm.max((w.end[k] - g.end[k]).abs());
        }
        match (&w.arc, &g.arc) {
            (Some(a), Some(b)) => {
                if a.plane != b.plane || a.turns != b.turns {
                    return fail("arc planes or turns differ".into());
                }
                if (0..2).any(|k| beyond(a.centre[k], b.centre[k], half) > 0.0) {
                    return fail("arc centres differ".into());
                }
                c.arcs += 1;
            }
            (None, None) => {}
            _ => return fail("one is an arc".into()),
        }
        match (w.feed_mm_min, g.feed_mm_min) {
            (Some(a), Some(b)) => {
                let slack = 0.5e-4 * w.feed_unit_mm + 1e-9 * a.abs();
                let floor = G93_FLOOR_PER_MIN * w.feed_unit_mm;
                let floored = beyond(a, floor, 0.5e-4 * w.feed_unit_mm) == 0.0 && b < floor;
                if beyond(a, b, slack) > 0.0 && !floored {
                    return fail("feed rates differ".into());
                }
                c.feed_rates += 1;
            }
            (None, None) => {}
            _ => return fail("one has no feed rate".into()),
        }
        c.moves += 1;
        match w.kind {
            Kind::Traverse => c.traverses += 1,
            Kind::Feed => c.feeds += 1,
            Kind::Arc => {}
        }
    }
    if want.len() != got.len() {
        let i = want.len().min(got.len());
        return Err(format!(
            "rs274 has {} moves, truecut {}; first unmatched: rs274 {:?}, truecut {:?}",
            want.len(),
            got.len(),
            want.get(i),
            got.get(i)
        ));
    }
    Ok(c)
}
