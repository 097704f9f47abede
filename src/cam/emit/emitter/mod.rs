//! Re-emission keeping the post's structure: every source line is copied byte for byte
//! unless its plan ([`LinePlan`]) says how its axis words change; a motion line may also be
//! replaced by a list of G1 points (split arcs and lines, contour pre-distortion).
//!
//! Numbers are written in the program's own units at a fixed precision: 4 decimals in mm
//! (0.1 µm) and 5 in inch (0.254 µm; Fanuc's IS-C input increments, ISO 6983-1 leaves the
//! format to the control), in the line's G90/G91 mode. The emitter keeps the commanded
//! machine position of the program it writes, so that increments (G91) and arc centres are
//! those of the compensated positions and rounding never accumulates.
//!
//! Safety rule: an axis the program has not yet placed absolutely (at the start, or after
//! G28 without a home) gets no new word in G90; only the words the post wrote are changed.

use super::text::{decimals, format_number, rewrite};
use super::text::{format_feed, g_times_ten, is_axis, is_centre, motion_style, round_to, spaced};

use crate::cam::paths::SubArc;

mod path;

use crate::motion::gcode::{LineFrame, WordSpan, word_spans};
use crate::motion::program::Plane;
pub use path::PathPiece;

/// How one source line is written.
#[derive(Clone, Debug, PartialEq)]
pub enum LinePlan {
    /// Copied unchanged.
    Keep,
    /// A G0/G1 line (or a G2/G3 line kept as an arc, see `Arc`): its end is `end_mm`
    /// (machine frame, mm).
    Move {
        /// End point, machine frame, mm.
        end_mm: [f64; 3],
    },
    /// A rapid (G0): its end is `end_mm` (machine frame, mm) in the axes the source names;
    /// it gains no axis word (a rapid cuts nothing: an axis it does not name keeps the
    /// position the lines before it left).
    Rapid {
        /// End point, machine frame, mm (only the named axes are used).
        end_mm: [f64; 3],
    },
    /// A G2/G3 line kept as arcs: sub-arcs of the same plane and direction, each with its
    /// end and centre (machine frame, mm; only the plane's two centre components are used).
    /// The first is written on the source line, the others on new lines after it (no N
    /// number: an inserted line carries none). R-form arcs write R (negative above 180°).
    Arcs {
        /// The sub-arcs in order; the last ends at the block's (compensated) end.
        pieces: Vec<SubArc>,
        /// Arc plane.
        plane: Plane,
        /// F word (program units) of each piece under G93 inverse time; `None` keeps the
        /// source's F.
        feeds: Option<Vec<f64>>,
    },
    /// A G2/G3 line written as sub-arcs (same plane, each turning as its sweep says) with
    /// straight moves between them (backlash take-ups where an axis of the plane reverses):
    /// the first piece on the source line, the others on new lines after it, each line's
    /// motion word written where it changes.
    Path {
        /// The pieces in order; the last ends at the block's (compensated) end.
        pieces: Vec<PathPiece>,
        /// Plane of the arcs.
        plane: Plane,
        /// F word (program units) of each piece under G93 inverse time; `None` keeps the
        /// source's F.
        feeds: Option<Vec<f64>>,
    },
    /// The line's motion replaced by G1 moves through `points_mm` (machine frame, mm; the
    /// last is the end). The first point is written on the source line (keeping its N, F,
    /// comments, M words), the others on new lines after it.
    Points {
        /// G1 points, machine frame, mm.
        points_mm: Vec<[f64; 3]>,
        /// F word (program units) of each point, when it must be written on every one
        /// (G93 inverse time, contour pre-distortion); `None` keeps the source's F.
        feeds: Option<Vec<f64>>,
        /// Stop at each point, s (`G4 P<ms>` on its own line after the point's, Fanuc's
        /// milliseconds; 0 or missing: none): the contour pre-distortion's exact stops at
        /// inside corners.
        dwells_s: Vec<f64>,
    },
    /// A canned-cycle hole (G90): X Y of the hole, the R plane and the bottom (machine frame,
    /// mm); `at_r_after` when the tool stays at R after the hole (G99).
    Hole {
        /// Hole position X, Y, mm.
        xy_mm: [f64; 2],
        /// Z of the R plane, mm.
        r_z_mm: f64,
        /// Z of the hole bottom, mm.
        bottom_z_mm: f64,
        /// The tool ends the hole at R (G99, or G98 with the initial level below R).
        at_r_after: bool,
    },
}

