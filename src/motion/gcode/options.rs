//! What the caller tells the reader ([`ReadOptions`]: strictness, work offsets, tool lengths,
//! tool diameters, home) and what the reader tells back ([`Warning`]): every word it passes through or cannot
//! model faithfully, each named once with the first line it appeared on.
//!
//! Why warnings and not silence: a post-processor's program is full of words that do not move
//! the tool tip (spindle, coolant, tool change, comments), and a few that would move it in ways
//! the service cannot see (a tool length it was not given, G28 without a home). The caller must
//! be able to tell the two apart, so each is named; `strict` turns every one of them into 422.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;

use crate::motion::error::Error;

/// How the reader treats words that do not move an axis or that it cannot model faithfully.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReadOptions {
    /// Refuse every such word: each is an [`Error::Gcode`] naming the line and the word
    /// (422 over HTTP). Default false: each is a [`Warning`] and the programmed tool-tip path
    /// is kept.
    pub strict: bool,
    /// Work offsets G54..G59 (index 0 = G54), mm in machine coordinates: a programmed point p
    /// under G5x is the machine point p + offset. `None`: zero, with a warning naming it.
    pub work_offsets_mm: [Option<[f64; 3]>; 6],
    /// Tool lengths by H number, mm: under `G43 Hn` the machine Z is the programmed Z + length.
    /// A missing number keeps the programmed tool-tip path, with a warning.
    pub tool_lengths_mm: BTreeMap<u32, f64>,
    /// Tool diameters by number, mm: under `G41/G42 Dn` (or, without D, the tool of the last
    /// `Tn M6`) the path is the tool centre, offset by half the diameter as LinuxCNC offsets
    /// it (`super::cutter`). Empty: G41/G42 keep the programmed path, with a warning.
    pub tool_diameters_mm: BTreeMap<u32, f64>,
    /// Machine home (G28 reference point), mm in machine coordinates. `None`: the axes that
    /// G28/G53 name are unknown until programmed absolutely again.
    pub home_mm: Option<[f64; 3]>,
    /// G30 position (Fanuc's second reference point, LinuxCNC's parameters 5181-5183), mm in
    /// machine coordinates. `None`: the axes that G30 names are unknown until programmed
    /// absolutely again (it is not the home).
    pub g30_mm: Option<[f64; 3]>,
}

impl ReadOptions {
    /// Fills the home and the G30 position the request did not give from the machine
    /// definition's (`MachineDef::home`, `MachineDef::g30`).
    pub fn with_reference_points(
        mut self,
        home_mm: Option<[f64; 3]>,
        g30_mm: Option<[f64; 3]>,
    ) -> Self {
        self.home_mm = self.home_mm.or(home_mm);
        self.g30_mm = self.g30_mm.or(g30_mm);
        self
    }
}

/// A word the reader passed through or could not model faithfully.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Warning {
    /// 1-based line where the word first appeared.
    pub line: usize,
    /// The word as named (`M3`, `G43 H1`, `T1`, `comment`, `%`, `O1234`, ...).
    pub word: String,
    /// What the reader did with it, in one sentence.
    pub message: String,
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}: {}: {}", self.line, self.word, self.message)
    }
}

/// Reading mode: the old strict-subset reader ([`super::parse`]), lenient, or strict.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Mode {
    /// What [`super::parse`] accepted before warnings existed passes silently; everything
    /// else is [`Error::UnsupportedCode`].
    Legacy,
    /// Warnings.
    Lenient,
    /// Every warning is an error.
    Strict,
}

/// Whether the pre-warning reader accepted a word silently (kept so that [`super::parse`]
/// answers exactly as it did).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Legacy {
    /// Accepted silently by [`super::parse`].
    Accepted,
    /// Refused by [`super::parse`] as an unsupported code.
    Refused,
}

/// Collects warnings, each word once, or turns them into errors by mode.
pub(crate) struct Notes {
    mode: Mode,
    seen: BTreeSet<String>,
    pub(crate) list: Vec<Warning>,
}

impl Notes {
    pub(crate) fn new(mode: Mode) -> Self {
        Notes {
            mode,
            seen: BTreeSet::new(),
            list: Vec::new(),
        }
    }

    /// True when reading as [`super::parse`] did.
    pub(crate) fn legacy(&self) -> bool {
        self.mode == Mode::Legacy
    }

    /// Names `word` (first time only) or refuses it, by mode.
    pub(crate) fn note(
        &mut self,
        line: usize,
        word: impl Into<String>,
        message: impl Into<String>,
        legacy: Legacy,
    ) -> Result<(), Error> {
        let word = word.into();
        match (self.mode, legacy) {
            (Mode::Legacy, Legacy::Accepted) => return Ok(()),
            (Mode::Legacy, Legacy::Refused) => {
                return Err(Error::UnsupportedCode { line, code: word });
            }
            (Mode::Strict, _) => {
                let message = message.into();
                return Err(Error::gcode(
                    line,
                    format!(
                        "{word}: {message}; refused because \"strict\" is true (send strict \
                         false to read it with a warning)"
                    ),
                ));
            }
            (Mode::Lenient, _) => {}
        }
        if self.seen.insert(word.clone()) {
            self.list.push(Warning {
                line,
                word,
                message: message.into(),
            });
        }
        Ok(())
    }

    /// A per-line warning (not deduplicated by word): positions unknown on this line.
    pub(crate) fn note_line(
        &mut self,
        line: usize,
        word: impl Into<String>,
        message: impl Into<String>,
    ) -> Result<(), Error> {
        let word = word.into();
        self.note(
            line,
            format!("{word} (line {line})"),
            message,
            Legacy::Refused,
        )
    }
}

impl Notes {
    /// A word the reader models faithfully but that [`super::parse`] refused: an error in
    /// legacy mode only.
    pub(crate) fn modelled(&mut self, line: usize, word: impl Into<String>) -> Result<(), Error> {
        match self.mode {
            Mode::Legacy => Err(Error::UnsupportedCode {
                line,
                code: word.into(),
            }),
            _ => Ok(()),
        }
    }

    /// A value the caller supplied and the reader applied (work offset, tool length): named
    /// once in lenient and strict mode, refused in legacy mode (which has no options).
    pub(crate) fn applied(
        &mut self,
        line: usize,
        word: impl Into<String>,
        message: impl Into<String>,
    ) -> Result<(), Error> {
        let word = word.into();
        self.modelled(line, word.clone())?;
        if self.seen.insert(word.clone()) {
            self.list.push(Warning {
                line,
                word,
                message: message.into(),
            });
        }
        Ok(())
    }
}
