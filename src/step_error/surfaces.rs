//! A seeded generator of varied surfaces for the step-error network's transfer study: ridges,
//! ripples, steps, bumps, saddles, waves and mixtures of them, each with its own height
//! (20-60 mm), orientation of its features, placement on the machine table, tool radius
//! (3-8 mm), CC points per segment (11-31) and step length. The exact route labels them; no
//! network was ever tuned on them.

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};

use crate::geometry::{self, PathPlan, StepErrorSegment, function_segments};
use crate::numeric::vec3::normalize;

/// The shape family of a generated surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    /// Long Gaussian crests.
    Ridges,
    /// Short small waves on a long swell.
    Ripples,
    /// Smooth steps (tanh profiles).
    Steps,
    /// Gaussian bumps and dimples.
    Bumps,
    /// A hyperbolic paraboloid with a swell.
    Saddle,
    /// Long plane waves in one or two directions.
    Waves,
    /// Three or four terms of the families above.
    Mixture,
}

/// The families in the order [`transfer_surfaces`] cycles through them.
pub const SHAPES: [Shape; 7] = [
    Shape::Ridges,
    Shape::Ripples,
    Shape::Steps,
    Shape::Bumps,
    Shape::Saddle,
    Shape::Waves,
    Shape::Mixture,
];

/// One term of the height function, in coordinates `(u, v)` turned by `angle` about `center`.
#[derive(Clone, Copy, Debug)]
enum Kind {
    /// `a sin(k u + p)`.
    Wave { k: f64, p: f64 },
    /// `a sin(k1 u + p1) sin(k2 v + p2)`.
    Ripple { k1: f64, p1: f64, k2: f64, p2: f64 },
    /// `a exp(-u^2 / (2 w^2))`.
    Ridge { w: f64 },
    /// `a tanh(u / w)`.
    Step { w: f64 },
    /// `a exp(-(u^2 / (2 sx^2) + v^2 / (2 sy^2)))`.
    Bump { sx: f64, sy: f64 },
    /// `a (u^2 - v^2) / (2 l^2)`.
    Saddle { l: f64 },
}

#[derive(Clone, Copy, Debug)]
struct Term {
    kind: Kind,
    a: f64,
    center: [f64; 2],
    angle: f64,
}

impl Term {
    /// Value and gradient (d/dx, d/dy) at (x, y).
    fn eval(&self, x: f64, y: f64) -> (f64, f64, f64) {
        let (s, c) = self.angle.sin_cos();
        let (dx, dy) = (x - self.center[0], y - self.center[1]);
        let (u, v) = (c * dx + s * dy, -s * dx + c * dy);
        let a = self.a;
        let (f, fu, fv) = match self.kind {
            Kind::Wave { k, p } => (a * (k * u + p).sin(), a * k * (k * u + p).cos(), 0.0),
            Kind::Ripple { k1, p1, k2, p2 } => {
                let (s1, c1) = (k1 * u + p1).sin_cos();
                let (s2, c2) = (k2 * v + p2).sin_cos();
                (a * s1 * s2, a * k1 * c1 * s2, a * k2 * s1 * c2)
            }
            Kind::Ridge { w } => {
                let g = a * (-u * u / (2.0 * w * w)).exp();
                (g, -g * u / (w * w), 0.0)
            }
            Kind::Step { w } => {
                let t = (u / w).tanh();
                (a * t, a * (1.0 - t * t) / w, 0.0)
            }
            Kind::Bump { sx, sy } => {
                let g = a * (-(u * u / (2.0 * sx * sx) + v * v / (2.0 * sy * sy))).exp();
                (g, -g * u / (sx * sx), -g * v / (sy * sy))
            }
            Kind::Saddle { l } => (
                a * (u * u - v * v) / (2.0 * l * l),
                a * u / (l * l),
                -a * v / (l * l),
            ),
        };
        (f, c * fu - s * fv, s * fu + c * fv)
    }
}