/// Motion G codes × 10 that set the modal motion group: G0..G3 and every canned cycle the
/// reader models (G73, G74, G81..G89).
const MOTION_CODES: [u32; 15] = [
    0, 10, 20, 30, 730, 740, 810, 820, 830, 840, 850, 860, 870, 880, 890,
];

/// What the emitter learned of a line before it is planned.
#[derive(Clone, Debug, Default)]
pub struct LineInfo {
    /// Words with their positions.
    pub spans: Vec<WordSpan>,
    /// X, Y, Z named as positions (not a dwell's X).
    pub named: [bool; 3],
    /// G28/G30/G53 on the line.
    pub machine_move: bool,
    /// G4 on the line.
    pub dwell: bool,
    /// The line names an axis and moves (not a dwell, not G28/G30/G53).
    pub moves: bool,
    /// The line has its own motion G word (G0..G3 or a cycle).
    pub explicit_motion: bool,
    /// Motion mode in force after the line in the source (G code × 10).
    pub modal: Option<u32>,
}

impl LineInfo {
    /// The line drills a hole of the canned cycle in force.
    pub fn is_hole(&self) -> bool {
        self.moves && self.modal.is_some_and(|m| m >= 730)
    }
}

/// Writes the output program line by line.
pub struct Emitter {
    lines: Vec<String>,
    source_lines: Vec<usize>,
    cmd: [f64; 3],
    known: [bool; 3],
    prev_pose: [f64; 3],
    orig_modal: Option<u32>,
    out_modal: Option<u32>,
    cycle_words: [Option<String>; 2],
    /// The source's F in force (program units), and the output's.
    src_feed: Option<f64>,
    out_feed: Option<f64>,
    /// How the source writes F: most decimals seen, and a trailing `.` on whole numbers.
    feed_decimals: usize,
    feed_dot: bool,
}

/// Letters of the three linear axes and of their centre words.
pub(super) const AXES: [char; 3] = ['X', 'Y', 'Z'];
pub(super) const CENTRES: [char; 3] = ['I', 'J', 'K'];

impl Default for Emitter {
    fn default() -> Self {
        Self::new()
    }
}

impl Emitter {
    /// An emitter at the reader's start (program zero, no axis placed yet).
    pub fn new() -> Self {
        Emitter {
            lines: Vec::new(),
            source_lines: Vec::new(),
            cmd: [0.0; 3],
            known: [false; 3],
            prev_pose: [0.0; 3],
            orig_modal: None,
            out_modal: None,
            cycle_words: [None, None],
            src_feed: None,
            out_feed: None,
            feed_decimals: 0,
            feed_dot: false,
        }
    }

    /// The output lines and the 1-based source line of each.
    pub fn finish(self) -> (Vec<String>, Vec<usize>) {
        (self.lines, self.source_lines)
    }

    /// Number of lines written so far.
    pub fn len(&self) -> usize {
        self.lines.len()
    }

    /// True before the first line.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// The commanded machine position (mm) of the output so far.
    pub fn commanded(&self) -> [f64; 3] {
        self.cmd
    }

