//! The safety invariants of every compensated program (issue 39, item 1; item 4's last
//! part), checked on LinuxCNC's canonical moves: every answer of `compensated-program`
//! (volumetric, contour, both; `crate::compensated::answers`, shared with the validity test)
//! of every program of `tests/data/programs` (real posts and held-out contours) and of the
//! canned-cycle programs is re-read by rs274 beside its original, both with a tool table of
//! the tools' real diameters (`crate::posts::POST_DIAMETERS_MM`, in inches as standalone
//! rs274 reads them). The moves are taken to the machine frame with the work offset and tool
//! length truecut's reader has in force on their line, and each is attributed to its source
//! line (`source_lines`). Checked ([`Rule`]):
//!
//! - **cutter**: a move that carries G40/G41/G42, and the first move after it, is one answer
//!   line; rs274 reads the answer (it refuses entry moves shorter than the radius) and makes
//!   as many moves of that source line as of the original's, each ending where the
//!   original's does less e(p) (volumetric) within [`END_MM`] plus the printout's rounding.
//! - **feed**: no feed move runs faster than the original's moves of its source line, nor
//!   faster than an axis' `max_vel`; F words have at most the source's decimals (and its
//!   trailing `.`), and an F not copied from the source changes the feed in force.
//! - **floor**: the lowest Z of each cutting level (the feed moves between two rapids) of
//!   the original; no commanded point (ends, and 16 points along each move) of the answer's
//!   level goes more than [`FLOOR_MM`] below it, nor any point of the answer simulated on the
//!   contour machine (nominal servo; the real tool point q + e(q) where the map applies).
//!   The simulated floor is the lower of the floor and the original's own simulated lowest
//!   point in the level (a servo that overshoots the original's plunge overshoots the same
//!   plunge kept as programmed; that is not the compensation's doing and is reported).
//! - **band**: where no G41/G42 gives the material side, the contour answer (as read back
//!   and simulated on every model of the set by `judge`, truecut's reader: rs274's agreement
//!   with it is the other tests' work) stays within the band on both sides wherever the
//!   original did: its `gouge_mm` is ≤ 0.
//! - **dwell**: rs274 dwells as often and as long in the answer as in the original, at the
//!   same source lines, and every G4 line of the answer is its source's line as written.
//! - **arc**: every move of an original arc's source line is an arc in the answer.
//! - **budget**: volumetric answers have at most [`VOLUMETRIC_BUDGET`] × the feed moves that
//!   0.5 µm linearity of e(p) along each original feed move needs; contour answers at most 3 ×
//!   the original's lines (and feed moves) + 50, and a source line gains moves only where it
//!   is an arc or touches a corner (a turn of at least `CORNER_MIN_RAD`); an answer of both
//!   at most 3 × its volumetric answer + 50.
//! - **words**: a rapid's line keeps its letters; in contour mode a 2-D cut gets no Z word
//!   and a pure Z move no X/Y word (and rs274's Z of it is the original's); every axis word
//!   the source line did not write moves its axis by more than half the last printed digit
//!   (on rs274's points in mm, on truecut's re-reading in inch, where rs274 prints fewer
//!   decimals than the answer has); inserted lines carry no N number (the service's stated
//!   rule) and a source line's first answer line keeps its N.
//!
//! Cases rs274 cannot read even as originals (G87: `valid::rs274_cannot`) are listed with
//! the reason; a case with any violation fails the test. The table printed per program and
//! mode gives the closing figures. Module `mutants` breaks answers by hand, one
//! invariant each, and holds that every break is caught by its rule. Files: `check` (one
//! case), `words` (the word rules), `mutants`.

use std::path::Path;

use truecut::motion::gcode::{Block, Feed, LineFrame, Motion, Plane, Pose, word_spans};
use truecut::motion::{DEFAULT_PERIOD_S, Machine, PathControl, Program, predict_program_with};

