//! Seeded random programs for the oracle comparison: G0..G3 in G17/G18/G19 (IJK and R arcs,
//! full circles, helices), G90/G91, G90.1/G91.1, G20/G21, canned cycles
//! G73/G74/G81/G82/G83/G84/G85/G86/G89 with G98/G99 (not G88: see `main`), modal hole lines and G80, N numbers,
//! comments and block delete.
//!
//! Every coordinate is an integer number of the resolution (0.001 mm, 0.0001 inch), tracked
//! as an integer, so both interpreters see exact decimals and rs274's four-decimal printout
//! is exact. After a G20/G21 switch the program rapids absolutely on all three axes: a
//! position carried across a unit switch would be printed rounded to four decimals of the
//! new unit, which is rs274's printout and not a disagreement.
//!
//! Every line carries `N<line>` so that rs274's printout names the source line.

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};

/// A generated program with its seed.
pub struct Generated {
    pub seed: u64,
    pub text: String,
}

struct Gen {
    rng: Xoshiro256PlusPlus,
    lines: Vec<String>,
    inch: bool,
    incremental: bool,
    abs_centres: bool,
    plane: usize,
    /// Position in resolution counts of the units in force.
    pos: [i64; 3],
    feed_set: bool,
    /// Motion mode in force (G0, G1, G2, G3), None after G80.
    motion: Option<&'static str>,
}

const PLANES: [(usize, usize, usize, &str); 3] =
    [(0, 1, 2, "G17"), (2, 0, 1, "G18"), (1, 2, 0, "G19")];
const AXES: [char; 3] = ['X', 'Y', 'Z'];

impl Gen {
    fn res_per_mm(&self) -> f64 {
        if self.inch { 10_000.0 / 25.4 } else { 1000.0 }
    }

    /// Counts for `mm` millimetres (rounded to the lattice).
    fn counts(&self, mm: f64) -> i64 {
        (mm * self.res_per_mm()).round() as i64
    }

    fn fmt(&self, counts: i64) -> String {
        if self.inch {
            format!("{:.4}", counts as f64 / 10_000.0)
        } else {
            format!("{:.3}", counts as f64 / 1000.0)
        }
    }

    fn mm_range(&mut self, lo: f64, hi: f64) -> i64 {
        let v = self.rng.random_range(lo..hi);
        self.counts(v)
    }

    /// Writes a line with its N number, sometimes block-deleted or commented.
    fn push(&mut self, body: String) {
        let n = self.lines.len() + 1;
        let slash = if self.rng.random_bool(0.05) { "/" } else { "" };
        let comment = match self.rng.random_range(0..20) {
            0 => " (note)",
            1 => " ; tail comment",
            _ => "",
        };
        self.lines.push(format!("{slash}N{n} {body}{comment}"));
    }

    /// Axis words to reach `to` (counts), in G90 or G91; `all` writes unchanged axes too.
    fn axis_words(&mut self, to: [i64; 3], axes: &[usize]) -> String {
        let mut s = String::new();
        for &k in axes {
            let v = if self.incremental {
                to[k] - self.pos[k]
            } else {
                to[k]
            };
            if to[k] != self.pos[k] || self.rng.random_bool(0.3) {
                s += &format!(" {}{}", AXES[k], self.fmt(v));
            }
        }
        s
    }

    fn feed_word(&mut self) -> String {
        if !self.feed_set || self.rng.random_bool(0.2) {
            self.feed_set = true;
            format!(" F{}", self.rng.random_range(20..2000))
        } else {
            String::new()
        }
    }

    fn straight(&mut self, rapid: bool) {
        let mut to = self.pos;
        for v in to.iter_mut() {
            if self.rng.random_bool(0.6) {
                *v += self.mm_range(-30.0, 30.0);
            }
        }
        if to == self.pos {
            to[0] += self.counts(1.0);
        }
        let words = self.axis_words(to, &[0, 1, 2]);
        let code = if rapid { "G0" } else { "G1" };
        let feed = if rapid {
            String::new()
        } else {
            self.feed_word()
        };
        let code = if self.motion == Some(code) && self.rng.random_bool(0.3) {
            ""
        } else {
            code
        };
        self.motion = Some(if rapid { "G0" } else { "G1" });
        // `to` differs from `pos` on some axis, so there is at least one axis word.
        self.push(format!("{code}{words}{feed}").trim().to_string());
        self.pos = to;
    }

