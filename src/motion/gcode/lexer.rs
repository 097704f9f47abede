//! One line of G-code into words: comments stripped, block delete `/` (at the start of the
//! block or in mid-block, where the words after it are the optional part), `%` and program
//! numbers (`O1234`, `:1234`, with the words that follow on the line still read) recognised, letter + number words (spaces allowed between them, as Fanuc does), G and
//! M codes as integers × 10, and the Sinumerik keywords TRAORI/TRAFOOF.
//!
//! What the words mean is the reader's business (`super::reader`); this file only refuses
//! what is not a word at all (a stray character, a letter without a number, a macro `#`).

use crate::motion::error::Error;

/// Largest coordinate magnitude accepted (mm or degrees); beyond this a number is a typo.
const MAX_ABS_VALUE: f64 = 1.0e7;

/// Letters read as value words (besides G, M, N). Q, L, B, U, V, W are read so that the
/// reader can name them; the others are the old subset.
const VALUE_LETTERS: &[u8] = b"XYZACIJKRFSTHDPQLBUVW";

/// Words of one line, each at most once.
#[derive(Default)]
pub(crate) struct Words {
    vals: [Option<f64>; 26],
}

impl Words {
    pub(crate) fn get(&self, letter: u8) -> Option<f64> {
        self.vals[(letter - b'A') as usize]
    }
}

/// A lexed line.
#[derive(Default)]
pub(crate) struct Lexed {
    /// Value words.
    pub words: Words,
    /// G codes × 10 in order (G43.4 → 434).
    pub gcodes: Vec<u32>,
    /// M codes in order.
    pub mcodes: Vec<u32>,
    /// TRAORI / TRAFOOF in order.
    pub keywords: Vec<&'static str>,
    /// The line had a comment.
    pub comment: bool,
    /// The line began with `/` (block delete).
    pub block_delete: bool,
    /// A `/` in mid-block (Fanuc, Haas: the words after it are skipped when the switch is on).
    pub mid_block_delete: bool,
    /// The line had an N number.
    pub numbered: bool,
    /// The line is `%` (tape start/end).
    pub percent: bool,
    /// The line opens with a program number (`O1234`, `:1234`): its text.
    pub program_number: Option<String>,
    /// Words other than the program number on its line.
    pub words_after_program_number: bool,
}

/// `X10`, `M3`, `G43.4`: a word as written back in messages.
pub(crate) fn word_name(letter: char, value: f64) -> String {
    if value.fract() == 0.0 && value.abs() < 1e15 {
        format!("{letter}{}", value as i64)
    } else {
        format!("{letter}{value}")
    }
}

/// G code × 10 as written (434 → `G43.4`).
pub(crate) fn g_name(g: u32) -> String {
    if g % 10 == 0 {
        format!("G{}", g / 10)
    } else {
        format!("G{}.{}", g / 10, g % 10)
    }
}

fn strip_comments(raw: &str, line: usize) -> Result<(String, bool), Error> {
    let mut out = String::with_capacity(raw.len());
    let mut depth = false;
    let mut comment = false;
    for ch in raw.chars() {
        match ch {
            ';' if !depth => {
                comment = true;
                break;
            }
            '(' if !depth => {
                depth = true;
                comment = true;
            }
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
    Ok((out, comment))
}

/// Lexes one line (1-based `line` for errors).
pub(crate) fn lex(raw: &str, line: usize) -> Result<Lexed, Error> {
    let (text, comment) = strip_comments(raw, line)?;
    let mut out = Lexed {
        comment,
        ..Lexed::default()
    };
    let mut trimmed = text.trim();
    if let Some(rest) = trimmed.strip_prefix('/') {
        out.block_delete = true;
        trimmed = rest.trim_start();
    }
    if trimmed.is_empty() {
        return Ok(out);
    }
    if trimmed == "%" {
        out.percent = true;
        return Ok(out);
    }
    if trimmed.starts_with('O') || trimmed.starts_with(':') {
        // Program number (Fanuc O1234 or :1234): no action; what follows is read as usual.
        let end = trimmed[1..]
            .find(|c: char| !c.is_ascii_digit())
            .map_or(trimmed.len(), |k| k + 1);
        out.program_number = Some(trimmed[..end].to_string());
        trimmed = trimmed[end..].trim_start();
        out.words_after_program_number = !trimmed.is_empty();
    }
    let bytes = trimmed.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        let b = bytes[i];
        if b.is_ascii_whitespace() {
            i += 1;
            continue;
        }
        if b == b'/' {
            out.mid_block_delete = true;
            i += 1;
            continue;
        }
        if !b.is_ascii_uppercase() {
            let code: String = trimmed[i..]
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
            match &trimmed[i..j] {
                "TRAORI" => out.keywords.push("TRAORI"),
                "TRAFOOF" => out.keywords.push("TRAFOOF"),
                kw => {
                    return Err(Error::UnsupportedCode {
                        line,
                        code: kw.to_string(),
                    });
                }
            }
            i = j;
            continue;
        }
        let mut k = i + 1;
        while k < bytes.len() && bytes[k] == b' ' {
            k += 1;
        }
        let num_start = k;
        if k < bytes.len() && (bytes[k] == b'+' || bytes[k] == b'-') {
            k += 1;
        }
        let (mut digits, mut dots) = (0, 0);
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
        let value: f64 = trimmed[num_start..k]
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
            b'G' => out.gcodes.push(code_times_ten(value, 'G', line)?),
            b'M' => {
                let c = code_times_ten(value, 'M', line)?;
                if c % 10 != 0 {
                    return Err(Error::UnsupportedCode {
                        line,
                        code: format!("M{value}"),
                    });
                }
                out.mcodes.push(c / 10);
            }
            b'N' => out.numbered = true,
            _ if VALUE_LETTERS.contains(&b) => {
                let slot = &mut out.words.vals[(b - b'A') as usize];
                if slot.is_some() {
                    return Err(Error::gcode(line, format!("word '{letter}' appears twice")));
                }
                *slot = Some(value);
            }
            _ => {
                return Err(Error::UnsupportedCode {
                    line,
                    code: format!("{letter}{}", &trimmed[num_start..k]),
                });
            }
        }
    }
    Ok(out)
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
