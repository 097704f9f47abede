//! A parsed G-code program: blocks with resolved modal state, and their geometry
//! (pose along a block, path length, arc centre and sweep).

use super::error::Error;
use super::gcode::Warning;

/// Working plane of circular interpolation (G17, G18, G19).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plane {
    /// G17: arcs in X-Y, helix along Z.
    Xy,
    /// G18: arcs in Z-X, helix along Y.
    Zx,
    /// G19: arcs in Y-Z, helix along X.
    Yz,
}

impl Plane {
    /// Indices (first, second, normal) of the plane's axes in `[x, y, z]`, ordered so that
    /// first × second = normal (right-handed; G3 turns from first towards second).
    pub fn axes(self) -> (usize, usize, usize) {
        match self {
            Plane::Xy => (0, 1, 2),
            Plane::Zx => (2, 0, 1),
            Plane::Yz => (1, 2, 0),
        }
    }
}

/// A programmed position: linear words in mm (after G20 conversion), rotary in degrees.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Pose {
    /// X, Y, Z in mm (tool-tip in the workpiece frame when RTCP is on, else machine axes).
    pub xyz: [f64; 3],
    /// A axis, degrees.
    pub a: f64,
    /// C axis, degrees.
    pub c: f64,
}

/// How a block's duration follows from its F word.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Feed {
    /// G0: the machine's rapid rate (and per-axis velocity limits).
    Rapid,
    /// G94: feed rate in mm/min.
    PerMinute(f64),
    /// G93: the block takes 1/F minutes.
    InverseTime(f64),
}

/// Geometric kind of a block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Motion {
    /// Straight line (G0, G1) from start to end in program coordinates.
    Linear,
    /// Circular / helical arc (G2, G3) about `center` (mm, program coordinates; only the
    /// plane components matter). `sweep_rad` > 0 turns counter-clockwise seen from the
    /// plane normal (G3), < 0 clockwise (G2); a full circle has |sweep_rad| = 2π.
    Arc {
        /// The arc plane (G17 XY, G18 ZX, G19 YZ).
        plane: Plane,
        /// Centre, mm, program coordinates.
        center: [f64; 3],
        /// Signed swept angle, rad: > 0 counter-clockwise (G3), < 0 clockwise (G2).
        sweep_rad: f64,
    },
    /// G4: stand still for `seconds`.
    Dwell {
        /// Dwell time, s.
        seconds: f64,
    },
}

/// One executable block after modal state is resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    /// 1-based source line.
    pub line: usize,
    /// What the block does: line, arc or dwell.
    pub motion: Motion,
    /// Position at the start of the block.
    pub start: Pose,
    /// Programmed position at the end of the block.
    pub end: Pose,
    /// Feed rate in force (G94 mm/min or G93 inverse time).
    pub feed: Feed,
    /// RTCP (G43.4 / TRAORI) active: XYZ are tool-tip coordinates in the workpiece frame.
    pub rtcp: bool,
}

/// A parsed program: the executable blocks in order.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Program {
    /// Executable blocks in program order.
    pub blocks: Vec<Block>,
    /// First line that programs the A axis, if any.
    pub first_a_line: Option<usize>,
    /// First line that programs the C axis, if any.
    pub first_c_line: Option<usize>,
}

impl Program {
    /// Lenient reading for a machine without A (`has_a` false) or C: a rotary word that never
    /// changes the axis from its start value 0 is forgotten and named in a warning (CONTRACT
    /// v1.1 "Reading real programs"); one that moves is left for the interpolator to refuse.
    pub fn forget_still_rotary_axes(&mut self, has_a: bool, has_c: bool) -> Vec<Warning> {
        let mut out = Vec::new();
        let still_a = self
            .blocks
            .iter()
            .all(|b| b.start.a == 0.0 && b.end.a == 0.0);
        let still_c = self
            .blocks
            .iter()
            .all(|b| b.start.c == 0.0 && b.end.c == 0.0);
        for (first, has, still, axis) in [
            (&mut self.first_a_line, has_a, still_a, 'A'),
            (&mut self.first_c_line, has_c, still_c, 'C'),
        ] {
            if let Some(line) = *first
                && !has
                && still
            {
                *first = None;
                out.push(Warning {
                    line,
                    word: format!("{axis}0"),
                    message: format!(
                        "the machine has no {axis} axis; the program never moves it, so it is ignored"
                    ),
                });
            }
        }
        out
    }
}

/// The I, J, K (centre offsets, program units) and R words of a G2/G3 line.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct ArcWords {
    pub ijk: [Option<f64>; 3],
    pub r: Option<f64>,
}

/// How much an R word may fall short of half the chord and still make a half circle, mm:
/// LinuxCNC's RADIUS_TOLERANCE (0.00005 inch), room for a post that rounds R of a half
/// circle down in its last digit.
const R_SHORT_OF_CHORD_MM: f64 = 0.00127;

