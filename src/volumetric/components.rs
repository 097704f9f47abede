//! The 21 ISO 230-1 component curves of a fitted map, in the units machine-tool
//! people read them in.

use super::kinematic::{FUNCTION_NAMES, KinematicModel, SQUARENESS_NAMES};
use serde::{Deserialize, Serialize};

/// One error motion sampled along its axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Curve {
    /// ISO 230-1 name, e.g. `EXX`, `EYX`, `EBX`.
    pub name: String,
    /// `positioning`, `straightness`, `roll`, `pitch`, `yaw` or `tilt`.
    pub kind: String,
    /// `um` (translations) or `urad` (rotations).
    pub unit: String,
    /// Values at the axis' `position_mm`, relative to the value at the axis' start;
    /// `None` when the data cannot identify this motion (fixed to 0 in the model).
    pub values: Option<Vec<f64>>,
}

/// The six error motions of one axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxisCurves {
    /// The moving axis: `X`, `Y` or `Z`.
    pub axis: String,
    /// Positions along the axis where the curves are sampled, mm.
    pub position_mm: Vec<f64>,
    /// Its six error motions (positioning, two straightnesses, roll, pitch, yaw).
    pub curves: Vec<Curve>,
}

/// A squareness error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Squareness {
    /// `EC0Y` (Y to X), `EB0Z` (Z to X) or `EA0Z` (Z to Y).
    pub name: String,
    /// The out-of-squareness angle, µrad.
    pub value_urad: f64,
}

/// All 21 components.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ComponentCurves {
    /// The 18 error motions, six per linear axis.
    pub axes: Vec<AxisCurves>,
    /// The three squareness errors.
    pub squareness: Vec<Squareness>,
    /// Tool offset from the spindle reference (x, y, z), mm, used for the Abbe terms.
    pub tool_offset_mm: [f64; 3],
    /// What could not be identified and why.
    pub notes: Vec<String>,
}

const KINDS: [[&str; 6]; 3] = [
    [
        "positioning",
        "straightness",
        "straightness",
        "roll",
        "pitch",
        "yaw",
    ],
    [
        "straightness",
        "positioning",
        "straightness",
        "pitch",
        "roll",
        "yaw",
    ],
    [
        "straightness",
        "straightness",
        "positioning",
        "tilt",
        "tilt",
        "roll",
    ],
];

/// Samples the 18 error motions of `model` at `samples` evenly spaced positions of each
/// axis' fitted range (translations in µm, rotations in µrad, each relative to its
/// value at the start of travel) and lists the three squareness errors (µrad).
///
/// Reference: ISO 230-1:2012 §3 (names and sign conventions). Known limits: the
/// constant part of every motion is not separable from the reference offset, and the
/// constant part of the rotations is folded into squareness, hence "relative to the
/// start"; with one tool offset Z's rotations and Y's yaw are not identifiable.
pub fn component_curves(model: &KinematicModel, samples: usize) -> ComponentCurves {
    let samples = samples.clamp(2, 1001);
    let mut notes = Vec::new();
    let axes = (0..3)
        .map(|axis| {
            let [a, b] = model.range[axis];
            let position_mm: Vec<f64> = (0..samples).map(|i| a + (b - a) * i as f64 / (samples - 1) as f64).collect();
            let curves = (0..6)
                .map(|f| {
                    // mm → µm, rad → µrad
                    let factor = if f < 3 { 1e3 } else { 1e6 };
                    let values = if model.identified[axis][f] {
                        let start = model.motion(axis, f, a);
                        Some(position_mm.iter().map(|&q| (model.motion(axis, f, q) - start) * factor).collect())
                    } else {
                        notes.push(format!(
                            "{} is not identifiable from these nodes (it acts only through the tool offset): measure with a second tool offset",
                            FUNCTION_NAMES[axis][f]
                        ));
                        None
                    };
                    Curve {
                        name: FUNCTION_NAMES[axis][f].to_string(),
                        kind: KINDS[axis][f].to_string(),
                        unit: if f < 3 { "um" } else { "urad" }.to_string(),
                        values,
                    }
                })
                .collect();
            AxisCurves { axis: ["X", "Y", "Z"][axis].to_string(), position_mm, curves }
        })
        .collect();
    let squareness = (0..3)
        .map(|w| Squareness {
            name: SQUARENESS_NAMES[w].to_string(),
            value_urad: model.squareness_rad[w] * 1e6,
        })
        .collect();
    ComponentCurves {
        axes,
        squareness,
        tool_offset_mm: model.tool_offset_mm,
        notes,
    }
}

#[cfg(test)]
mod tests;
