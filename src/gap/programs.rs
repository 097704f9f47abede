//! Test programs for the self-check: circles (CW/CCW), rectangles, S-curves, zig-zags and
//! stop-and-go moves, interpolated with a trapezoidal feed profile into per-period commands.
//!
//! Written here (no crate): a few lines and arcs with a trapezoidal profile; the full G-code
//! interpolator lives in `motion/` and is not needed for synthetic truth data.

use rand::{Rng, RngExt};

/// Program families of the self-check.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Program {
    /// A full circle (CW or CCW), one or two turns.
    Circle,
    /// A rectangle with a stop at each corner.
    Rectangle,
    /// Two opposite half-circle arcs joined tangentially, back and forth.
    SCurve,
    /// Parallel passes in X with short steps in Y, stopping at each end.
    ZigZag,
    /// Short moves with dwells, back and forth in both axes.
    StopAndGo,
}

impl Program {
    /// All families.
    pub const ALL: [Program; 5] = [
        Program::Circle,
        Program::Rectangle,
        Program::SCurve,
        Program::ZigZag,
        Program::StopAndGo,
    ];
}

enum Piece {
    Line([f64; 2], [f64; 2]),
    /// centre, radius, start angle, signed sweep (rad)
    Arc([f64; 2], f64, f64, f64),
    Dwell(f64),
}

impl Piece {
    fn length(&self) -> f64 {
        match self {
            Piece::Line(a, b) => (b[0] - a[0]).hypot(b[1] - a[1]),
            Piece::Arc(_, r, _, sweep) => r * sweep.abs(),
            Piece::Dwell(_) => 0.0,
        }
    }
    fn at(&self, s: f64) -> [f64; 2] {
        match self {
            Piece::Line(a, b) => {
                let l = self.length().max(1e-300);
                [a[0] + (b[0] - a[0]) * s / l, a[1] + (b[1] - a[1]) * s / l]
            }
            Piece::Arc(c, r, th0, sweep) => {
                let th = th0 + sweep.signum() * s / r;
                [c[0] + r * th.cos(), c[1] + r * th.sin()]
            }
            Piece::Dwell(_) => [f64::NAN, f64::NAN],
        }
    }
}

/// Arc length travelled after time `t` of a trapezoidal profile over length `l` (mm) with
/// feed `v` (mm/s) and acceleration `a` (mm/s²), and the profile's total time.
fn trapezoid(l: f64, v: f64, a: f64) -> (f64, impl Fn(f64) -> f64) {
    let vp = v.min((l * a).sqrt());
    let ta = vp / a;
    let tf = if vp > 0.0 { (l - vp * ta) / vp } else { 0.0 };
    let total = 2.0 * ta + tf;
    (total, move |t: f64| {
        if t <= ta {
            0.5 * a * t * t
        } else if t <= ta + tf {
            0.5 * vp * ta + vp * (t - ta)
        } else {
            let td = (total - t).max(0.0);
            l - 0.5 * a * td * td
        }
    })
}