use crate::compensated::{Answered, answers, setup};
use crate::rs274;

/// How far below a level's floor a point may go, mm (issue 39: 1 µm).
pub const FLOOR_MM: f64 = 1e-3;
/// How far a kept-whole cutter-compensation move may end from the original's end less e(p),
/// mm: the 1 µm of the volumetric check (`valid::TOLERANCE_MM`).
pub const END_MM: f64 = 1e-3;
/// Linearity of e(p) the volumetric block budget is counted at, mm (issue 39: 0.5 µm).
pub const NEED_LINEARITY_MM: f64 = 5e-4;
/// Volumetric answers' feed moves over the moves 0.5 µm linearity needs (issue 39: 1.5).
pub const VOLUMETRIC_BUDGET: f64 = 1.5;
/// Contour answers: at most this many times the original's blocks...
pub const CONTOUR_FACTOR: usize = 3;
/// ...plus this many (issue 39).
pub const CONTOUR_EXTRA: usize = 50;
/// Points sampled along a move for the floor (with an arc's lowest point, found exactly) and
/// for e(p)'s linearity (ends excluded): e of a map varies over tens of mm, 16 points a piece
/// see its bending within a piece.
const SAMPLES: usize = 16;
/// Longest simulated program, periods (the route's limit, `predistort::MAX_PERIODS`).
const MAX_PERIODS: usize = truecut::cam::predistort::MAX_PERIODS;
/// Half a digit of rs274's printout (four decimals of the unit), per axis.
const PRINT_HALF_DIGIT: f64 = 0.5e-4;

/// The invariants (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Rule {
    Cutter,
    Feed,
    Floor,
    Band,
    Dwell,
    Arc,
    Budget,
    Words,
}

/// A canonical move of rs274 in the machine frame.
#[derive(Clone, Debug)]
struct Mv {
    /// Line of the file rs274 read (answer line, or original line).
    line: usize,
    /// Source line of the original.
    src: usize,
    start: [f64; 3],
    end: [f64; 3],
    feed: bool,
    /// Plane, centre (machine frame, the plane's two axes) and turns.
    arc: Option<(Plane, [f64; 2], i32)>,
    feed_mm_min: f64,
    /// mm per printed unit of the feed, and of the points.
    feed_unit_mm: f64,
    unit_mm: f64,
}

impl Mv {
    /// An arc's signed sweep, rad (> 0 counter-clockwise in its plane), from its turns.
    fn sweep(&self) -> f64 {
        let Some((plane, c, turns)) = self.arc else {
            return 0.0;
        };
        let (a0, a1, _) = plane.axes();
        let ang = |p: [f64; 3]| (p[a1] - c[1]).atan2(p[a0] - c[0]);
        let tau = std::f64::consts::TAU;
        let mut sweep = ang(self.end) - ang(self.start);
        let dir = f64::from(turns.signum());
        while sweep * dir <= 1e-12 {
            sweep += dir * tau;
        }
        while sweep * dir > tau + 1e-12 {
            sweep -= dir * tau;
        }
        sweep + f64::from(turns.abs() - 1) * tau * dir
    }

    /// The point at fraction `t` of the move, mm.
    fn at(&self, t: f64) -> [f64; 3] {
        let (s, e) = (self.start, self.end);
        let lin = |k: usize| s[k] + (e[k] - s[k]) * t;
        let Some((plane, c, _)) = self.arc else {
            return [0, 1, 2].map(lin);
        };
        let (a0, a1, an) = plane.axes();
        let (rs, re) = (
            (s[a0] - c[0]).hypot(s[a1] - c[1]),
            (e[a0] - c[0]).hypot(e[a1] - c[1]),
        );
        let rho = rs + (re - rs) * t;
        let ang = (s[a1] - c[1]).atan2(s[a0] - c[0]) + self.sweep() * t;
        let mut p = [0.0; 3];
        p[a0] = c[0] + rho * ang.cos();
        p[a1] = c[1] + rho * ang.sin();
        p[an] = lin(an);
        p
    }

