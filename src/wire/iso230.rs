//! Bodies of the ISO 230-2 and ISO 230-4 routes (CONTRACT v1.1 "ISO 230-2 and ISO 230-4"),
//! as the server answers them and `truecut iso230-2` / `truecut iso230-4` read and print them.
//! Contract fields first (their exact names: `A`, `E_fwd`, …), extensions after. Lengths in mm.

use serde::{Deserialize, Serialize};

use crate::metrology::{Axis230_2, Circular230_4, Hysteresis, TraceEvaluation};

/// `POST /v1/iso230-2` body: a table (`targets`, `forward`, `backward`) or a logged run
/// (`trace`).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Iso2302Request {
    /// Target positions, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub targets: Option<Vec<f64>>,
    /// Measured positions approached in the positive direction: a row per target, a column
    /// per cycle, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forward: Option<Vec<Vec<f64>>>,
    /// Measured positions approached in the negative direction, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub backward: Option<Vec<Vec<f64>>>,
    /// A logged positioning run instead of the table.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trace: Option<TraceBody>,
    /// A label kept with a stored run (e.g. "before compensation"); only for the machine-axis
    /// route.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
}

/// A logged positioning run of one axis.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TraceBody {
    /// Sampling period, s.
    pub period_s: f64,
    /// Commanded position per sample, mm.
    pub commanded: Vec<f64>,
    /// Measured position per sample (laser or scale), mm.
    pub measured: Vec<f64>,
    /// Shortest hold of the command that counts as a commanded approach, s (default 0.1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_dwell_s: Option<f64>,
    /// Commanded positions closer than this are one target, mm (default 0.001).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_tolerance_mm: Option<f64>,
    /// The measured position has settled while it moves slower than this, mm/s (default 0.01).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settle_speed_mm_s: Option<f64>,
    /// ... for at least this long, s (default 0.3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_settled_s: Option<f64>,
}

/// One row of the per-target table, mm.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[allow(non_snake_case)]
pub struct TargetRow {
    /// Target position P_i, mm.
    pub target: f64,
    /// Mean unidirectional positional deviation x̄_i↑ (measured − target), mm.
    pub mean_fwd: f64,
    /// x̄_i↓, mm.
    pub mean_bwd: f64,
    /// s_i↑ (n − 1), mm.
    pub s_fwd: f64,
    /// s_i↓, mm.
    pub s_bwd: f64,
    /// Reversal value B_i = x̄_i↑ − x̄_i↓, mm (signed).
    pub B: f64,
    /// Bidirectional repeatability R_i = max(2s↑ + 2s↓ + |B_i|, 4s↑, 4s↓), mm.
    pub R: f64,
    /// Mean bidirectional positional deviation x̄_i, mm.
    pub mean: f64,
    /// R_i↑ = 4 s_i↑, mm.
    pub R_fwd: f64,
    /// R_i↓ = 4 s_i↓, mm.
    pub R_bwd: f64,
    /// Cycles approached in the positive direction.
    pub n_fwd: usize,
    /// Cycles approached in the negative direction.
    pub n_bwd: usize,
}

/// A reading taken from a logged run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UsedReading {
    /// Target, mm.
    pub target: f64,
    /// `"fwd"` (positive approach) or `"bwd"`.
    pub direction: String,
    /// Cycle number in that direction (0-based).
    pub cycle: usize,
    /// The command's hold this reading answers, `[start, end)` in command samples.
    pub dwell: [usize; 2],
    /// The reading window: the stop's settled end (its last settling window before the axis
    /// moves again), `[start, end)` in measured samples.
    pub samples: [usize; 2],
    /// The reading window in time, `[start, end)` s (sample × `period_s`).
    #[serde(default)]
    pub window_s: [f64; 2],
    /// The reading, mm.
    pub reading: f64,
}

