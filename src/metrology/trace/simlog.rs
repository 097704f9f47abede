//! A generator of logged ISO 230-2 runs for the reader's tests, written apart from the reader:
//! it knows no window, threshold or matching rule, only a drive and a measuring device.
//!
//! The program is the standard's linear cycle (ISO 230-2:2014 §5.3.2): the targets upwards,
//! an overrun past the last, the targets downwards, an overrun below the first, `cycles`
//! times. The drive: a position loop of gain `kv` with a speed limit (so a slow axis travels
//! tens of seconds), the stop's own scatter per approach, a backlash (play) between motor and
//! table, and a smooth pitch error of a few µm. The log: the command either as the
//! interpolated set-point (the program dwells a fixed time) or as the target itself written
//! when the move starts (the control system steps to the next target once the axis has been
//! in position for the dwell); the measured position with the device's offset, noise and its
//! own sample clock.
//!
//! The truth is the table of settled table positions (in the command's frame), known in closed
//! form from the stop, the backlash side and the pitch error; the generator checks at the end
//! of every dwell that the simulated axis has reached it.

use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

use super::PositioningTrace;
use crate::metrology::PositionTable;

/// How the drive logs its command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Command {
    /// The interpolated set-point, moving at this feed, mm/s; the program dwells a fixed time.
    Interpolated { feed_mm_s: f64 },
    /// The target itself, written when the move starts.
    Stepped,
}

/// The axis.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Drive {
    /// Position-loop gain, 1/s.
    pub kv_per_s: f64,
    /// Speed limit, mm/s.
    pub v_max_mm_s: f64,
    /// Play between motor and table, mm.
    pub backlash_mm: f64,
    /// Standard deviation of where a stop ends, per approach, mm.
    pub scatter_mm: f64,
    /// Amplitude of the pitch error, mm.
    pub pitch_mm: f64,
}

/// The measuring device.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Device {
    /// Constant added to every reading, mm.
    pub offset_mm: f64,
    /// Its sample interval over the command's (1.03: its samples are 3 % farther apart).
    pub clock: f64,
    /// Standard deviation of the noise per sample, mm.
    pub noise_mm: f64,
}

/// One logged run to generate.
#[derive(Clone, Debug)]
pub(crate) struct RunSpec {
    /// Targets, ascending, mm.
    pub targets_mm: Vec<f64>,
    /// Cycles of the linear cycle.
    pub cycles: usize,
    /// Overrun past the end targets, mm.
    pub overrun_mm: f64,
    /// Range of the dwell at each stop, s.
    pub dwell_s: [f64; 2],
    /// Command sampling period, s.
    pub period_s: f64,
    /// How the command is logged.
    pub command: Command,
    /// The axis.
    pub drive: Drive,
    /// The measuring device.
    pub device: Device,
    /// Seed of the scatter, the dwells, the pitch phases and the noise.
    pub seed: u64,
    /// An approach (target index, forward, cycle) whose dwell lasts 0.1 s only: the axis
    /// leaves before it has stood still.
    pub cut_dwell: Option<(usize, bool, usize)>,
}

/// A generated run and its truth.
pub(crate) struct SimLog {
    /// The log.
    pub trace: PositioningTrace,
    /// The settled positions per target, direction and cycle (without the device's offset).
    pub truth: PositionTable,
}

/// Simulation steps per command sample.
const SUB: usize = 10;
/// The control system's in-position window for the stepped command, mm.
const IN_POSITION_MM: f64 = 0.001;

struct Axis {
    dt: f64,
    drive: Drive,
    phase: [f64; 2],
    motor: f64,
    table: f64,
    command_log: Vec<f64>,
    true_log: Vec<f64>,
}

impl Axis {
    fn pitch(&self, x: f64) -> f64 {
        use std::f64::consts::TAU;
        let a = self.drive.pitch_mm;
        a * ((TAU * x / 170.0 + self.phase[0]).sin()
            + 0.5 * (TAU * x / 37.0 + self.phase[1]).sin()
            + x / 250.0)
    }

    /// One simulation step towards `goal` (command plus the stop's scatter), logging `command`.
    fn step(&mut self, command: f64, goal: f64) {
        let d = &self.drive;
        let v = (d.kv_per_s * (goal - self.motor)).clamp(-d.v_max_mm_s, d.v_max_mm_s);
        self.motor += v * self.dt;
        let half = 0.5 * d.backlash_mm;
        self.table = self.table.clamp(self.motor - half, self.motor + half);
        self.command_log.push(command);
        self.true_log.push(self.table + self.pitch(self.table));
    }
}