    /// The fraction of an arc at which it passes its lowest Z, when its plane holds Z and
    /// it passes the circle's bottom.
    fn bottom(&self) -> Option<f64> {
        let (plane, c, _) = self.arc?;
        let (a0, a1, _) = plane.axes();
        let phi = match (a0, a1) {
            (2, _) => std::f64::consts::PI,
            (_, 2) => -std::f64::consts::FRAC_PI_2,
            _ => return None,
        };
        let s = self.start;
        let ang0 = (s[a1] - c[1]).atan2(s[a0] - c[0]);
        let sweep = self.sweep();
        let tau = std::f64::consts::TAU;
        let d = if sweep > 0.0 {
            (phi - ang0).rem_euclid(tau)
        } else {
            -(ang0 - phi).rem_euclid(tau)
        };
        let t = d / sweep;
        (0.0..=1.0).contains(&t).then_some(t)
    }

    /// The ends, [`SAMPLES`] points between, and an arc's lowest point.
    fn points(&self) -> Vec<[f64; 3]> {
        let mut out: Vec<[f64; 3]> = (0..=SAMPLES + 1)
            .map(|i| self.at(i as f64 / (SAMPLES + 1) as f64))
            .collect();
        out.extend(self.bottom().map(|t| self.at(t)));
        out
    }
}

/// What rs274 made of one file: its moves and dwells (source line, seconds).
struct Reading {
    moves: Vec<Mv>,
    dwells: Vec<(usize, f64)>,
}

/// Runs rs274 on `text` (numbered, written as `dir/name.ngc`) with `table`, and takes its
/// moves to the machine frame by `frames` (truecut's reading of `text`); `src` maps a line
/// of `text` to the original's.
fn read(
    rs: &Path,
    dir: &Path,
    name: &str,
    text: &str,
    table: &Path,
    frames: &[LineFrame],
    src: &dyn Fn(usize) -> usize,
) -> Result<Reading, String> {
    let file = dir.join(format!("{name}.ngc"));
    std::fs::write(&file, crate::valid::for_rs274(text)).map_err(|e| e.to_string())?;
    let (out, _) = rs274::printout(rs, &file, Some(table))?;
    let oracle = rs274::parse(&out)?;
    let shift = |line: usize| {
        frames
            .iter()
            .find(|f| f.line == line)
            .map_or([0.0; 3], |f| f.shift_mm)
    };
    let mut moves: Vec<Mv> = Vec::with_capacity(oracle.len());
    let (mut at, mut last_line) = (None::<[f64; 3]>, 1);
    for m in &oracle {
        let line = m.n.unwrap_or(last_line);
        last_line = line;
        let sh = shift(line);
        let end = [0, 1, 2].map(|k| m.xyz_mm[k] + sh[k]);
        let arc = m.arc_geometry.map(|a| {
            let (a0, a1, _) = a.plane.axes();
            (
                a.plane,
                [a.centre_mm[0] + sh[a0], a.centre_mm[1] + sh[a1]],
                a.turns,
            )
        });
        moves.push(Mv {
            line,
            src: src(line),
            start: at.unwrap_or(end),
            end,
            feed: m.feed,
            arc,
            feed_mm_min: m.feed_mm_min,
            feed_unit_mm: m.feed_unit_mm,
            unit_mm: m.unit_mm,
        });
        at = Some(end);
    }
    let dwells = rs274::dwells(&out)
        .into_iter()
        .map(|(n, s)| (src(n.unwrap_or(0)), s))
        .collect();
    Ok(Reading { moves, dwells })
}

