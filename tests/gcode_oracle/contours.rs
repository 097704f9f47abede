//! Seeded random contour programs with cutter radius compensation for the oracle: one or two
//! closed star-shaped contours each (so they have inside and outside corners), edges of lines
//! and G2/G3 arcs (IJK and R, bulging in or out) and now and then a G0, cut with G41 or G42
//! (the material inside or outside, clockwise or counter-clockwise), entered from outside by
//! a G1 (sometimes a G0 or an arc),
//! left by G40 with a G1; sometimes in G91, under G93 inverse time, with Z-only moves and
//! dwells inside the compensation, without D (the tool of T1 M6), in G20 or G21. The tool's
//! diameter is drawn per program and given to both readers.
//!
//! Coordinates are integers of the resolution (0.001 mm, 0.0001 inch), as in `generate`.

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};

/// A generated contour program: its seed, text and tool 1's diameter, mm.
pub struct Contour {
    pub seed: u64,
    pub text: String,
    pub diameter_mm: f64,
}

struct Gen {
    rng: Xoshiro256PlusPlus,
    lines: Vec<String>,
    inch: bool,
    incremental: bool,
    inverse_time: bool,
    /// Programmed position, counts.
    pos: [i64; 3],
}

impl Gen {
    fn res_per_mm(&self) -> f64 {
        if self.inch { 10_000.0 / 25.4 } else { 1000.0 }
    }

    fn counts(&self, mm: f64) -> i64 {
        (mm * self.res_per_mm()).round() as i64
    }

    /// Counts of a random length in `mm` millimetres.
    fn mm(&mut self, mm: std::ops::Range<f64>) -> i64 {
        let v = self.rng.random_range(mm);
        self.counts(v)
    }

    fn fmt(&self, counts: i64) -> String {
        if self.inch {
            format!("{:.4}", counts as f64 / 10_000.0)
        } else {
            format!("{:.3}", counts as f64 / 1000.0)
        }
    }

    fn push(&mut self, body: String) {
        let n = self.lines.len() + 1;
        self.lines.push(format!("N{n} {body}"));
    }

    /// X Y words to reach `to` (counts), absolute or incremental.
    fn xy(&self, to: [i64; 2]) -> String {
        let v = |k: usize| {
            if self.incremental {
                to[k] - self.pos[k]
            } else {
                to[k]
            }
        };
        format!("X{} Y{}", self.fmt(v(0)), self.fmt(v(1)))
    }

    fn z(&self, to: i64) -> String {
        let v = if self.incremental {
            to - self.pos[2]
        } else {
            to
        };
        format!("Z{}", self.fmt(v))
    }

    /// The F word of a feed move (always under G93, sometimes under G94).
    fn feed(&mut self, first: bool) -> String {
        if self.inverse_time {
            format!(" F{}", self.rng.random_range(5..200))
        } else if first || self.rng.random_bool(0.15) {
            let f = if self.inch {
                self.rng.random_range(5..120)
            } else {
                self.rng.random_range(100..3000)
            };
            format!(" F{f}")
        } else {
            String::new()
        }
    }

    /// A G1 (now and then a G0) to `to`.
    fn line_to(&mut self, to: [i64; 2]) {
        let words = self.xy(to);
        if self.rng.random_bool(0.08) {
            self.push(format!("G0 {words}"));
        } else {
            let f = self.feed(false);
            self.push(format!("G1 {words}{f}"));
        }
        self.pos[0] = to[0];
        self.pos[1] = to[1];
    }

    /// An arc to `to` (its line opening with `prefix`): its centre off the chord's middle by
    /// up to 1.2 half chords either way, either direction, as I J or as R.
    fn arc_to(&mut self, prefix: &str, to: [i64; 2]) {
        let (a, b) = (
            [self.pos[0] as f64, self.pos[1] as f64],
            [to[0] as f64, to[1] as f64],
        );
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let h = self.rng.random_range(-1.2..1.2);
        let centre = [
            ((a[0] + b[0]) / 2.0 - h * dy / 2.0).round() as i64,
            ((a[1] + b[1]) / 2.0 + h * dx / 2.0).round() as i64,
        ];
        let cw = self.rng.random_bool(0.5);
        let code = if cw { "G2" } else { "G3" };
        let words = self.xy(to);
        let centre_words = if self.rng.random_bool(0.3) {
            // R: negative for the arc longer than a half circle (the centre on the side the
            // arc turns away from).
            let r = ((centre[0] - self.pos[0]) as f64).hypot((centre[1] - self.pos[1]) as f64);
            let left = dx * (centre[1] as f64 - a[1]) - dy * (centre[0] as f64 - a[0]) > 0.0;
            let major = left == cw;
            // Rounded up, and never short of half the chord (both readers refuse that).
            let r = (r.ceil() as i64).max((dx.hypot(dy) / 2.0).ceil() as i64 + 1);
            format!("R{}", self.fmt(if major { -r } else { r }))
        } else {
            format!(
                "I{} J{}",
                self.fmt(centre[0] - self.pos[0]),
                self.fmt(centre[1] - self.pos[1])
            )
        };
        let f = self.feed(false);
        self.push(format!("{prefix}{code} {words} {centre_words}{f}"));
        self.pos[0] = to[0];
        self.pos[1] = to[1];
    }

