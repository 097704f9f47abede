//! The whole contour-error prediction: G-code → interpolation → servo → contour error.
//!
//! Reference: Zhang & Chen 2025 (§2 interpolation with RTCP, §3 per-axis servo feed model, §4
//! contour error by cubic spline and windowed nearest point).

use super::contour::{ContourReport, contour_error};
use super::error::Error;
use super::gcode;
use super::interpolate::{Trajectory, interpolate_with};
use super::machine::Machine;
use super::path_control::PathControl;
use super::servo::simulate_axis;

/// Commanded and simulated motion with its contour error.
#[derive(Clone, Debug, PartialEq)]
pub struct ContourPrediction {
    /// The interpolated command (times, machine-axis columns, source lines).
    pub commanded: Trajectory,
    /// Simulated machine-axis positions, one column per axis (mm / degrees).
    pub actual: Vec<Vec<f64>>,
    /// Contour error of `actual` against the commanded path, per period and summarised.
    pub report: ContourReport,
}

/// Simulates every axis of `machine` for an interpolated command: the servo cascade of openapi.yaml
/// schema `Servo` (exact discretization, [`simulate_axis`]) followed, where the machine has one, by
/// the structural mode of Zhang & Chen 2025 eq. 10 ([`super::physical::StructuralMode::filter`]),
/// then the effects stored with the machine ([`super::effects`]), if any.
pub fn simulate_machine(machine: &Machine, commanded: &Trajectory) -> Result<Vec<Vec<f64>>, Error> {
    let linear = simulate_linear(machine, commanded)?;
    machine.effects.apply(
        &machine.axis_models(),
        commanded.period_s,
        &commanded.axes,
        linear,
    )
}

/// [`simulate_machine`] without the stored effects: the linear cascade and structural mode only.
pub fn simulate_linear(machine: &Machine, commanded: &Trajectory) -> Result<Vec<Vec<f64>>, Error> {
    machine
        .axes
        .iter()
        .zip(&commanded.axes)
        .map(|(axis, col)| {
            let x = simulate_axis(&axis.servo, col, commanded.period_s)?;
            Ok(match &axis.structure {
                Some(mode) => mode.filter(&x, commanded.period_s),
                None => x,
            })
        })
        .collect()
}

/// Predicts the contour error of `gcode` on `machine` with interpolation period `period_s`
/// (s; 1e-5..0.1), refusing programs longer than `max_periods` periods.
/// Errors: G-code errors name the line and code; machine errors name the field.
pub fn predict_contour_error(
    machine: &Machine,
    gcode_text: &str,
    period_s: f64,
    max_periods: usize,
) -> Result<ContourPrediction, Error> {
    let program = gcode::parse(gcode_text)?;
    predict_program(machine, &program, period_s, max_periods)
}

/// Predicts the contour error of a program already read (e.g. by [`gcode::parse_with`], whose
/// warnings the caller keeps) on `machine` with interpolation period `period_s` (s; 1e-5..0.1),
/// refusing programs longer than `max_periods` periods.
pub fn predict_program(
    machine: &Machine,
    program: &gcode::Program,
    period_s: f64,
    max_periods: usize,
) -> Result<ContourPrediction, Error> {
    predict_program_with(
        machine,
        program,
        &PathControl::default(),
        period_s,
        max_periods,
    )
}

/// [`predict_program`] with the program's path-control modes (read by
/// [`gcode::parse_modes`]): exact stops and G64 P blends as the program asks.
pub fn predict_program_with(
    machine: &Machine,
    program: &gcode::Program,
    control: &PathControl,
    period_s: f64,
    max_periods: usize,
) -> Result<ContourPrediction, Error> {
    let commanded = interpolate_with(program, control, machine, period_s, max_periods)?;
    let actual = simulate_machine(machine, &commanded)?;
    let report = contour_error(
        &machine.kinematics,
        &commanded.axes,
        &actual,
        &commanded.corners,
    );
    Ok(ContourPrediction {
        commanded,
        actual,
        report,
    })
}

#[cfg(test)]
mod tests;