/// A generated surface `z = scale * sum(terms) + shift` on `[0, lx] x [0, ly]`, its paths
/// along x, and where it sits on the table. All lengths mm, angles radians.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TransferSurface {
    /// Position in the generated list.
    pub index: usize,
    /// Shape family.
    pub shape: Shape,
    /// Extent along the paths.
    pub lx: f64,
    /// Extent across the paths.
    pub ly: f64,
    /// Height range max z - min z over the domain (20-60).
    pub height_mm: f64,
    /// Lowest z over the domain before placement.
    pub base_mm: f64,
    /// Turn of the whole part about the machine's z axis (its paths then run at this angle to
    /// machine x).
    pub placement_rad: f64,
    /// Shift of the part on the table after the turn.
    pub shift_mm: [f64; 3],
    /// Ball radius R (3-8).
    pub tool_radius_mm: f64,
    /// CC points per segment, ends included (11-31).
    pub cc_points: usize,
    /// CL step length along the paths in the parameter plane.
    pub cl_spacing_mm: f64,
    /// Distance between paths.
    pub step_over_mm: f64,
    /// Largest |curvature| of the path curves (x, y, z(x)) over the domain, 1/mm (0.5 mm grid
    /// along x, 2 mm across).
    pub max_curvature_per_mm: f64,
    #[serde(skip)]
    terms: Vec<Term>,
    #[serde(skip)]
    scale: f64,
    #[serde(skip)]
    shift: f64,
}

impl TransferSurface {
    /// z, dz/dx, dz/dy at (x, y) in the part's own frame.
    pub fn height(&self, x: f64, y: f64) -> (f64, f64, f64) {
        let (mut z, mut zx, mut zy) = (0.0, 0.0, 0.0);
        for t in &self.terms {
            let (f, fx, fy) = t.eval(x, y);
            (z, zx, zy) = (z + f, zx + fx, zy + fy);
        }
        (
            self.scale * z + self.shift,
            self.scale * zx,
            self.scale * zy,
        )
    }

    /// The segments of paths along x every `step_over_mm` (fewer, evenly spread, if that would
    /// make more than `budget` segments), CL points every `cl_spacing_mm`, `CL = P + R n`, then
    /// turned by `placement_rad` about z and shifted by `shift_mm` (machine coordinates).
    pub fn segments(&self, budget: usize) -> Result<Vec<StepErrorSegment>, geometry::Error> {
        let pts = (self.lx / self.cl_spacing_mm).round() as usize + 1;
        let lines =
            ((self.ly / self.step_over_mm).round() as usize + 1).min((budget / (pts - 1)).max(2));
        let plan = PathPlan {
            tool_radius_mm: self.tool_radius_mm,
            step_over_mm: None,
            cl_spacing_mm: None,
            lines: Some(lines),
            points_per_line: Some(pts),
            cc_points: self.cc_points,
        };
        let (s, c) = self.placement_rad.sin_cos();
        let t = self.shift_mm;
        let place = |p: [f64; 3]| {
            [
                c * p[0] - s * p[1] + t[0],
                s * p[0] + c * p[1] + t[1],
                p[2] + t[2],
            ]
        };
        let turn = |n: [f64; 3]| [c * n[0] - s * n[1], s * n[0] + c * n[1], n[2]];
        function_segments(
            self.lx,
            self.ly,
            |x, y| {
                let (z, zx, zy) = self.height(x, y);
                (place([x, y, z]), turn(normalize([-zx, -zy, 1.0])))
            },
            &plan,
        )
    }
}

/// Random term of a family; `l` is the shorter side of the domain.
fn term(rng: &mut Xoshiro256PlusPlus, shape: Shape, lx: f64, ly: f64) -> Term {
    let l = lx.min(ly);
    let center = [
        rng.random_range(0.1..0.9) * lx,
        rng.random_range(0.1..0.9) * ly,
    ];
    let angle = rng.random_range(0.0..std::f64::consts::PI);
    let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let tau = std::f64::consts::TAU;
    let (kind, a) = match shape {
        Shape::Ridges => (
            Kind::Ridge {
                w: rng.random_range(0.08..0.2) * l,
            },
            sign * rng.random_range(0.5..1.0),
        ),
        Shape::Ripples => (
            Kind::Ripple {
                k1: tau / rng.random_range(18.0..35.0),
                p1: rng.random_range(0.0..tau),
                k2: tau / rng.random_range(18.0..35.0),
                p2: rng.random_range(0.0..tau),
            },
            rng.random_range(0.03..0.06),
        ),
        Shape::Steps => (
            Kind::Step {
                w: rng.random_range(0.1..0.25) * l,
            },
            sign * rng.random_range(0.5..1.0),
        ),
        Shape::Bumps => (
            Kind::Bump {
                sx: rng.random_range(0.1..0.25) * l,
                sy: rng.random_range(0.1..0.25) * l,
            },
            sign * rng.random_range(0.4..1.0),
        ),
        Shape::Saddle => (
            Kind::Saddle {
                l: rng.random_range(0.4..0.7) * l,
            },
            sign,
        ),
        Shape::Waves | Shape::Mixture => (
            Kind::Wave {
                k: tau / (rng.random_range(0.5..1.4) * l),
                p: rng.random_range(0.0..tau),
            },
            rng.random_range(0.5..1.0),
        ),
    };
    Term {
        kind,
        a,
        center,
        angle,
    }
}