/// The settling rule a logged run was read with, and what the matching found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SettlingUsed {
    /// Speed threshold, mm/s.
    pub settle_speed_mm_s: f64,
    /// Minimum settled time, s.
    pub min_settled_s: f64,
    /// Length of the centred window the speed is judged over, s; a reading averages the last
    /// such window of its stop.
    pub window_s: f64,
    /// How far a stop may sit from a commanded position to answer it, mm.
    pub match_tolerance_mm: f64,
    /// Median of reading − target, mm: the measuring device's offset plus the axis' mean
    /// deviation. Kept in the readings (a constant changes no figure).
    pub measured_offset_mm: f64,
}

/// A settled stop of a logged run that was not used, and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IgnoredDwell {
    /// Settled samples of the stop, `[start, end)` in measured samples.
    pub samples: [usize; 2],
    /// Why it was not used.
    pub reason: String,
}

/// The answer of `POST /v1/iso230-2` (mm).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[allow(non_snake_case)]
pub struct Iso2302Answer {
    /// Bidirectional accuracy A (both directions), mm.
    pub A: f64,
    /// Unidirectional accuracy A↑, mm.
    pub A_fwd: f64,
    /// A↓, mm.
    pub A_bwd: f64,
    /// Bidirectional systematic positioning error E (both directions), mm.
    pub E: f64,
    /// E↑, mm.
    pub E_fwd: f64,
    /// E↓, mm.
    pub E_bwd: f64,
    /// Mean bidirectional positional deviation M, mm.
    pub M: f64,
    /// Bidirectional repeatability R = max R_i, mm.
    pub R: f64,
    /// R↑ = max 4 s_i↑, mm.
    pub R_fwd: f64,
    /// R↓, mm.
    pub R_bwd: f64,
    /// Reversal value B = max |B_i|, mm.
    pub B: f64,
    /// Mean reversal value B̄ (signed), mm.
    pub B_avg: f64,
    /// The per-target table.
    pub targets: Vec<TargetRow>,
    /// Departures from the standard's test conditions that were evaluated anyway.
    pub warnings: Vec<String>,
    /// The standard the figures follow.
    pub standard: String,
    /// With a logged run: the readings used, in time order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub used: Option<Vec<UsedReading>>,
    /// With a logged run: the settled stops not used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ignored: Option<Vec<IgnoredDwell>>,
    /// With a logged run: the settling rule used and the matching.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settling: Option<SettlingUsed>,
}

impl Iso2302Answer {
    /// The answer for an evaluated table.
    pub fn from_axis(a: &Axis230_2) -> Self {
        Iso2302Answer {
            A: a.a,
            A_fwd: a.a_fwd,
            A_bwd: a.a_bwd,
            E: a.e,
            E_fwd: a.e_fwd,
            E_bwd: a.e_bwd,
            M: a.m,
            R: a.r,
            R_fwd: a.r_fwd,
            R_bwd: a.r_bwd,
            B: a.b,
            B_avg: a.b_avg,
            targets: a
                .targets
                .iter()
                .map(|t| TargetRow {
                    target: t.target_mm,
                    mean_fwd: t.mean_fwd,
                    mean_bwd: t.mean_bwd,
                    s_fwd: t.s_fwd,
                    s_bwd: t.s_bwd,
                    B: t.reversal,
                    R: t.r,
                    mean: t.mean,
                    R_fwd: t.r_fwd,
                    R_bwd: t.r_bwd,
                    n_fwd: t.n_fwd,
                    n_bwd: t.n_bwd,
                })
                .collect(),
            warnings: a.warnings.clone(),
            standard: "ISO 230-2:2014".into(),
            used: None,
            ignored: None,
            settling: None,
        }
    }

    /// The answer for an evaluated logged run (with `used` and `ignored`).
    pub fn from_trace(ev: &TraceEvaluation, period_s: f64) -> Self {
        let mut answer = Self::from_axis(&ev.axis);
        answer.used = Some(
            ev.used
                .iter()
                .map(|r| UsedReading {
                    target: r.target_mm,
                    direction: if r.forward { "fwd" } else { "bwd" }.into(),
                    cycle: r.cycle,
                    dwell: r.command,
                    samples: r.settled,
                    window_s: r.settled.map(|k| k as f64 * period_s),
                    reading: r.reading_mm,
                })
                .collect(),
        );
        answer.ignored = Some(
            ev.ignored
                .iter()
                .map(|(s, e, why)| IgnoredDwell {
                    samples: [*s, *e],
                    reason: why.clone(),
                })
                .collect(),
        );
        let s = &ev.settling;
        answer.settling = Some(SettlingUsed {
            settle_speed_mm_s: s.settle_speed_mm_s,
            min_settled_s: s.min_settled_s,
            window_s: s.window_s,
            match_tolerance_mm: s.match_tolerance_mm,
            measured_offset_mm: s.measured_offset_mm,
        });
        answer
    }
}

