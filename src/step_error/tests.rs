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
    assert!(features.two_sided);
    assert_eq!(ModelMeta::of(&reg).unwrap().output_unit, "um");
}

#[test]
fn too_few_segments_to_split_is_its_own_error() {
    let (r, segs) = segments(2, 3);
    let err = TrainJob::new(r).run(&segs[..2], &|_| true).unwrap_err();
    assert!(matches!(err, Error::TooFewToSplit | Error::Nn(_)), "{err}");
}
