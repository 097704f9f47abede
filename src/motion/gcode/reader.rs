//! G-code reader: an ISO 6983 / Fanuc-style reader, lenient by default, strict on request.
//!
//! Hand-written: the `gcode` crate panics on inputs such as `M0444444444` under fuzzing
//! (see DESIGN.md), and we need line-accurate typed errors and warnings.
//!
//! Modelled (they move the tool): G0 G1 G2 G3 (IJK or R, negative R > 180°, full circles,
//! helical third axis), G4 dwell (X s or P ms), G17/G18/G19, G20/G21, G90/G91, G90.1/G91.1
//! (absolute / incremental arc centres), G93/G94, G43.4/G49 and TRAORI/TRAFOOF (RTCP), modal
//! motion lines without a G word, canned cycles G73/G74/G81..G89 with G98/G99 (G80 cancels;
//! `super::cycles`), G54..G59 with caller-given offsets, G43 H with caller-given tool
//! lengths, G28/G53 with a caller-given home, G30 with a caller-given G30 position, G41/G42
//! with caller-given tool diameters (the tool-centre path as LinuxCNC offsets it in XY;
//! `super::cutter_reader`) and G40. Passed
//! through with a warning (each word once, [`Warning`]), or refused under `strict`: comments,
//! `%`, O numbers (words after one on its line are read), N, S, T, D, H, M codes (vendor ones
//! included), F-only lines, G41/G42 without tool diameters, G49, G61/G64 (read as path-control
//! modes by [`parse_modes`]: `super::modes`), G80, what a cycle does that the path
//! cannot show (pecks' clearance, tapping's spindle reversal, G86-G88's spindle stop and
//! manual retract), block delete `/` at the start of a block or in mid-block (read with the
//! switch off), offsets and tool lengths the caller did not give, G28/G30 without their
//! position (the axes they name are unknown until programmed absolutely again; the lines
//! that ran meanwhile are named), axes B U V W that never change value. Everything else (G12.1, macros `#`,
//! CYCLE800, a moving B axis, ...) is an error naming the line and the code.
//!
//! [`parse`] is the reader as it was before warnings: what it accepted then passes silently,
//! everything else is [`Error::UnsupportedCode`]. Tests are in `super::tests`.

use super::cutter::Cutter;
use super::cutter_reader::CompCode;
use super::cycles::Cycle;
use super::lexer::{Lexed, lex, word_name};
use super::modes::{PathModal, PathWords};
use super::options::{Legacy, Mode, Notes, ReadOptions, Warning};
use super::trace::LineFrame;
use crate::motion::error::Error;
use crate::motion::path_control::PathControl;
use crate::motion::program::{Plane, Pose, Program};

pub(super) const MM_PER_INCH: f64 = 25.4;

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum MotionMode {
    Rapid,
    Linear,
    ArcCw,
    ArcCcw,
}

pub(super) struct Modal {
    pub(super) motion: Option<MotionMode>,
    pub(super) plane: Plane,
    pub(super) inch: bool,
    pub(super) incremental: bool,
    pub(super) absolute_centres: bool,
    pub(super) inverse_time: bool,
    pub(super) feed_mm_min: Option<f64>,
    pub(super) rtcp: bool,
    /// Position in the machine frame (program point + work offset + tool length on Z).
    pub(super) pose: Pose,
    /// Work offset in force, mm.
    pub(super) work_mm: [f64; 3],
    /// Tool length in force (G43 H), mm.
    pub(super) tool_mm: f64,
    pub(super) cycle: Option<Cycle>,
    /// G98 (true, default) or G99.
    pub(super) to_initial: bool,
    /// Axes (X, Y, Z) whose position is unknown after G28/G30/G53 without a home, with the
    /// line that made them so.
    pub(super) unknown: [Option<usize>; 3],
    /// Last value of each unmodelled axis word B, U, V, W.
    pub(super) still_axes: [Option<f64>; 4],
    /// Path-control modes in force (G61/G64, look-ahead on/off).
    pub(super) path: PathModal,
    /// Tool selected by the last T word.
    pub(super) selected_tool: Option<u32>,
    /// Tool in the spindle (the selected one at the last M6).
    pub(super) spindle_tool: Option<u32>,
}

impl Modal {
    pub(super) fn shift(&self, k: usize) -> f64 {
        self.work_mm[k] + if k == 2 { self.tool_mm } else { 0.0 }
    }
}

/// Parses a whole program as the reader did before warnings existed: words it passed
/// silently still pass, every other word is an [`Error::UnsupportedCode`].
///
/// The machine starts at program zero (X0 Y0 Z0 A0 C0), in G90 G17 G21 G94, RTCP off, with
/// no motion mode and no feed. Zero-length moves are kept (after an RTCP switch they
/// still move the machine); the interpolator drops those that move nothing.
/// Never panics; every rejected input yields a typed [`Error`] naming the 1-based line.
pub fn parse(text: &str) -> Result<Program, Error> {
    read(text, &ReadOptions::default(), Mode::Legacy, None, None).map(|(p, _)| p)
}

