//! The codes of one line: what each G code sets or asks for ([`LineCodes`]), and the words
//! that move nothing (comments, `%`, program numbers, block delete, N, S, T, D unless G41/G42
//! use it), each named in a warning or refused by mode.
//!
//! Split from `super::reader` so that each file keeps to one concept: the reader walks the
//! lines and decides what a line does, this file reads its codes.

use super::cutter::Side;
use super::cutter_reader::CompCode;
use super::cycles::unmodelled;
use super::lexer::{Lexed, g_name, word_name};
use super::options::Legacy::{Accepted, Refused};
use super::reader::{LineCodes, MotionMode, Reader};
use crate::motion::error::Error;
use crate::motion::program::Plane;

impl Reader<'_> {
    /// Applies G code `g` (× 10) of `line` to the modal state and to `c`.
    pub(super) fn g_code(&mut self, line: usize, g: u32, c: &mut LineCodes) -> Result<(), Error> {
        let name = g_name(g);
        let mut set_motion = |mm: MotionMode| {
            if c.motion.is_some() || c.cycle.is_some() {
                return Err(Error::gcode(
                    line,
                    "two motion codes (G0/G1/G2/G3 or a cycle) on one line",
                ));
            }
            c.motion = Some(mm);
            Ok(())
        };
        match g {
            0 => set_motion(MotionMode::Rapid)?,
            10 => set_motion(MotionMode::Linear)?,
            20 => set_motion(MotionMode::ArcCw)?,
            30 => set_motion(MotionMode::ArcCcw)?,
            40 => c.dwell = true,
            170 => self.m.plane = Plane::Xy,
            180 => self.m.plane = Plane::Zx,
            190 => self.m.plane = Plane::Yz,
            200 => self.m.inch = true,
            210 => self.m.inch = false,
            400 => {
                self.notes
                    .note(line, name, "cutter compensation cancel", Accepted)?;
                c.comp = Some(CompCode::Off);
            }
            410 | 420 => {
                c.comp = Some(CompCode::On(if g == 410 { Side::Left } else { Side::Right }));
            }
            280 | 300 | 530 => {
                self.notes.modelled(line, name)?;
                c.home = Some(g);
            }
            430 => {
                self.notes.modelled(line, name)?;
                c.tool_length = true;
                c.tool_offset = true;
            }
            440 => self.notes.note(
                line,
                name,
                "negative tool length compensation is not modelled: the programmed tool-tip path is used",
                Refused,
            )?,
            434 => self.m.rtcp = true,
            490 => {
                c.tool_offset = true;
                self.m.rtcp = false;
                self.m.tool_mm = 0.0;
                self.notes.note(line, name, "tool length compensation cancelled", Accepted)?;
            }
            540..=590 if g % 10 == 0 => {
                c.work_offset = true;
                self.work_offset(line, g)?
            }
            610 | 611 | 640 | 90 | 51 | 80 => self.path_code(line, g, c)?,
            150 | 500 | 501 | 670 | 690 => self.notes.note(
                line,
                name,
                "cancel of a mode the reader does not model: no effect",
                Refused,
            )?,
            800 => {
                self.m.cycle = None;
                self.notes.note(line, name, "canned cycle cancel", Accepted)?;
            }
            730 | 740 | 810..=890 if g % 10 == 0 => {
                if c.motion.is_some() || c.cycle.is_some() {
                    return Err(Error::gcode(
                        line,
                        "two motion codes (G0/G1/G2/G3 or a cycle) on one line",
                    ));
                }
                match unmodelled(g / 10) {
                    Some(what) => self.notes.note(line, name, what, Refused)?,
                    None => self.notes.modelled(line, name)?,
                }
                c.cycle = Some(g / 10);
                // Cycles share G0..G3's modal group: after G80 nothing is in force.
                self.m.motion = None;
            }
            900 => self.m.incremental = false,
            910 => self.m.incremental = true,
            901 | 911 => {
                self.notes.modelled(line, name)?;
                self.m.absolute_centres = g == 901;
            }
            930 => {
                if !self.m.inverse_time {
                    self.m.feed_mm_min = None;
                }
                self.m.inverse_time = true
            }
            940 => {
                if self.m.inverse_time {
                    self.m.feed_mm_min = None;
                }
                self.m.inverse_time = false
            }
            980 | 990 => {
                self.notes.modelled(line, name)?;
                self.m.to_initial = g == 980;
            }
            _ => return Err(Error::UnsupportedCode { line, code: name }),
        }
        Ok(())
    }

    /// Names the words of a line that do not move anything.
    pub(super) fn passive_words(&mut self, line: usize, l: &Lexed) -> Result<(), Error> {
        let n = &mut self.notes;
        if l.block_delete {
            n.note(
                line,
                "/",
                "block delete read with the switch off: the block is executed",
                Refused,
            )?;
        }
        if l.percent {
            n.note(line, "%", "tape start/end mark passed through", Accepted)?;
        }
        if l.mid_block_delete {
            n.note(
                line,
                "/ (mid-block)",
                "block delete in mid-block read with the switch off: the optional words after \
                 it are executed",
                Refused,
            )?;
        }
        if let Some(o) = &l.program_number {
            n.note(line, o.clone(), "program number passed through", Accepted)?;
            if l.words_after_program_number {
                n.note(
                    line,
                    format!("{o} (with words)"),
                    "words after a program number on its line are read as a block",
                    Refused,
                )?;
            }
        }
        if l.comment {
            n.note(line, "comment", "comments are passed through", Accepted)?;
        }
        if l.numbered {
            n.note(line, "N", "line numbers are passed through", Accepted)?;
        }
        let w = &l.words;
        for (letter, what) in [
            (b'S', "spindle speed: not modelled"),
            (b'T', "tool select: not modelled"),
        ] {
            if let Some(v) = w.get(letter) {
                n.note(line, word_name(letter as char, v), what, Accepted)?;
            }
        }
        self.note_d_word(line, l)
    }
}
