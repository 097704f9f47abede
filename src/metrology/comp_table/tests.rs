//! The compensation table: hand cases for the mean table, LinuxCNC's interpolation and the
//! model's coefficients; and the test: the table applied to its own run and to a
//! second, independently drawn run of the same axis cuts E and M by at least 80 %.

use rand::{Rng, RngExt, SeedableRng};

use super::*;
use crate::metrology::comp_model::{Cyclic, fit_model};
use crate::metrology::iso230_2::tests::hand_table;

/// The table referenced to its default (the lowest target, for a table).
pub(crate) fn build_first(axis: &Axis230_2, source: TableSource) -> Result<CompTable, Error> {
    build_table(axis, source, Reference::first_forward_of(axis))
}

fn close(got: f64, want: f64, tol: f64, what: &str) {
    assert!(
        (got - want).abs() <= tol,
        "{what}: got {got}, want {want} (±{tol})"
    );
}

#[test]
fn mean_table_negates_the_hand_means_from_the_reference_in_ascending_order() {
    // Hand table (µm): x̄↑ = 2, 4, 1, −1, 3 and x̄↓ = −1, 0, −3, −4, 1 at 0…400 mm; the
    // reference is the lowest target (x̄↑ = 2 µm), so c = 2 µm − x̄.
    let mut t = hand_table();
    // Send the targets in reverse order: the table must still ascend.
    t.targets_mm.reverse();
    t.forward_mm.reverse();
    t.backward_mm.reverse();
    let axis = evaluate_table(&t).unwrap();
    let table = build_first(&axis, TableSource::Mean).unwrap();
    assert_eq!(table.positions_mm, vec![0.0, 100.0, 200.0, 300.0, 400.0]);
    for (k, (f, b)) in [(2., -1.), (4., 0.), (1., -3.), (-1., -4.), (3., 1.)]
        .into_iter()
        .enumerate()
    {
        close(
            table.forward_mm[k],
            (2.0 - f) * 1e-3,
            1e-12,
            "forward correction",
        );
        close(
            table.backward_mm[k],
            (2.0 - b) * 1e-3,
            1e-12,
            "backward correction",
        );
    }
    assert!(table.model.is_none() && table.spacing_mm.is_none());
    assert_eq!(table.reference, Reference::FirstForward(0.0));
}

#[test]
fn the_device_zero_never_enters_and_a_named_reference_reads_zero_forward() {
    // The hand table read by a laser zeroed 37.215 mm away: every reading carries it.
    let mut t = hand_table();
    let plain = build_first(&evaluate_table(&t).unwrap(), TableSource::Mean).unwrap();
    for row in t.forward_mm.iter_mut().chain(t.backward_mm.iter_mut()) {
        for x in row {
            *x += 37.215;
        }
    }
    let axis = evaluate_table(&t).unwrap();
    let source = TableSource::Model {
        cyclic: Cyclic::Off,
        spacing_mm: Some(50.0),
    };
    for (src, want) in [
        (TableSource::Mean, plain.clone()),
        (
            source,
            build_first(&evaluate_table(&hand_table()).unwrap(), source).unwrap(),
        ),
    ] {
        let got = build_first(&axis, src).unwrap();
        for k in 0..got.len() {
            close(got.forward_mm[k], want.forward_mm[k], 1e-9, "forward");
            close(got.backward_mm[k], want.backward_mm[k], 1e-9, "backward");
        }
        close(got.forward_mm[0], 0.0, 1e-9, "forward at the reference");
    }
    // Named 300 mm (x̄↑ = −1 µm): its forward correction is 0, the others counted from it.
    let named = build_table(&axis, TableSource::Mean, Reference::Named(300.0)).unwrap();
    close(named.forward_mm[3], 0.0, 1e-9, "forward at 300");
    close(
        named.forward_mm[1],
        -5e-3,
        1e-9,
        "forward at 100: −(4 − (−1)) µm",
    );
    close(
        named.backward_mm[4],
        -2e-3,
        1e-9,
        "backward at 400: −(1 − (−1)) µm",
    );
    let text = named.reference.describe();
    assert!(
        text.starts_with("corrections are relative to 300 mm"),
        "{text}"
    );
    assert!(text.contains("reference_mm"), "{text}");
    // A reference that is no target is refused, listing the targets.
    let e = build_table(&axis, TableSource::Mean, Reference::Named(250.0)).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("reference_mm: 250 mm is not a target of this run")
            && e.to_string().contains("0, 100, 200, 300, 400"),
        "{e}"
    );
}

