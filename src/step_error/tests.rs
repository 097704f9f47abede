//! The flat-batch solve against the per-segment oracle, and the training recipe's plumbing.

use super::*;
use crate::geometry::{
    self, HeightSurface, PathPlan, StepErrorSegment, height_surface_segments, step_error,
};

fn segments(lines: usize, points_per_line: usize) -> (f64, Vec<StepErrorSegment>) {
    let r = 5.0;
    let plan = PathPlan {
        tool_radius_mm: r,
        step_over_mm: None,
        cl_spacing_mm: None,
        lines: Some(lines),
        points_per_line: Some(points_per_line),
        cc_points: 20,
    };
    let s = HeightSurface::reference(1).unwrap();
    (r, height_surface_segments(&s, &plan).unwrap())
}

/// Splits `segs` into flat parts of the given sizes, as the decoder's threads would.
fn flat_parts(segs: &[StepErrorSegment], sizes: &[usize]) -> Vec<SegmentBatch> {
    let mut out = Vec::new();
    let mut at = 0;
    for &n in sizes {
        let mut b = SegmentBatch::default();
        for s in &segs[at..at + n] {
            b.cl.push(s.cl);
            b.cc.extend_from_slice(&s.cc);
            b.start.push(b.cc.len());
        }
        at += n;
        out.push(b);
    }
    out
}

#[test]
fn solve_batch_matches_the_one_segment_oracle_across_parts_and_threads() {
    // Enough segments for several threads (2048 each) and parts cut at odd places.
    let (r, segs) = segments(60, 100);
    let n = segs.len();
    assert!(n > 5000, "{n}");
    let parts = flat_parts(&segs, &[1, 2999, n - 3000]);
    let got = solve_batch(r, &parts).unwrap();
    assert_eq!(got.len(), n);
    for (i, (g, s)) in got.iter().zip(&segs).enumerate() {
        let want = step_error(r, s).unwrap();
        assert_eq!(g.error_mm.to_bits(), want.error_mm.to_bits(), "segment {i}");
        assert_eq!(g.inflection, want.inflection, "segment {i}");
        assert_eq!(g.convex, want.convex, "segment {i}");
    }
    let flat = geometry::step_errors(r, &segs, 0).unwrap();
    assert!(flat.iter().zip(&got).all(|(a, b)| a.error_mm == b.error_mm));
}

#[test]
fn solve_batch_names_the_bad_segment_by_its_index_in_the_whole_batch() {
    let (r, mut segs) = segments(60, 100);
    let bad = segs.len() - 7;
    segs[bad].cc[3][2] = f64::NAN;
    let parts = flat_parts(&segs, &[100, segs.len() - 100]);
    match solve_batch(r, &parts) {
        Err(geometry::Error::InSegment { index, .. }) => assert_eq!(index, bad),
        other => panic!("expected InSegment, got {other:?}"),
    }
}

#[test]
fn a_trained_model_carries_its_features_and_radius() {
    let (r, segs) = segments(6, 12);
    let mut job = TrainJob::new(r);
    job.cfg.epochs = 3;
    let (reg, report) = job.run(&segs, &|_| true).unwrap();
    assert_eq!(report["kind"], MODEL_KIND);
    let (features, radius) = model_features(&reg).unwrap();
    assert_eq!(radius, r);
    assert_eq!(features.n_outputs(), 2);
    assert_eq!(ModelMeta::of(&reg).unwrap().output_unit, "um");
}

#[test]
fn too_few_segments_to_split_is_its_own_error() {
    let (r, segs) = segments(2, 3);
    let err = TrainJob::new(r).run(&segs[..2], &|_| true).unwrap_err();
    assert!(matches!(err, Error::TooFewToSplit | Error::Nn(_)), "{err}");
}

#[test]
fn a_version_1_model_loads_with_its_coordinates_and_a_newer_one_is_refused() {
    let (r, segs) = segments(6, 12);
    let mut job = TrainJob::new(r);
    job.cfg.epochs = 2;
    job.features = geometry::StepFeatures {
        two_sided: true,
        ..geometry::StepFeatures::local()
    };
    let (mut reg, _) = job.run(&segs, &|_| true).unwrap();
    let before = predict_um(
        &reg,
        &job_features(&reg),
        r,
        segs.iter().map(|s| (s.cl, &s.cc[..])),
    )
    .unwrap()
    .um;
    // What a version-1 file holds: no "version", no "features.inputs".
    let mut meta: serde_json::Value = serde_json::from_str(&reg.metadata).unwrap();
    meta.as_object_mut().unwrap().remove("version");
    meta["features"].as_object_mut().unwrap().remove("inputs");
    reg.metadata = meta.to_string();
    let old = ModelMeta::of(&reg).unwrap();
    assert_eq!(old.version, 1);
    assert_eq!(old.features.inputs, geometry::StepInputs::Coordinates);
    let after = predict_um(
        &reg,
        &old.features,
        r,
        segs.iter().map(|s| (s.cl, &s.cc[..])),
    )
    .unwrap()
    .um;
    assert_eq!(before, after);
    // A newer file is refused with a sentence that says what to do.
    meta["version"] = serde_json::json!(META_VERSION + 1);
    reg.metadata = meta.to_string();
    let err = ModelMeta::of(&reg).unwrap_err().to_string();
    assert!(
        err.contains("retrain") && err.contains(&format!("{}", META_VERSION + 1)),
        "{err}"
    );
}

fn job_features(reg: &crate::nn::Regressor) -> geometry::StepFeatures {
    model_features(reg).unwrap().0
}

#[test]
fn new_models_read_the_distance_profile() {
    let (r, segs) = segments(6, 12);
    let mut job = TrainJob::new(r);
    job.cfg.epochs = 2;
    let (reg, _) = job.run(&segs, &|_| true).unwrap();
    let meta = ModelMeta::of(&reg).unwrap();
    assert_eq!(meta.version, META_VERSION);
    assert_eq!(meta.features, geometry::StepFeatures::profile());
    assert_eq!(reg.n_inputs(), 22);
}