    /// Reads a line's words and the source's modal motion after it (call once per line,
    /// before [`Emitter::write`]).
    pub fn begin(&mut self, raw: &str) -> LineInfo {
        let spans = word_spans(raw);
        let gs: Vec<u32> = spans
            .iter()
            .filter(|s| s.letter == 'G')
            .map(|s| g_times_ten(s.value))
            .collect();
        let dwell = gs.contains(&40);
        let machine_move = gs.iter().any(|g| matches!(g, 280 | 300 | 530));
        let mut named = [false; 3];
        for s in &spans {
            if let Some(k) = AXES.iter().position(|&a| a == s.letter) {
                named[k] = !dwell;
            }
        }
        for f in spans.iter().filter(|s| s.letter == 'F') {
            let text = &raw[f.start + 1..f.end];
            if let Some((_, frac)) = text.split_once('.') {
                let digits = frac.chars().take_while(char::is_ascii_digit).count();
                self.feed_decimals = self.feed_decimals.max(digits);
                self.feed_dot |= digits == 0;
            }
        }
        let mut explicit_motion = false;
        for &g in &gs {
            if MOTION_CODES.contains(&g) {
                self.orig_modal = Some(g);
                explicit_motion = true;
            } else if g == 800 {
                self.orig_modal = None;
            }
        }
        LineInfo {
            moves: named.iter().any(|&n| n) && !dwell && !machine_move,
            spans,
            named,
            machine_move,
            dwell,
            explicit_motion,
            modal: self.orig_modal,
        }
    }

