//! G-code reader: an ISO 6983 / Fanuc-style subset with Sinumerik TRAORI/TRAFOOF.
//!
//! Hand-written: the `gcode` crate panics on inputs such as `M0444444444` under fuzzing
//! (see DESIGN.md), and we need line-accurate typed errors for anything unsupported.
//!
//! Supported: G0 G1 G2 G3 (IJK or R, full circles, helical third axis), G4 dwell (X s or
//! P ms), G17/G18/G19, G20/G21, G90/G91, G93/G94, G43.4/G49 and TRAORI/TRAFOOF (RTCP on/off),
//! the harmless cancels G40 G80 and G54 (taken as program zero = machine zero), words
//! X Y Z A C I J K R F N S T H D P, M0..M9 and M30 (M2/M30 end the program), comments in
//! parentheses and after `;`, `%` and `O` lines. Everything else is an
//! [`Error::UnsupportedCode`] naming the line and the code.
//!
//! The reader itself; its tests are in `super::tests`.

use crate::motion::error::Error;
use crate::motion::program::{ArcWords, Block, Feed, Motion, Plane, Pose, Program, arc_geometry};
const MM_PER_INCH: f64 = 25.4;
/// Largest coordinate magnitude accepted (mm or degrees); beyond this a number is a typo.
const MAX_ABS_VALUE: f64 = 1.0e7;

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum MotionMode {
    Rapid,
    Linear,
    ArcCw,
    ArcCcw,
}

struct Modal {
    motion: Option<MotionMode>,
    plane: Plane,
    inch: bool,
    incremental: bool,
    inverse_time: bool,
    feed_mm_min: Option<f64>,
    rtcp: bool,
    pose: Pose,
}

/// Words of one line, each at most once.
#[derive(Default)]
struct Words {
    vals: [Option<f64>; 26],
}

impl Words {
    fn get(&self, letter: u8) -> Option<f64> {
        self.vals[(letter - b'A') as usize]
    }
}

/// Parses a whole program.
///
/// The machine starts at program zero (X0 Y0 Z0 A0 C0), in G90 G17 G21 G94, RTCP off, with
/// no motion mode and no feed. Zero-length moves are kept (after an RTCP switch they
/// still move the machine); the interpolator drops those that move nothing.
/// Never panics; every rejected input yields a typed [`Error`] naming the 1-based line.
pub fn parse(text: &str) -> Result<Program, Error> {
    let mut m = Modal {
        motion: None,
        plane: Plane::Xy,
        inch: false,
        incremental: false,
        inverse_time: false,
        feed_mm_min: None,
        rtcp: false,
        pose: Pose::default(),
    };
    let mut prog = Program::default();
    for (idx, raw) in text.lines().enumerate() {
        let line = idx + 1;
        let ended = parse_line(raw, line, &mut m, &mut prog)?;
        if ended {
            break;
        }
    }
    Ok(prog)
}

fn strip_comments(raw: &str, line: usize) -> Result<String, Error> {
    let mut out = String::with_capacity(raw.len());
    let mut depth = false;
    for ch in raw.chars() {
        match ch {
            ';' if !depth => break,
            '(' if !depth => depth = true,
            '(' => return Err(Error::gcode(line, "nested '(' in a comment")),
            ')' if depth => depth = false,
            ')' => return Err(Error::gcode(line, "')' without a matching '('")),
            _ if depth => {}
            _ => out.push(ch.to_ascii_uppercase()),
        }
    }
    if depth {
        return Err(Error::gcode(line, "comment '(' is not closed on this line"));
    }
    Ok(out)
}