/// One case's figures and violations.
pub struct Report {
    pub tag: String,
    /// Why rs274 did not check it (the original is no LinuxCNC program).
    pub not_read: Option<String>,
    /// rs274's moves of the original and of the answer; lines of both.
    pub moves: (usize, usize),
    pub lines: (usize, usize),
    /// Feed moves 0.5 µm linearity of e(p) needs (volumetric and both).
    pub need: Option<usize>,
    pub arcs: (usize, usize),
    /// Answer lines (blocks) checked.
    pub checked: usize,
    pub violations: Vec<(Rule, String)>,
    /// What is worth saying that is no violation (the original's own simulated dips).
    pub notes: Vec<String>,
}

/// Lines (1-based) whose moves must stay whole: a move that carries G40/G41/G42 and the
/// first move after it (as `cam::program::WholeMoves` decides).
fn whole_lines(text: &str) -> Vec<usize> {
    let mut pending = 0;
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let w = word_spans(raw);
        let g = |v: f64| (v * 10.0).round() as i64;
        if w.iter()
            .any(|s| s.letter == 'G' && matches!(g(s.value), 400 | 410 | 420))
        {
            pending = 2;
        }
        let dwell = w.iter().any(|s| s.letter == 'G' && g(s.value) == 40);
        let moves = !dwell && w.iter().any(|s| matches!(s.letter, 'X' | 'Y' | 'Z'));
        if moves && pending > 0 {
            pending -= 1;
            out.push(i + 1);
        }
    }
    out
}

/// The fewest pieces of `m` along which e(p) is linear within [`NEED_LINEARITY_MM`]
/// (pieces grown in steps of 1/400 of the move while [`SAMPLES`] points of each stay
/// within it of the chord of e between the piece's ends).
fn need(e: &dyn Fn([f64; 3]) -> [f64; 3], m: &Mv) -> usize {
    const STEPS: usize = 400;
    let ev = |t: f64| e(m.at(t));
    let linear = |t0: f64, t1: f64| {
        let (e0, e1) = (ev(t0), ev(t1));
        (1..=SAMPLES).all(|k| {
            let u = k as f64 / (SAMPLES + 1) as f64;
            let q = ev(t0 + (t1 - t0) * u);
            let d: f64 = (0..3)
                .map(|i| (q[i] - e0[i] - (e1[i] - e0[i]) * u).powi(2))
                .sum();
            d.sqrt() <= NEED_LINEARITY_MM
        })
    };
    let step = 1.0 / STEPS as f64;
    let (mut pieces, mut t0) = (0, 0.0);
    while t0 < 1.0 - 1e-12 {
        let mut t1 = (t0 + step).min(1.0);
        while t1 < 1.0 && linear(t0, (t1 + step).min(1.0)) {
            t1 = (t1 + step).min(1.0);
        }
        pieces += 1;
        t0 = t1;
    }
    pieces
}

/// The moves of `r` as a program (machine frame) the contour machine can simulate; block
/// line = index of the move + 1.
fn as_program(moves: &[Mv]) -> Program {
    let pose = |xyz| Pose {
        xyz,
        a: 0.0,
        c: 0.0,
    };
    let blocks = moves
        .iter()
        .enumerate()
        .filter(|(_, m)| m.arc.is_some() || m.start != m.end)
        .map(|(i, m)| {
            let motion = match m.arc {
                None => Motion::Linear,
                Some((plane, c, _)) => {
                    let (a0, a1, _) = plane.axes();
                    let mut center = [0.0; 3];
                    center[a0] = c[0];
                    center[a1] = c[1];
                    Motion::Arc {
                        plane,
                        center,
                        sweep_rad: m.sweep(),
                    }
                }
            };
            Block {
                line: i + 1,
                motion,
                start: pose(m.start),
                end: pose(m.end),
                feed: if m.feed {
                    Feed::PerMinute(m.feed_mm_min)
                } else {
                    Feed::Rapid
                },
                rtcp: false,
            }
        })
        .collect();
    Program {
        blocks,
        ..Program::default()
    }
}