/// `POST /v1/iso230-4` body.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Iso2304Request {
    /// The run's points [x, y], mm.
    pub points: Vec<[f64; 2]>,
    /// Nominal radius, mm.
    pub radius: f64,
    /// Fixed centre [x, y], mm (default: the orthogonal least-squares circle's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub centre: Option<[f64; 2]>,
    /// The same circle run in the opposite direction, [x, y] mm: adds its figures and the
    /// circular hysteresis H.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reverse_points: Option<Vec<[f64; 2]>>,
}

/// The figures of one circle run (mm).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[allow(non_snake_case)]
pub struct CircleFigures {
    /// Circular deviation G: radial range about the least-squares circle, mm.
    pub G: f64,
    /// Largest radial deviation from the nominal radius, mm.
    pub F_max: f64,
    /// Smallest radial deviation from the nominal radius, mm.
    pub F_min: f64,
    /// Centre [x, y], mm.
    pub centre: [f64; 2],
    /// Least-squares radius about that centre, mm.
    pub radius_fit: f64,
    /// Points evaluated.
    pub n: usize,
    /// Whether the centre was fitted (orthogonal least squares) or given.
    pub centre_fitted: bool,
}

impl CircleFigures {
    /// The figures of an evaluated run.
    pub fn from_eval(e: &Circular230_4) -> Self {
        CircleFigures {
            G: e.g,
            F_max: e.f_max,
            F_min: e.f_min,
            centre: e.centre,
            radius_fit: e.radius_fit,
            n: e.radial_deviation.len(),
            centre_fitted: e.centre_fitted,
        }
    }
}

/// The answer of `POST /v1/iso230-4` (mm): the contract's figures of `points` at the top,
/// then the extensions.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[allow(non_snake_case)]
pub struct Iso2304Answer {
    /// Circular deviation G of `points`, mm.
    pub G: f64,
    /// F_max of `points`, mm.
    pub F_max: f64,
    /// F_min of `points`, mm.
    pub F_min: f64,
    /// Centre, [x, y] mm.
    pub centre: [f64; 2],
    /// Least-squares radius, mm.
    pub radius_fit: f64,
    /// Points evaluated.
    pub n: usize,
    /// Whether the centre was fitted (orthogonal least squares) or given.
    pub centre_fitted: bool,
    /// Radial deviation of each point from the nominal radius about the centre, mm.
    pub radial_deviation: Vec<f64>,
    /// The figures of `reverse_points`, when sent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reverse: Option<CircleFigures>,
    /// Circular hysteresis H between `points` and `reverse_points`, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub H: Option<f64>,
    /// Angle of H about the common centre, degrees from +x.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub H_angle_deg: Option<f64>,
    /// The standard the figures follow.
    pub standard: String,
}

impl Iso2304Answer {
    /// The answer for one run and, optionally, its reverse run and their hysteresis.
    pub fn new(e: &Circular230_4, reverse: Option<(&Circular230_4, &Hysteresis)>) -> Self {
        let f = CircleFigures::from_eval(e);
        Iso2304Answer {
            G: f.G,
            F_max: f.F_max,
            F_min: f.F_min,
            centre: f.centre,
            radius_fit: f.radius_fit,
            n: f.n,
            centre_fitted: f.centre_fitted,
            radial_deviation: e.radial_deviation.clone(),
            reverse: reverse.map(|(r, _)| CircleFigures::from_eval(r)),
            H: reverse.map(|(_, h)| h.h),
            H_angle_deg: reverse.map(|(_, h)| h.at_angle_deg),
            standard: "ISO 230-4:2005".into(),
        }
    }
}