    /// Writes source line `line` (text `raw`, words `info` from [`Emitter::begin`], reader
    /// frame `frame`, `None` for lines the reader did not read) by `plan`.
    pub fn write(
        &mut self,
        line: usize,
        raw: &str,
        info: &LineInfo,
        frame: Option<&LineFrame>,
        plan: LinePlan,
    ) {
        let Some(frame) = frame else {
            self.push(line, raw.to_string());
            return;
        };
        let scale = if frame.inch { 25.4 } else { 1.0 };
        let d = decimals(frame.inch);
        let is_points = matches!(plan, LinePlan::Points { .. });
        // The motion mode a path's last piece leaves (its G word x 1).
        let last_path = match &plan {
            LinePlan::Path { pieces, .. } => pieces.last().map(PathPiece::code),
            _ => None,
        };
        // The source's F word on this line, and the F the output must write again because
        // points before it ran at another feed than the source's in force.
        let line_feed = info.spans.iter().find(|s| s.letter == 'F').map(|s| s.value);
        let own_feeds = match &plan {
            LinePlan::Points { feeds, .. }
            | LinePlan::Arcs { feeds, .. }
            | LinePlan::Path { feeds, .. } => feeds.is_some(),
            _ => false,
        };
        let restore: Vec<String> = match (line_feed, self.src_feed) {
            (None, Some(src))
                if info.moves
                    && !own_feeds
                    && !frame.inverse_time
                    && self.orig_modal != Some(0)
                    && self.out_feed != Some(src) =>
            {
                self.out_feed = Some(src);
                vec![format_feed(src, self.feed_decimals, self.feed_dot)]
            }
            _ => Vec::new(),
        };
        if let Some(f) = line_feed {
            self.src_feed = Some(f);
            if !own_feeds {
                self.out_feed = Some(f);
            }
        }
        match plan {
            LinePlan::Keep => {
                let motion = self.modal_word(info);
                let text = if motion.is_some() || !restore.is_empty() {
                    rewrite(raw, &info.spans, |_| false, &restore, motion.as_deref())
                } else {
                    raw.to_string()
                };
                self.push(line, text);
                self.follow(info, frame);
            }
            LinePlan::Rapid { end_mm } => {
                let words = self.named_words(end_mm, info.named, frame);
                let motion = self.modal_word(info);
                let text = rewrite(raw, &info.spans, is_axis, &words, motion.as_deref());
                self.push(line, text);
            }
            LinePlan::Move { end_mm } => {
                let mut words = self.axis_words(end_mm, info.named, frame);
                words.extend(restore);
                let motion = self.modal_word(info);
                let text = rewrite(raw, &info.spans, is_axis, &words, motion.as_deref());
                self.push(line, text);
            }
            LinePlan::Arcs {
                pieces,
                plane,
                feeds,
            } => {
                let r_form = info.spans.iter().any(|s| s.letter == 'R');
                let inverse = feeds.is_some();
                let drop =
                    |s: &WordSpan| is_axis(s) || is_centre(s) || (inverse && s.letter == 'F');
                let sep = if spaced(raw, &info.spans) { " " } else { "" };
                for (i, arc) in pieces.iter().enumerate() {
                    let named = if i == 0 { info.named } else { [false; 3] };
                    let mut words = self.arc_words(arc, named, frame, plane, r_form);
                    if let Some(f) = feeds.as_ref().and_then(|f| f.get(i)) {
                        words.extend(self.feed_word(*f, frame.inverse_time));
                    }
                    if i == 0 {
                        words.extend(restore.iter().cloned());
                    }
                    if i == 0 {
                        let motion = self.modal_word(info);
                        let text = rewrite(raw, &info.spans, drop, &words, motion.as_deref());
                        self.push(line, text);
                    } else {
                        self.push(line, words.join(sep));
                    }
                }
            }
            LinePlan::Path {
                pieces,
                plane,
                feeds,
            } => self.write_path((line, raw), info, frame, (&pieces, plane, feeds), &restore),
            LinePlan::Points {
                points_mm,
                feeds,
                dwells_s,
            } => {
                let g1 = motion_style(raw, &info.spans, 1);
                let always = frame.inverse_time;
                let fw = |em: &mut Self, i: usize| {
                    feeds
                        .as_ref()
                        .and_then(|f| f.get(i))
                        .and_then(|f| em.feed_word(*f, always))
                };
                let mut words = match points_mm.first() {
                    Some(&p) => self.axis_words(p, info.named, frame),
                    None => Vec::new(),
                };
                words.extend(fw(self, 0));
                words.extend(restore);
                let drop = |s: &WordSpan| {
                    is_axis(s) || is_centre(s) || (feeds.is_some() && s.letter == 'F')
                };
                let text = rewrite(raw, &info.spans, drop, &words, Some(&g1));
                self.push(line, text);
                self.out_modal = Some(10);
                let sep = if spaced(raw, &info.spans) { " " } else { "" };
                // G4 is one-shot: the bare points after it stay G1.
                let stop = |em: &mut Self, i: usize| {
                    let ms = dwells_s.get(i).map_or(0.0, |s| (s * 1e3).round());
                    if ms > 0.0 {
                        em.push(line, format!("G4{sep}P{ms}"));
                    }
                };
                stop(self, 0);
                for (i, &p) in points_mm.iter().enumerate().skip(1) {
                    let mut words = self.axis_words(p, [false; 3], frame);
                    if !words.is_empty() {
                        words.extend(fw(self, i));
                        self.push(line, words.join(sep));
                    }
                    stop(self, i);
                }
            }
            LinePlan::Hole {
                xy_mm,
                r_z_mm,
                bottom_z_mm,
                at_r_after,
            } => {
                let mut words = Vec::new();
                for k in 0..2 {
                    let v = round_to((xy_mm[k] - frame.shift_mm[k]) / scale, d);
                    let cur = round_to((self.cmd[k] - frame.shift_mm[k]) / scale, d);
                    if info.named[k] || v != cur || !self.known[k] {
                        words.push(format!("{}{}", AXES[k], format_number(v, d)));
                        self.cmd[k] = v * scale + frame.shift_mm[k];
                        self.known[k] = true;
                    }
                }
                let z = round_to((bottom_z_mm - frame.shift_mm[2]) / scale, d);
                let r = round_to((r_z_mm - frame.shift_mm[2]) / scale, d);
                let zr = [
                    format!("Z{}", format_number(z, d)),
                    format!("R{}", format_number(r, d)),
                ];
                let had = [info.named[2], info.spans.iter().any(|s| s.letter == 'R')];
                for (i, w) in zr.into_iter().enumerate() {
                    if had[i] || self.cycle_words[i].as_deref() != Some(w.as_str()) {
                        words.push(w.clone());
                        self.cycle_words[i] = Some(w);
                    }
                }
                if at_r_after {
                    self.cmd[2] = r * scale + frame.shift_mm[2];
                }
                words.extend(restore);
                let drop = |s: &WordSpan| is_axis(s) || s.letter == 'R';
                let text = rewrite(raw, &info.spans, drop, &words, None);
                self.push(line, text);
            }
        }
        if info.moves || info.explicit_motion {
            self.out_modal = match last_path {
                Some(c) => Some(c * 10),
                None if is_points => Some(10),
                None => self.orig_modal,
            };
        }
        self.prev_pose = frame.pose_mm;
    }

