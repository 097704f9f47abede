//! What a program rewriter needs beside the blocks: the reader's frame at the end of each
//! source line ([`LineFrame`]: units, G90/G91, work offset + tool length, position) and where
//! the words of a line sit in its text ([`word_spans`]), so that axis words can be replaced
//! while everything else (N numbers, comments, T/M/S/F words) is copied byte for byte.
//!
//! Used by `crate::cam` (compensated programs for CAM post-processors, CONTRACT v1.1
//! "Compensated programs"); the reader itself does not need it.

/// The reader's state at the end of one source line (after its words were applied).
#[derive(Clone, Debug, PartialEq)]
pub struct LineFrame {
    /// 1-based source line.
    pub line: usize,
    /// G20 in force: the line's numbers are inches (25.4 mm each).
    pub inch: bool,
    /// G91 in force: axis words are increments.
    pub incremental: bool,
    /// G90.1 in force: I/J/K are absolute centre positions in the program frame.
    pub absolute_centres: bool,
    /// G93 in force: F is inverse time (1/min) and every feed move carries its own F.
    pub inverse_time: bool,
    /// Work offset + tool length on Z in force, mm: under G90 a programmed point p (mm) is
    /// the machine point p + shift.
    pub shift_mm: [f64; 3],
    /// Machine position after the line, mm (the reader's guess where `known` is false).
    pub pose_mm: [f64; 3],
    /// Axes whose machine position is known after the line (false after G28/G30/G53 without
    /// a home until programmed absolutely again).
    pub known: [bool; 3],
}

/// One word of a line as written: its letter (upper case), value and byte range in the line.
#[derive(Clone, Debug, PartialEq)]
pub struct WordSpan {
    /// Letter, upper case.
    pub letter: char,
    /// The number as written (program units).
    pub value: f64,
    /// Byte offset of the letter in the line.
    pub start: usize,
    /// Byte offset just past the number.
    pub end: usize,
}

/// Words of `raw` (one source line) with their byte ranges, in order: comments `( )` and
/// `;`, a block-delete `/`, `%` lines, a leading program number (`O1234`, `:1234`; the words
/// after it are given) and keywords (TRAORI) give no words. Meant for lines the reader
/// accepted; a character that is not part of a word is skipped.
pub fn word_spans(raw: &str) -> Vec<WordSpan> {
    let bytes = raw.as_bytes();
    let mut out = Vec::new();
    let first = raw.trim_start().trim_start_matches('/').trim_start();
    if first.starts_with('%') {
        return out;
    }
    let mut i = 0;
    if first.starts_with(['O', 'o', ':']) {
        // Skip the program number itself.
        i = raw.len() - first.len() + 1;
        while i < bytes.len() && bytes[i].is_ascii_digit() {
            i += 1;
        }
    }
    while i < bytes.len() {
        let b = bytes[i];
        match b {
            b';' => break,
            b'(' => {
                while i < bytes.len() && bytes[i] != b')' {
                    i += 1;
                }
                i += 1;
                continue;
            }
            _ if !b.is_ascii_alphabetic() => {
                i += 1;
                continue;
            }
            _ => {}
        }
        let mut j = i + 1;
        while j < bytes.len() && bytes[j].is_ascii_alphabetic() {
            j += 1;
        }
        if j > i + 1 {
            // A keyword such as TRAORI.
            i = j;
            continue;
        }
        let mut k = j;
        while k < bytes.len() && bytes[k] == b' ' {
            k += 1;
        }
        let num_start = k;
        if k < bytes.len() && (bytes[k] == b'+' || bytes[k] == b'-') {
            k += 1;
        }
        while k < bytes.len() && (bytes[k].is_ascii_digit() || bytes[k] == b'.') {
            k += 1;
        }
        if let Ok(value) = raw[num_start..k].parse::<f64>() {
            out.push(WordSpan {
                letter: (b as char).to_ascii_uppercase(),
                value,
                start: i,
                end: k,
            });
            i = k;
        } else {
            i = j;
        }
    }
    out
}
