//! The reader's path-control codes: how each block ends ([`BlockEnd`]), read into the
//! program's [`PathControl`](crate::motion::path_control::PathControl) when the caller asks
//! for it ([`super::parse_modes`]).
//!
//! | code | dialect | read as |
//! |---|---|---|
//! | G61 | Fanuc exact stop mode (LinuxCNC: exact path) | modal stop at every block end |
//! | G61.1 | LinuxCNC exact stop mode | modal stop at every block end |
//! | G9 | Fanuc exact stop, this block only | stop at this block's end |
//! | G64 | continuous (cutting) mode, cancels G61 | the service's look-ahead |
//! | G64 P*t* \[Q*q*\] | LinuxCNC blending within *t* (program units) | corners blended (P0: as G64) |
//! | G05.1 Q1 / Q0 | Fanuc AI contour control on / off | look-ahead on / off |
//! | G08 P1 / P0 | Fanuc look-ahead (advanced preview) control on / off | look-ahead on / off |
//!
//! Sources: LinuxCNC G-code reference, "G61, G61.1 Exact Path and Exact Stop" and "G64 Path
//! Blending" ("the actual path will be no more than P away from the programmed endpoint";
//! "G64 P0" is G64, since the planner reads a zero tolerance as none: `tcFindBlendTolerance`
//! in `src/emc/tp/tc.c`); Fanuc AI contour control specifications (A-63512EN §2.3: "reads
//! maximum 40 blocks ahead to perform linear acceleration/deceleration before
//! interpolation"). LinuxCNC's G61 is "exact path": it visits every programmed point but does
//! not stop between collinear blocks; the reader follows Fanuc, where G61 stops at every
//! block end, as it does for every dialect difference.
//!
//! Look-ahead off (G05.1 Q0, G08 P0) is read as a stop at every block end: a planner that
//! sees only the block it executes must be able to stop at that block's end point (the
//! look-ahead window of one block; `crate::motion::interpolate::controller`). A Fanuc control
//! without look-ahead does not stop but applies its acceleration/deceleration after
//! interpolation, which rounds corners by an amount set by its time constant (A-63512EN
//! §2.3); the machine model has no such time constant, so the reader says so in a warning.

use super::lexer::{Lexed, g_name, word_name};
use super::options::Legacy::Refused;
use super::reader::{LineCodes, Reader};
use crate::motion::error::Error;
use crate::motion::path_control::BlockEnd;

/// Modal path-control state: modal group 13 and the look-ahead switch.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct PathModal {
    /// G61 / G61.1 in force (until G64).
    pub(super) exact_stop: bool,
    /// The tolerance of G64 P in mm; None under G64 without P (or P0).
    pub(super) blend_mm: Option<f64>,
    /// Look-ahead switched off (G05.1 Q0, G08 P0).
    pub(super) lookahead_off: bool,
}

/// The path-control codes of one line and the words they take.
#[derive(Default)]
pub(super) struct PathWords {
    /// Codes × 10 in order (610, 611, 640, 90, 51, 80).
    pub(super) codes: Vec<u32>,
    /// The line's P is G64's tolerance or G08's switch.
    pub(super) p: bool,
    /// The line's Q is G64's naive-CAM tolerance or G05.1's switch.
    pub(super) q: bool,
    /// The line's R is G05.1's machining condition level.
    pub(super) r: bool,
    /// G9 on this line.
    pub(super) stop_once: bool,
}

impl Reader<'_> {
    /// A path-control code `g` (× 10) of `line`: kept for [`Reader::path_words`] when the
    /// caller reads modes; otherwise answered as before modes were read (G61/G61.1/G64 a
    /// warning, G9/G05.1/G08 unsupported).
    pub(super) fn path_code(
        &mut self,
        line: usize,
        g: u32,
        c: &mut LineCodes,
    ) -> Result<(), Error> {
        let name = g_name(g);
        if self.path.is_some() {
            self.notes.modelled(line, name)?;
            c.path.codes.push(g);
            return Ok(());
        }
        match g {
            610 | 611 | 640 => self.notes.note(
                line,
                name,
                "path-control mode is not modelled: the service's own look-ahead is used",
                Refused,
            ),
            _ => Err(Error::UnsupportedCode { line, code: name }),
        }
    }

    /// Applies the line's path-control codes to the modal state with their words.
    pub(super) fn path_words(
        &mut self,
        line: usize,
        l: &Lexed,
        c: &mut LineCodes,
    ) -> Result<(), Error> {
        let w = &l.words;
        let codes = std::mem::take(&mut c.path.codes);
        for g in codes {
            match g {
                610 | 611 => self.m.path.exact_stop = true,
                90 => c.path.stop_once = true,
                640 => {
                    self.m.path.exact_stop = false;
                    c.path.p = w.get(b'P').is_some();
                    self.m.path.blend_mm = match w.get(b'P') {
                        Some(p) if p.is_nan() || p < 0.0 => {
                            return Err(Error::gcode(
                                line,
                                "G64 P (blending tolerance) must be >= 0",
                            ));
                        }
                        Some(p) if p > 0.0 => Some(p * self.scale()),
                        _ => None,
                    };
                    if let Some(q) = w.get(b'Q') {
                        c.path.q = true;
                        self.notes.note(
                            line,
                            word_name('Q', q),
                            "G64 Q (LinuxCNC's naive-CAM tolerance) is not modelled: collinear \
                             blocks are planned as written, not merged",
                            Refused,
                        )?;
                    }
                }
                51 => {
                    c.path.q = true;
                    let on = self.switch(line, "G5.1", 'Q', w.get(b'Q'))?;
                    if let Some(r) = w.get(b'R') {
                        c.path.r = true;
                        self.notes.note(
                            line,
                            word_name('R', r),
                            "G5.1 R (machining condition level) is not modelled",
                            Refused,
                        )?;
                    }
                    self.m.path.lookahead_off = !on;
                }
                80 => {
                    c.path.p = true;
                    let on = self.switch(line, "G8", 'P', w.get(b'P'))?;
                    self.m.path.lookahead_off = !on;
                }
                _ => unreachable!("path_code keeps only path-control codes"),
            }
        }
        Ok(())
    }

    /// The on/off word of G5.1 (Q) or G8 (P): 1 on, 0 off (off is a warning: see the module
    /// docs), anything else refused.
    fn switch(
        &mut self,
        line: usize,
        code: &str,
        letter: char,
        v: Option<f64>,
    ) -> Result<bool, Error> {
        match v {
            Some(1.0) => Ok(true),
            Some(0.0) => {
                self.notes.note(
                    line,
                    format!("{code} {letter}0"),
                    "look-ahead off is read as a stop at every block end (a planner that sees \
                     one block); the control's acceleration/deceleration after interpolation, \
                     which rounds corners instead, is not modelled",
                    Refused,
                )?;
                Ok(false)
            }
            _ => Err(Error::gcode(
                line,
                format!("{code} needs {letter}1 (look-ahead on) or {letter}0 (off)"),
            )),
        }
    }

    /// How the blocks of the line just read end: a stop under G9, G61/G61.1 or look-ahead
    /// off, a blend under G64 P, else the service's look-ahead.
    pub(super) fn block_end(&self, stop_once: bool) -> BlockEnd {
        let p = self.m.path;
        if stop_once || p.exact_stop || p.lookahead_off {
            BlockEnd::Stop
        } else if let Some(tolerance_mm) = p.blend_mm {
            BlockEnd::Blend { tolerance_mm }
        } else {
            BlockEnd::Continuous
        }
    }
}

#[cfg(test)]
mod tests;