#[test]
fn a_correction_beyond_a_millimetre_is_refused_naming_the_target() {
    // Target 200 mm read 1.5 mm off both ways (another axis' readings, or inches).
    let mut t = hand_table();
    for row in [&mut t.forward_mm[2], &mut t.backward_mm[2]] {
        for x in row.iter_mut() {
            *x += 1.5;
        }
    }
    let e = build_first(&evaluate_table(&t).unwrap(), TableSource::Mean).unwrap_err();
    assert!(
        matches!(
            e,
            Error::CorrectionTooLarge {
                position_mm: 200.0,
                limit_mm: MAX_CORRECTION_MM,
                ..
            }
        ),
        "{e:?}"
    );
    let text = e.to_string();
    assert!(
        text.starts_with("the forward correction at 200 mm is -1.499000 mm")
            && text.contains("at most 1 mm"),
        "{text}"
    );
}

#[test]
fn correction_interpolates_and_holds_the_ends_like_linuxcnc() {
    let table = CompTable {
        positions_mm: vec![0.0, 10.0, 30.0],
        forward_mm: vec![1.0, 3.0, -1.0],
        backward_mm: vec![-1.0, 1.0, 0.0],
        model: None,
        spacing_mm: None,
        reference: Reference::FirstForward(0.0),
    };
    // Inside: c_k + slope (P − P_k); at a position exactly; below the first and beyond the
    // last the end value (LinuxCNC's sentinels carry zero slope).
    close(table.correction_mm(5.0, true), 2.0, 1e-12, "fwd at 5");
    close(table.correction_mm(20.0, true), 1.0, 1e-12, "fwd at 20");
    close(table.correction_mm(20.0, false), 0.5, 1e-12, "bwd at 20");
    close(table.correction_mm(10.0, true), 3.0, 1e-12, "fwd at 10");
    close(table.correction_mm(-7.0, true), 1.0, 1e-12, "fwd below");
    close(
        table.correction_mm(30.0, false),
        0.0,
        1e-12,
        "bwd at the end",
    );
    close(table.correction_mm(99.0, true), -1.0, 1e-12, "fwd beyond");
}

#[test]
fn the_mean_table_zeroes_e_and_m_of_its_own_run() {
    let t = hand_table();
    let table = build_first(&evaluate_table(&t).unwrap(), TableSource::Mean).unwrap();
    let (before, after) = table.predict(&t).unwrap();
    close(before.e, 8e-3, 1e-12, "E before");
    close(before.m, 4.5e-3, 1e-12, "M before");
    close(after.e, 0.0, 1e-12, "E after");
    close(after.m, 0.0, 1e-12, "M after");
    // Only the means move: every B_i becomes 0 and the scatter stays, so
    // R_i = max(2s↑ + 2s↓, 4s↑, 4s↓) = 4, 8, 4, 8, 8 µm (hand table's s) and R = 8 µm.
    close(before.r, 10e-3, 1e-12, "R before");
    close(after.r, 8e-3, 1e-12, "R after");
}

#[test]
fn the_backlash_is_the_mean_reversal_and_the_model_is_refitted_exactly() {
    // Hand table: B̄ = 3.2 µm with five cycles everywhere.
    let axis = evaluate_table(&hand_table()).unwrap();
    let m = fit_model(&axis, Cyclic::Off).unwrap();
    close(m.backlash_mm, 3.2e-3, 1e-12, "backlash = B̄");
    // Readings drawn exactly from a model (no noise, pitch on and off the scan grid) are
    // fitted back exactly: scale 23 µm/m, reversal 4 µm, 2 µm cyclic of pitch 317 mm.
    let truth = |p: f64, fwd: bool| {
        0.001
            + 23e-6 * (p - 400.0)
            + if fwd { 2e-3 } else { -2e-3 }
            + 2e-3 * (2.0 * std::f64::consts::PI * p / 317.0 + 0.4).sin()
    };
    let targets: Vec<f64> = (0..11).map(|i| 80.0 * i as f64 + (i % 3) as f64).collect();
    let rows = |fwd: bool| -> Vec<Vec<f64>> {
        targets
            .iter()
            .map(|&p| {
                [-1.0, 0.0, 1.0]
                    .map(|j| p + truth(p, fwd) + j * 1e-4)
                    .to_vec()
            })
            .collect()
    };
    let t = PositionTable {
        forward_mm: rows(true),
        backward_mm: rows(false),
        targets_mm: targets,
    };
    let axis = evaluate_table(&t).unwrap();
    for cyclic in [Cyclic::Pitch(317.0), Cyclic::Fit] {
        let m = fit_model(&axis, cyclic).unwrap();
        let c = m.cyclic.unwrap();
        close(c.pitch_mm, 317.0, 1e-3, "pitch");
        close(c.amplitude_mm(), 2e-3, 1e-8, "cyclic amplitude");
        close(m.scale, 23e-6, 1e-10, "scale");
        close(m.backlash_mm, 4e-3, 1e-10, "backlash");
        assert!(m.rms_residual_mm < 1e-8, "{}", m.rms_residual_mm);
        for p in [3.0, 250.0, 801.0] {
            for fwd in [true, false] {
                close(m.deviation_mm(p, fwd), truth(p, fwd), 1e-8, "model at p");
            }
        }
    }
}

