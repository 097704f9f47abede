//! Body of the ISO 230-2 compensation-table routes with `format=json`
//! (`GET /v1/machines/{machine}/axes/{axis}/iso230-2/compensation`,
//! `POST /v1/iso230-2/compensation`). Lengths in mm.

use serde::{Deserialize, Serialize};

use crate::metrology::{Axis230_2, CompTable, PitchModel, SIGN_CONVENTION};

/// The fitted model of a `mode=model` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelBody {
    /// Position the scale term is taken about (middle of the run), mm.
    pub reference_mm: f64,
    /// Mean bidirectional deviation at the reference, mm.
    pub offset_mm: f64,
    /// Scale error, µm per m (deviation grows by this much per metre of travel).
    pub scale_um_per_m: f64,
    /// Reversal e↑ − e↓ (half applied to each direction), mm, signed.
    pub backlash_mm: f64,
    /// The cyclic term, when asked for.
    pub cyclic: Option<CyclicBody>,
    /// RMS misfit of the model to the run's per-target means, mm.
    pub rms_residual_mm: f64,
}

/// A fitted cyclic term `sin_mm · sin(2πP/pitch_mm) + cos_mm · cos(2πP/pitch_mm)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CyclicBody {
    /// Pitch, mm.
    pub pitch_mm: f64,
    /// Amplitude, mm.
    pub amplitude_mm: f64,
    /// Coefficient of the sine, mm.
    pub sin_mm: f64,
    /// Coefficient of the cosine, mm.
    pub cos_mm: f64,
}

/// ISO 230-2 figures of the run (mm).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[allow(non_snake_case)]
pub struct Figures {
    /// Bidirectional systematic positioning error E, mm.
    pub E: f64,
    /// Mean bidirectional positional deviation M, mm.
    pub M: f64,
    /// Bidirectional accuracy A, mm.
    pub A: f64,
    /// Bidirectional repeatability R, mm.
    pub R: f64,
    /// Reversal value B, mm.
    pub B: f64,
}

impl Figures {
    /// The figures of an evaluation.
    pub fn of(a: &Axis230_2) -> Self {
        Figures {
            E: a.e,
            M: a.m,
            A: a.a,
            R: a.r,
            B: a.b,
        }
    }
}

/// The compensation table as JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompTableAnswer {
    /// `mean` or `model`.
    pub mode: String,
    /// The sign convention of the corrections.
    pub sign: String,
    /// The target the corrections are counted from: its forward correction is 0, mm.
    pub reference_mm: f64,
    /// How the reference was chosen: `first_forward` (the first target approached in the
    /// positive direction, the default) or `named` (the query's `reference_mm`).
    pub reference_rule: String,
    /// The reference as a sentence (the files' `reference:` note).
    pub reference: String,
    /// Nominal (commanded) positions, ascending, mm.
    pub positions: Vec<f64>,
    /// Correction the controller adds to the command while approaching in +, mm.
    pub forward_correction: Vec<f64>,
    /// Correction while approaching in −, mm.
    pub backward_correction: Vec<f64>,
    /// Spacing of a model table, mm.
    pub spacing_mm: Option<f64>,
    /// The fitted model of a model table.
    pub model: Option<ModelBody>,
    /// The run's figures as measured.
    pub before: Figures,
    /// The run's figures predicted with the table loaded (each reading plus its correction).
    pub after: Figures,
    /// Stored run the table comes from (GET only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub run: Option<String>,
}

impl CompTableAnswer {
    /// The answer for a table and the run's figures before and after.
    pub fn new(
        mode: &str,
        table: &CompTable,
        before: &Axis230_2,
        after: &Axis230_2,
        run: Option<String>,
    ) -> Self {
        CompTableAnswer {
            mode: mode.into(),
            sign: SIGN_CONVENTION.into(),
            reference_mm: table.reference.position_mm(),
            reference_rule: table.reference.rule().into(),
            reference: table.reference.describe(),
            positions: table.positions_mm.clone(),
            forward_correction: table.forward_mm.clone(),
            backward_correction: table.backward_mm.clone(),
            spacing_mm: table.spacing_mm,
            model: table.model.as_ref().map(model_body),
            before: Figures::of(before),
            after: Figures::of(after),
            run,
        }
    }
}

fn model_body(m: &PitchModel) -> ModelBody {
    ModelBody {
        reference_mm: m.reference_mm,
        offset_mm: m.offset_mm,
        scale_um_per_m: m.scale * 1e6,
        backlash_mm: m.backlash_mm,
        cyclic: m.cyclic.map(|c| CyclicBody {
            pitch_mm: c.pitch_mm,
            amplitude_mm: c.amplitude_mm(),
            sin_mm: c.sin_mm,
            cos_mm: c.cos_mm,
        }),
        rms_residual_mm: m.rms_residual_mm,
    }
}
