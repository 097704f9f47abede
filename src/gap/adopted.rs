//! Effects adopted into a machine's model (`PUT /v1/machines/{m}/effects`): the body, read
//! and checked, and added to every simulation of the machine ([`crate::motion::AddedEffects`]).
//!
//! The names and parameter keys are exactly those of a motion diagnosis' `effects[]` and
//! `steps[]` (per-axis keys start with the axis letter, lower-cased: `x_mm`, `y_ppm`, ...), so
//! a diagnosis' `accept` body is stored as it stands. The formulas are the diagnosis' own
//! ([`Fitted::predict`]), added as the diagnosis' steps add them ([`crate::gap::steps`]): each
//! effect's change to the linear simulation, summed. So diagnosing a run again with its
//! effects adopted measures what they leave.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::gap::Error;
use crate::gap::effects::{Effect, Fitted, thermal_basis};
use crate::gap::plant::AxisPlant;
use crate::gap::steps::delta;
use crate::motion::{AddedEffects, AxisModel};

/// One effect of a body: its openapi.yaml name and its parameters by key.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectEntry {
    /// `backlash`, `coulomb_friction`, `servo_gain_mismatch`, `axis_squareness`,
    /// `scale_error`, `cyclic_error` or `thermal_drift`.
    pub effect: String,
    /// Parameters by key, as a diagnosis answers them.
    pub params: BTreeMap<String, f64>,
}

/// The body of `PUT /v1/machines/{m}/effects` (and what is stored).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectSet {
    /// The effects, each added to the simulation.
    pub effects: Vec<EffectEntry>,
    /// Where they come from, for people (e.g. "gap-diagnosis job 0193..."); free text.
    #[serde(default)]
    pub source: Option<String>,
}

/// Most effects a set holds (one of each library effect per axis is 7 × 5).
pub const MAX_EFFECTS: usize = 64;

/// The axes a set may name: the machine's letters and whether each has a velocity loop (the
/// friction key then is `*_accel_mm_s2`, otherwise `*_velocity_deficit_mm_s`).
#[derive(Clone, Debug)]
pub struct AxisInfo {
    /// Axis letter, upper case.
    pub name: String,
    /// The stored cascade has a velocity loop (`kp_v` given).
    pub velocity_loop: bool,
}

/// One effect, read: its values per axis letter (upper case).
#[derive(Clone, Debug, PartialEq)]
enum Adopted {
    /// mm/s² or mm/s per axis.
    Friction(BTreeMap<String, f64>),
    /// Width (mm) and initial place in the gap (−1..1) per axis.
    Backlash(BTreeMap<String, (f64, f64)>),
    /// Gain: absolute 1/s (`Ok`) or a ratio to the stored kv (`Err`) per axis.
    Gain(BTreeMap<String, Result<f64, f64>>),
    /// `target += alpha · source`.
    Squareness(String, String, f64),
    /// Scale (dimensionless) per axis.
    Scale(BTreeMap<String, f64>),
    /// Pitch mm, sine and cosine amplitudes mm, per axis.
    Cyclic(BTreeMap<String, (f64, f64, f64)>),
    /// Rate mm/s per axis, and the time constant (s; infinite when absent).
    Thermal(BTreeMap<String, f64>, f64),
}

fn bad(effect: &str, key: &str, why: &str) -> Error {
    Error::Effects(format!("effects: {effect}.params.{key}: {why}"))
}

/// Splits a per-axis key `x_mm` into (`X`, `mm`), checking the letter is one of `axes`.
fn split<'k>(effect: &str, key: &'k str, axes: &[AxisInfo]) -> Result<(String, &'k str), Error> {
    let letters: Vec<&str> = axes.iter().map(|a| a.name.as_str()).collect();
    let (l, rest) = key.split_once('_').unwrap_or((key, ""));
    let upper = l.to_uppercase();
    if !letters.contains(&upper.as_str()) {
        return Err(bad(
            effect,
            key,
            &format!(
                "keys start with an axis of the machine ({}), lower-cased, e.g. {}_{}",
                letters.join(", "),
                letters.first().copied().unwrap_or("x").to_lowercase(),
                rest
            ),
        ));
    }
    Ok((upper, rest))
}

