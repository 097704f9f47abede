//! Demo data for `truecut serve --demo`: machine `demo` (3-axis, servo models), surface
//! `saddle` (41×41 grid of z = (x² − y²)/200 mm over ±20 mm) and probe measurements `demo-1`
//! and `demo-2` of two parts (a waviness of 20 µm plus 10 µm of material left plus 3 µm of
//! seeded noise, different on each part); machine
//! `demo-vmc` (an 800 × 500 × 400 mm machining centre, same servo models) with a volumetric
//! map fitted (ISO 230-1 kinematic model) to a synthetic machine's 7 × 6 × 5 measured grid,
//! so the dashboard's volumetric view has its 21 component curves to show.

use anyhow::Result;
use serde_json::json;

use crate::store::{Measurement, Store, Surface};
use crate::volumetric::{self, FitOptions, ModelKind, ShapeFamily, SyntheticMachine};

/// Kind under which the service keeps a machine's volumetric map in the model store (the
/// same string as `api::volumetric::MODEL_KIND`, which the CLI may not import; the demo
/// test reads the map back through the HTTP route).
pub const VOLUMETRIC_MODEL_KIND: &str = "volumetric_map";

/// The demo machining centre's volumetric map: the ISO 230-1 kinematic model fitted to
/// `truecut volumetric --synthetic 7,6,5 --seed 1` (150 mm tool along −Z).
pub fn demo_volumetric_map() -> Result<volumetric::VolumetricMap> {
    let machine = SyntheticMachine::new(1, ShapeFamily::TrendAndWaviness);
    let data = machine.measure_grid([7, 6, 5], 1001);
    let options = FitOptions {
        model: ModelKind::Kinematic,
        tool_offset_mm: machine.tool_offset_mm,
        ..FitOptions::default()
    };
    Ok(volumetric::fit(&data, &options)?)
}

/// Grid size of the demo surface along u and v.
pub const DEMO_N: usize = 41;

/// The demo saddle: points (mm) and outward unit normals, u along x, v along y.
pub fn saddle() -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut points = Vec::with_capacity(DEMO_N * DEMO_N);
    let mut normals = Vec::with_capacity(DEMO_N * DEMO_N);
    for iv in 0..DEMO_N {
        for iu in 0..DEMO_N {
            let x = -20.0 + 40.0 * iu as f64 / (DEMO_N - 1) as f64;
            let y = -20.0 + 40.0 * iv as f64 / (DEMO_N - 1) as f64;
            points.push([x, y, (x * x - y * y) / 200.0]);
            // Outward normal of z = f(x, y) with material below: (-f_x, -f_y, 1)/|.|.
            let (fx, fy) = (x / 100.0, -y / 100.0);
            let len = (fx * fx + fy * fy + 1.0).sqrt();
            normals.push([-fx / len, -fy / len, 1.0 / len]);
        }
    }
    (points, normals)
}

/// Deterministic noise in [-1, 1) (xorshift64*), so the demo is the same everywhere.
fn noise(state: &mut u64) -> f64 {
    *state ^= *state >> 12;
    *state ^= *state << 25;
    *state ^= *state >> 27;
    let r = state.wrapping_mul(0x2545_F491_4F6C_DD1D);
    (r >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// A demo part's deviations (mm): 10 µm of material left plus a waviness of 20 µm (the same
/// on every part) plus 3 µm of noise drawn from `seed` (different per part).
fn part_deviations(points: &[[f64; 3]], mut seed: u64) -> Vec<f64> {
    let tau = std::f64::consts::TAU;
    points
        .iter()
        .map(|p| {
            0.010
                + 0.020 * (tau * p[0] / 40.0).sin() * (tau * p[1] / 40.0).cos()
                + 0.003 * noise(&mut seed)
        })
        .collect()
}

/// Loads the demo records unless machine `demo` exists. Returns `true` when loaded.
pub async fn load(store: &Store) -> Result<bool> {
    if store.get_machine("demo").await?.is_some() {
        return Ok(false);
    }
    let servo = json!({"kv": 30.0, "kff": 0.6, "kp_v": 400.0, "ti_v": 0.01, "tc": 0.0005});
    store
        .put_machine(
            "demo",
            &json!({
                "name": "Demo 3-axis vertical mill",
                "kinematics": "xyz",
                "axes": {"X": servo, "Y": servo, "Z": servo},
            }),
        )
        .await?;
    let (points, normals) = saddle();
    let surface = Surface {
        machine: "demo".into(),
        surface: "saddle".into(),
        nu: DEMO_N,
        nv: DEMO_N,
        points: points.clone(),
        normals,
        tool_radius: Some(3.0),
    };
    store
        .put_surface(&surface, &json!({"name": "saddle z = (x^2 - y^2)/200"}))
        .await?;
    for (id, seed) in [("demo-1", 0x5EED_u64), ("demo-2", 0x5EED_u64 + 1)] {
        let m = Measurement::new(
            id.into(),
            "demo".into(),
            "saddle".into(),
            part_deviations(&points, seed),
            None,
        );
        store.insert_measurement(&m).await?;
    }
    store
        .put_machine(
            "demo-vmc",
            &json!({
                "name": "Demo 800 x 500 x 400 mm machining centre (volumetric map)",
                "kinematics": "xyz",
                "axes": {"X": servo, "Y": servo, "Z": servo},
            }),
        )
        .await?;
    let map = tokio::task::spawn_blocking(demo_volumetric_map).await??;
    store
        .models()
        .save("demo-vmc", None, VOLUMETRIC_MODEL_KIND, &map.to_bytes())
        .await?;
    Ok(true)
}

#[cfg(test)]
mod tests;
