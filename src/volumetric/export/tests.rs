//! Unit tests of `crate::volumetric::export`.

use super::*;
use crate::volumetric::{
    FitOptions, ModelKind, ShapeFamily, SyntheticMachine, VolumetricData, fit,
};

#[test]
fn table_rows_follow_the_map_and_limits_are_checked() {
    let m = SyntheticMachine::new(9, ShapeFamily::TrendAndWaviness);
    let d = m.measure_grid([4, 4, 3], 1);
    let map = fit(
        &d,
        &FitOptions {
            model: ModelKind::Kinematic,
            tool_offset_mm: m.tool_offset_mm,
            ..FitOptions::default()
        },
    )
    .unwrap();
    let mut spec = TableSpec::over(&map, [5, 3, 2]);
    spec.max[0] += 100.0;
    let csv = compensation_table_csv(&map, &spec).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows.len(), 1 + 5 * 3 * 2);
    // the table reads back as nodes + errors, and matches the map's prediction
    let back = VolumetricData::from_csv(&csv).unwrap();
    assert_eq!(back.nodes[1], [225.0, 0.0, 0.0]);
    let want = map.error_at([225.0, 0.0, 0.0]);
    (0..3).for_each(|j| assert!((back.errors[1][j] - want[j]).abs() < 1e-6));
    assert!(
        rows[5].ends_with(",1") && rows[1].ends_with(",0"),
        "{} / {}",
        rows[5],
        rows[1]
    );
    let cells: Vec<f64> = rows[2].split(',').map(|c| c.parse().unwrap()).collect();
    assert_eq!(cells[3], -cells[6]);
    spec.max_points_per_axis = Some(4);
    assert_eq!(
        compensation_table_csv(&map, &spec),
        Err(Error::TableTooLarge {
            axis: 'x',
            points: 5,
            limit: 4
        })
    );
    spec.points = [0, 3, 3];
    assert!(compensation_table_csv(&map, &spec).is_err());
}
