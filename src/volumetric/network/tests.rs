//! Unit tests of `crate::volumetric::network`.

use super::*;
use crate::volumetric::{ShapeFamily, SyntheticMachine};

#[test]
fn learns_a_smooth_map_and_round_trips() {
    let m = SyntheticMachine::new(4, ShapeFamily::TrendAndWaviness);
    let d = m.measure_grid([7, 6, 5], 2);
    let net = NetworkMap::fit(&d, &NetworkOptions::default()).unwrap();
    assert_eq!(net.parameter_count(), 3 * 8 + 8 + 8 * 3 + 3 + 12);
    let pts = m.random_points(500, 3);
    let pred = net.eval_many(&pts);
    let (mut se, mut ss) = (0.0, 0.0);
    for (p, e) in pts.iter().zip(&pred) {
        let t = m.error(*p);
        se += (0..3).map(|j| (e[j] - t[j]).powi(2)).sum::<f64>();
        ss += (0..3).map(|j| t[j].powi(2)).sum::<f64>();
    }
    // Wang, Dai & Hong's confidence measure RMSDL/RMSAL (paper: 0.0396 on its machine)
    let ratio = (se / ss).sqrt();
    assert!(ratio < 0.3, "RMSDL/RMSAL = {ratio}");
    let json = serde_json::to_string(&net).unwrap();
    let back: NetworkMap = serde_json::from_str(&json).unwrap();
    assert_eq!(back.eval_many(&pts[..5]), pred[..5].to_vec());
}