/// Parses a whole program with `options`: lenient (the default: words that do not move an
/// axis or that the reader cannot model are [`Warning`]s, the programmed tool-tip path is
/// kept) or strict (each such word is an [`Error::Gcode`] naming the line and the word).
/// Coordinates in the answer are mm in the machine frame: program point + work offset
/// (G54..G59) + tool length on Z (G43 H), inch programs (G20) converted.
/// Never panics.
pub fn parse_with(text: &str, options: &ReadOptions) -> Result<(Program, Vec<Warning>), Error> {
    let mode = if options.strict {
        Mode::Strict
    } else {
        Mode::Lenient
    };
    read(text, options, mode, None, None)
}

/// [`parse_with`] that also reads the program's path-control codes (G61, G61.1, G9, G64 P,
/// G05.1 Q, G08 P; `super::modes`) into how each block ends, for a caller that interpolates
/// with them (`crate::motion::interpolate::interpolate_with`). [`parse_with`] and
/// [`parse_traced`] answer those codes as before they were modelled (G61/G64 a warning, the
/// others unsupported), since their callers plan every junction in the service's look-ahead.
pub fn parse_modes(
    text: &str,
    options: &ReadOptions,
) -> Result<(Program, PathControl, Vec<Warning>), Error> {
    let mode = if options.strict {
        Mode::Strict
    } else {
        Mode::Lenient
    };
    let mut path = PathControl::default();
    let (p, w) = read(text, options, mode, None, Some(&mut path))?;
    Ok((p, path, w))
}

/// [`parse_with`] that also answers the reader's frame at the end of every line it read
/// (lines after M2/M30 are not read and have no frame), for tools that rewrite the program
/// (`crate::cam`).
pub fn parse_traced(
    text: &str,
    options: &ReadOptions,
) -> Result<(Program, Vec<Warning>, Vec<LineFrame>), Error> {
    let mode = if options.strict {
        Mode::Strict
    } else {
        Mode::Lenient
    };
    let mut frames = Vec::new();
    let (p, w) = read(text, options, mode, Some(&mut frames), None)?;
    Ok((p, w, frames))
}

fn read(
    text: &str,
    opts: &ReadOptions,
    mode: Mode,
    mut trace: Option<&mut Vec<LineFrame>>,
    path: Option<&mut PathControl>,
) -> Result<(Program, Vec<Warning>), Error> {
    let mut r = Reader {
        opts,
        notes: Notes::new(mode),
        m: Modal {
            motion: None,
            plane: Plane::Xy,
            inch: false,
            incremental: false,
            absolute_centres: false,
            inverse_time: false,
            feed_mm_min: None,
            rtcp: false,
            pose: Pose::default(),
            work_mm: [0.0; 3],
            tool_mm: 0.0,
            cycle: None,
            to_initial: true,
            unknown: [None; 3],
            still_axes: [None; 4],
            path: PathModal::default(),
            selected_tool: None,
            spindle_tool: None,
        },
        prog: Program::default(),
        cutter: None,
        after_exit: None,
        path,
        stop_once: false,
    };
    let mut last = 0;
    for (idx, raw) in text.lines().enumerate() {
        let line = idx + 1;
        last = line;
        let lexed = lex(raw, line)?;
        let before = r.prog.blocks.len();
        r.stop_once = false;
        let ends = r.apply(line, &lexed)?;
        if r.prog.blocks.len() > before {
            let end = r.block_end(r.stop_once);
            if let Some(path) = r.path.as_deref_mut() {
                path.set(line, end);
            }
        }
        if let Some(frames) = trace.as_deref_mut() {
            frames.push(LineFrame {
                line,
                inch: r.m.inch,
                incremental: r.m.incremental,
                absolute_centres: r.m.absolute_centres,
                inverse_time: r.m.inverse_time,
                shift_mm: [0, 1, 2].map(|k| r.m.shift(k)),
                pose_mm: r.m.pose.xyz,
                known: r.m.unknown.map(|u| u.is_none()),
            });
        }
        if ends {
            break;
        }
    }
    // The program's end cancels cutter compensation: its held moves end where they are.
    r.cutter_off(last)?;
    Ok((r.prog, r.notes.list))
}

pub(super) struct Reader<'a> {
    pub(super) opts: &'a ReadOptions,
    pub(super) notes: Notes,
    pub(super) m: Modal,
    pub(super) prog: Program,
    /// How each block ends, when the caller reads path-control modes ([`parse_modes`]).
    pub(super) path: Option<&'a mut PathControl>,
    /// G9 on the line being read.
    pub(super) stop_once: bool,
    /// Cutter radius compensation in force (G41/G42 with a tool diameter).
    pub(super) cutter: Option<Cutter>,
    /// The tool centre right after G40: where the next move starts.
    pub(super) after_exit: Option<Pose>,
}