/// Commands per axis (mm) sampled every `period_s` for a random instance of `program`,
/// `axes` = 2 or 3 (a third axis rises slowly, helically). Machine coordinates: the program
/// sits 50–350 mm from zero. `flip` mirrors the direction of travel (CW ↔ CCW).
pub fn generate(
    program: Program,
    axes: usize,
    period_s: f64,
    flip: bool,
    rng: &mut impl Rng,
) -> Vec<Vec<f64>> {
    let c = [rng.random_range(80.0..320.0), rng.random_range(60.0..260.0)];
    let feed = rng.random_range(15.0..60.0);
    let accel = rng.random_range(400.0..1500.0);
    let mut groups: Vec<Vec<Piece>> = Vec::new();
    match program {
        Program::Circle => {
            let r = rng.random_range(10.0..40.0);
            let sweep = if flip {
                -std::f64::consts::TAU
            } else {
                std::f64::consts::TAU
            };
            let th0 = rng.random_range(0.0..std::f64::consts::TAU);
            groups.push(vec![Piece::Arc(
                c,
                r,
                th0,
                sweep * rng.random_range(1.0..1.6),
            )]);
        }
        Program::Rectangle => {
            let (w, h) = (rng.random_range(20.0..80.0), rng.random_range(15.0..60.0));
            let mut p = [
                [c[0], c[1]],
                [c[0] + w, c[1]],
                [c[0] + w, c[1] + h],
                [c[0], c[1] + h],
                [c[0], c[1]],
            ];
            if flip {
                p.reverse();
            }
            for k in 0..4 {
                groups.push(vec![Piece::Line(p[k], p[k + 1])]);
            }
        }
        Program::SCurve => {
            let r = rng.random_range(8.0..25.0);
            let dir = if flip { -1.0 } else { 1.0 };
            let a = Piece::Arc(
                [c[0], c[1]],
                r,
                std::f64::consts::PI,
                -dir * std::f64::consts::PI,
            );
            let b = Piece::Arc(
                [c[0] + 2.0 * r, c[1]],
                r,
                std::f64::consts::PI,
                dir * std::f64::consts::PI,
            );
            let back_b = Piece::Arc([c[0] + 2.0 * r, c[1]], r, 0.0, -dir * std::f64::consts::PI);
            let back_a = Piece::Arc([c[0], c[1]], r, 0.0, dir * std::f64::consts::PI);
            groups.push(vec![a, b]);
            groups.push(vec![back_b, back_a]);
        }
        Program::ZigZag => {
            let (w, step) = (rng.random_range(20.0..70.0), rng.random_range(2.0..8.0));
            let passes = rng.random_range(3..6);
            let mut y = c[1];
            for k in 0..passes {
                let (x0, x1) = if (k % 2 == 0) ^ flip {
                    (c[0], c[0] + w)
                } else {
                    (c[0] + w, c[0])
                };
                groups.push(vec![Piece::Line([x0, y], [x1, y])]);
                groups.push(vec![Piece::Line([x1, y], [x1, y + step])]);
                y += step;
            }
        }
        Program::StopAndGo => {
            let mut p = c;
            for _ in 0..rng.random_range(5..9) {
                let d = [rng.random_range(-25.0..25.0), rng.random_range(-25.0..25.0)];
                let q = [p[0] + d[0], p[1] + d[1]];
                groups.push(vec![Piece::Line(p, q)]);
                groups.push(vec![Piece::Dwell(rng.random_range(0.05..0.3))]);
                p = q;
            }
        }
    }
    // path samples
    let mut pts: Vec<[f64; 2]> = Vec::new();
    let start = groups.iter().flatten().find_map(|p| match p {
        Piece::Dwell(_) => None,
        other => Some(other.at(0.0)),
    });
    let mut last = start.unwrap_or(c);
    let hold = (0.05 / period_s) as usize;
    pts.extend(std::iter::repeat_n(last, hold));
    for g in &groups {
        if let [Piece::Dwell(d)] = g.as_slice() {
            pts.extend(std::iter::repeat_n(last, (d / period_s) as usize));
            continue;
        }
        let lengths: Vec<f64> = g.iter().map(Piece::length).collect();
        let total: f64 = lengths.iter().sum();
        let (time, s_of_t) = trapezoid(total, feed, accel);
        let steps = (time / period_s).ceil() as usize;
        for i in 1..=steps {
            let mut s = s_of_t((i as f64 * period_s).min(time));
            let mut k = 0;
            while k + 1 < g.len() && s > lengths[k] {
                s -= lengths[k];
                k += 1;
            }
            last = g[k].at(s.min(lengths[k]));
            pts.push(last);
        }
    }
    pts.extend(std::iter::repeat_n(last, hold));
    let mut cols = vec![
        pts.iter().map(|p| p[0]).collect::<Vec<f64>>(),
        pts.iter().map(|p| p[1]).collect(),
    ];
    if axes == 3 {
        let z0 = rng.random_range(-200.0..-50.0);
        let rise = rng.random_range(-5.0..5.0);
        let n = pts.len().max(2) as f64;
        cols.push(
            (0..pts.len())
                .map(|i| {
                    z0 + rise * 0.5 * (1.0 - (std::f64::consts::PI * i as f64 / (n - 1.0)).cos())
                })
                .collect(),
        );
    }
    cols
}