#[test]
fn the_model_table_spans_the_run_on_the_spacing() {
    close(default_spacing_mm(800.0), 10.0, 1e-12, "800 mm");
    close(default_spacing_mm(2000.0), 20.0, 1e-12, "2 m");
    close(default_spacing_mm(430.0), 5.0, 1e-12, "430 mm");
    close(default_spacing_mm(50.0), 0.5, 1e-12, "50 mm");
    let axis = evaluate_table(&hand_table()).unwrap();
    let model = |spacing_mm| TableSource::Model {
        cyclic: Cyclic::Off,
        spacing_mm,
    };
    let t = build_first(&axis, model(None)).unwrap();
    // 400 mm wants 4 mm steps: 5 mm, 81 positions.
    assert_eq!((t.len(), t.spacing_mm), (81, Some(5.0)));
    let t = build_first(&axis, model(Some(30.0))).unwrap();
    // 0, 30, …, 390, then the last target 400 (a 10 mm step).
    assert_eq!(t.len(), 15);
    assert_eq!((t.positions_mm[13], t.positions_mm[14]), (390.0, 400.0));
    // A last step under 1 % of the spacing is merged: 0, 133.34, 266.68, 400.
    let t = build_first(&axis, model(Some(133.34))).unwrap();
    assert_eq!(t.len(), 4, "{:?}", t.positions_mm);
    // The forward and backward columns differ by the backlash everywhere.
    for k in 0..t.len() {
        close(t.backward_mm[k] - t.forward_mm[k], 3.2e-3, 1e-12, "split");
    }
}

#[test]
fn refusals_name_the_parameter() {
    let axis = evaluate_table(&hand_table()).unwrap();
    let model = |cyclic, spacing_mm| TableSource::Model { cyclic, spacing_mm };
    for bad in [0.0, -1.0, f64::NAN, 0.0005] {
        let e = build_first(&axis, model(Cyclic::Off, Some(bad))).unwrap_err();
        assert!(
            matches!(
                e,
                Error::Invalid {
                    field: "spacing_mm",
                    ..
                }
            ),
            "{e}"
        );
    }
    let e = build_first(&axis, model(Cyclic::Off, Some(0.01))).unwrap_err();
    assert!(e.to_string().contains("at most 10001"), "{e}");
    // 5 targets 100 mm apart cannot resolve a 150 mm pitch.
    let e = build_first(&axis, model(Cyclic::Pitch(150.0), None)).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("cyclic_pitch_mm: a pitch of 150 mm"),
        "{e}"
    );
    let mut t = hand_table();
    t.targets_mm.truncate(3);
    t.forward_mm.truncate(3);
    t.backward_mm.truncate(3);
    let three = evaluate_table(&t).unwrap();
    assert!(build_first(&three, model(Cyclic::Off, None)).is_ok());
    for cyclic in [Cyclic::Fit, Cyclic::Pitch(500.0)] {
        let e = build_first(&three, model(cyclic, None)).unwrap_err();
        assert!(matches!(e, Error::TooFew { got: 3, .. }), "{e}");
    }
}

/// A systematic error drawn wider than the model can express: scale, a reversal that
/// changes by up to ±30 % along the axis, a cyclic error of any phase with a pitch of 0.4 to
/// 1.5 ranges, and a bow (unmodelled) of up to 3 µm; readings scattered with σ 0.3–1 µm.
struct Axis {
    lo: f64,
    range: f64,
    scale: f64,
    reversal: [f64; 2],
    cyclic: [f64; 3],
    bow_mm: f64,
    sigma_mm: f64,
}

impl Axis {
    fn draw(rng: &mut impl Rng) -> Axis {
        let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
        let range = rng.random_range(500.0..2000.0);
        Axis {
            lo: rng.random_range(-200.0..200.0),
            range,
            scale: sign * rng.random_range(10e-6..60e-6),
            reversal: [rng.random_range(2e-3..12e-3), rng.random_range(-0.3..0.3)],
            cyclic: [
                rng.random_range(0.4..1.5) * range,
                rng.random_range(1e-3..6e-3),
                rng.random_range(0.0..std::f64::consts::TAU),
            ],
            bow_mm: rng.random_range(-3e-3..3e-3),
            sigma_mm: rng.random_range(0.3e-3..1e-3),
        }
    }

    /// Deviation (measured − target) at `p`, mm, without the scatter.
    fn deviation(&self, p: f64, forward: bool) -> f64 {
        let u = (p - self.lo) / self.range;
        let b = self.reversal[0] * (1.0 + self.reversal[1] * (2.0 * u - 1.0));
        let [pitch, amp, phase] = self.cyclic;
        self.scale * (p - self.lo)
            + if forward { 0.5 * b } else { -0.5 * b }
            + amp * (std::f64::consts::TAU * p / pitch + phase).sin()
            + self.bow_mm * 4.0 * u * (1.0 - u)
    }

