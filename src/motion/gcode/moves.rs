//! The reader's moves: plain motion blocks (G0..G3), dwell, canned cycles, and the M codes
//! and unmodelled axes of a line (the machine frame is `super::frame`).
//!
//! Split from `super::reader` (which reads a line's codes and decides what it asks for) so
//! that each file keeps to one concept.

use super::cycles::Cycle;
use super::lexer::{Lexed, word_name};
use super::options::Legacy::{Accepted, Refused};
use super::reader::{MotionMode, Reader};
use crate::motion::error::Error;
use crate::motion::program::{ArcWords, Block, Feed, Motion, arc_geometry};

const XYZ: [u8; 3] = [b'X', b'Y', b'Z'];

impl Reader<'_> {
    /// M codes: each named once; M2/M30 end the program (returns true).
    pub(super) fn m_codes(&mut self, line: usize, mcodes: &[u32]) -> Result<bool, Error> {
        let mut ends = false;
        for &mc in mcodes {
            if matches!(mc, 0 | 1 | 6 | 60) {
                let what = match mc {
                    6 => "a tool change (M6)".to_string(),
                    _ => format!("a program stop (M{mc})"),
                };
                self.refuse_under_cutter(line, &what)?;
            }
            if mc == 6 {
                self.m.spindle_tool = self.m.selected_tool;
            }
            let what = match mc {
                0 | 1 => "program stop: not modelled (no wait)",
                2 | 30 => "program end: reading stops here",
                3..=5 => "spindle: not modelled",
                6 => "tool change: the programmed tool-tip path is used",
                7..=9 => "coolant: not modelled",
                19 => "spindle orientation: not modelled",
                29 => "rigid tapping mode: the tapping cycle's path is read, its timing is not",
                97 | 98 => "subprogram call not followed: its moves are missing from the path",
                99 => "subprogram return: not followed",
                _ => "machine (vendor) M code: no axis motion, passed through",
            };
            let legacy = if mc <= 9 || mc == 30 {
                Accepted
            } else {
                Refused
            };
            self.notes.note(line, format!("M{mc}"), what, legacy)?;
            ends |= mc == 2 || mc == 30;
        }
        Ok(ends)
    }

    /// Axis words B U V W: passed through while they keep one value, refused once they move.
    pub(super) fn still_axes(&mut self, line: usize, l: &Lexed) -> Result<(), Error> {
        for (i, letter) in [b'B', b'U', b'V', b'W'].into_iter().enumerate() {
            let Some(v) = l.words.get(letter) else {
                continue;
            };
            let name = letter as char;
            self.notes.note(
                line,
                word_name(name, v),
                format!("axis {name} is not modelled; it keeps one value in this program"),
                Refused,
            )?;
            let prev = self.m.still_axes[i];
            let now = if self.m.incremental {
                prev.unwrap_or(0.0) + v
            } else {
                v
            };
            if prev.is_some_and(|p| p != now) || (self.m.incremental && v != 0.0) {
                return Err(Error::gcode(
                    line,
                    format!(
                        "axis {name} moves, but the reader models X Y Z A C only: remove the {name} \
                         moves or post the program for an X Y Z [A C] machine"
                    ),
                ));
            }
            self.m.still_axes[i] = Some(now);
        }
        Ok(())
    }

    /// G4: X seconds or P milliseconds; on a line with motion (`G4 P.001 G0 X1`, as
    /// LinuxCNC runs it: the dwell first) only P, X being the move's.
    pub(super) fn dwell(&mut self, line: usize, l: &Lexed, with_motion: bool) -> Result<(), Error> {
        let x = if with_motion { None } else { l.words.get(b'X') };
        let seconds = match (x, l.words.get(b'P')) {
            (Some(x), None) => x,
            (None, Some(p)) => p / 1000.0,
            (None, None) if with_motion => {
                return Err(Error::gcode(
                    line,
                    "G4 on a line with motion needs P (milliseconds)",
                ));
            }
            _ => {
                return Err(Error::gcode(
                    line,
                    "G4 needs exactly one of X (seconds) or P (milliseconds)",
                ));
            }
        };
        if seconds < 0.0 {
            return Err(Error::gcode(line, "G4 dwell time must be >= 0"));
        }
        if seconds > 0.0 {
            self.push_dwell(line, seconds);
        }
        Ok(())
    }

    /// The feed of a block in `mode` on this line.
    fn feed(&self, line: usize, rapid: bool, l: &Lexed) -> Result<Feed, Error> {
        if rapid {
            Ok(Feed::Rapid)
        } else if self.m.inverse_time {
            // G93: F must be programmed on every feed block.
            match l.words.get(b'F') {
                Some(f) => Ok(Feed::InverseTime(f)),
                None => Err(Error::gcode(
                    line,
                    "G93 inverse-time mode needs F on every G1/G2/G3 block",
                )),
            }
        } else {
            match self.m.feed_mm_min {
                Some(f) => Ok(Feed::PerMinute(f)),
                None => Err(Error::gcode(
                    line,
                    "feed move without a feed rate: add an F word",
                )),
            }
        }
    }

    /// Target of axis `k` (0 X, 1 Y, 2 Z) for word value `v` in the current G90/G91 mode.
    pub(super) fn target(&self, k: usize, v: f64) -> f64 {
        if self.m.incremental {
            self.m.pose.xyz[k] + v * self.scale()
        } else {
            v * self.scale() + self.m.shift(k)
        }
    }

    pub(super) fn unknown_since(&self) -> Option<usize> {
        self.m.unknown.iter().flatten().copied().min()
    }

    /// Starts (`code` Some) or updates the canned cycle from the line's R, Z, P words.
    pub(super) fn set_cycle(
        &mut self,
        line: usize,
        code: Option<u32>,
        l: &Lexed,
    ) -> Result<(), Error> {
        if self.m.inverse_time {
            return Err(Error::gcode(
                line,
                "canned cycles need G94 (feed per minute), not G93",
            ));
        }
        let prev = self.m.cycle;
        let scale = self.scale();
        let code = code.or(prev.map(|c| c.code)).unwrap_or(81);
        let initial_z_mm = match prev {
            Some(c) => c.initial_z_mm,
            None => self.m.pose.xyz[2],
        };
        let r_z_mm = match (l.words.get(b'R'), prev) {
            (Some(r), _) if self.m.incremental => initial_z_mm + r * scale,
            (Some(r), _) => r * scale + self.m.shift(2),
            (None, Some(c)) => c.r_z_mm,
            (None, None) => {
                return Err(Error::gcode(line, format!("G{code} needs R (the R plane)")));
            }
        };
        let bottom_z_mm = match (l.words.get(b'Z'), prev) {
            (Some(z), _) if self.m.incremental => r_z_mm + z * scale,
            (Some(z), _) => z * scale + self.m.shift(2),
            (None, Some(c)) => c.bottom_z_mm,
            (None, None) => {
                return Err(Error::gcode(
                    line,
                    format!("G{code} needs Z (the hole bottom)"),
                ));
            }
        };
        let dwell_s = match (l.words.get(b'P'), prev) {
            (Some(p), _) if p >= 0.0 => p / 1000.0,
            (Some(_), _) => return Err(Error::gcode(line, "P (dwell, ms) must be >= 0")),
            (None, Some(c)) => c.dwell_s,
            (None, None) => 0.0,
        };
        let peck_mm = match (l.words.get(b'Q'), prev) {
            (Some(q), _) if matches!(code, 73 | 83) && q <= 0.0 => {
                return Err(Error::gcode(line, "Q (peck depth) must be > 0"));
            }
            (Some(q), _) => Some(q * scale),
            (None, Some(c)) => c.peck_mm,
            (None, None) => None,
        };
        self.m.cycle = Some(Cycle {
            code,
            initial_z_mm,
            r_z_mm,
            bottom_z_mm,
            dwell_s,
            peck_mm,
        });
        Ok(())
    }

    /// One hole of the cycle in force at the line's X Y (current position for absent words).
    pub(super) fn drill(&mut self, line: usize, l: &Lexed) -> Result<(), Error> {
        let Some(cycle) = self.m.cycle else {
            return Ok(());
        };
        self.refuse_under_cutter(line, &format!("a canned cycle (G{})", cycle.code))?;
        let feed = self.feed(line, false, l)?;
        let mut xy = [self.m.pose.xyz[0], self.m.pose.xyz[1]];
        for (k, v) in xy.iter_mut().enumerate() {
            if let Some(w) = l.words.get(XYZ[k]) {
                *v = self.target(k, w);
                if !self.m.incremental {
                    self.m.unknown[k] = None;
                }
            }
        }
        if let Some(since) = self.unknown_since() {
            return self.notes.note_line(
                line,
                format!("G{}", cycle.code),
                format!("ran at an unknown machine position (since line {since}): not modelled"),
            );
        }
        let from = self.move_start();
        let blocks = cycle.hole(line, from, xy, feed, self.m.to_initial, self.m.rtcp);
        if let Some(last) = blocks.last() {
            self.m.pose = last.end;
        }
        self.prog.blocks.extend(blocks);
        Ok(())
    }

    /// A G0/G1/G2/G3 block (or a modal line without a G word).
    pub(super) fn motion_block(
        &mut self,
        line: usize,
        l: &Lexed,
        has_arc_words: bool,
    ) -> Result<(), Error> {
        let w = &l.words;
        let mode = match self.m.motion {
            Some(mode) => mode,
            None if self.notes.legacy() => {
                return Err(Error::gcode(
                    line,
                    "axis words without a motion mode: add G0, G1, G2 or G3",
                ));
            }
            None => {
                // Fanuc and Haas power on in G0 (Smid 2008 ch. 4): a post relies on it.
                self.notes.note(
                    line,
                    "no motion mode",
                    "axis words before any G0/G1/G2/G3 are read as G0 (the power-on default)",
                    Refused,
                )?;
                self.m.motion = Some(MotionMode::Rapid);
                MotionMode::Rapid
            }
        };
        if w.get(b'A').is_some() && self.prog.first_a_line.is_none() {
            self.prog.first_a_line = Some(line);
        }
        if w.get(b'C').is_some() && self.prog.first_c_line.is_none() {
            self.prog.first_c_line = Some(line);
        }
        let start = self.m.pose;
        let mut end = start;
        let was_unknown = self.unknown_since();
        for (k, &letter) in XYZ.iter().enumerate() {
            if let Some(v) = w.get(letter) {
                end.xyz[k] = self.target(k, v);
                if !self.m.incremental {
                    self.m.unknown[k] = None;
                }
            }
        }
        if let Some(v) = w.get(b'A') {
            end.a = if self.m.incremental { start.a + v } else { v };
        }
        if let Some(v) = w.get(b'C') {
            end.c = if self.m.incremental { start.c + v } else { v };
        }
        let feed = self.feed(line, mode == MotionMode::Rapid, l)?;
        let scale = self.scale();
        let motion = match mode {
            MotionMode::Rapid | MotionMode::Linear => {
                if has_arc_words {
                    return Err(Error::gcode(line, "I/J/K/R are only allowed with G2/G3"));
                }
                Motion::Linear
            }
            MotionMode::ArcCw | MotionMode::ArcCcw => {
                let mut ijk = [w.get(b'I'), w.get(b'J'), w.get(b'K')];
                if self.m.absolute_centres {
                    // G90.1: centres are absolute program points; the geometry wants offsets.
                    for (k, v) in ijk.iter_mut().enumerate() {
                        if let Some(c) = v {
                            *c -= (start.xyz[k] - self.m.shift(k)) / scale;
                        }
                    }
                }
                let words = ArcWords {
                    ijk,
                    r: w.get(b'R'),
                };
                let cw = mode == MotionMode::ArcCw;
                arc_geometry(line, self.m.plane, cw, &start, &end, words, scale)?
            }
        };
        self.m.pose = end;
        let word = match mode {
            MotionMode::Rapid => "G0",
            MotionMode::Linear => "G1",
            MotionMode::ArcCw => "G2",
            MotionMode::ArcCcw => "G3",
        };
        if let Some(since) = self.unknown_since() {
            return self.notes.note_line(
                line,
                word,
                format!("ran at an unknown machine position (since line {since}): not modelled"),
            );
        }
        if let Some(since) = was_unknown {
            self.notes.note_line(
                line,
                word,
                format!(
                    "starts from an unknown machine position (since line {since}): taken straight \
                     from the last known point"
                ),
            )?;
            if matches!(motion, Motion::Arc { .. }) {
                return Ok(());
            }
        }
        let mut block = Block {
            line,
            motion,
            start,
            end,
            feed,
            rtcp: self.m.rtcp,
        };
        if self.compensate(&block)? {
            return Ok(());
        }
        if let Some(tool) = self.after_exit.take() {
            if matches!(motion, Motion::Arc { .. }) {
                return Err(Error::gcode(
                    line,
                    "the move after G40 must be a straight line, not an arc (it leaves the \
                     compensated path; LinuxCNC refuses an arc here too)",
                ));
            }
            // It starts from the tool centre; under G93 it keeps the rate of its programmed
            // length, as LinuxCNC runs it.
            if let Feed::InverseTime(f) = feed {
                block.feed = Feed::PerMinute(f * block.xyz_length());
            }
            block.start = tool;
        }
        self.prog.blocks.push(block);
        Ok(())
    }
}
