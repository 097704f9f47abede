//! The reader's side of cutter radius compensation: G41/G42 with a caller-given tool
//! diameter turn it on (`super::cutter` computes the tool-centre path), G40 and the program's
//! end turn it off, and what LinuxCNC does not run under it is refused with a sentence.
//!
//! Which diameter: `D n` names tool n of `tool_diameters` (LinuxCNC reads D as a tool
//! number); without D, the tool of the last `T n M6`. A negative diameter swaps the side and
//! a zero one leaves the path as programmed (both as LinuxCNC does). Without
//! `tool_diameters`, or without the number in it, the programmed tool-tip path is kept with a
//! warning (refused under `strict`), as before the compensation was modelled.
//!
//! Refused while it is on (LinuxCNC refuses each too): another G41/G42, a plane other than
//! G17, G43/G49 and G54..G59 changes, RTCP, canned cycles, G28/G30/G53, M6, and an arc as
//! the first move after G40. Refused although LinuxCNC runs them: G41/G42 in G18 (LinuxCNC
//! offsets in XZ too; truecut models XY only), M0/M1/M60 while it is on (LinuxCNC ends the
//! held move there without its corner and reads the next corner from an empty queue), and
//! G41/G42 while an axis position is unknown (G28/G30/G53 without a home).

use super::cutter::{Cutter, Side};
use super::lexer::{Lexed, word_name};
use super::options::Legacy::{Accepted, Refused};
use super::reader::{LineCodes, Reader};
use crate::motion::error::Error;
use crate::motion::program::{Block, Feed, Motion, Plane, Pose};

/// What the G40/G41/G42 of a line asks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum CompCode {
    /// G40.
    Off,
    /// G41 (left) or G42 (right).
    On(Side),
}