    fn arc(&mut self) {
        if self.rng.random_bool(0.3) {
            let p = self.rng.random_range(0..3);
            if p != self.plane {
                self.plane = p;
                self.push(PLANES[p].3.to_string());
            }
        }
        let (a0, a1, n, _) = PLANES[self.plane];
        let cw = self.rng.random_bool(0.5);
        let radius_mm = self.rng.random_range(1.0..25.0);
        let mut to = self.pos;
        if self.rng.random_bool(0.3) {
            to[n] += self.mm_range(-5.0, 5.0);
        }
        let use_r = self.rng.random_bool(0.35);
        let mut centre_words = String::new();
        if use_r {
            let ang = self.rng.random_range(0.0..std::f64::consts::TAU);
            let chord_mm = self.rng.random_range(0.5..(2.0 * radius_mm * 0.95));
            to[a0] += self.counts(chord_mm * ang.cos());
            to[a1] += self.counts(chord_mm * ang.sin());
            if to[a0] == self.pos[a0] && to[a1] == self.pos[a1] {
                to[a0] += self.counts(1.0);
            }
            let chord = (((to[a0] - self.pos[a0]) as f64).powi(2)
                + ((to[a1] - self.pos[a1]) as f64).powi(2))
            .sqrt();
            let r = (chord / 2.0 * self.rng.random_range(1.05..3.0)).ceil() as i64;
            let r = if self.rng.random_bool(0.3) { -r } else { r };
            centre_words = format!(" R{}", self.fmt(r));
        } else {
            let start_ang = self.rng.random_range(0.0..std::f64::consts::TAU);
            let r = self.counts(radius_mm) as f64;
            let off = [
                (-r * start_ang.cos()).round() as i64,
                (-r * start_ang.sin()).round() as i64,
            ];
            let centre = [self.pos[a0] + off[0], self.pos[a1] + off[1]];
            let r_exact = ((off[0] as f64).powi(2) + (off[1] as f64).powi(2)).sqrt();
            if self.rng.random_bool(0.15) {
                // Full circle: end = start in the plane.
            } else {
                let sweep = self.rng.random_range(0.2..6.0);
                let end_ang = start_ang + if cw { -sweep } else { sweep };
                to[a0] = centre[0] + (r_exact * end_ang.cos()).round() as i64;
                to[a1] = centre[1] + (r_exact * end_ang.sin()).round() as i64;
            }
            let letters = ['I', 'J', 'K'];
            for (k, (&axis, &o)) in [a0, a1].iter().zip(&off).enumerate() {
                let v = if self.abs_centres { centre[k] } else { o };
                centre_words += &format!(" {}{}", letters[axis], self.fmt(v));
            }
        }
        let words = self.axis_words(to, &[a0, a1, n]);
        let words = if words.is_empty() {
            // A full circle still needs one axis word.
            let v = if self.incremental { 0 } else { to[a0] };
            format!(" {}{}", AXES[a0], self.fmt(v))
        } else {
            words
        };
        let feed = self.feed_word();
        let code = if cw { "G2" } else { "G3" };
        self.motion = Some(code);
        self.push(format!("{code}{words}{centre_words}{feed}"));
        self.pos = to;
    }

    fn switch_modes(&mut self) {
        match self.rng.random_range(0..4) {
            0 => {
                self.inch = !self.inch;
                // Re-establish every axis exactly in the new unit (see the module docs).
                let to = [
                    self.mm_range(-50.0, 50.0),
                    self.mm_range(-50.0, 50.0),
                    self.mm_range(0.0, 40.0),
                ];
                let g = if self.inch { "G20" } else { "G21" };
                let (x, y, z) = (self.fmt(to[0]), self.fmt(to[1]), self.fmt(to[2]));
                self.push(format!("{g} G90 G0 X{x} Y{y} Z{z}"));
                self.motion = Some("G0");
                self.incremental = false;
                self.pos = to;
            }
            1 => {
                self.incremental = !self.incremental;
                self.push((if self.incremental { "G91" } else { "G90" }).to_string());
            }
            2 => {
                self.abs_centres = !self.abs_centres;
                self.push((if self.abs_centres { "G90.1" } else { "G91.1" }).to_string());
            }
            _ => {}
        }
    }

