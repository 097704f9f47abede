//! Unit tests of `crate::volumetric::components`.

use super::*;
use crate::volumetric::{ShapeFamily, SyntheticMachine};

#[test]
fn units_and_identifiability_are_reported() {
    let mut m = SyntheticMachine::new(5, ShapeFamily::TrendAndWaviness);
    m.noise_mm = 0.0;
    let d = m.measure_grid([7, 6, 5], 1);
    let k = KinematicModel::fit(&d, 4, m.tool_offset_mm).unwrap();
    let c = component_curves(&k, 11);
    assert_eq!(c.axes.len(), 3);
    assert_eq!(
        c.axes.iter().map(|a| a.curves.len()).sum::<usize>() + c.squareness.len(),
        21
    );
    let exx = &c.axes[0].curves[0];
    assert_eq!(
        (exx.name.as_str(), exx.unit.as_str(), exx.kind.as_str()),
        ("EXX", "um", "positioning")
    );
    let v = exx.values.as_ref().unwrap();
    let want = (m.motion(0, 0, 800.0) - m.motion(0, 0, 0.0)) * 1e3;
    assert!(
        (v[10] - want).abs() < 0.5,
        "EXX at 800 mm: {} µm vs {} µm",
        v[10],
        want
    );
    let ebx = c.axes[0].curves[4].values.as_ref().unwrap();
    let want = (m.motion(0, 4, 400.0) - m.motion(0, 4, 0.0)) * 1e6;
    assert!(
        (ebx[5] - want).abs() < 1.5,
        "EBX at 400 mm: {} µrad vs {} µrad",
        ebx[5],
        want
    );
    assert!(c.axes[2].curves[5].values.is_none() && c.notes.iter().any(|n| n.starts_with("ECZ")));
}