fn unknown(effect: &str, key: &str, keys: &str) -> Error {
    bad(effect, key, &format!("unknown key: {effect} takes {keys}"))
}

fn check_range(effect: &str, key: &str, v: f64, ok: bool, range: &str) -> Result<(), Error> {
    if ok {
        Ok(())
    } else {
        Err(bad(effect, key, &format!("{v} is out of range: {range}")))
    }
}

/// Reads one entry against the machine's `axes` (400-worthy sentences naming the key).
fn read(e: &EffectEntry, axes: &[AxisInfo]) -> Result<Adopted, Error> {
    let name = e.effect.as_str();
    for (k, v) in &e.params {
        if !v.is_finite() {
            return Err(bad(name, k, "values must be finite numbers"));
        }
    }
    let effect = Effect::LIBRARY
        .iter()
        .copied()
        .find(|x| x.name() == name)
        .ok_or_else(|| {
            let names: Vec<&str> = Effect::LIBRARY.iter().map(|x| x.name()).collect();
            Error::Effects(format!(
                "effects: \"{name}\" is not an effect that can be stored: use one of {}",
                names.join(", ")
            ))
        })?;
    let per_axis = |keys: &[&str]| -> Result<BTreeMap<String, BTreeMap<String, f64>>, Error> {
        let mut out: BTreeMap<String, BTreeMap<String, f64>> = BTreeMap::new();
        for (k, &v) in &e.params {
            let (axis, suffix) = split(name, k, axes)?;
            if !keys.contains(&suffix) {
                return Err(unknown(
                    name,
                    k,
                    &format!("<axis>_{}", keys.join(", <axis>_")),
                ));
            }
            out.entry(axis).or_default().insert(suffix.to_string(), v);
        }
        Ok(out)
    };
    Ok(match effect {
        Effect::CoulombFriction => {
            let m = per_axis(&["accel_mm_s2", "velocity_deficit_mm_s"])?;
            let mut out = BTreeMap::new();
            for (axis, p) in m {
                let info = axes.iter().find(|a| a.name == axis).expect("checked");
                let want = if info.velocity_loop {
                    "accel_mm_s2"
                } else {
                    "velocity_deficit_mm_s"
                };
                let l = axis.to_lowercase();
                let f = p.get(want).copied().ok_or_else(|| {
                    bad(
                        name,
                        &format!("{l}_{want}"),
                        &format!(
                            "axis {axis} {} a velocity loop in the machine's servo model: give \
                         its friction as {l}_{want}",
                            if info.velocity_loop { "has" } else { "has no" }
                        ),
                    )
                })?;
                check_range(
                    name,
                    &format!("{l}_{want}"),
                    f,
                    (0.0..=1e6).contains(&f),
                    "0..1e6",
                )?;
                out.insert(axis, f);
            }
            Adopted::Friction(out)
        }
        Effect::Backlash => {
            let m = per_axis(&["mm", "start_in_gap"])?;
            let mut out = BTreeMap::new();
            for (axis, p) in m {
                let l = axis.to_lowercase();
                let b = p.get("mm").copied().ok_or_else(|| {
                    bad(
                        name,
                        &format!("{l}_mm"),
                        "missing: give the gap width in mm",
                    )
                })?;
                check_range(
                    name,
                    &format!("{l}_mm"),
                    b,
                    (0.0..=10.0).contains(&b),
                    "0..10 mm",
                )?;
                // the table's place in the gap at the program's start is unknown: in contact
                // against the first move (−1) shows the whole lost motion there
                let st = p.get("start_in_gap").copied().unwrap_or(-1.0);
                let key = format!("{l}_start_in_gap");
                check_range(name, &key, st, (-1.0..=1.0).contains(&st), "−1..1")?;
                out.insert(axis, (b, st));
            }
            Adopted::Backlash(out)
        }
        Effect::ServoGainMismatch => {
            let m = per_axis(&["kv_per_s", "kv_ratio"])?;
            let mut out = BTreeMap::new();
            for (axis, p) in m {
                let l = axis.to_lowercase();
                // the absolute gain is what was measured; the ratio only when it is absent
                let g = match (p.get("kv_per_s"), p.get("kv_ratio")) {
                    (Some(&kv), _) => {
                        let key = format!("{l}_kv_per_s");
                        check_range(
                            name,
                            &key,
                            kv,
                            (0.01..=1e4).contains(&kv),
                            "0.01..10,000 1/s",
                        )?;
                        Ok(kv)
                    }
                    (None, Some(&r)) => {
                        let key = format!("{l}_kv_ratio");
                        check_range(name, &key, r, (0.01..=100.0).contains(&r), "0.01..100")?;
                        Err(r)
                    }
                    (None, None) => unreachable!("an axis appears only with a key"),
                };
                out.insert(axis, g);
            }
            Adopted::Gain(out)
        }
        Effect::AxisSquareness => {
            let mut found = None;
            for (k, &v) in &e.params {
                if k == "urad" {
                    continue;
                }
                let pair = k
                    .strip_suffix("_rad")
                    .and_then(|s| s.split_once("_per_"))
                    .ok_or_else(|| unknown(name, k, "<target>_per_<source>_rad (and urad)"))?;
                let (t, _) = split(name, &format!("{}_", pair.0), axes)?;
                let (s, _) = split(name, &format!("{}_", pair.1), axes)?;
                if t == s || found.is_some() {
                    return Err(bad(name, k, "give one pair of two different axes"));
                }
                check_range(name, k, v, v.abs() <= 0.01, "at most 0.01 rad")?;
                found = Some(Adopted::Squareness(t, s, v));
            }
            found.ok_or_else(|| {
                bad(
                    name,
                    "urad",
                    "name the axes: give <target>_per_<source>_rad, e.g. y_per_x_rad",
                )
            })?
        }
        Effect::ScaleError => {
            let m = per_axis(&["ppm"])?;
            let mut out = BTreeMap::new();
            for (axis, p) in m {
                let ppm = p["ppm"];
                let key = format!("{}_ppm", axis.to_lowercase());
                check_range(name, &key, ppm, ppm.abs() <= 1e5, "within ±100,000 ppm")?;
                out.insert(axis, ppm * 1e-6);
            }
            Adopted::Scale(out)
        }
        Effect::CyclicError => {
            let m = per_axis(&["pitch_mm", "amplitude_mm", "phase_rad"])?;
            let mut out = BTreeMap::new();
            for (axis, p) in m {
                let l = axis.to_lowercase();
                let need = |k: &str| {
                    p.get(k)
                        .copied()
                        .ok_or_else(|| bad(name, &format!("{l}_{k}"), "missing"))
                };
                let (pitch, amp) = (need("pitch_mm")?, need("amplitude_mm")?);
                let phase = p.get("phase_rad").copied().unwrap_or(0.0);
                let key = format!("{l}_pitch_mm");
                check_range(
                    name,
                    &key,
                    pitch,
                    (1e-3..=1e4).contains(&pitch),
                    "0.001..10,000 mm",
                )?;
                let key = format!("{l}_amplitude_mm");
                check_range(name, &key, amp, (0.0..=10.0).contains(&amp), "0..10 mm")?;
                // the diagnosis answers phase = atan2(cos, sin) and amplitude = |(sin, cos)|
                out.insert(axis, (pitch, amp * phase.cos(), amp * phase.sin()));
            }
            Adopted::Cyclic(out)
        }
        Effect::ThermalDrift => {
            let tau = e.params.get("tau_s").copied().unwrap_or(f64::INFINITY);
            let ok = tau == f64::INFINITY || (1e-3..=1e9).contains(&tau);
            check_range(
                name,
                "tau_s",
                tau,
                ok,
                "0.001..1e9 s (leave it out for a linear drift)",
            )?;
            let mut rates = BTreeMap::new();
            for (k, &v) in &e.params {
                if k == "tau_s" {
                    continue;
                }
                let (axis, suffix) = split(name, k, axes)?;
                match suffix {
                    "rate_mm_s" => {
                        check_range(name, k, v, v.abs() <= 1.0, "within ±1 mm/s")?;
                        rates.insert(axis, v);
                    }
                    // derived from the rate and the diagnosed run's length: not an input
                    "drift_at_end_mm" => {}
                    _ => return Err(unknown(name, k, "<axis>_rate_mm_s and tau_s")),
                }
            }
            Adopted::Thermal(rates, tau)
        }
        Effect::None | Effect::Unexplained => unreachable!("not in the library"),
    })
}