/// The terms of one surface of a family.
fn terms(rng: &mut Xoshiro256PlusPlus, shape: Shape, lx: f64, ly: f64) -> Vec<Term> {
    let mut out = Vec::new();
    match shape {
        Shape::Ripples => {
            out.push(term(rng, Shape::Waves, lx, ly));
            out.push(term(rng, Shape::Ripples, lx, ly));
        }
        Shape::Saddle => {
            out.push(term(rng, Shape::Saddle, lx, ly));
            let mut w = term(rng, Shape::Waves, lx, ly);
            w.a *= 0.2;
            out.push(w);
        }
        Shape::Mixture => {
            for _ in 0..rng.random_range(3..=4) {
                let pick = SHAPES[rng.random_range(0..6)];
                out.push(term(rng, pick, lx, ly));
            }
        }
        _ => {
            for _ in 0..rng.random_range(1..=3) {
                out.push(term(rng, shape, lx, ly));
            }
        }
    }
    out
}

/// `n` surfaces, deterministic in `seed` (surface i does not depend on `n`), cycling through
/// [`SHAPES`]. Each: domain 80-160 mm a side, height range 20-60 mm on a base -30..80 mm, the
/// part turned 0-360° and shifted up to ±200 mm on the table, R 3-8 mm, m 11-31, CL step
/// 0.5-2 mm, step-over 0.5-3 mm. A draw is kept when the ball fits every concave part of the
/// paths with room to spare (the paths' |curvature| * R <= 0.5 on a 0.5 mm x 2 mm grid),
/// otherwise the family is drawn again (at most 500 times, then the last draw is kept).
pub fn transfer_surfaces(n: usize, seed: u64) -> Vec<TransferSurface> {
    (0..n).map(|i| one_surface(i, seed)).collect()
}

fn one_surface(index: usize, seed: u64) -> TransferSurface {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(
        seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (index as u64 + 1),
    );
    let shape = SHAPES[index % SHAPES.len()];
    let tool_radius_mm = rng.random_range(3.0..8.0);
    let cc_points = rng.random_range(11..=31);
    let cl_spacing_mm = rng.random_range(0.5..2.0);
    let step_over_mm = rng.random_range(0.5..3.0);
    let placement_rad = rng.random_range(0.0..std::f64::consts::TAU);
    let shift_mm = [
        rng.random_range(-200.0..200.0),
        rng.random_range(-200.0..200.0),
        rng.random_range(-50.0..50.0),
    ];
    let mut last = None;
    for _ in 0..500 {
        let lx = rng.random_range(80.0..160.0);
        let ly = rng.random_range(80.0..160.0);
        let height_mm = rng.random_range(20.0..60.0);
        let base_mm = rng.random_range(-30.0..80.0);
        let terms = terms(&mut rng, shape, lx, ly);
        let mut s = TransferSurface {
            index,
            shape,
            lx,
            ly,
            height_mm,
            base_mm,
            placement_rad,
            shift_mm,
            tool_radius_mm,
            cc_points,
            cl_spacing_mm,
            step_over_mm,
            max_curvature_per_mm: 0.0,
            terms,
            scale: 1.0,
            shift: 0.0,
        };
        // Height range from a 0.5 mm grid, then the largest curvature along x.
        let (nx, ny) = ((lx / 0.5) as usize + 1, (ly / 2.0) as usize + 1);
        let grid = |i: usize, j: usize| {
            (
                i as f64 * lx / (nx - 1) as f64,
                j as f64 * ly / (ny - 1) as f64,
            )
        };
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for j in 0..ny {
            for i in 0..nx {
                let (x, y) = grid(i, j);
                let z = s.height(x, y).0;
                (lo, hi) = (lo.min(z), hi.max(z));
            }
        }
        s.scale = height_mm / (hi - lo);
        s.shift = base_mm - s.scale * lo;
        let mut kmax = 0.0f64;
        for j in 0..ny {
            for i in 1..nx - 1 {
                let (x, y) = grid(i, j);
                let h = lx / (nx - 1) as f64;
                let (z0, zx, _) = s.height(x, y);
                let zxx = (s.height(x + h, y).0 - 2.0 * z0 + s.height(x - h, y).0) / (h * h);
                kmax = kmax.max(zxx.abs() / (1.0 + zx * zx).powf(1.5));
            }
        }
        s.max_curvature_per_mm = kmax;
        let ok = kmax * tool_radius_mm <= 0.5;
        last = Some(s);
        if ok {
            break;
        }
    }
    last.expect("at least one draw")
}