    fn cycle(&mut self) {
        const CODES: [u32; 9] = [73, 74, 81, 82, 83, 84, 85, 86, 89];
        let code = CODES[self.rng.random_range(0..CODES.len())];
        if self.plane != 0 {
            self.plane = 0;
            self.push("G17".to_string());
        }
        // Tapping needs the spindle turning its way (rs274 refuses otherwise).
        self.push((if code == 74 { "M4" } else { "M3" }).to_string());
        let initial = self.pos[2];
        let r_abs = initial - self.mm_range(-2.0, 10.0);
        let z_abs = r_abs - self.mm_range(1.0, 15.0).max(1);
        let mut to_initial = self.rng.random_bool(0.5);
        let mode = if to_initial { "G98" } else { "G99" };
        let (r_word, z_word) = if self.incremental {
            (r_abs - initial, z_abs - r_abs)
        } else {
            (r_abs, z_abs)
        };
        let mut extra = String::new();
        if matches!(code, 73 | 83) {
            let q = self.mm_range(0.5, 6.0).max(1);
            extra += &format!(" Q{}", self.fmt(q));
        }
        if matches!(code, 82 | 86 | 89) {
            // rs274 reads P as seconds, Fanuc as ms: a small value is valid for both.
            extra += " P0.5";
        }
        let hole = |g: &mut Gen| {
            let mut to = g.pos;
            to[0] += g.mm_range(-20.0, 20.0);
            if g.rng.random_bool(0.7) {
                to[1] += g.mm_range(-20.0, 20.0);
            }
            to
        };
        let to = hole(self);
        let words = self.axis_words(to, &[0, 1]);
        let words = if words.is_empty() {
            format!(" X{}", self.fmt(if self.incremental { 0 } else { to[0] }))
        } else {
            words
        };
        let (r, z) = (self.fmt(r_word), self.fmt(z_word));
        let feed = self.feed_word();
        self.push(format!("{mode} G{code}{words} Z{z} R{r}{extra}{feed}"));
        let at = |g: &mut Gen, xy: [i64; 3], to_initial: bool| {
            let clear = if to_initial {
                initial.max(r_abs)
            } else {
                r_abs
            };
            g.pos = [xy[0], xy[1], clear];
        };
        at(self, to, to_initial);
        for _ in 0..self.rng.random_range(0..4) {
            let to = hole(self);
            let words = self.axis_words(to, &[0, 1]);
            let words = if words.is_empty() {
                format!(" X{}", self.fmt(if self.incremental { 0 } else { to[0] }))
            } else {
                words
            };
            let mut prefix = String::new();
            if self.rng.random_bool(0.2) {
                to_initial = !to_initial;
                prefix = (if to_initial { "G98 " } else { "G99 " }).to_string();
            }
            self.push(format!("{prefix}{}", words.trim()));
            at(self, to, to_initial);
        }
        self.push("G80".to_string());
        self.motion = None;
    }
}

/// The program of `seed`.
pub fn program(seed: u64) -> Generated {
    let mut g = Gen {
        rng: Xoshiro256PlusPlus::seed_from_u64(seed),
        lines: Vec::new(),
        inch: false,
        incremental: false,
        abs_centres: false,
        plane: 0,
        pos: [0, 0, 0],
        feed_set: false,
        motion: None,
    };
    g.inch = g.rng.random_bool(0.3);
    let unit = if g.inch { "G20" } else { "G21" };
    g.push(format!("{unit} G90 G17 G94 S500 M3"));
    let start = [
        g.mm_range(-40.0, 40.0),
        g.mm_range(-40.0, 40.0),
        g.mm_range(5.0, 40.0),
    ];
    let (x, y, z) = (g.fmt(start[0]), g.fmt(start[1]), g.fmt(start[2]));
    g.push(format!("G0 X{x} Y{y} Z{z}"));
    g.motion = Some("G0");
    g.pos = start;
    for _ in 0..g.rng.random_range(10..40) {
        match g.rng.random_range(0..10) {
            0 => g.straight(true),
            1..=3 => g.straight(false),
            4..=6 => g.arc(),
            7 => g.cycle(),
            _ => g.switch_modes(),
        }
    }
    g.push("M2".to_string());
    Generated {
        seed,
        text: g.lines.join("\n") + "\n",
    }
}
