//! The motion-gap request: the body of `POST /v1/machines/{machine}/gap-diagnosis` (both
//! domains; the part fields are read by `api`, which loads the stored surface), checked into a
//! [`MotionBlock`] and run against a machine's servo axes. The server, `truecut gap diagnose`
//! and `truecut gap csv` all come here. Errors name the field and the fix.

use std::collections::BTreeMap;

use serde::Deserialize;
use serde_json::Value;

use super::align::{Alignment, TimedLog, check_times, refine_delay, step_effects};
use super::answer::motion_answer;
use super::error::Error;
use super::motion::{MotionBlock, MotionOptions, diagnose_motion_structured};
use super::plant::AxisPlant;
use crate::motion::ServoAxes;

/// Samples per block accepted at all.
pub const MAX_SAMPLES: usize = 2_000_000;

/// Body of the route (both domains; fields of the other domain are rejected).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GapRequest {
    /// "motion" or "part".
    pub domain: String,
    /// Motion: sample period, s.
    #[serde(default)]
    pub period_s: Option<f64>,
    /// Motion: command rows `[x, y]` or `[x, y, z]`, mm.
    #[serde(default)]
    pub commanded: Option<Vec<Vec<f64>>>,
    /// Motion: measured rows, mm.
    #[serde(default)]
    pub measured: Option<Vec<Vec<f64>>>,
    /// Motion: the measured rows' own time stamps, s, strictly increasing, on the log's clock
    /// (any origin, any rate, jitter and gaps): the log is aligned to the program
    /// ([`crate::gap::align`]) instead of being read one row a period.
    #[serde(default)]
    pub measured_t: Option<Vec<f64>>,
    /// Part: surface id.
    #[serde(default)]
    pub surface: Option<String>,
    /// Part: measurement id.
    #[serde(default)]
    pub measurement: Option<String>,
    /// Part: simulated deviation per point, mm (default: volumetric map along the normals, else 0).
    #[serde(default)]
    pub predicted: Option<Vec<f64>>,
    /// Part: cutting time per point, s.
    #[serde(default)]
    pub time: Option<Vec<f64>>,
    /// Part: probe approach direction per point.
    #[serde(default)]
    pub approach: Option<Vec<[f64; 3]>>,
    /// Validation block (shape depends on the domain).
    #[serde(default)]
    pub validation: Option<Value>,
    /// Extension: cross-validation folds (default 5, 2..=10).
    #[serde(default)]
    pub folds: Option<usize>,
    /// Motion: the program whose interpolation on this machine is the command (instead of
    /// `commanded`; CONTRACT v1.1).
    #[serde(default)]
    pub gcode: Option<String>,
    /// Motion with `gcode`: refuse (422) every word the reader would pass with a warning.
    #[serde(default)]
    pub strict: bool,
    /// Motion with `gcode`: work offsets by code ("G54".."G59"), [x, y, z] mm.
    #[serde(default)]
    pub work_offsets: BTreeMap<String, [f64; 3]>,
    /// Motion with `gcode`: tool lengths by H number, mm.
    #[serde(default)]
    pub tool_lengths: BTreeMap<String, f64>,
    /// Motion with `gcode`: tool diameters by tool number, mm (G41/G42: the tool-centre path).
    #[serde(default)]
    pub tool_diameters: BTreeMap<String, f64>,
    /// Motion with `gcode`: machine home for G28/G30/G53, [x, y, z] mm.
    #[serde(default)]
    pub home: Option<[f64; 3]>,
    /// Motion: `"stored"` (default) simulates with the effects stored with the machine,
    /// `"none"` with its servo model alone (read by the API layer into the axes' effects).
    #[serde(default)]
    pub effects: Option<String>,
}

/// The command of a motion request that came as a program: per-axis columns (mm), the program
/// line executing at each sample, and the reader's warnings.
#[derive(Clone, Debug, Default)]
pub struct ProgramCommand {
    /// Command per axis, mm, one sample per `period_s` from the program's start.
    pub commanded: Vec<Vec<f64>>,
    /// 1-based program line per sample.
    pub lines: Vec<u32>,
    /// Reader warnings and notes on the program ("line N: word: message").
    pub warnings: Vec<String>,
}

/// The motion domain's `validation` block.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MotionValidationBody {
    commanded: Vec<Vec<f64>>,
    measured: Vec<Vec<f64>>,
}