/// Checks a body against the machine's `axes`: every name and key known, every value finite
/// and in range, at most [`MAX_EFFECTS`] effects, each with at least one parameter.
pub fn check(set: &EffectSet, axes: &[AxisInfo]) -> Result<(), Error> {
    if set.effects.len() > MAX_EFFECTS {
        return Err(Error::Effects(format!(
            "effects: {} effects, at most {MAX_EFFECTS}",
            set.effects.len()
        )));
    }
    for e in &set.effects {
        if e.params.is_empty() {
            return Err(Error::Effects(format!(
                "effects: {} has no params: give them as the gap diagnosis answers them",
                e.effect
            )));
        }
        read(e, axes)?;
    }
    Ok(())
}

/// A stored set, ready to add to simulations.
#[derive(Clone, Debug)]
pub struct StoredEffects {
    version: i64,
    effects: Vec<Adopted>,
}

impl StoredEffects {
    /// Reads a stored `set` (version `version`) against the machine's `axes`.
    pub fn new(set: &EffectSet, axes: &[AxisInfo], version: i64) -> Result<Self, Error> {
        let effects = set
            .effects
            .iter()
            .map(|e| read(e, axes))
            .collect::<Result<_, _>>()?;
        Ok(Self { version, effects })
    }

    /// Whether the set adds nothing.
    pub fn is_empty(&self) -> bool {
        self.effects.is_empty()
    }