    /// The source's motion G word, when a modal line needs it because the output's motion
    /// mode differs (after a split arc the output is in G1).
    fn modal_word(&self, info: &LineInfo) -> Option<String> {
        match self.orig_modal {
            Some(g) if info.moves && !info.explicit_motion && self.out_modal != self.orig_modal => {
                (g <= 30).then(|| format!("G{}", g / 10))
            }
            _ => None,
        }
    }

    /// Axis words placing the tool at `q` (machine frame, mm) in the line's mode; updates
    /// the commanded position. Absolute: the named axes and every placed axis that moves;
    /// incremental: the named axes and every non-zero increment.
    fn axis_words(&mut self, q: [f64; 3], named: [bool; 3], frame: &LineFrame) -> Vec<String> {
        let scale = if frame.inch { 25.4 } else { 1.0 };
        let d = decimals(frame.inch);
        let mut words = Vec::new();
        for k in 0..3 {
            if frame.incremental {
                let inc = round_to((q[k] - self.cmd[k]) / scale, d);
                if named[k] || inc != 0.0 {
                    words.push(format!("{}{}", AXES[k], format_number(inc, d)));
                    self.cmd[k] += inc * scale;
                }
            } else {
                let shift = frame.shift_mm[k];
                let v = round_to((q[k] - shift) / scale, d);
                let cur = round_to((self.cmd[k] - shift) / scale, d);
                if named[k] || (self.known[k] && v != cur) {
                    words.push(format!("{}{}", AXES[k], format_number(v, d)));
                    self.cmd[k] = v * scale + shift;
                    self.known[k] = true;
                }
            }
        }
        words
    }

    /// Axis words for the named axes only (a rapid's, [`LinePlan::Rapid`]), placing them at
    /// `q` (machine frame, mm); the other axes keep the output's position.
    fn named_words(&mut self, q: [f64; 3], named: [bool; 3], frame: &LineFrame) -> Vec<String> {
        let mut target = self.cmd;
        for k in 0..3 {
            if named[k] {
                target[k] = q[k];
            }
        }
        // An unnamed axis keeps the output's position: no word (axis_words writes an unnamed
        // axis only where its value changes).
        self.axis_words(target, named, frame)
    }

    /// A line copied unchanged moves the output as it moves the source.
    fn follow(&mut self, info: &LineInfo, frame: &LineFrame) {
        for k in 0..3 {
            let moved = frame.pose_mm[k] != self.prev_pose[k];
            let relative = frame.incremental && !info.machine_move;
            if info.named[k] || moved {
                if relative {
                    self.cmd[k] += frame.pose_mm[k] - self.prev_pose[k];
                } else {
                    self.cmd[k] = frame.pose_mm[k];
                }
            }
            let placed = info.named[k] && !relative;
            self.known[k] = frame.known[k] && (self.known[k] || placed);
        }
    }

    /// The F word of feed `f` (program units) as the source writes F (its decimals, a
    /// trailing `.` if it writes one), rounded down so that the written feed never exceeds
    /// `f`; `None` when the output already runs at that feed and `always` is false (G93
    /// needs F on every feed block).
    fn feed_word(&mut self, f: f64, always: bool) -> Option<String> {
        // Inverse time (1/min) keeps three decimals at least: its values are small numbers
        // whose rounding would change the time of a block by per cents.
        let d = if always {
            self.feed_decimals.max(3)
        } else {
            self.feed_decimals
        };
        let s = 10f64.powi(d as i32);
        // Round down, but not what is already an exact decimal of the source's precision.
        let v = ((f * s) + 1e-9).floor() / s;
        if !always && self.out_feed == Some(v) {
            return None;
        }
        self.out_feed = Some(v);
        Some(format_feed(v, d, self.feed_dot))
    }

    fn push(&mut self, line: usize, text: String) {
        self.lines.push(text);
        self.source_lines.push(line);
    }
}