/// Reads one line; returns true when the program ends (M2/M30).
fn parse_line(raw: &str, line: usize, m: &mut Modal, prog: &mut Program) -> Result<bool, Error> {
    let text = strip_comments(raw, line)?;
    let bytes = text.as_bytes();
    let trimmed = text.trim();
    if trimmed.is_empty() || trimmed == "%" {
        return Ok(false);
    }
    if trimmed.starts_with('O') || trimmed.starts_with(':') {
        // Program number line (Fanuc O1234 or :1234): no action.
        return Ok(false);
    }
    let mut words = Words::default();
    let mut gcodes: Vec<u32> = Vec::new();
    let mut mcodes: Vec<u32> = Vec::new();
    let mut keywords: Vec<&'static str> = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let b = bytes[i];
        if b.is_ascii_whitespace() {
            i += 1;
            continue;
        }
        if !b.is_ascii_uppercase() {
            let code: String = text[i..]
                .chars()
                .next()
                .map(String::from)
                .unwrap_or_default();
            return Err(Error::UnsupportedCode { line, code });
        }
        // A run of letters is a keyword (TRAORI, TRAFOOF, ...).
        let mut j = i + 1;
        while j < bytes.len() && bytes[j].is_ascii_uppercase() {
            j += 1;
        }
        if j > i + 1 {
            let kw = &text[i..j];
            match kw {
                "TRAORI" => keywords.push("TRAORI"),
                "TRAFOOF" => keywords.push("TRAFOOF"),
                _ => {
                    return Err(Error::UnsupportedCode {
                        line,
                        code: kw.to_string(),
                    });
                }
            }
            i = j;
            continue;
        }
        // Letter + number (spaces allowed between them, as Fanuc does).
        let mut k = i + 1;
        while k < bytes.len() && bytes[k] == b' ' {
            k += 1;
        }
        let num_start = k;
        if k < bytes.len() && (bytes[k] == b'+' || bytes[k] == b'-') {
            k += 1;
        }
        let mut digits = 0;
        let mut dots = 0;
        while k < bytes.len() && (bytes[k].is_ascii_digit() || bytes[k] == b'.') {
            if bytes[k] == b'.' {
                dots += 1;
            } else {
                digits += 1;
            }
            k += 1;
        }
        let letter = b as char;
        if digits == 0 || dots > 1 {
            return Err(Error::gcode(
                line,
                format!("word '{letter}' needs a number (e.g. {letter}10.5)"),
            ));
        }
        let value: f64 = text[num_start..k]
            .parse()
            .map_err(|_| Error::gcode(line, format!("bad number after '{letter}'")))?;
        if !value.is_finite() || (value.abs() > MAX_ABS_VALUE && b != b'G' && b != b'M') {
            return Err(Error::gcode(
                line,
                format!("value of '{letter}' is out of range (|v| <= {MAX_ABS_VALUE})"),
            ));
        }
        i = k;
        match b {
            b'G' => gcodes.push(code_times_ten(value, 'G', line)?),
            b'M' => {
                let c = code_times_ten(value, 'M', line)?;
                if c % 10 != 0 {
                    return Err(Error::UnsupportedCode {
                        line,
                        code: format!("M{value}"),
                    });
                }
                mcodes.push(c / 10);
            }
            b'N' => {}
            b'X' | b'Y' | b'Z' | b'A' | b'C' | b'I' | b'J' | b'K' | b'R' | b'F' | b'S' | b'T'
            | b'H' | b'D' | b'P' => {
                let slot = &mut words.vals[(b - b'A') as usize];
                if slot.is_some() {
                    return Err(Error::gcode(line, format!("word '{letter}' appears twice")));
                }
                *slot = Some(value);
            }
            _ => {
                return Err(Error::UnsupportedCode {
                    line,
                    code: format!("{letter}{}", &text[num_start..k]),
                });
            }
        }
    }
    apply_line(line, m, prog, &words, &gcodes, &mcodes, &keywords)
}

/// G/M number × 10 as an integer (G43.4 → 434); rejects more than one decimal.
fn code_times_ten(value: f64, letter: char, line: usize) -> Result<u32, Error> {
    let t = value * 10.0;
    if !(0.0..10000.0).contains(&t) || (t - t.round()).abs() > 1e-6 {
        return Err(Error::UnsupportedCode {
            line,
            code: format!("{letter}{value}"),
        });
    }
    Ok(t.round() as u32)
}