/// The lowest simulated real Z (mm, the tool point q + e(q)) per cutting level of `moves`
/// on `machine` (`level` of each move; feed moves only).
fn simulated_lows(
    machine: &Machine,
    moves: &[Mv],
    level: &[Option<usize>],
    e: &dyn Fn([f64; 3]) -> [f64; 3],
    levels: usize,
) -> Result<Vec<f64>, String> {
    let program = as_program(moves);
    let run = predict_program_with(
        machine,
        &program,
        &PathControl::default(),
        DEFAULT_PERIOD_S,
        MAX_PERIODS,
    )
    .map_err(|err| format!("cannot simulate: {err}"))?;
    let mut low = vec![f64::INFINITY; levels];
    for (i, &l) in run.commanded.line.iter().enumerate() {
        let i_move = l as usize - 1;
        let Some(k) = level[i_move] else {
            continue;
        };
        let q = [0, 1, 2].map(|a| run.actual[a][i]);
        let z = q[2] + e(q)[2];
        low[k] = low[k].min(z);
    }
    Ok(low)
}

mod check;
mod mutants;
mod words;
use check::check_case;

#[test]
fn every_compensated_answer_keeps_the_safety_invariants() {
    let Some(rs) = crate::oracle() else { return };
    let s = setup();
    let dir = tempfile::tempdir().unwrap();
    let table = crate::posts::post_tool_table(dir.path(), "tools.tbl");
    let all: &[Answered] = answers();
    let volumetric_lines = |name: &str| {
        all.iter()
            .find(|a| a.name == name && a.mode == "volumetric")
            .and_then(|a| a.answer.as_ref().ok())
            .map(|(c, _)| c.blocks)
    };
    let reports = crate::on_two_threads(all.len(), |i| {
        let a = &all[i];
        match &a.answer {
            Ok((c, p)) => check_case(
                a,
                c,
                p.as_ref(),
                volumetric_lines(&a.name),
                s,
                rs.as_path(),
                dir.path(),
                &table,
            ),
            Err(e) => Err(format!(
                "{}_{}: the service refused it: {e}",
                a.name, a.mode
            )),
        }
    });
    println!(
        "{:<34} {:>11} {:>13} {:>6} {:>9} {:>8} {:>10}",
        "case", "lines o->a", "moves o->a", "need", "arcs i/o", "checked", "violations"
    );
    let (mut checked, mut violations, mut failures, mut not_read) = (0, 0, Vec::new(), Vec::new());
    let mut by_rule = std::collections::BTreeMap::new();
    for r in &reports {
        let r = match r {
            Ok(r) => r,
            Err(e) => {
                failures.push(e.clone());
                continue;
            }
        };
        if let Some(why) = &r.not_read {
            not_read.push(format!("{}: {why}", r.tag));
            continue;
        }
        println!(
            "{:<34} {:>11} {:>13} {:>6} {:>9} {:>8} {:>10}",
            r.tag,
            format!("{}->{}", r.lines.0, r.lines.1),
            format!("{}->{}", r.moves.0, r.moves.1),
            r.need.map_or("-".to_string(), |n| n.to_string()),
            format!("{}/{}", r.arcs.0, r.arcs.1),
            r.checked,
            r.violations.len()
        );
        for n in &r.notes {
            println!("  note: {n}");
        }
        checked += r.checked;
        violations += r.violations.len();
        for (rule, v) in &r.violations {
            *by_rule.entry(*rule).or_insert(0) += 1;
            failures.push(format!("{}: {rule:?}: {v}", r.tag));
        }
    }
    println!(
        "invariants of issue 39 item 1 on rs274's canonical moves: {} answers, {checked} blocks \
         checked, {violations} violations {by_rule:?}; not read by rs274:\n  {}",
        reports.len(),
        not_read.join("\n  ")
    );
    assert!(checked > 0, "nothing was checked");
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
