//! The physical ranges a machine definition's numbers must lie in ([`Bounds`]), one constant
//! per key, with the unit and the reason for each bound.

use crate::motion::error::Error;

/// A closed interval `[lo, hi]` (or `(lo, hi]` when `lo_open`) a definition number must lie
/// in, with its unit and meaning for the 400 sentence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Lower end.
    pub lo: f64,
    /// True when `lo` itself is refused (a gain of 0 is no loop at all).
    pub lo_open: bool,
    /// Upper end (inclusive).
    pub hi: f64,
    /// Unit and meaning, e.g. "1/s, position loop gain".
    pub what: &'static str,
}

impl Bounds {
    const fn open(lo: f64, hi: f64, what: &'static str) -> Bounds {
        Bounds {
            lo,
            lo_open: true,
            hi,
            what,
        }
    }
    const fn closed(lo: f64, hi: f64, what: &'static str) -> Bounds {
        Bounds {
            lo,
            lo_open: false,
            hi,
            what,
        }
    }

    /// Refuses `value` outside the bounds (or not finite) with [`Error::BadDefinition`].
    pub fn check(&self, field: &str, value: f64) -> Result<f64, Error> {
        let above_lo = if self.lo_open {
            value > self.lo
        } else {
            value >= self.lo
        };
        if value.is_finite() && above_lo && value <= self.hi {
            return Ok(value);
        }
        let range = if self.lo_open {
            format!(
                "must be > {} and at most {}",
                short(self.lo),
                short(self.hi)
            )
        } else {
            format!("must be in {}..{}", short(self.lo), short(self.hi))
        };
        Err(Error::BadDefinition {
            field: field.to_string(),
            message: format!("{range} ({}), got {}", self.what, short(value)),
        })
    }
}

/// A number as a person reads it: `1e300`, not three hundred digits.
fn short(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e7).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Position-loop gain `kv`: (0, 10000] 1/s. Real feed drives run 10–100 1/s; the bound is the
/// the HTTP contract's (v1.1) example of a physical range, and keeps `kv·period_s` far from the discretization's
/// limits at the shortest period a simulation accepts (1e-5 s).
pub const KV: Bounds = Bounds::open(0.0, 10_000.0, "1/s, position loop gain");
/// Velocity feed-forward fraction `kff`: [0, 1] (beyond 1 the axis runs ahead of the command).
pub const KFF: Bounds = Bounds::closed(0.0, 1.0, "velocity feed-forward fraction");
/// Velocity-loop gain `kp_v`: (0, 1e5] 1/s. A velocity loop of 1–2 kHz bandwidth is
/// `kp_v` ≈ 1e4 1/s; ten times that is no drive's.
pub const KP_V: Bounds = Bounds::open(0.0, 1e5, "1/s, velocity loop gain");
/// Velocity-loop integral time `ti_v`: [1e-5, 10] s (drives use 1 ms – 1 s).
pub const TI_V: Bounds = Bounds::closed(1e-5, 10.0, "s, velocity loop integral time");
/// Current-loop time constant `tc`: [1e-6, 0.1] s (drives: 50 µs – 5 ms).
pub const TC: Bounds = Bounds::closed(1e-6, 0.1, "s, current loop time constant");
/// Interpolator velocity cap `max_vel`: (0, 1e6] mm/s or deg/s. Generous on purpose: tests and
/// studies set huge limits to switch the feed profile off; the bound keeps the profile finite.
pub const MAX_VEL: Bounds = Bounds::open(0.0, 1e6, "mm/s or deg/s, velocity limit");
/// Interpolator acceleration cap `max_accel`: (0, 1e8] mm/s² or deg/s².
pub const MAX_ACCEL: Bounds = Bounds::open(0.0, 1e8, "mm/s² or deg/s², acceleration limit");
/// Interpolator jerk cap `max_jerk`: (0, 1e11] mm/s³ or deg/s³.
pub const MAX_JERK: Bounds = Bounds::open(0.0, 1e11, "mm/s³ or deg/s³, jerk limit");
/// G0 rate `rapid_mm_min`: (0, 1e6] mm/min (1 km/min; the fastest linear axes do 120 m/min).
pub const RAPID_MM_MIN: Bounds = Bounds::open(0.0, 1e6, "mm/min, rapid rate");
/// Controller block rate `block_rate_hz`: (0, 1e6] blocks/s. A GRBL on an ATmega328p plans
/// about 400 lines a second; a PC controller tens of thousands; a million is no controller's.
pub const BLOCK_RATE_HZ: Bounds =
    Bounds::open(0.0, 1e6, "blocks per second the controller reads and plans");
/// Controller look-ahead `lookahead_blocks`: [1, 100000] blocks (GRBL 15-16, Fanuc AI contour
/// control 40, high-end controls a few thousand).
pub const LOOKAHEAD_BLOCKS: Bounds = Bounds::closed(
    1.0,
    100_000.0,
    "blocks the planner sees ahead of the one it executes",
);
/// Any geometry coordinate or length: |v| ≤ 1e5 mm (100 m).
pub const GEOMETRY_MM: f64 = 1e5;

/// Physical drive parameters' ranges (field of [`PhysicalAxis`](crate::motion::PhysicalAxis), bounds). Generous physical
/// ceilings: they refuse typos of several orders of magnitude, not unusual machines.
pub const PHYSICAL: [(&str, Bounds); 12] = [
    ("motor_inertia_kg_m2", Bounds::open(0.0, 100.0, "kg·m²")),
    (
        "velocity_gain_nm_s_per_rad",
        Bounds::open(0.0, 1e4, "N·m·s/rad"),
    ),
    ("current_bandwidth_hz", Bounds::open(0.0, 1e5, "Hz")),
    ("lead_mm", Bounds::open(0.0, 1000.0, "mm per revolution")),
    ("table_mass_kg", Bounds::open(0.0, 1e6, "kg")),
    ("axial_stiffness_n_per_um", Bounds::open(0.0, 1e5, "N/µm")),
    (
        "screw_torsional_stiffness_nm_per_rad",
        Bounds::open(0.0, 1e10, "N·m/rad"),
    ),
    (
        "table_damping_n_s_per_m",
        Bounds::closed(0.0, 1e10, "N·s/m"),
    ),
    (
        "gear_ratio",
        Bounds::open(0.0, 1e5, "motor revolutions per table revolution"),
    ),
    ("table_inertia_kg_m2", Bounds::open(0.0, 1e6, "kg·m²")),
    (
        "torsional_stiffness_nm_per_rad",
        Bounds::open(0.0, 1e10, "N·m/rad"),
    ),
    (
        "table_damping_nm_s_per_rad",
        Bounds::closed(0.0, 1e10, "N·m·s/rad"),
    ),
];
