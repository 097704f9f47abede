//! Unit tests of `crate::volumetric::additive`.

use super::*;
use crate::volumetric::{ShapeFamily, SyntheticMachine};

fn lines_from(
    f: &dyn Fn([f64; 3]) -> [f64; 3],
    r: [f64; 3],
    n: usize,
    travel: [f64; 3],
) -> AxisLines {
    let line = |k: usize| {
        let positions: Vec<f64> = (0..n)
            .map(|i| travel[k] * i as f64 / (n - 1) as f64)
            .collect();
        let errors = positions
            .iter()
            .map(|&q| {
                let mut p = r;
                p[k] = q;
                f(p)
            })
            .collect();
        AxisLine { positions, errors }
    };
    AxisLines {
        reference: r,
        x: line(0),
        y: line(1),
        z: line(2),
    }
}

#[test]
fn exact_for_additive_errors() {
    let f = |p: [f64; 3]| {
        [
            1e-5 * p[0] + 3e-3 * (p[1] / 100.0).sin(),
            2e-8 * p[1] * p[1] - 1e-5 * p[2],
            4e-3 * (p[0] / 200.0).cos() + 2e-3,
        ]
    };
    let lines = lines_from(&f, [200.0, 100.0, 0.0], 5, [800.0, 400.0, 300.0]);
    let d = additive_grid(&lines).unwrap();
    assert_eq!(d.nodes.len(), 125);
    for (p, e) in d.nodes.iter().zip(&d.errors) {
        let t = f(*p);
        (0..3).for_each(|j| assert!((e[j] - t[j]).abs() < 1e-12, "{p:?}"));
    }
}

#[test]
fn misses_abbe_products_of_a_rigid_machine() {
    let mut m = SyntheticMachine::new(3, ShapeFamily::TrendAndWaviness);
    m.noise_mm = 0.0;
    let f = |p: [f64; 3]| m.error(p);
    let lines = lines_from(&f, [0.0, 0.0, 0.0], 6, m.travel_mm);
    let d = additive_grid(&lines).unwrap();
    let mut on_lines = 0.0f64;
    let mut worst = 0.0f64;
    for (p, e) in d.nodes.iter().zip(&d.errors) {
        let t = m.error(*p);
        let dev = (0..3).map(|j| (e[j] - t[j]).powi(2)).sum::<f64>().sqrt();
        if p.iter().filter(|&&v| v == 0.0).count() >= 2 {
            on_lines = on_lines.max(dev);
        }
        worst = worst.max(dev);
    }
    assert!(on_lines < 1e-9, "the rule reproduces the lines: {on_lines}");
    assert!(
        worst > 2e-3,
        "Abbe products are missed away from the lines: {worst}"
    );
}

#[test]
fn rejects_a_line_missing_the_reference() {
    let f = |_: [f64; 3]| [0.0; 3];
    let mut lines = lines_from(&f, [0.0, 0.0, 0.0], 3, [10.0, 10.0, 10.0]);
    lines.reference = [0.0, 0.0, 20.0];
    assert!(matches!(
        additive_grid(&lines),
        Err(Error::AxisLine { line: 'z', .. })
    ));
    lines.reference = [0.0; 3];
    lines.y.errors.pop();
    assert!(matches!(
        additive_grid(&lines),
        Err(Error::AxisLine { line: 'y', .. })
    ));
}