    /// The openapi.yaml names of the effects, in the stored order.
    pub fn names(&self) -> Vec<&'static str> {
        self.effects.iter().map(|e| e.effect().name()).collect()
    }

    /// The set split in two of the same version: the effects a program corrects in its
    /// points (scale, squareness, cyclic error: functions of the axis positions alone, see
    /// [`StoredEffects::geometric_error_at`]; backlash: of the direction of motion, see
    /// [`StoredEffects::backlash_mm`]; thermal drift: of the program's time, see
    /// [`StoredEffects::drift_at`]) and the others (friction, gain: of the motion's
    /// dynamics).
    pub fn split_corrected(&self) -> (StoredEffects, StoredEffects) {
        let (geo, rest) = self.effects.iter().cloned().partition(|a| {
            a.is_geometric() || matches!(a, Adopted::Backlash(_) | Adopted::Thermal(..))
        });
        let version = self.version;
        (
            StoredEffects {
                version,
                effects: geo,
            },
            StoredEffects {
                version,
                effects: rest,
            },
        )
    }

    /// The drift (mm, X Y Z) the set's thermal drift adds `t_s` seconds after the start of a
    /// simulated run: `rate·τ·(1 − e^(−t/τ))`, `rate·t` without τ (the diagnosis' formula,
    /// [`thermal_basis`]); zero without thermal drift.
    pub fn drift_at(&self, t_s: f64) -> [f64; 3] {
        let mut d = [0.0; 3];
        for a in &self.effects {
            if let Adopted::Thermal(m, tau) = a {
                for (l, r) in m {
                    if let Some(k) = ["X", "Y", "Z"].iter().position(|x| x == l) {
                        d[k] += r * thermal_basis(t_s, *tau);
                    }
                }
            }
        }
        d
    }

    /// The play (mm) of the set's backlash per axis X, Y, Z (0: none).
    pub fn backlash_mm(&self) -> [f64; 3] {
        let mut b = [0.0; 3];
        for a in &self.effects {
            if let Adopted::Backlash(m) = a {
                for (l, (w, _)) in m {
                    if let Some(k) = ["X", "Y", "Z"].iter().position(|x| x == l) {
                        b[k] += w;
                    }
                }
            }
        }
        b
    }

    /// The error e(p) (mm) the set's geometric effects add at machine point `p` (X, Y, Z,
    /// mm) of a machine with axes X, Y, Z: the tool arrives at p + e(p). The diagnosis' own
    /// formulas ([`Fitted::predict`]: `s·x` for scale, `α·source` for squareness, the sine
    /// and cosine of `2π·x/pitch` for cyclic error), summed; the set's other effects add
    /// nothing here.
    pub fn geometric_error_at(&self, p: [f64; 3]) -> [f64; 3] {
        let index = |l: &str| ["X", "Y", "Z"].iter().position(|a| *a == l);
        let mut e = [0.0; 3];
        for a in self.effects.iter().filter(|a| a.is_geometric()) {
            let Some((idx, f)) = fitted(a, &index, &|_| 0.0) else {
                continue;
            };
            let base: Vec<Vec<f64>> = idx.iter().map(|&i| vec![p[i]]).collect();
            let d = delta(&f, &[], &base, &base);
            for (j, &i) in idx.iter().enumerate() {
                e[i] += d[j][0];
            }
        }
        e
    }
}

