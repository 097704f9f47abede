//! The machine frame of the reader: G54..G59 work offsets and G43 H tool lengths given by the
//! caller, and G28/G30/G53 moves to machine positions (G28/G30 through the intermediate point
//! to the caller's home or G30 position; G53 to machine coordinates when the home is given;
//! else the axes are unknown until programmed absolutely again).
//!
//! Why unknown rather than a guess: without the machine's home, any path after G28 would be
//! invented, and a compensation computed on it would be wrong where it matters (CONTRACT v1.1
//! "Reading real programs").

use super::lexer::{Lexed, word_name};
use super::options::Legacy::{Accepted, Refused};
use super::reader::Reader;
use crate::motion::error::Error;
use crate::motion::program::{Block, Feed, Motion, Pose};

const XYZ: [u8; 3] = [b'X', b'Y', b'Z'];

impl Reader<'_> {
    /// G43 H: the caller's tool length for H is added to Z, else the tool-tip path is kept.
    pub(super) fn tool_length(&mut self, line: usize, h: Option<f64>) -> Result<(), Error> {
        self.m.tool_mm = 0.0;
        let Some(h) = h else {
            return self.notes.note(
                line,
                "G43",
                "no H word: the programmed tool-tip path is used",
                Refused,
            );
        };
        let word = format!("G43 {}", word_name('H', h));
        let number = (h >= 0.0 && h.fract() == 0.0).then_some(h as u32);
        match number.and_then(|n| self.opts.tool_lengths_mm.get(&n)) {
            Some(&len) => {
                self.m.tool_mm = len;
                self.notes
                    .applied(line, word, format!("tool length {len} mm added to Z"))
            }
            None => self.notes.note(
                line,
                word,
                format!(
                    "no tool length given for H{h} in tool_lengths: the programmed tool-tip \
                     path is used"
                ),
                Refused,
            ),
        }
    }

    /// G54..G59 (`g` = code × 10): the caller's offset, else zero.
    pub(super) fn work_offset(&mut self, line: usize, g: u32) -> Result<(), Error> {
        let idx = (g / 10 - 54) as usize;
        let name = format!("G{}", g / 10);
        match self.opts.work_offsets_mm[idx] {
            Some(off) => {
                self.m.work_mm = off;
                self.notes.applied(
                    line,
                    name,
                    format!(
                        "work offset [{}, {}, {}] mm applied",
                        off[0], off[1], off[2]
                    ),
                )
            }
            None => {
                self.m.work_mm = [0.0; 3];
                let legacy = if idx == 0 { Accepted } else { Refused };
                self.notes.note(
                    line,
                    name,
                    "no offset given in work_offsets: taken as zero (program zero = machine zero)",
                    legacy,
                )
            }
        }
    }

    fn push_rapid(&mut self, line: usize, end: Pose) {
        let start = self.move_start();
        if end != start {
            self.prog.blocks.push(Block {
                line,
                motion: Motion::Linear,
                start,
                end,
                feed: Feed::Rapid,
                rtcp: self.m.rtcp,
            });
        }
        self.m.pose = end;
    }

    /// G28/G30 (through the intermediate point to home) and G53 (machine coordinates).
    pub(super) fn home(&mut self, line: usize, g: u32, l: &Lexed) -> Result<(), Error> {
        self.refuse_under_cutter(line, "G28/G30/G53")?;
        let named: Vec<usize> = (0..3).filter(|&k| l.words.get(XYZ[k]).is_some()).collect();
        if g != 530 {
            let mut mid = self.m.pose;
            for &k in &named {
                mid.xyz[k] = self.target(k, l.words.get(XYZ[k]).unwrap_or(0.0));
            }
            if self.unknown_since().is_none() {
                self.push_rapid(line, mid);
            } else {
                self.m.pose = mid;
            }
        }
        let name = if g == 530 {
            "G53"
        } else if g == 280 {
            "G28"
        } else {
            "G30"
        };
        let (target, missing) = if g == 300 {
            (
                self.opts.g30_mm,
                "no G30 position given (machine definition `g30`)",
            )
        } else {
            (self.opts.home_mm, "no home given")
        };
        match target {
            Some(home) => {
                let mut end = self.m.pose;
                for &k in &named {
                    end.xyz[k] = if g == 530 {
                        l.words.get(XYZ[k]).unwrap_or(0.0) * self.scale()
                    } else {
                        home[k]
                    };
                }
                let known = self.unknown_since().is_none();
                for &k in &named {
                    self.m.unknown[k] = None;
                }
                if known {
                    self.push_rapid(line, end);
                } else {
                    self.m.pose = end;
                }
            }
            None => {
                let axes: String = named.iter().map(|&k| XYZ[k] as char).collect();
                for &k in &named {
                    self.m.unknown[k] = Some(line);
                }
                if !named.is_empty() {
                    self.notes.note(
                        line,
                        name,
                        format!(
                            "{missing}: axes {axes} are at unknown machine positions until \
                             programmed absolutely again"
                        ),
                        Refused,
                    )?;
                }
            }
        }
        Ok(())
    }
}
