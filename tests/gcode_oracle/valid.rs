//! Is a compensated program still a valid program? (issue 24, item 3.) Every answer of
//! `compensated-program` in the tests goes through [`check`]: it is re-read by truecut's
//! reader and by LinuxCNC's `rs274`; both must parse it, and every programmed point p of the
//! original must be hit at p − e(p) (e: the volumetric map's error, 0 without volumetric
//! compensation) within [`TOLERANCE_MM`].
//!
//! Programmed points, from truecut's reading of the original: the end of every G0/G1/G2/G3
//! line; for a canned-cycle hole its bottom (the deepest feed end: X Y Z) and its R plane (Z
//! at the start of the first feed). Not checked: G28/G30/G53 lines (machine positions, copied
//! uncompensated by design), axes the program has not yet placed absolutely (the service
//! writes no word for them), and, with `contour`, the ends of feed moves (pre-distorted by
//! design: their deviation is reported). The re-reading's point of a line is where the tool
//! is after it: the end of the last move of the answer's lines that come from source lines
//! up to it (`source_lines`).
//!
//! Structure, as the issue names it: every answer line has at most one motion code (G0..G3 or
//! a cycle), a rapid line's moves are all rapids, a hole's feed moves run at the programmed
//! feed, and a cycle line that had R still has it.
//!
//! rs274 reads the answer with every line numbered `N<answer line>` (so that its moves name
//! their line) and a tool table of zero lengths and diameters (so that G41/G42 leave the path
//! as programmed, as truecut reads it); its printout is in the program frame, which
//! is taken to the machine frame with the work offset and tool length truecut's reader has in
//! force on that line. It prints four decimals of the program's unit, so its points are held
//! within [`TOLERANCE_MM`] plus that rounding (0.05 µm per axis in mm, 1.27 µm in inch).

use std::path::Path;

use truecut::motion::gcode::{
    Block, Feed, LineFrame, Motion, ReadOptions, parse_traced, word_spans,
};

use crate::rs274;

/// Largest distance of a re-read point from p − e(p), mm (1 µm).
pub const TOLERANCE_MM: f64 = 1e-3;

/// What the service was asked for.
pub struct Asked<'a> {
    /// e(p) (mm) of the map the program was compensated against; None: no volumetric.
    pub error: Option<&'a dyn Fn([f64; 3]) -> [f64; 3]>,
    /// Contour pre-distortion asked.
    pub contour: bool,
}

/// What the re-readings found.
#[derive(Clone, Debug)]
pub struct Checked {
    /// Programmed points held against p − e(p) (per re-reading).
    pub points: usize,
    /// Worst |q − (p − e(p))| on truecut's re-reading, mm.
    pub worst_truecut_mm: f64,
    /// The same on rs274's (before the printout's rounding is allowed for), or why rs274 did
    /// not read it.
    pub worst_rs274_mm: Result<f64, String>,
    /// With contour: worst |q − (p − e(p))| over feed-move ends (pre-distorted), mm.
    pub feed_ends_mm: f64,
}

/// How a source line is checked.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Skip,
    Rapid,
    Feed,
    Hole,
}

fn g10(v: f64) -> u32 {
    (v * 10.0).round() as u32
}

/// Per source line (index = line, 0 unused): its kind and the axes placed absolutely by it or
/// before it.
fn classify(text: &str, blocks: &[Vec<&Block>]) -> (Vec<Kind>, Vec<[bool; 3]>) {
    let mut kinds = vec![Kind::Skip];
    let mut placed_at = vec![[false; 3]];
    let (mut cycle, mut incremental, mut placed) = (false, false, [false; 3]);
    for (i, raw) in text.lines().enumerate() {
        let words = word_spans(raw);
        let gs: Vec<u32> = words
            .iter()
            .filter(|w| w.letter == 'G')
            .map(|w| g10(w.value))
            .collect();
        let machine = gs.iter().any(|g| matches!(g, 280 | 300 | 530));
        let dwell = gs.contains(&40);
        for &g in &gs {
            match g {
                0 | 10 | 20 | 30 | 800 => cycle = false,
                730 | 740 | 810..=890 if g % 10 == 0 => cycle = true,
                900 => incremental = false,
                910 => incremental = true,
                _ => {}
            }
        }
        let b = &blocks[i + 1];
        let kind = if machine || dwell || b.is_empty() {
            Kind::Skip
        } else if cycle && b.len() > 1 {
            Kind::Hole
        } else if b.iter().all(|b| b.feed == Feed::Rapid) {
            Kind::Rapid
        } else {
            Kind::Feed
        };
        if !machine && !dwell && !incremental {
            for (k, a) in ['X', 'Y', 'Z'].iter().enumerate() {
                placed[k] |= words.iter().any(|w| w.letter == *a);
            }
        }
        kinds.push(kind);
        placed_at.push(placed);
    }
    (kinds, placed_at)
}