impl Adopted {
    /// The library effect this is.
    fn effect(&self) -> Effect {
        match self {
            Adopted::Friction(_) => Effect::CoulombFriction,
            Adopted::Backlash(_) => Effect::Backlash,
            Adopted::Gain(_) => Effect::ServoGainMismatch,
            Adopted::Squareness(..) => Effect::AxisSquareness,
            Adopted::Scale(_) => Effect::ScaleError,
            Adopted::Cyclic(_) => Effect::CyclicError,
            Adopted::Thermal(..) => Effect::ThermalDrift,
        }
    }

    /// A function of the axis positions alone (scale, squareness, cyclic error).
    fn is_geometric(&self) -> bool {
        matches!(
            self,
            Adopted::Squareness(..) | Adopted::Scale(_) | Adopted::Cyclic(_)
        )
    }
}

/// The columns of `v` at `idx`.
/// One adopted effect as the diagnosis' [`Fitted`] on the axes it names: (their indices in
/// the simulation's axes, the effect on those axes only); `None` when none of its axes is
/// simulated. `index` finds an axis letter; `kv_of` gives an axis' stored gain (1/s), which
/// a gain given as a ratio multiplies.
fn fitted(
    e: &Adopted,
    index: &dyn Fn(&str) -> Option<usize>,
    kv_of: &dyn Fn(usize) -> f64,
) -> Option<(Vec<usize>, Fitted)> {
    let (idx, f) = match e {
        Adopted::Friction(m) => {
            let (i, f): (Vec<usize>, Vec<f64>) =
                m.iter().filter_map(|(l, &v)| Some((index(l)?, v))).unzip();
            (i, Fitted::CoulombFriction { f })
        }
        Adopted::Backlash(m) => {
            let (i, bs): (Vec<usize>, Vec<(f64, f64)>) =
                m.iter().filter_map(|(l, &v)| Some((index(l)?, v))).unzip();
            let (b, start) = bs.into_iter().unzip();
            (i, Fitted::Backlash { b, start })
        }
        Adopted::Gain(m) => {
            let mut i = Vec::new();
            let mut kv = Vec::new();
            for (l, g) in m {
                let Some(k) = index(l) else { continue };
                i.push(k);
                kv.push(match g {
                    Ok(kv) => *kv,
                    Err(r) => r * kv_of(k),
                });
            }
            (i, Fitted::ServoGainMismatch { kv })
        }
        Adopted::Squareness(t, s, alpha) => {
            let (Some(t), Some(s)) = (index(t), index(s)) else {
                return None;
            };
            let f = Fitted::AxisSquareness {
                target: 0,
                source: 1,
                alpha: *alpha,
            };
            (vec![t, s], f)
        }
        Adopted::Scale(m) => {
            let (i, s) = m.iter().filter_map(|(l, &v)| Some((index(l)?, v))).unzip();
            (i, Fitted::ScaleError { s })
        }
        Adopted::Cyclic(m) => {
            let (i, v): (Vec<usize>, Vec<(f64, f64, f64)>) =
                m.iter().filter_map(|(l, &v)| Some((index(l)?, v))).unzip();
            let pitch = v.iter().map(|x| x.0).collect();
            let sin = v.iter().map(|x| x.1).collect();
            let cos = v.iter().map(|x| x.2).collect();
            (i, Fitted::CyclicError { pitch, sin, cos })
        }
        Adopted::Thermal(m, tau) => {
            let (i, rate) = m.iter().filter_map(|(l, &v)| Some((index(l)?, v))).unzip();
            (i, Fitted::ThermalDrift { rate, tau: *tau })
        }
    };
    (!idx.is_empty()).then_some((idx, f))
}

