//! The emitter's writing of a [`LinePlan::Path`]: an arc line written as sub-arcs with
//! straight moves between them (backlash take-ups where an axis of its plane reverses).

use super::super::text::spaced;
use super::super::text::{decimals, format_number, is_axis, is_centre, motion_style, rewrite};
use super::{CENTRES, Emitter, LineInfo};
use crate::cam::paths::SubArc;
use crate::motion::gcode::{LineFrame, WordSpan};
use crate::motion::program::Plane;

/// One piece of a [`super::LinePlan::Path`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PathPiece {
    /// A straight move (G1) to this point, machine frame, mm.
    Line([f64; 3]),
    /// A sub-arc (G2/G3 by its sweep's sign).
    Arc(SubArc),
}

impl PathPiece {
    /// Its motion code: 1 (G1), or 2/3 (G2/G3) by the sub-arc's turn in its plane.
    pub fn code(&self) -> u32 {
        match self {
            PathPiece::Line(_) => 1,
            PathPiece::Arc(a) if a.sweep_rad < 0.0 => 2,
            PathPiece::Arc(_) => 3,
        }
    }
}

impl Emitter {
    /// Writes the pieces of `path` (pieces, plane, F per piece under G93) for the source line
    /// `src` (number, text): the first on the source line with its motion word replaced, the
    /// others on new lines, each with its motion word where it changes; `restore` are words
    /// the source line must write again (its F).
    pub(super) fn write_path(
        &mut self,
        (line, raw): (usize, &str),
        info: &LineInfo,
        frame: &LineFrame,
        (pieces, plane, feeds): (&[PathPiece], Plane, Option<Vec<f64>>),
        restore: &[String],
    ) {
        let r_form = info.spans.iter().any(|s| s.letter == 'R');
        let inverse = feeds.is_some();
        let drop = |s: &WordSpan| is_axis(s) || is_centre(s) || (inverse && s.letter == 'F');
        let sep = if spaced(raw, &info.spans) { " " } else { "" };
        let mut prev = None;
        for (i, piece) in pieces.iter().enumerate() {
            let named = if i == 0 { info.named } else { [false; 3] };
            let mut words = match piece {
                PathPiece::Line(end) => self.axis_words(*end, named, frame),
                PathPiece::Arc(arc) => self.arc_words(arc, named, frame, plane, r_form),
            };
            if let Some(f) = feeds.as_ref().and_then(|f| f.get(i)) {
                words.extend(self.feed_word(*f, frame.inverse_time));
            }
            let c = piece.code();
            let motion = motion_style(raw, &info.spans, c);
            if i == 0 {
                words.extend(restore.iter().cloned());
                let text = rewrite(raw, &info.spans, drop, &words, Some(&motion));
                self.push(line, text);
            } else {
                if prev != Some(c) {
                    words.insert(0, motion);
                }
                self.push(line, words.join(sep));
            }
            prev = Some(c);
        }
    }

    /// Axis and centre words (IJK, or R where the source writes R) of the sub-arc `arc` from
    /// the output's position, in `plane`; updates the commanded position.
    pub(super) fn arc_words(
        &mut self,
        arc: &SubArc,
        named: [bool; 3],
        frame: &LineFrame,
        plane: Plane,
        r_form: bool,
    ) -> Vec<String> {
        let scale = if frame.inch { 25.4 } else { 1.0 };
        let d = decimals(frame.inch);
        let start = self.cmd;
        let mut words = self.axis_words(arc.end_mm, named, frame);
        let (p0, p1, _) = plane.axes();
        if r_form {
            let rho = (start[p0] - arc.centre_mm[p0]).hypot(start[p1] - arc.centre_mm[p1]) / scale;
            let signed = if arc.sweep_rad.abs() > std::f64::consts::PI {
                -rho
            } else {
                rho
            };
            words.push(format!("R{}", format_number(signed, d)));
        } else {
            let mut ks = [p0, p1];
            ks.sort_unstable();
            for k in ks {
                let v = if frame.absolute_centres {
                    (arc.centre_mm[k] - frame.shift_mm[k]) / scale
                } else {
                    (arc.centre_mm[k] - start[k]) / scale
                };
                words.push(format!("{}{}", CENTRES[k], format_number(v, d)));
            }
        }
        words
    }
}