/// One move of a re-reading: answer line, start and end (machine frame, mm), feed or rapid.
#[derive(Clone, Debug)]
struct Move {
    line: usize,
    start: [f64; 3],
    end: [f64; 3],
    feed: bool,
}

/// What a re-reading shows of each source line: where the tool is after it, and for holes
/// the bottom and the R plane's Z.
struct Seen {
    after: Vec<Option<[f64; 3]>>,
    bottom: Vec<Option<[f64; 3]>>,
    r_z: Vec<Option<f64>>,
}

fn seen(moves: &[Move], source_lines: &[usize], n_source: usize) -> Seen {
    let mut s = Seen {
        after: vec![None; n_source + 1],
        bottom: vec![None; n_source + 1],
        r_z: vec![None; n_source + 1],
    };
    for m in moves {
        let Some(&l) = source_lines.get(m.line.wrapping_sub(1)) else {
            continue;
        };
        if l > n_source {
            continue;
        }
        s.after[l] = Some(m.end);
        if m.feed {
            if s.r_z[l].is_none() {
                s.r_z[l] = Some(m.start[2]);
            }
            if s.bottom[l].is_none_or(|b| m.end[2] < b[2]) {
                s.bottom[l] = Some(m.end);
            }
        }
    }
    // Lines without a move of their own leave the tool where the line before left it.
    for l in 1..=n_source {
        if s.after[l].is_none() {
            s.after[l] = s.after[l - 1];
        }
    }
    s
}