/// Rows `[[x, y(, z)]; n]` → per-axis columns, checking shape, size and finiteness.
pub fn rows_to_columns(field: &str, rows: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, Error> {
    let Some(first) = rows.first() else {
        return Err(Error::Request(format!(
            "{field} is empty: send one row [x, y] or [x, y, z] (mm) per period"
        )));
    };
    let dims = first.len();
    if !(2..=3).contains(&dims) {
        return Err(Error::Request(format!(
            "{field}[0] has {dims} values: rows are [x, y] or [x, y, z] in mm"
        )));
    }
    if rows.len() > MAX_SAMPLES {
        return Err(Error::TooManySamples {
            field: field.to_string(),
            rows: rows.len(),
            max: MAX_SAMPLES,
        });
    }
    let mut cols = vec![Vec::with_capacity(rows.len()); dims];
    for (i, row) in rows.iter().enumerate() {
        if row.len() != dims {
            return Err(Error::Request(format!(
                "{field}[{i}] has {} values but {field}[0] has {dims}: every row needs the same axes",
                row.len()
            )));
        }
        for (k, v) in row.iter().enumerate() {
            if !v.is_finite() {
                return Err(Error::NonFinite {
                    field: format!("{field}[{i}]"),
                    index: k,
                });
            }
            cols[k].push(*v);
        }
    }
    Ok(cols)
}

/// Runs the motion diagnosis of `req` against the machine's servo models (sync core call;
/// also used by `truecut gap diagnose` and `truecut gap csv`).
pub fn diagnose_motion_request(axes: &ServoAxes, req: &GapRequest) -> Result<Value, Error> {
    diagnose_motion_program(axes, req, None)
}

/// As [`diagnose_motion_request`], with the command taken from `program` (the interpolation of
/// the request's `gcode`, made by the caller) instead of `commanded`: `where` then names the
/// program lines and the answer carries the reader's `warnings`. A time-stamped log
/// (`measured_t`) is diagnosed twice when the first diagnosis takes a step: its delay is
/// chosen again with the steps' effects refitted at every delay tried ([`refine_delay`]),
/// and the answer is the diagnosis at that delay.
pub fn diagnose_motion_program(
    axes: &ServoAxes,
    req: &GapRequest,
    program: Option<&ProgramCommand>,
) -> Result<Value, Error> {
    let ((mut main, validation, period_s, mut opts), timed) =
        motion_inputs_timed(axes, req, program)?;
    let dims = main.commanded.len();
    let run = |main: &MotionBlock, opts: &MotionOptions| {
        // a timed log's grid is the program's cut or held to the log: so are its lines
        let lines: Option<Vec<u32>> = program.map(|p| {
            let mut lines = p.lines.clone();
            let last = lines.last().copied().unwrap_or(1);
            lines.resize(main.commanded[0].len(), last);
            lines
        });
        diagnose_motion_structured(
            &axes.names[..dims],
            &axes.servo[..dims],
            &axes.structure[..dims],
            period_s,
            main,
            validation.as_ref(),
            lines.as_deref(),
            opts,
        )
    };
    let mut d = run(&main, &opts)?;
    let mut alignment = None;
    if let Some((timed, first)) = timed {
        // the first delay matched the stored simulation alone: choose it again with the
        // effects the diagnosis named, and diagnose the log at that delay
        let effects = step_effects(&d);
        alignment = Some(if effects.is_empty() {
            first
        } else {
            let a = refine_delay(&timed, &first, &effects)?;
            main = a.block;
            opts.observed = Some(a.observed);
            d = run(&main, &opts)?;
            a.alignment
        });
    }
    let mut answer = motion_answer(&axes.names[..dims], &d);
    if let Some(a) = alignment {
        answer["alignment"] = serde_json::json!(a);
    }
    if let Some(p) = program {
        answer["warnings"] = serde_json::json!(p.warnings);
    }
    Ok(answer)
}

/// A motion request checked: the block, the validation block, the period (s), the options.
pub type MotionInputs = (MotionBlock, Option<MotionBlock>, f64, MotionOptions);

/// Checks a motion-domain request against the machine's servo axes and turns it into
/// [`MotionInputs`]: refuses part-domain fields, requires `period_s` in (0, 10] s and
/// `commanded` and `measured` rows (mm) of the same shape, with no more columns than the
/// machine has axes. Each error names the field to fix.
pub fn motion_inputs(axes: &ServoAxes, req: &GapRequest) -> Result<MotionInputs, Error> {
    motion_inputs_with(axes, req, None)
}

/// As [`motion_inputs`], the command coming from `program` when given: its columns are cut
/// to the measured row width and its length must equal the measured rows' (the caller fits
/// the interpolation to the measurement's length).
pub fn motion_inputs_with(
    axes: &ServoAxes,
    req: &GapRequest,
    program: Option<&ProgramCommand>,
) -> Result<MotionInputs, Error> {
    motion_inputs_aligned(axes, req, program).map(|(inputs, _)| inputs)
}

/// As [`motion_inputs_with`]; with `measured_t`, the log is aligned to the stored simulation of
/// the command and put on the program's grid ([`TimedLog`]): the block is that grid's, the
/// options carry the observed instants, and the alignment is returned beside.
pub fn motion_inputs_aligned(
    axes: &ServoAxes,
    req: &GapRequest,
    program: Option<&ProgramCommand>,
) -> Result<(MotionInputs, Option<Alignment>), Error> {
    motion_inputs_timed(axes, req, program).map(|(inputs, timed)| (inputs, timed.map(|(_, a)| a)))
}

/// As [`motion_inputs_aligned`], returning the time-stamped log itself beside its first
/// alignment, for [`refine_delay`].
pub fn motion_inputs_timed(
    axes: &ServoAxes,
    req: &GapRequest,
    program: Option<&ProgramCommand>,
) -> Result<(MotionInputs, Option<(TimedLog, Alignment)>), Error> {
    if req.gcode.is_some() && req.commanded.is_some() {
        return Err(Error::Request(
            "send either commanded (rows) or gcode (a program), not both".into(),
        ));
    }
    if req.gcode.is_none()
        && (req.strict
            || !req.work_offsets.is_empty()
            || !req.tool_lengths.is_empty()
            || !req.tool_diameters.is_empty()
            || req.home.is_some())
    {
        return Err(Error::Request(
            "strict, work_offsets, tool_lengths, tool_diameters and home read a program: send \
             them with gcode"
                .into(),
        ));
    }
    for (name, present) in [
        ("surface", req.surface.is_some()),
        ("measurement", req.measurement.is_some()),
        ("predicted", req.predicted.is_some()),
        ("time", req.time.is_some()),
        ("approach", req.approach.is_some()),
    ] {
        if present {
            return Err(Error::Request(format!(
                "{name} belongs to domain \"part\": a motion diagnosis takes period_s, commanded, measured and validation"
            )));
        }
    }
    let period_s = req.period_s.ok_or_else(|| {
        Error::Request("period_s is missing: give the sample period in seconds, e.g. 0.001".into())
    })?;
    if !(period_s.is_finite() && period_s > 0.0 && period_s <= 10.0) {
        return Err(Error::Request(format!(
            "period_s must be a positive number of seconds (at most 10), got {period_s}"
        )));
    }
    let need = |field: &str, v: &Option<Vec<Vec<f64>>>| -> Result<Vec<Vec<f64>>, Error> {
        rows_to_columns(
            field,
            v.as_deref().ok_or_else(|| {
                Error::Request(format!(
                    "{field} is missing: send rows [x, y] or [x, y, z] in mm"
                ))
            })?,
        )
    };
    let measured = need("measured", &req.measured)?;
    if let Some(t) = &req.measured_t {
        check_times("measured_t", t, measured[0].len())?;
    }
    let commanded = match program {
        Some(p) => {
            let dims = measured.len();
            if p.commanded.len() < dims {
                return Err(Error::Request(format!(
                    "measured rows have {dims} values but the program moves only {} axes",
                    p.commanded.len()
                )));
            }
            p.commanded[..dims].to_vec()
        }
        None => need("commanded", &req.commanded)?,
    };
    let dims = commanded.len();
    if measured.len() != dims {
        return Err(Error::Request(format!(
            "measured rows have {} values but commanded rows have {dims}",
            measured.len()
        )));
    }
    if req.measured_t.is_none() && measured[0].len() != commanded[0].len() {
        return Err(Error::Request(format!(
            "measured has {} rows but commanded has {}: one measured row per commanded row",
            measured[0].len(),
            commanded[0].len()
        )));
    }
    if axes.names.len() < dims {
        return Err(Error::MissingAxes {
            machine: axes.machine.clone(),
            have: axes.names.clone(),
            dims,
        });
    }
    let validation = match &req.validation {
        None | Some(Value::Null) => None,
        Some(v) => {
            let body: MotionValidationBody = serde_json::from_value(v.clone()).map_err(|e| {
                Error::Request(format!(
                    "validation must be {{\"commanded\": [...], \"measured\": [...]}}: {e}"
                ))
            })?;
            let c = rows_to_columns("validation.commanded", &body.commanded)?;
            let m = rows_to_columns("validation.measured", &body.measured)?;
            if c.len() != dims || m.len() != dims || c[0].len() != m[0].len() {
                return Err(Error::Request(format!(
                    "validation.commanded and validation.measured need {dims}-value rows and the same number of rows"
                )));
            }
            Some(MotionBlock {
                commanded: c,
                measured: m,
            })
        }
    };
    let folds = req.folds.unwrap_or(5);
    if !(2..=10).contains(&folds) {
        return Err(Error::Request(format!("folds must be 2..=10, got {folds}")));
    }
    // small blocks: one thread per request (the pool runs requests side by side); large
    // blocks: the effect fits on 2 threads (benches/gap.rs: about 16 s for 100,000 samples x 3
    // axes with steps on this 2-core machine)
    let (main, observed, timed) = match &req.measured_t {
        None => (
            MotionBlock {
                commanded,
                measured,
            },
            None,
            None,
        ),
        Some(t) => {
            let plants: Vec<AxisPlant> = (0..dims)
                .map(|k| {
                    AxisPlant::new(&axes.names[k], &axes.servo[k], period_s)
                        .map(|p| p.with_structure(axes.structure.get(k).copied().flatten()))
                })
                .collect::<Result<_, _>>()?;
            let timed = TimedLog::new(plants, &commanded, t.clone(), measured, period_s)?;
            let a = timed.place(&timed.estimate()?)?;
            (a.block, Some(a.observed), Some((timed, a.alignment)))
        }
    };
    let threads = if main.commanded[0].len() >= 20_000 {
        2
    } else {
        1
    };
    let opts = MotionOptions {
        folds,
        threads,
        observed,
        prior: axes.effects.clone(),
        ..MotionOptions::default()
    };
    Ok(((main, validation, period_s, opts), timed))
}