/// What the G words of one line asked for, beyond modal state.
#[derive(Default)]
pub(super) struct LineCodes {
    pub(super) motion: Option<MotionMode>,
    pub(super) dwell: bool,
    pub(super) tool_length: bool,
    pub(super) home: Option<u32>,
    pub(super) cycle: Option<u32>,
    pub(super) path: PathWords,
    /// G40, G41 or G42.
    pub(super) comp: Option<CompCode>,
    /// G43 or G49 (the tool length changes).
    pub(super) tool_offset: bool,
    /// G54..G59.
    pub(super) work_offset: bool,
}

impl Reader<'_> {
    /// Reads one lexed line; returns true when the program ends (M2/M30).
    fn apply(&mut self, line: usize, l: &Lexed) -> Result<bool, Error> {
        use Legacy::{Accepted, Refused};
        self.passive_words(line, l)?;
        let w = &l.words;
        let mut c = LineCodes::default();
        for &g in &l.gcodes {
            self.g_code(line, g, &mut c)?;
        }
        self.path_words(line, l, &mut c)?;
        self.stop_once = c.path.stop_once;
        for kw in &l.keywords {
            self.m.rtcp = *kw == "TRAORI";
        }
        if let Some(t) = w.get(b'T').filter(|t| *t >= 0.0 && t.fract() == 0.0) {
            self.m.selected_tool = Some(t as u32);
        }
        let ends = self.m_codes(line, &l.mcodes)?;
        self.cutter_codes(line, &c, l)?;
        self.still_axes(line, l)?;
        if c.tool_length {
            self.tool_length(line, w.get(b'H'))?;
        } else if let Some(h) = w.get(b'H') {
            let what = if l.gcodes.contains(&434) {
                "tool length number of G43.4: RTCP uses the machine's geometry.tool_length"
            } else {
                "tool length offset number without G43: not used"
            };
            self.notes.note(line, word_name('H', h), what, Accepted)?;
        }
        if let Some(q) = w.get(b'Q') {
            if c.cycle.is_none() && self.m.cycle.is_none() && !c.path.q {
                self.notes
                    .note(line, word_name('Q', q), "not used by the motion", Refused)?;
            }
        }
        if let Some(v) = w.get(b'L') {
            self.notes.note(
                line,
                word_name('L', v),
                "repeat count / data word not modelled",
                Refused,
            )?;
        }
        let scale = self.scale();
        if c.dwell {
            self.dwell(line, l, c.motion.is_some())?;
            if c.motion.is_none() {
                return Ok(ends);
            }
        }
        if let Some(p) = w.get(b'P') {
            let in_cycle = c.cycle.is_some() || self.m.cycle.is_some();
            if !in_cycle && !c.dwell && !c.path.p {
                self.notes
                    .note(line, word_name('P', p), "not used by the motion", Accepted)?;
            }
        }
        if let Some(mm) = c.motion {
            self.m.motion = Some(mm);
            self.m.cycle = None;
        }
        if let Some(f) = w.get(b'F') {
            if f <= 0.0 {
                return Err(Error::gcode(line, "F must be > 0"));
            }
            self.m.feed_mm_min = Some(if self.m.inverse_time { f } else { f * scale });
        }
        let has_axis = [b'X', b'Y', b'Z', b'A', b'C']
            .iter()
            .any(|&k| w.get(k).is_some());
        if let Some(g) = c.home {
            self.home(line, g, l)?;
            return Ok(ends);
        }
        if let Some(code) = c.cycle {
            self.set_cycle(line, Some(code), l)?;
            self.drill(line, l)?;
            return Ok(ends);
        }
        if self.m.cycle.is_some() && c.motion.is_none() {
            if w.get(b'X').is_some() || w.get(b'Y').is_some() {
                self.set_cycle(line, None, l)?;
                self.drill(line, l)?;
            }
            return Ok(ends);
        }
        // G5.1's R is its machining condition level, not an arc radius.
        let has_arc_words = [b'I', b'J', b'K', b'R']
            .iter()
            .any(|&k| w.get(k).is_some() && !(k == b'R' && c.path.r));
        if !has_axis {
            let arc = matches!(self.m.motion, Some(MotionMode::ArcCw | MotionMode::ArcCcw));
            if arc && w.get(b'R').is_none() && has_arc_words {
                // G2 I.5 J.5: a full circle back to where it starts (Fanuc, LinuxCNC).
                self.motion_block(line, l, true)?;
                return Ok(ends);
            }
            if has_arc_words {
                return Err(Error::gcode(
                    line,
                    "I/J/K/R given without an end point (only a G2/G3 full circle may omit it, \
                     with I/J/K)",
                ));
            }
            if w.get(b'F').is_some() && c.motion.is_none() {
                self.notes.note(
                    line,
                    "F-only line",
                    "sets the feed; nothing moves",
                    Accepted,
                )?;
            }
            return Ok(ends);
        }
        self.motion_block(line, l, has_arc_words)?;
        Ok(ends)
    }

    pub(super) fn scale(&self) -> f64 {
        if self.m.inch { MM_PER_INCH } else { 1.0 }
    }
}