/// Holds a re-reading against the expected points; returns (points, worst, worst feed end).
fn hold(
    name: &str,
    who: &str,
    seen: &Seen,
    expected: &[Expect],
    slack_mm: &dyn Fn(usize) -> f64,
) -> Result<(usize, f64, f64), String> {
    let (mut n, mut worst, mut feed_worst) = (0, 0.0f64, 0.0f64);
    for e in expected {
        let (got, want, axes) = match e.what {
            What::End(q) => (seen.after[e.line], q, e.axes),
            What::Bottom(q) => (seen.bottom[e.line], q, [true; 3]),
            What::RPlane(z) => (
                seen.r_z[e.line].map(|r| [0.0, 0.0, r]),
                [0.0, 0.0, z],
                [false, false, true],
            ),
        };
        let Some(got) = got else {
            return Err(format!(
                "{name}, {who}: line {}: no move found for {:?}",
                e.line, e.what
            ));
        };
        let d = (0..3)
            .filter(|&k| axes[k])
            .map(|k| (got[k] - want[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        if e.predistorted {
            feed_worst = feed_worst.max(d);
            continue;
        }
        n += 1;
        worst = worst.max(d);
        if d > TOLERANCE_MM + slack_mm(e.line) {
            return Err(format!(
                "{name}, {who}: line {}: {:?} re-read at {got:?}, p - e(p) is {want:?} (|d| {:.3} µm)",
                e.line,
                e.what,
                d * 1e3
            ));
        }
    }
    Ok((n, worst, feed_worst))
}

#[derive(Clone, Copy, Debug)]
enum What {
    End([f64; 3]),
    Bottom([f64; 3]),
    RPlane(f64),
}

struct Expect {
    line: usize,
    what: What,
    axes: [bool; 3],
    predistorted: bool,
}

fn moves_of(blocks: &[Block]) -> Vec<Move> {
    blocks
        .iter()
        .filter(|b| !matches!(b.motion, Motion::Dwell { .. }))
        .map(|b| Move {
            line: b.line,
            start: b.start.xyz,
            end: b.end.xyz,
            feed: b.feed != Feed::Rapid,
        })
        .collect()
}

/// `text` with every line that can carry one numbered `N<line>` (an existing leading N
/// replaced; `%`, program-number and empty lines left alone).
pub fn numbered(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + text.len() / 4);
    for (i, raw) in text.lines().enumerate() {
        let t = raw.trim_start();
        if t.is_empty() || t.starts_with(['%', 'O', 'o', ':']) {
            out += raw;
        } else {
            let (slash, rest) = match t.strip_prefix('/') {
                Some(r) => ("/", r.trim_start()),
                None => ("", t),
            };
            let rest = match rest.strip_prefix(['N', 'n']) {
                Some(r) if r.starts_with(|c: char| c.is_ascii_digit()) => {
                    r.trim_start_matches(|c: char| c.is_ascii_digit())
                }
                _ => rest,
            };
            out += &format!("{slash}N{} {}", i + 1, rest.trim_start());
        }
        out.push('\n');
    }
    out
}

/// `text` as rs274 is given it: [`numbered`], and ended by `M2` when it has no program end
/// (M2, M30 or a closing `%`; rs274 refuses a file without one, and the held-out contours
/// have none).
pub fn for_rs274(text: &str) -> String {
    let ends = text.trim_end().ends_with('%')
        || text
            .lines()
            .flat_map(word_spans)
            .any(|w| w.letter == 'M' && matches!(w.value as i64, 2 | 30));
    let mut out = numbered(text);
    if !ends {
        out += "M2\n";
    }
    out
}

/// Why rs274 cannot read even the original, or None.
pub fn rs274_cannot(original: &str) -> Option<&'static str> {
    let g87 = original
        .lines()
        .flat_map(word_spans)
        .any(|w| w.letter == 'G' && g10(w.value) == 870);
    g87.then_some(
        "G87 back boring: Fanuc takes Q with R as the bottom, LinuxCNC I J K (the original is \
         no LinuxCNC program either)",
    )
}

/// Re-reads `answer` (its lines' source lines `source_lines`) of the compensation `asked` of
/// `original`, both read with `options`, by truecut's reader and, when `rs274` is given, by
/// rs274 (files in `dir`); Err names the first failure. See the module docs.
#[allow(clippy::too_many_arguments)]
pub fn check(
    name: &str,
    original: &str,
    options: &ReadOptions,
    asked: &Asked<'_>,
    answer: &str,
    source_lines: &[usize],
    rs274: Option<&Path>,
    dir: &Path,
) -> Result<Checked, String> {
    let (src, _, _) =
        parse_traced(original, options).map_err(|e| format!("{name}: the original: {e}"))?;
    let (out, _, frames) = parse_traced(answer, options)
        .map_err(|e| format!("{name}: truecut's reader refuses the answer: {e}"))?;
    let out_lines: Vec<&str> = answer.lines().collect();
    if out_lines.len() != source_lines.len() {
        return Err(format!(
            "{name}: {} answer lines but {} source_lines",
            out_lines.len(),
            source_lines.len()
        ));
    }
    let n_source = original.lines().count();
    let mut by_line: Vec<Vec<&Block>> = vec![Vec::new(); n_source + 1];
    for b in &src.blocks {
        by_line[b.line].push(b);
    }
    let (kinds, placed) = classify(original, &by_line);
    // Structure.
    for (i, raw) in out_lines.iter().enumerate() {
        let motion = word_spans(raw)
            .iter()
            .filter(|w| w.letter == 'G')
            .filter(|w| matches!(g10(w.value), 0 | 10 | 20 | 30 | 730 | 740 | 810..=890))
            .count();
        if motion > 1 {
            return Err(format!(
                "{name}: answer line {}: two motion codes: {raw}",
                i + 1
            ));
        }
    }
    let mut out_by_source: Vec<Vec<&Block>> = vec![Vec::new(); n_source + 1];
    for b in &out.blocks {
        out_by_source[source_lines[b.line - 1]].push(b);
    }
    for l in 1..=n_source {
        let got = &out_by_source[l];
        match kinds[l] {
            Kind::Rapid if got.iter().any(|b| b.feed != Feed::Rapid) => {
                return Err(format!(
                    "{name}: line {l}: a rapid came back as a feed move"
                ));
            }
            Kind::Hole => {
                let want: Vec<Feed> = by_line[l]
                    .iter()
                    .filter(|b| b.feed != Feed::Rapid && b.motion == Motion::Linear)
                    .map(|b| b.feed)
                    .collect();
                let feeds: Vec<Feed> = got
                    .iter()
                    .filter(|b| b.feed != Feed::Rapid && b.motion == Motion::Linear)
                    .map(|b| b.feed)
                    .collect();
                if feeds.is_empty() || feeds.iter().any(|f| Some(f) != want.first()) {
                    return Err(format!(
                        "{name}: line {l}: the hole's feed moves run at {feeds:?}, programmed {:?}",
                        want.first()
                    ));
                }
                let had_r = word_spans(original.lines().nth(l - 1).unwrap_or(""))
                    .iter()
                    .any(|w| w.letter == 'R');
                let has_r = source_lines
                    .iter()
                    .zip(&out_lines)
                    .filter(|(s, _)| **s == l)
                    .any(|(_, raw)| word_spans(raw).iter().any(|w| w.letter == 'R'));
                if had_r && !has_r {
                    return Err(format!("{name}: line {l}: the cycle's R was dropped"));
                }
            }
            _ => {}
        }
    }
    // Programmed points.
    let zero = |_: [f64; 3]| [0.0; 3];
    let e: &dyn Fn([f64; 3]) -> [f64; 3] = asked.error.unwrap_or(&zero);
    let comp = |p: [f64; 3]| {
        let d = e(p);
        [p[0] - d[0], p[1] - d[1], p[2] - d[2]]
    };
    let mut expected = Vec::new();
    for l in 1..=n_source {
        let b = &by_line[l];
        match kinds[l] {
            Kind::Skip => {}
            Kind::Rapid | Kind::Feed => {
                let p = b[b.len() - 1].end.xyz;
                // A rapid gains no axis word (issue 39): the axes it does not name keep the
                // position the lines before it left, and are not compensated there.
                let raw = original.lines().nth(l - 1).unwrap_or("");
                let named = [0, 1, 2].map(|k| {
                    word_spans(raw)
                        .iter()
                        .any(|w| w.letter == ['X', 'Y', 'Z'][k])
                });
                let axes = [0, 1, 2].map(|k| placed[l][k] && (kinds[l] == Kind::Feed || named[k]));
                expected.push(Expect {
                    line: l,
                    what: What::End(comp(p)),
                    axes,
                    predistorted: asked.contour && kinds[l] == Kind::Feed,
                });
            }
            Kind::Hole => {
                let feeds: Vec<&&Block> = b
                    .iter()
                    .filter(|b| b.feed != Feed::Rapid && b.motion == Motion::Linear)
                    .collect();
                let r = feeds[0].start.xyz;
                let bottom = feeds
                    .iter()
                    .map(|b| b.end.xyz)
                    .fold(feeds[0].end.xyz, |a, c| if c[2] < a[2] { c } else { a });
                expected.push(Expect {
                    line: l,
                    what: What::Bottom(comp(bottom)),
                    axes: [true; 3],
                    predistorted: false,
                });
                expected.push(Expect {
                    line: l,
                    what: What::RPlane(comp(r)[2]),
                    axes: [false, false, true],
                    predistorted: false,
                });
            }
        }
    }
    let truecut_seen = seen(&moves_of(&out.blocks), source_lines, n_source);
    let (points, worst_truecut_mm, feed_ends_mm) =
        hold(name, "truecut", &truecut_seen, &expected, &|_| 0.0)?;
    let worst_rs274_mm = match (rs274, rs274_cannot(original)) {
        (None, _) => Err("rs274 not installed".to_string()),
        (Some(_), Some(why)) => Err(why.to_string()),
        (Some(rs), None) => {
            let file = dir.join(format!("{name}.ngc"));
            std::fs::write(&file, for_rs274(answer)).map_err(|e| e.to_string())?;
            let tools = dir.join(format!("{name}.tbl"));
            let table: String = (1..=99).map(|t| format!("T{t} P{t} Z0 D0 ;\n")).collect();
            std::fs::write(&tools, table).map_err(|e| e.to_string())?;
            let moves = rs274::run_with_tools(rs, &file, Some(&tools))
                .map_err(|e| format!("{name}: rs274 refuses the answer: {e}"))?;
            let moves = machine_frame(&moves, &frames);
            let rs_seen = seen(&moves, source_lines, n_source);
            let unit = |l: usize| {
                let inch = frames
                    .iter()
                    .rev()
                    .find(|f| source_lines.get(f.line - 1).is_some_and(|s| *s <= l))
                    .is_some_and(|f| f.inch);
                3f64.sqrt() * 0.5e-4 * if inch { 25.4 } else { 1.0 }
            };
            let (_, worst, _) = hold(name, "rs274", &rs_seen, &expected, &unit)?;
            Ok(worst)
        }
    };
    Ok(Checked {
        points,
        worst_truecut_mm,
        worst_rs274_mm,
        feed_ends_mm,
    })
}

/// rs274's moves (program frame) in the machine frame: plus the work offset and tool length
/// truecut's reader has in force on the move's answer line.
fn machine_frame(moves: &[rs274::OracleMove], frames: &[LineFrame]) -> Vec<Move> {
    let mut out = Vec::with_capacity(moves.len());
    let mut at: Option<[f64; 3]> = None;
    for m in moves {
        let Some(line) = m.n else { continue };
        let shift = frames
            .iter()
            .find(|f| f.line == line)
            .map_or([0.0; 3], |f| f.shift_mm);
        let end = [0, 1, 2].map(|k| m.xyz_mm[k] + shift[k]);
        out.push(Move {
            line,
            start: at.unwrap_or(end),
            end,
            feed: m.feed,
        });
        at = Some(end);
    }
    out
}

/// Every point of `original` (read with `options`) at which [`check`] may ask e(p): the
/// start and end of each block, machine frame, mm (for callers that get e from a route: the
/// HTTP tests; the oracle's binary has the map itself).
#[allow(dead_code)]
pub fn needed_points(original: &str, options: &ReadOptions) -> Vec<[f64; 3]> {
    let Ok((p, _, _)) = parse_traced(original, options) else {
        return Vec::new();
    };
    p.blocks
        .iter()
        .flat_map(|b| [b.start.xyz, b.end.xyz])
        .collect()
}