/// Centre and signed sweep of a G2/G3 block from IJK (centre offsets from the start,
/// always incremental) or R (negative R: the arc longer than 180°).
pub(crate) fn arc_geometry(
    line: usize,
    plane: Plane,
    clockwise: bool,
    start: &Pose,
    end: &Pose,
    w: ArcWords,
    scale: f64,
) -> Result<Motion, Error> {
    let (p0, p1, _) = plane.axes();
    let (s0, s1) = (start.xyz[p0], start.xyz[p1]);
    let (e0, e1) = (end.xyz[p0], end.xyz[p1]);
    let chord = ((e0 - s0).powi(2) + (e1 - s1).powi(2)).sqrt();
    let ijk = w.ijk;
    let has_ijk = ijk.iter().any(Option::is_some);
    let mut center = start.xyz;
    match (w.r, has_ijk) {
        (Some(_), true) => return Err(Error::gcode(line, "give either R or I/J/K, not both")),
        (None, false) => {
            return Err(Error::gcode(
                line,
                "G2/G3 needs I/J/K (centre) or R (radius)",
            ));
        }
        (None, true) => {
            for (k, v) in ijk.iter().enumerate() {
                center[k] = start.xyz[k] + v.unwrap_or(0.0) * scale;
            }
        }
        (Some(r), false) => {
            let r_mm = r * scale;
            if chord < 1e-9 {
                return Err(Error::gcode(
                    line,
                    "R-format arc with start == end is ambiguous: use I/J/K for a full circle",
                ));
            }
            let half = chord / 2.0;
            if r_mm.abs() < half - R_SHORT_OF_CHORD_MM {
                return Err(Error::gcode(
                    line,
                    format!("arc radius R{r} is smaller than half the chord ({half:.4} mm)"),
                ));
            }
            let h = (r_mm * r_mm - half * half).max(0.0).sqrt();
            let (d0, d1) = ((e0 - s0) / chord, (e1 - s1) / chord);
            // Left of the chord for G3 with R > 0; mirrored for G2 and for R < 0.
            let mut side = if clockwise { -1.0 } else { 1.0 };
            if r_mm < 0.0 {
                side = -side;
            }
            center[p0] = (s0 + e0) / 2.0 + side * h * -d1;
            center[p1] = (s1 + e1) / 2.0 + side * h * d0;
        }
    }
    let (c0, c1) = (center[p0], center[p1]);
    let r_start = ((s0 - c0).powi(2) + (s1 - c1).powi(2)).sqrt();
    let r_end = ((e0 - c0).powi(2) + (e1 - c1).powi(2)).sqrt();
    if r_start < 1e-6 {
        return Err(Error::gcode(line, "arc radius is zero: check I/J/K"));
    }
    let tol = 0.005_f64.max(1e-3 * r_start);
    if (r_end - r_start).abs() > tol {
        return Err(Error::gcode(
            line,
            format!(
                "arc end point is not on the circle: radius at start {r_start:.4} mm, at end \
                 {r_end:.4} mm (tolerance {tol:.4} mm)"
            ),
        ));
    }
    let th0 = (s1 - c1).atan2(s0 - c0);
    let th1 = (e1 - c1).atan2(e0 - c0);
    let tau = std::f64::consts::TAU;
    let sweep = if chord < 1e-9_f64.max(1e-9 * r_start) {
        if clockwise { -tau } else { tau }
    } else if clockwise {
        -(th0 - th1).rem_euclid(tau)
    } else {
        (th1 - th0).rem_euclid(tau)
    };
    Ok(Motion::Arc {
        plane,
        center,
        sweep_rad: sweep,
    })
}

impl Block {
    /// Program pose at fraction `u` ∈ [0, 1] of the block (lines and rotary axes linear in
    /// u; arcs at constant angular rate with the radius and helix axis linear in u).
    /// `u >= 1` returns exactly `end`.
    pub fn pose_at(&self, u: f64) -> Pose {
        if u >= 1.0 {
            return self.end;
        }
        let u = u.max(0.0);
        let (s, e) = (&self.start, &self.end);
        let a = s.a + u * (e.a - s.a);
        let c = s.c + u * (e.c - s.c);
        let xyz = match self.motion {
            Motion::Linear => [
                s.xyz[0] + u * (e.xyz[0] - s.xyz[0]),
                s.xyz[1] + u * (e.xyz[1] - s.xyz[1]),
                s.xyz[2] + u * (e.xyz[2] - s.xyz[2]),
            ],
            Motion::Dwell { .. } => s.xyz,
            Motion::Arc {
                plane,
                center,
                sweep_rad,
            } => {
                let (p0, p1, n) = plane.axes();
                let r0 =
                    ((s.xyz[p0] - center[p0]).powi(2) + (s.xyz[p1] - center[p1]).powi(2)).sqrt();
                let r1 =
                    ((e.xyz[p0] - center[p0]).powi(2) + (e.xyz[p1] - center[p1]).powi(2)).sqrt();
                let th0 = (s.xyz[p1] - center[p1]).atan2(s.xyz[p0] - center[p0]);
                let th = th0 + u * sweep_rad;
                let r = r0 + u * (r1 - r0);
                let mut out = [0.0; 3];
                out[p0] = center[p0] + r * th.cos();
                out[p1] = center[p1] + r * th.sin();
                out[n] = s.xyz[n] + u * (e.xyz[n] - s.xyz[n]);
                out
            }
        };
        Pose { xyz, a, c }
    }

    /// Length of the block's path in program XYZ (mm): chord for lines, helix length
    /// √((r̄·|sweep|)² + Δh²) for arcs with mean radius r̄, 0 for dwells.
    /// Reference: Zhang & Chen 2025 eq. 2 (L_i, tool-tip displacement of a block).
    pub fn xyz_length(&self) -> f64 {
        let (s, e) = (&self.start.xyz, &self.end.xyz);
        match self.motion {
            Motion::Linear => dist3(s, e),
            Motion::Dwell { .. } => 0.0,
            Motion::Arc {
                plane,
                center,
                sweep_rad,
            } => {
                let (p0, p1, n) = plane.axes();
                let r0 = ((s[p0] - center[p0]).powi(2) + (s[p1] - center[p1]).powi(2)).sqrt();
                let r1 = ((e[p0] - center[p0]).powi(2) + (e[p1] - center[p1]).powi(2)).sqrt();
                let planar = 0.5 * (r0 + r1) * sweep_rad.abs();
                (planar * planar + (e[n] - s[n]).powi(2)).sqrt()
            }
        }
    }
}

pub(crate) fn dist3(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}
