//! A machine's controller and the limits its trajectory planner puts on dense blocks: the
//! machine definition's optional `"controller"` object ([`ControllerDef`]), checked once into
//! [`ControllerLimits`], which the interpolator applies (`super::interpolate::controller`).
//!
//! `{"kind": "linuxcnc" | "grbl" | "fanuc" | "generic", "segment_cap"?: bool,
//! "block_rate_hz"?: 1/s, "lookahead_blocks"?: int}`. Absent, the interpolator plans as it
//! always did: every block at its own feed, with a look-ahead over the whole program.
//!
//! - `segment_cap`: LinuxCNC's trajectory planner caps a segment's speed at its length over
//!   1.02 interpolation periods, so that every segment is sampled at least once
//!   (`tp.c` `tpAddLine`: `sample_maxvel = tc.target / (tp->cycleTime *
//!   TP_MIN_SEGMENT_CYCLES)` with `TP_MIN_SEGMENT_CYCLES 1.02` in `tp_types.h`, LinuxCNC 2.7 onwards):
//!   20 µm chords at a 1 ms period run at most 19.6 mm/s. The planner always does it, so it
//!   defaults to true for `"linuxcnc"` and to false otherwise.
//! - `block_rate_hz`: blocks the controller can read and plan per second. A GRBL on an
//!   ATmega328p needs about 2.5-5 ms to parse and plan a line (S. Jeon, grbl/grbl issues 492
//!   and 1284: "Grbl can handle up to 400 lines per second"); a block shorter than v / rate
//!   then runs at no more than its length × rate.
//! - `lookahead_blocks`: how many blocks the planner sees ahead of the one it executes (GRBL's
//!   planner buffer, 15-16 blocks on an ATmega328p; Fanuc AI contour control reads 40,
//!   A-63512EN §2.3). The planner must be able to stop within what it sees, so short blocks
//!   cap the speed at what stops within the window ("the short line segments ... limit the
//!   amount of distance inside the planner. And limit the top speed", grbl/grbl pull 498).
//!
//! `kind` names the controller (and sets `segment_cap`'s default); every limit is stated.

use serde::{Deserialize, Serialize};

use super::bounds::{BLOCK_RATE_HZ, LOOKAHEAD_BLOCKS};
use super::error::Error;

/// Controllers the definition names (`"kind"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ControllerKind {
    /// LinuxCNC (its segment cap is on by default).
    Linuxcnc,
    /// GRBL and other hobby controllers that plan over a small block buffer.
    Grbl,
    /// A Fanuc control (AI contour control looks 40 blocks ahead).
    Fanuc,
    /// Any other controller; only the limits stated apply.
    Generic,
}

/// The `"controller"` object of a machine definition (see the module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a controller object like {\"kind\": \"linuxcnc\"} or {\"kind\": \"grbl\", \"block_rate_hz\": 400, \"lookahead_blocks\": 15}"
)]
pub struct ControllerDef {
    /// Which controller.
    pub kind: ControllerKind,
    /// LinuxCNC's cap of a segment's speed at its length / (1.02 × period); default true for
    /// `linuxcnc`, false otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub segment_cap: Option<bool>,
    /// Blocks read and planned per second ([`BLOCK_RATE_HZ`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub block_rate_hz: Option<f64>,
    /// Blocks the planner sees ahead of the one it executes ([`LOOKAHEAD_BLOCKS`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lookahead_blocks: Option<u32>,
}

/// The checked limits the interpolator applies; the default is none (today's planning).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ControllerLimits {
    /// Cap each block's speed at its length / (1.02 × interpolation period), mm/s.
    pub segment_cap: bool,
    /// Cap each block's speed at its length × this rate (blocks per second).
    pub block_rate_hz: Option<f64>,
    /// The planner sees this many blocks ahead of the one it executes.
    pub lookahead_blocks: Option<usize>,
}

impl ControllerDef {
    /// The limits, ranges checked: `block_rate_hz` in [`BLOCK_RATE_HZ`], `lookahead_blocks`
    /// in [`LOOKAHEAD_BLOCKS`]; errors name `controller.{field}`.
    pub fn limits(&self) -> Result<ControllerLimits, Error> {
        let block_rate_hz = self
            .block_rate_hz
            .map(|r| BLOCK_RATE_HZ.check("controller.block_rate_hz", r))
            .transpose()?;
        let lookahead_blocks = self
            .lookahead_blocks
            .map(|n| LOOKAHEAD_BLOCKS.check("controller.lookahead_blocks", f64::from(n)))
            .transpose()?
            .map(|n| n as usize);
        Ok(ControllerLimits {
            segment_cap: self
                .segment_cap
                .unwrap_or(self.kind == ControllerKind::Linuxcnc),
            block_rate_hz,
            lookahead_blocks,
        })
    }
}

#[cfg(test)]
mod tests;