/// Generates the run (see the module docs).
pub(crate) fn simulate(spec: &RunSpec) -> SimLog {
    let mut rng = rand::rngs::StdRng::seed_from_u64(spec.seed);
    let scatter = Normal::new(0.0, spec.drive.scatter_mm).unwrap();
    let noise = Normal::new(0.0, spec.device.noise_mm).unwrap();
    let dt = spec.period_s / SUB as f64;
    let m = spec.targets_mm.len();
    let (lo, hi) = (
        spec.targets_mm[0] - spec.overrun_mm,
        spec.targets_mm[m - 1] + spec.overrun_mm,
    );
    let mut axis = Axis {
        dt,
        drive: spec.drive,
        phase: [rng.random_range(0.0..6.0), rng.random_range(0.0..6.0)],
        motor: lo,
        table: lo,
        command_log: Vec::new(),
        true_log: Vec::new(),
    };
    // (position, target index and direction)
    let mut stops: Vec<(f64, Option<(usize, bool)>)> = Vec::new();
    let mut cycle_of = Vec::new();
    for j in 0..spec.cycles {
        stops.extend((0..m).map(|i| (spec.targets_mm[i], Some((i, true)))));
        stops.push((hi, None));
        stops.extend((0..m).rev().map(|i| (spec.targets_mm[i], Some((i, false)))));
        stops.push((lo, None));
        cycle_of.resize(stops.len(), j);
    }
    let mut truth = PositionTable {
        targets_mm: spec.targets_mm.clone(),
        forward_mm: vec![Vec::new(); m],
        backward_mm: vec![Vec::new(); m],
    };
    for _ in 0..(1.0 / dt) as usize {
        axis.step(lo, lo);
    }
    let mut here = lo;
    for (&(at, target), &cycle) in stops.iter().zip(&cycle_of) {
        let goal = at + scatter.sample(&mut rng);
        let mut dwell = rng.random_range(spec.dwell_s[0]..spec.dwell_s[1]);
        let cut = target.is_some_and(|(i, f)| spec.cut_dwell == Some((i, f, cycle)));
        if cut {
            dwell = 0.1;
        }
        match spec.command {
            Command::Interpolated { feed_mm_s } => {
                let steps = ((at - here).abs() / (feed_mm_s * dt)).ceil().max(1.0) as usize;
                for s in 1..=steps {
                    let c = here + (at - here) * s as f64 / steps as f64;
                    axis.step(c, c + goal - at);
                }
                if target.is_some() {
                    for _ in 0..(dwell / dt) as usize {
                        axis.step(at, goal);
                    }
                }
            }
            Command::Stepped => {
                while (axis.motor - goal).abs() > IN_POSITION_MM {
                    axis.step(at, goal);
                }
                for _ in 0..(dwell / dt) as usize {
                    axis.step(at, goal);
                }
            }
        }
        here = at;
        if let Some((i, forward)) = target {
            let half = 0.5 * spec.drive.backlash_mm;
            let table = if forward { goal - half } else { goal + half };
            let settled = table + axis.pitch(table);
            let reached = *axis.true_log.last().unwrap();
            assert!(
                cut || (reached - settled).abs() < 1e-5,
                "the generator's axis did not settle: {reached} vs {settled}"
            );
            let row = if forward {
                &mut truth.forward_mm[i]
            } else {
                &mut truth.backward_mm[i]
            };
            row.push(settled);
        }
    }
    // A rest after the run, longer than the clocks' difference over it.
    let rest = (axis.true_log.len() as f64 * 0.06) as usize + (2.0 / dt) as usize;
    for _ in 0..rest {
        axis.step(here, here);
    }
    let len = axis.true_log.len();
    let n = ((len - 1) as f64 / (SUB as f64 * spec.device.clock.max(1.0))).floor() as usize;
    let commanded_mm = (0..n).map(|k| axis.command_log[k * SUB]).collect();
    let measured_mm = (0..n)
        .map(|k| {
            let j = (k * SUB) as f64 * spec.device.clock;
            let (i, f) = (j.floor() as usize, j.fract());
            let next = axis.true_log[(i + 1).min(len - 1)];
            let x = axis.true_log[i] * (1.0 - f) + next * f;
            x + spec.device.offset_mm + noise.sample(&mut rng)
        })
        .collect();
    SimLog {
        trace: PositioningTrace {
            period_s: spec.period_s,
            commanded_mm,
            measured_mm,
        },
        truth,
    }
}