    /// ISO-style uneven targets: 8 to 16 over the range, inner ones moved up to ±20 % of a step.
    fn targets(&self, rng: &mut impl Rng) -> Vec<f64> {
        let m = rng.random_range(8..=16);
        let step = self.range / (m - 1) as f64;
        (0..m)
            .map(|i| {
                let jitter = if i == 0 || i == m - 1 {
                    0.0
                } else {
                    rng.random_range(-0.2..0.2) * step
                };
                self.lo + i as f64 * step + jitter
            })
            .collect()
    }

    /// One ISO 230-2 run of five cycles each way at `targets`, with fresh scatter.
    fn run(&self, targets: &[f64], rng: &mut impl Rng) -> PositionTable {
        let noise = rand_distr::Normal::new(0.0, self.sigma_mm).unwrap();
        let mut rows = |fwd: bool| -> Vec<Vec<f64>> {
            targets
                .iter()
                .map(|&p| {
                    (0..5)
                        .map(|_| p + self.deviation(p, fwd) + rng.sample(noise))
                        .collect()
                })
                .collect()
        };
        PositionTable {
            forward_mm: rows(true),
            backward_mm: rows(false),
            targets_mm: targets.to_vec(),
        }
    }
}

/// Share of E and of M the table removes from `run`: (1 − after/before) each.
fn cut(table: &CompTable, run: &PositionTable) -> (f64, f64, Axis230_2, Axis230_2) {
    let (before, after) = table.predict(run).unwrap();
    (
        1.0 - after.e / before.e,
        1.0 - after.m / before.m,
        before,
        after,
    )
}

/// The goal: the table applied to its own run and to a second run of the same axis
/// (same systematic error, fresh scatter) cuts E and M by at least 80 %, for the mean table
/// and the model table (scale, backlash and a fitted cyclic term on the default spacing).
/// Also the model table at a third run read midway between the targets, where it is
/// sampled on its spacing rather than at its own targets. 40 axes drawn on seeds 1001–1040;
/// nothing in the tables is tuned to a draw (seeds 1–20, looked at while writing them, give
/// the same worst cuts). The worst cut per mode and run is printed
/// (`cargo test --lib comp_table -- --nocapture`).
#[test]
fn tables_cut_e_and_m_by_80_percent_on_their_own_and_a_second_run() {
    let modes = [
        ("mean", TableSource::Mean),
        (
            "model",
            TableSource::Model {
                cyclic: Cyclic::Fit,
                spacing_mm: None,
            },
        ),
    ];
    // worst[mode][run] = (E cut, M cut); run 3 (between the targets) for the model only.
    let mut worst = [[(f64::INFINITY, f64::INFINITY); 3]; 2];
    for seed in 1001..=1040u64 {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let axis = Axis::draw(&mut rng);
        let targets = axis.targets(&mut rng);
        let first = axis.run(&targets, &mut rng);
        let second = axis.run(&targets, &mut rng);
        let midway: Vec<f64> = targets.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
        let third = axis.run(&midway, &mut rng);
        let evaluated = evaluate_table(&first).unwrap();
        for (k, (name, source)) in modes.iter().enumerate() {
            let table = build_first(&evaluated, *source).unwrap();
            let runs: &[&PositionTable] = if *name == "model" {
                &[&first, &second, &third]
            } else {
                &[&first, &second]
            };
            for (r, run) in runs.iter().enumerate() {
                let (ce, cm, before, after) = cut(&table, run);
                println!(
                    "seed {seed} {name:5} run {}: E {:6.2} -> {:5.2} um ({:5.1} %), M {:6.2} -> {:5.2} um ({:5.1} %)",
                    r + 1,
                    before.e * 1e3,
                    after.e * 1e3,
                    ce * 100.0,
                    before.m * 1e3,
                    after.m * 1e3,
                    cm * 100.0
                );
                worst[k][r].0 = worst[k][r].0.min(ce);
                worst[k][r].1 = worst[k][r].1.min(cm);
            }
        }
    }
    for (k, (name, _)) in modes.iter().enumerate() {
        let runs = if *name == "model" { 3 } else { 2 };
        for (r, &(e, m)) in worst[k].iter().enumerate().take(runs) {
            println!(
                "goal >= 80 %: {name} table on run {}: worst E cut {:.1} %, worst M cut {:.1} %",
                r + 1,
                e * 100.0,
                m * 100.0
            );
            assert!(
                e >= 0.8 && m >= 0.8,
                "{name} table on run {}: E cut {e}, M cut {m}",
                r + 1
            );
        }
    }
}