fn apply_line(
    line: usize,
    m: &mut Modal,
    prog: &mut Program,
    w: &Words,
    gcodes: &[u32],
    mcodes: &[u32],
    keywords: &[&'static str],
) -> Result<bool, Error> {
    let mut motion_this_line: Option<MotionMode> = None;
    let mut dwell = false;
    for &g in gcodes {
        let set_motion = |mm: MotionMode, cur: &mut Option<MotionMode>| {
            if cur.is_some() {
                return Err(Error::gcode(
                    line,
                    "two motion codes (G0/G1/G2/G3) on one line",
                ));
            }
            *cur = Some(mm);
            Ok(())
        };
        match g {
            0 => set_motion(MotionMode::Rapid, &mut motion_this_line)?,
            10 => set_motion(MotionMode::Linear, &mut motion_this_line)?,
            20 => set_motion(MotionMode::ArcCw, &mut motion_this_line)?,
            30 => set_motion(MotionMode::ArcCcw, &mut motion_this_line)?,
            40 => dwell = true,
            170 => m.plane = Plane::Xy,
            180 => m.plane = Plane::Zx,
            190 => m.plane = Plane::Yz,
            200 => m.inch = true,
            210 => m.inch = false,
            400 | 540 | 800 => {}
            434 => m.rtcp = true,
            490 => m.rtcp = false,
            900 => m.incremental = false,
            910 => m.incremental = true,
            930 => {
                if !m.inverse_time {
                    m.feed_mm_min = None;
                }
                m.inverse_time = true
            }
            940 => {
                if m.inverse_time {
                    m.feed_mm_min = None;
                }
                m.inverse_time = false
            }
            _ => {
                let code = if g % 10 == 0 {
                    format!("G{}", g / 10)
                } else {
                    format!("G{}.{}", g / 10, g % 10)
                };
                return Err(Error::UnsupportedCode { line, code });
            }
        }
    }
    for kw in keywords {
        m.rtcp = *kw == "TRAORI";
    }
    let mut ends = false;
    for &mc in mcodes {
        match mc {
            0..=1 | 3..=9 => {}
            2 | 30 => ends = true,
            _ => {
                return Err(Error::UnsupportedCode {
                    line,
                    code: format!("M{mc}"),
                });
            }
        }
    }
    let scale = if m.inch { MM_PER_INCH } else { 1.0 };
    if dwell {
        if motion_this_line.is_some() {
            return Err(Error::gcode(
                line,
                "G4 dwell cannot share a line with motion",
            ));
        }
        let seconds = match (w.get(b'X'), w.get(b'P')) {
            (Some(x), None) => x,
            (None, Some(p)) => p / 1000.0,
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
            prog.blocks.push(Block {
                line,
                motion: Motion::Dwell { seconds },
                start: m.pose,
                end: m.pose,
                feed: Feed::Rapid,
                rtcp: m.rtcp,
            });
        }
        return Ok(ends);
    }
    if let Some(mm) = motion_this_line {
        m.motion = Some(mm);
    }
    // F word.
    if let Some(f) = w.get(b'F') {
        if f <= 0.0 {
            return Err(Error::gcode(line, "F must be > 0"));
        }
        m.feed_mm_min = Some(if m.inverse_time { f } else { f * scale });
    }
    let has_axis = [b'X', b'Y', b'Z', b'A', b'C']
        .iter()
        .any(|&l| w.get(l).is_some());
    let has_arc_words = [b'I', b'J', b'K', b'R'].iter().any(|&l| w.get(l).is_some());
    if !has_axis {
        if has_arc_words {
            return Err(Error::gcode(line, "I/J/K/R given without an end point"));
        }
        return Ok(ends);
    }
    let mode = m.motion.ok_or_else(|| {
        Error::gcode(
            line,
            "axis words without a motion mode: add G0, G1, G2 or G3",
        )
    })?;
    if w.get(b'A').is_some() && prog.first_a_line.is_none() {
        prog.first_a_line = Some(line);
    }
    if w.get(b'C').is_some() && prog.first_c_line.is_none() {
        prog.first_c_line = Some(line);
    }
    let start = m.pose;
    let mut end = start;
    for (k, l) in [b'X', b'Y', b'Z'].iter().enumerate() {
        if let Some(v) = w.get(*l) {
            end.xyz[k] = if m.incremental {
                start.xyz[k] + v * scale
            } else {
                v * scale
            };
        }
    }
    if let Some(v) = w.get(b'A') {
        end.a = if m.incremental { start.a + v } else { v };
    }
    if let Some(v) = w.get(b'C') {
        end.c = if m.incremental { start.c + v } else { v };
    }
    let feed = if mode == MotionMode::Rapid {
        Feed::Rapid
    } else if m.inverse_time {
        // G93: F must be programmed on every feed block.
        match w.get(b'F') {
            Some(f) => Feed::InverseTime(f),
            None => {
                return Err(Error::gcode(
                    line,
                    "G93 inverse-time mode needs F on every G1/G2/G3 block",
                ));
            }
        }
    } else {
        match m.feed_mm_min {
            Some(f) => Feed::PerMinute(f),
            None => {
                return Err(Error::gcode(
                    line,
                    "feed move without a feed rate: add an F word",
                ));
            }
        }
    };
    let motion = match mode {
        MotionMode::Rapid | MotionMode::Linear => {
            if has_arc_words {
                return Err(Error::gcode(line, "I/J/K/R are only allowed with G2/G3"));
            }
            Motion::Linear
        }
        MotionMode::ArcCw | MotionMode::ArcCcw => {
            let words = ArcWords {
                ijk: [w.get(b'I'), w.get(b'J'), w.get(b'K')],
                r: w.get(b'R'),
            };
            arc_geometry(
                line,
                m.plane,
                mode == MotionMode::ArcCw,
                &start,
                &end,
                words,
                scale,
            )?
        }
    };
    m.pose = end;
    prog.blocks.push(Block {
        line,
        motion,
        start,
        end,
        feed,
        rtcp: m.rtcp,
    });
    Ok(ends)
}
