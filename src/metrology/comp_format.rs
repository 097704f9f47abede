//! A compensation table in the files controllers load: LinuxCNC's joint compensation file
//! (`COMP_FILE_TYPE = 1`) and a plain CSV with the sign stated.
//!
//! LinuxCNC's loader (`usrmotLoadComp`, `src/emc/motion/usrmotintf.cc`) reads a line at a time
//! with `sscanf("%lf %lf %lf")` and **stops at the first line that is not three numbers**: a
//! comment at the top would load an empty table without a word. So the file is the triplets
//! first, then a blank line and the `#` notes, which the loader never reaches. Nominals must
//! strictly increase (`EMCMOT_SET_JOINT_COMP` refuses the rest) and at most 256 triplets are
//! loaded per joint (LinuxCNC INI documentation, `[JOINT_n]COMP_FILE`). Values are in machine
//! units: these files are mm.

use super::comp_table::{CompTable, SIGN_CONVENTION};
use super::error::Error;

/// Most triplets LinuxCNC loads per joint ("Currently the limit inside LinuxCNC is for 256
/// triplets per joint", LinuxCNC INI documentation, `COMP_FILE`).
pub const LINUXCNC_MAX_TRIPLETS: usize = 256;

/// Decimals written: 1 nm for positions and corrections in mm.
const DECIMALS: usize = 6;

fn fixed(x: f64) -> String {
    // `{:.6}` of -0.0000001 is "-0.000000": write zero without a sign.
    let s = format!("{x:.DECIMALS$}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

/// The notes every file carries: the reference the corrections are counted from, the sign
/// convention and how the controller reads the columns.
fn standard_notes(table: &CompTable) -> Vec<String> {
    let mut notes = vec![
        format!("reference: {}", table.reference.describe()),
        format!("sign: {SIGN_CONVENTION}"),
        "units: as the run, mm for a linear axis (degrees for a rotary one); they must be the \
         controller's machine units"
            .into(),
    ];
    match (&table.model, table.spacing_mm) {
        (Some(m), Some(s)) => {
            let cyclic = m.cyclic.map_or("no cyclic term".to_string(), |c| {
                format!(
                    "cyclic term pitch {:.3} mm amplitude {:.4} um",
                    c.pitch_mm,
                    c.amplitude_mm() * 1e3
                )
            });
            notes.push(format!(
                "mode model: scale {:.3} um/m about {:.3} mm, backlash (reversal) {:.4} um, {cyclic}; \
                 rms misfit to the run's means {:.4} um; every {s} mm",
                m.scale * 1e6,
                m.reference_mm,
                m.backlash_mm * 1e3,
                m.rms_residual_mm * 1e3
            ));
        }
        _ => notes.push(
            "mode mean: the negated mean deviations at the run's targets, less the reference's"
                .into(),
        ),
    }
    notes
}

/// LinuxCNC's joint compensation file, `COMP_FILE_TYPE = 1`: one line per position
/// `nominal forward_trim reverse_trim` (mm, space-separated, ascending nominals), then a blank
/// line and `#` notes (`notes` first, then how to load it, the reference, the sign, units and
/// mode).
///
/// Formula: trim = correction = −(mean deviation − the reference's forward mean deviation,
/// [`crate::metrology::comp_table::Reference`]); LinuxCNC adds it to the commanded joint
/// position (the type-0 equivalent would be `nominal, nominal − trim_fwd, nominal − trim_rev`).
///
/// Reference: LinuxCNC INI documentation (`[JOINT_n]COMP_FILE`, `COMP_FILE_TYPE`);
/// `usrmotLoadComp` and `compute_screw_comp` in LinuxCNC's sources.
///
/// Known bad cases: more than [`LINUXCNC_MAX_TRIPLETS`] positions, or positions closer than
/// the 1 nm the file prints, are refused ([`Error::Unresolvable`]) rather than written into
/// a file LinuxCNC would load only in part.
pub fn linuxcnc_file(table: &CompTable, notes: &[String]) -> Result<String, Error> {
    if table.len() > LINUXCNC_MAX_TRIPLETS {
        let range = table.positions_mm[table.len() - 1] - table.positions_mm[0];
        return Err(Error::Unresolvable {
            field: "spacing_mm",
            reason: format!(
                "the table has {} positions; LinuxCNC loads at most {LINUXCNC_MAX_TRIPLETS} per \
                 joint: use mode=model with spacing_mm of at least {} (the run spans {range} mm)",
                table.len(),
                (range / (LINUXCNC_MAX_TRIPLETS - 1) as f64 * 1e3).ceil() / 1e3
            ),
        });
    }
    let mut out = String::with_capacity(table.len() * 40 + 1200);
    let mut last: Option<String> = None;
    for k in 0..table.len() {
        let p = fixed(table.positions_mm[k]);
        if let Some(prev) = &last {
            if p.parse::<f64>().ok() <= prev.parse::<f64>().ok() {
                return Err(Error::Unresolvable {
                    field: "targets",
                    reason: format!(
                        "positions {prev} and {p} mm are equal to the file's 1 nm: LinuxCNC \
                         needs strictly increasing nominals; drop one of those targets"
                    ),
                });
            }
        }
        out.push_str(&format!(
            "{p} {} {}\n",
            fixed(table.forward_mm[k]),
            fixed(table.backward_mm[k])
        ));
        last = Some(p);
    }
    out.push('\n');
    let how = [
        "LinuxCNC joint compensation file, COMP_FILE_TYPE = 1: nominal (commanded) position, \
         forward trim, reverse trim"
            .to_string(),
        "load with [JOINT_n] COMP_FILE = <this file> and COMP_FILE_TYPE = 1 ([AXIS_n] before \
         LinuxCNC 2.8); BACKLASH is then not used: the two trims carry it"
            .to_string(),
        "LinuxCNC reads triplets up to the first other line, so these notes come last".into(),
    ];
    for line in notes
        .iter()
        .cloned()
        .chain(how)
        .chain(standard_notes(table))
    {
        out.push_str("# ");
        out.push_str(&line.replace('\n', " "));
        out.push('\n');
    }
    Ok(out)
}

/// The table as CSV: `#` notes (`notes`, then the reference, the sign, units and mode), then
/// the header `position_mm,forward_correction_mm,backward_correction_mm` and a row per
/// position.
///
/// Formula: as [`linuxcnc_file`]: correction = −(mean deviation − the reference's forward
/// mean deviation), added to the command.
/// Reference: RFC 4180 (comma-separated, one record per line; the `#` lines are a common
/// extension that pandas (`comment='#'`) and numpy skip).
/// Known bad cases: none; the table's length is limited by [`crate::metrology::comp_table`].
pub fn csv_file(table: &CompTable, notes: &[String]) -> String {
    let mut out = String::with_capacity(table.len() * 40 + 800);
    for line in notes.iter().cloned().chain(standard_notes(table)) {
        out.push_str("# ");
        out.push_str(&line.replace('\n', " "));
        out.push('\n');
    }
    out.push_str("position_mm,forward_correction_mm,backward_correction_mm\n");
    for k in 0..table.len() {
        out.push_str(&format!(
            "{},{},{}\n",
            fixed(table.positions_mm[k]),
            fixed(table.forward_mm[k]),
            fixed(table.backward_mm[k])
        ));
    }
    out
}

#[cfg(test)]
mod tests;