impl Reader<'_> {
    /// Applies the line's G40/G41/G42 (after its plane and units, before its motion, as
    /// LinuxCNC orders them) and refuses what may not run under the compensation.
    pub(super) fn cutter_codes(
        &mut self,
        line: usize,
        c: &LineCodes,
        l: &Lexed,
    ) -> Result<(), Error> {
        match c.comp {
            Some(CompCode::Off) => self.cutter_off(line)?,
            Some(CompCode::On(side)) => self.cutter_on(line, side, l.words.get(b'D'))?,
            None => {}
        }
        if self.cutter.is_none() {
            return Ok(());
        }
        let refused = if self.m.plane != Plane::Xy {
            Some("a plane other than G17")
        } else if c.tool_offset {
            Some("a tool length change (G43/G49)")
        } else if c.work_offset {
            Some("a work offset change (G54..G59)")
        } else if self.m.rtcp {
            Some("RTCP (G43.4/TRAORI)")
        } else {
            None
        };
        match refused {
            Some(what) => Err(refused_under(line, what)),
            None => Ok(()),
        }
    }

    /// G41/G42 on `line` with the line's D word `d`.
    fn cutter_on(&mut self, line: usize, side: Side, d: Option<f64>) -> Result<(), Error> {
        let name = if side == Side::Left { "G41" } else { "G42" };
        if self.cutter.is_some() {
            return Err(Error::gcode(
                line,
                format!(
                    "{name} while cutter compensation is already on: cancel it with G40 first \
                     (LinuxCNC refuses it too)"
                ),
            ));
        }
        if self.opts.tool_diameters_mm.is_empty() {
            return self.notes.note(
                line,
                name,
                "cutter radius compensation is not modelled without tool_diameters: the \
                 programmed tool-tip path is used",
                Refused,
            );
        }
        let word = match d {
            Some(v) => format!("{name} {}", word_name('D', v)),
            None => name.to_string(),
        };
        let number = match d {
            Some(v) if v >= 0.0 && v.fract() == 0.0 => Some(v as u32),
            Some(v) => {
                return Err(Error::gcode(
                    line,
                    format!("{name} D{v}: D must be a whole tool number"),
                ));
            }
            None => self.m.spindle_tool,
        };
        let Some(number) = number else {
            return self.notes.note(
                line,
                word,
                "no D word and no tool loaded by T.. M6: the programmed tool-tip path is used",
                Refused,
            );
        };
        let Some(&diameter) = self.opts.tool_diameters_mm.get(&number) else {
            return self.notes.note(
                line,
                word,
                format!(
                    "no diameter given for tool {number} in tool_diameters: the programmed \
                     tool-tip path is used"
                ),
                Refused,
            );
        };
        if self.m.plane != Plane::Xy {
            return Err(Error::gcode(
                line,
                format!(
                    "{name}: cutter radius compensation is modelled in the XY plane (G17) only \
                     (LinuxCNC also offsets in G18): select G17 before {name}, or send no \
                     tool_diameters to read the programmed path"
                ),
            ));
        }
        if self.m.rtcp {
            return Err(refused_under(line, "RTCP (G43.4/TRAORI)"));
        }
        if let Some(since) = self.unknown_since() {
            return Err(Error::gcode(
                line,
                format!(
                    "{name}: the tool's position is unknown since line {since} (G28/G30/G53 \
                     without a home): program X and Y absolutely before {name}, or give home"
                ),
            ));
        }
        let (side, radius_mm) = if diameter < 0.0 {
            (side.flipped(), -diameter / 2.0)
        } else {
            (side, diameter / 2.0)
        };
        let towards = if side == Side::Left { "left" } else { "right" };
        self.notes.applied(
            line,
            word,
            format!(
                "tool {number} of diameter {diameter} mm: the path is the tool centre, \
                 {radius_mm} mm to the {towards} of the programmed path as LinuxCNC offsets it"
            ),
        )?;
        if radius_mm > 0.0 {
            let tool = self.after_exit.take().unwrap_or(self.m.pose);
            self.cutter = Some(Cutter::new(side, radius_mm, self.m.pose, tool));
        }
        Ok(())
    }

    /// G40 (or the program's end) on `line`: the held moves end where they are.
    pub(super) fn cutter_off(&mut self, line: usize) -> Result<(), Error> {
        if let Some(mut cutter) = self.cutter.take() {
            cutter.inch = self.m.inch;
            let (blocks, tool) = cutter.finish(line)?;
            self.prog.blocks.extend(blocks);
            self.after_exit = Some(tool);
        }
        Ok(())
    }

    /// Where the next move starts: the tool centre right after G40, else the position.
    pub(super) fn move_start(&mut self) -> Pose {
        self.after_exit.take().unwrap_or(self.m.pose)
    }

    /// Refuses `what` (a cycle, G28, ...) on `line` while the compensation is on.
    pub(super) fn refuse_under_cutter(&self, line: usize, what: &str) -> Result<(), Error> {
        match self.cutter {
            Some(_) => Err(refused_under(line, what)),
            None => Ok(()),
        }
    }

    /// A dwell of `seconds` on `line`, behind the moves the compensation holds.
    pub(super) fn push_dwell(&mut self, line: usize, seconds: f64) {
        match &mut self.cutter {
            Some(cutter) => {
                let out = cutter.dwell(line, seconds);
                self.prog.blocks.extend(out);
            }
            None => self.prog.blocks.push(Block {
                line,
                motion: Motion::Dwell { seconds },
                start: self.m.pose,
                end: self.m.pose,
                feed: Feed::Rapid,
                rtcp: self.m.rtcp,
            }),
        }
    }

    /// Hands the programmed `block` to the compensation when it is on (true), else leaves it
    /// to the caller (false). Under G93 its feed becomes the rate the programmed length
    /// takes, which the compensated moves keep (as LinuxCNC does).
    pub(super) fn compensate(&mut self, block: &Block) -> Result<bool, Error> {
        let Some(cutter) = &mut self.cutter else {
            return Ok(false);
        };
        cutter.inch = self.m.inch;
        let feed = match block.feed {
            Feed::InverseTime(f) => Feed::PerMinute(f * inverse_time_length_mm(block)),
            other => other,
        };
        let out = match block.motion {
            Motion::Arc {
                center, sweep_rad, ..
            } => {
                let turn = if sweep_rad > 0.0 { 1 } else { -1 };
                cutter.arc(block.line, feed, block.end, [center[0], center[1]], turn)?
            }
            _ => cutter.straight(block.line, feed, block.end)?,
        };
        self.prog.blocks.extend(out);
        Ok(true)
    }

    /// The D word is named unless a G41/G42 with `tool_diameters` uses it.
    pub(super) fn note_d_word(&mut self, line: usize, l: &Lexed) -> Result<(), Error> {
        let Some(v) = l.words.get(b'D') else {
            return Ok(());
        };
        let used = !self.opts.tool_diameters_mm.is_empty()
            && l.gcodes.iter().any(|g| matches!(g, 410 | 420));
        if used {
            return Ok(());
        }
        self.notes.note(
            line,
            word_name('D', v),
            "cutter radius offset number: the programmed tool-tip path is used",
            Accepted,
        )
    }
}

/// The programmed length of `block` that G93's F divides, mm, as LinuxCNC measures it: an
/// arc by its start radius (its end radius may differ by the program's rounding).
fn inverse_time_length_mm(block: &Block) -> f64 {
    match block.motion {
        Motion::Arc {
            center, sweep_rad, ..
        } => {
            let (s, e) = (&block.start.xyz, &block.end.xyz);
            let r = (s[0] - center[0]).hypot(s[1] - center[1]);
            (r * sweep_rad).hypot(e[2] - s[2])
        }
        _ => block.xyz_length(),
    }
}

/// The error of `what` on `line` while cutter compensation is on.
fn refused_under(line: usize, what: &str) -> Error {
    Error::gcode(
        line,
        format!(
            "{what} while cutter radius compensation (G41/G42) is on is not modelled \
             (LinuxCNC refuses most of these too): cancel it with G40 first"
        ),
    )
}