fn pick(v: &[Vec<f64>], idx: &[usize]) -> Vec<Vec<f64>> {
    idx.iter().map(|&i| v[i].clone()).collect()
}

impl AddedEffects for StoredEffects {
    /// `linear + Σ Δ`: each effect's [`Fitted::predict`] minus the linear simulation, on the
    /// axes it names (an effect is column-wise except squareness, which reads two columns).
    fn apply(
        &self,
        axes: &[AxisModel<'_>],
        period_s: f64,
        commanded: &[Vec<f64>],
        linear: &[Vec<f64>],
    ) -> Result<Vec<Vec<f64>>, crate::motion::Error> {
        let index = |l: &str| axes.iter().position(|a| a.name == l);
        let mut plants: Vec<Option<AxisPlant>> = vec![None; axes.len()];
        let mut plant = |i: usize| -> Result<AxisPlant, crate::motion::Error> {
            if plants[i].is_none() {
                let a = &axes[i];
                let p = AxisPlant::new(a.name, a.servo, period_s)
                    .map_err(|e| crate::motion::Error::Effects(e.to_string()))?
                    .with_structure(a.structure);
                plants[i] = Some(p);
            }
            Ok(plants[i].clone().expect("just made"))
        };
        let mut out = linear.to_vec();
        for e in &self.effects {
            let Some((idx, f)) = fitted(e, &index, &|k| axes[k].servo.kv) else {
                continue;
            };
            let p: Vec<AxisPlant> = idx.iter().map(|&i| plant(i)).collect::<Result<_, _>>()?;
            let d = delta(&f, &p, &pick(commanded, &idx), &pick(linear, &idx));
            // a squareness displaces its target only: the source column's Δ is zero
            for (j, &i) in idx.iter().enumerate() {
                out[i].iter_mut().zip(&d[j]).for_each(|(o, d)| *o += d);
            }
        }
        if out.iter().flatten().any(|v| !v.is_finite()) {
            return Err(crate::motion::Error::Effects(
                "they give a position that is not a finite number (a gain that makes an axis' \
                 loop unstable at this period?): PUT effects again, or send \"effects\": \"none\""
                    .into(),
            ));
        }
        Ok(out)
    }

    fn version(&self) -> i64 {
        self.version
    }
}

#[cfg(test)]
mod tests;