    fn contour(&mut self) {
        let centre = [self.mm(-30.0..30.0), self.mm(-30.0..30.0)];
        let n = self.rng.random_range(3..=8);
        let mut angles: Vec<f64> = (0..n)
            .map(|i| {
                let slot = std::f64::consts::TAU / n as f64;
                slot * (i as f64 + self.rng.random_range(0.1..0.9))
            })
            .collect();
        if self.rng.random_bool(0.5) {
            angles.reverse();
        }
        let vertices: Vec<[i64; 2]> = angles
            .iter()
            .map(|a| {
                let r = self.mm(12.0..40.0) as f64;
                [
                    centre[0] + (r * a.cos()).round() as i64,
                    centre[1] + (r * a.sin()).round() as i64,
                ]
            })
            .collect();
        // Start and end outside the contour, beyond the first vertex.
        let out = |g: &mut Gen, v: [i64; 2]| {
            let (dx, dy) = ((v[0] - centre[0]) as f64, (v[1] - centre[1]) as f64);
            let len = dx.hypot(dy);
            let away = g.mm(6.0..15.0) as f64;
            let skew = g.rng.random_range(-0.5..0.5);
            [
                v[0] + ((dx - skew * dy) / len * away).round() as i64,
                v[1] + ((dy + skew * dx) / len * away).round() as i64,
            ]
        };
        let start = out(self, vertices[0]);
        self.incremental = false;
        let (z_safe, z_cut) = (self.counts(5.0), -self.mm(1.0..6.0));
        self.push(format!(
            "G90 G0 X{} Y{} Z{}",
            self.fmt(start[0]),
            self.fmt(start[1]),
            self.fmt(z_safe)
        ));
        self.pos = [start[0], start[1], z_safe];
        self.inverse_time = self.rng.random_bool(0.15);
        if self.inverse_time {
            self.push("G93".into());
        }
        self.incremental = self.rng.random_bool(0.2);
        if self.incremental {
            self.push("G91".into());
        }
        let (words, f) = (self.z(z_cut), self.feed(true));
        self.push(format!("G1 {words}{f}"));
        self.pos[2] = z_cut;
        let side = if self.rng.random_bool(0.5) {
            "G41"
        } else {
            "G42"
        };
        let d = if self.rng.random_bool(0.7) { " D1" } else { "" };
        let words = self.xy(vertices[0]);
        match self.rng.random_range(0..10) {
            0 => self.push(format!("{side}{d} G0 {words}")),
            1 | 2 => self.arc_to(&format!("{side}{d} "), vertices[0]),
            _ => {
                let f = self.feed(false);
                self.push(format!("{side}{d} G1 {words}{f}"));
            }
        }
        self.pos[0] = vertices[0][0];
        self.pos[1] = vertices[0][1];
        for i in 1..=n {
            let to = vertices[i % n];
            if self.rng.random_bool(0.4) {
                self.arc_to("", to);
            } else {
                self.line_to(to);
            }
            match self.rng.random_range(0..20) {
                0 => {
                    let z = z_cut - self.mm(0.1..1.0);
                    let (words, f) = (self.z(z), self.feed(false));
                    self.push(format!("G1 {words}{f}"));
                    self.pos[2] = z;
                }
                1 => self.push("G4 P0.2".into()),
                _ => {}
            }
        }
        let exit = out(self, vertices[0]);
        let words = self.xy(exit);
        let f = self.feed(false);
        self.push(format!("G40 G1 {words}{f}"));
        self.pos[0] = exit[0];
        self.pos[1] = exit[1];
        let words = self.z(z_safe);
        self.push(format!("G0 {words}"));
        self.pos[2] = z_safe;
        if self.incremental {
            self.push("G90".into());
        }
        if self.inverse_time {
            self.push("G94".into());
        }
    }
}

/// The contour program of `seed`.
pub fn program(seed: u64) -> Contour {
    let mut g = Gen {
        rng: Xoshiro256PlusPlus::seed_from_u64(seed),
        lines: Vec::new(),
        inch: false,
        incremental: false,
        inverse_time: false,
        pos: [0; 3],
    };
    g.inch = g.rng.random_bool(0.3);
    let unit = if g.inch { "G20" } else { "G21" };
    let diameter_mm = (g.rng.random_range(0.5..5.0) * 1000.0f64).round() / 1000.0;
    g.push(format!("{unit} G90 G17 G94 G40 G49 G80"));
    g.push("T1 M6".into());
    g.push("S5000 M3".into());
    for _ in 0..g.rng.random_range(1..=2) {
        g.contour();
    }
    g.push("M2".into());
    Contour {
        seed,
        text: g.lines.join("\n") + "\n",
        diameter_mm,
    }
}
