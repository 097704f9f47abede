//! `truecut step transfer`: the transfer study of issue 12 (the `step_error` core's
//! [`transfer_study`]) printed as a table, the worst surface beside the goals.

use crate::geometry::StepFeatures;
use crate::step_error::transfer::{StudyConfig, StudyReport, transfer_study};

/// Goals of issue 12, worst surface (µm): zero-shot max, zero-shot mean, 15 % fine-tune max.
pub const GOALS_UM: (f64, f64, f64) = (0.5, 0.05, 0.3);

fn print_report(name: &str, rep: &StudyReport) {
    println!("== {name} ==");
    println!(
        "{:>3} {:>8} {:>5} {:>5} {:>3} {:>5} {:>6} {:>6} {:>9} {:>9} | {:>9} {:>9} {:>9} {:>9}",
        "s",
        "shape",
        "H",
        "R",
        "m",
        "step",
        "turn",
        "segs",
        "label max",
        "mean",
        "worst max",
        "worst mean",
        "knot max",
        "knot mean"
    );
    for (i, s) in rep.surfaces.iter().enumerate() {
        // The worst any network did on this surface (zero-shot; trained-on surfaces skipped).
        let scores = rep
            .runs
            .iter()
            .flat_map(|r| r.zero_shot.iter().filter(move |z| z.surface == i));
        let (mut mx, mut mn, mut kx, mut kn) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for z in scores {
            (mx, mn) = (mx.max(z.max_um), mn.max(z.mean_um));
            (kx, kn) = (kx.max(z.knot_max_um), kn.max(z.knot_mean_um));
        }
        let g = &s.surface;
        println!(
            "{:>3} {:>8} {:>5.1} {:>5.2} {:>3} {:>5.2} {:>6.0} {:>6} {:>9.2} {:>9.3} | {:>9.3} {:>10.4} {:>9.3} {:>9.4}",
            i,
            format!("{:?}", g.shape).to_lowercase(),
            g.height_mm,
            g.tool_radius_mm,
            g.cc_points,
            g.cl_spacing_mm,
            g.placement_rad.to_degrees(),
            s.segments,
            s.label_max_um,
            s.label_mean_um,
            mx,
            mn,
            kx,
            kn,
        );
    }
    let w = rep.worst();
    let (gmax, gmean, gft) = GOALS_UM;
    let ((tmax, wmax), (tmean, wmean)) = (&w.max, &w.mean);
    println!(
        "WORST zero-shot max  {:.3} um (surface {}, trained on {tmax}; knot samples alone {:.3})  goal <= {gmax}",
        wmax.max_um, wmax.surface, wmax.knot_max_um
    );
    println!(
        "WORST zero-shot mean {:.4} um (surface {}, trained on {tmean}; knot samples alone {:.4})  goal <= {gmean}",
        wmean.mean_um, wmean.surface, wmean.knot_mean_um
    );
    if let Some((t, f)) = &w.fine_tuned {
        println!(
            "WORST 15 % fine-tune max {:.3} um, mean {:.4} um (surface {}, trained on {t}, {} samples tuned on; before {:.3} / {:.4})  goal <= {gft}",
            f.max_um, f.mean_um, f.surface, f.tuned_on, f.before_max_um, f.before_mean_um
        );
    }
}

/// Runs the study with the default network (and with `coordinates`, the previous default too).
pub fn run(
    surfaces: usize,
    train_on: usize,
    budget: usize,
    coordinates: bool,
    json: bool,
) -> anyhow::Result<()> {
    anyhow::ensure!(surfaces >= 2, "--surfaces must be at least 2");
    let mut cfg = StudyConfig::full(train_on.min(surfaces));
    cfg.surfaces = surfaces;
    cfg.budget = budget;
    let mut variants = vec![("default: distance profile (model version 2)", cfg.features)];
    if coordinates {
        variants.push((
            "previous default: local-frame coordinates, two outputs (model version 1)",
            StepFeatures {
                two_sided: true,
                ..StepFeatures::local()
            },
        ));
    }
    for (name, f) in variants {
        let t = std::time::Instant::now();
        let c = StudyConfig {
            features: f,
            ..cfg.clone()
        };
        let rep = transfer_study(&c, &mut |line| eprintln!("{line}"))?;
        print_report(name, &rep);
        println!("({:.0} s)", t.elapsed().as_secs_f64());
        if json {
            println!("{}", serde_json::to_string(&rep)?);
        }
    }
    Ok(())
}
