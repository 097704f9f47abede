//! Probe measurements: deviations (mm, signed along the outward normal) per surface point.

use anyhow::{Context, Result};
use serde::Serialize;
use sqlx::Row;

use super::codec::{decode_f64s, decode_points, encode_f64s, encode_points};
use super::database::{Store, now_ms};

/// A stored probe measurement of a surface: one deviation per nominal grid point.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Measurement {
    /// Measurement id.
    pub id: String,
    /// Machine id.
    pub machine: String,
    /// Surface id.
    pub surface: String,
    /// `(measured - nominal) · n` per grid point, mm (positive where material was left).
    pub deviations: Vec<f64>,
    /// The measured points, when the upload sent points.
    pub points: Option<Vec<[f64; 3]>>,
    /// Largest |deviation|, mm.
    pub max_abs: f64,
    /// Mean |deviation|, mm.
    pub mean_abs: f64,
}

/// One line of a surface's measurement list.
#[derive(Clone, Debug, Serialize)]
pub struct MeasurementSummary {
    /// Measurement id.
    pub id: String,
    /// Number of points.
    pub n: usize,
    /// Largest |deviation|, mm.
    pub max_abs: f64,
    /// Mean |deviation|, mm.
    pub mean_abs: f64,
    /// Upload time, Unix milliseconds.
    pub created_at_ms: i64,
}

impl Measurement {
    /// Builds a measurement from deviations, computing `max_abs` and `mean_abs`
    /// (both 0 for an empty slice).
    pub fn new(
        id: String,
        machine: String,
        surface: String,
        deviations: Vec<f64>,
        points: Option<Vec<[f64; 3]>>,
    ) -> Measurement {
        let max_abs = deviations.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
        let mean_abs = if deviations.is_empty() {
            0.0
        } else {
            deviations.iter().map(|d| d.abs()).sum::<f64>() / deviations.len() as f64
        };
        Measurement {
            id,
            machine,
            surface,
            deviations,
            points,
            max_abs,
            mean_abs,
        }
    }
}

/// What [`Store::insert_measurement`] did with a measurement whose id may be taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Inserted {
    /// Stored: the id was free.
    Created,
    /// Not stored: the id holds a measurement with the same deviations and points (a retry).
    Same,
    /// Not stored: the id holds a measurement with other data.
    Different,
}

/// BLOB bytes above which a measurement write waits for its turn (16 MiB: about 500,000
/// points with their deviations).
pub(crate) const LARGE_WRITE: usize = 16 << 20;

impl Store {
    /// Stores a new measurement (one row, arrays as BLOBs) unless its id is taken; then says
    /// whether the stored one holds the same data. Concurrent inserts of one id store one row
    /// and never fail for it (`INSERT ... ON CONFLICT DO NOTHING`).
    pub async fn insert_measurement(&self, m: &Measurement) -> Result<Inserted> {
        self.insert_measurement_blobs(
            m,
            encode_f64s(&m.deviations),
            m.points.as_deref().map(encode_points),
        )
        .await
    }

    /// Like [`Store::insert_measurement`], taking the measurement: its arrays are dropped once
    /// encoded, so a large upload holds its BLOBs, not its arrays beside them, while written.
    /// Writes of more than `LARGE_WRITE` bytes go one at a time on this instance and are
    /// encoded only when their turn comes (the database writes one at a time anyway on
    /// SQLite; the driver and SQLite each copy the BLOBs of a bound statement while it waits
    /// for the database's lock).
    pub async fn insert_measurement_owned(&self, mut m: Measurement) -> Result<Inserted> {
        let bytes = m.deviations.len() * 8 + m.points.as_ref().map_or(0, |p| p.len() * 24);
        let _turn = if bytes > LARGE_WRITE {
            Some(self.large_writes.lock().await)
        } else {
            None
        };
        let deviations = encode_f64s(&std::mem::take(&mut m.deviations));
        let points = m.points.take().map(|p| encode_points(&p));
        self.insert_measurement_blobs(&m, deviations, points).await
    }

    async fn insert_measurement_blobs(
        &self,
        m: &Measurement,
        deviations: Vec<u8>,
        points: Option<Vec<u8>>,
    ) -> Result<Inserted> {
        // The BLOBs move into the statement; their digest (a few ms for 16 MiB) is what a
        // taken id is compared with.
        let n = i64::try_from(deviations.len() / 8)?;
        let digest = blob_digest(&deviations, points.as_deref());
        let inserted = sqlx::query(
            "INSERT INTO measurements (machine, surface, id, n, max_abs, mean_abs, deviations, \
             points, created_at) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9) \
             ON CONFLICT (machine, surface, id) DO NOTHING",
        )
        .bind(m.machine.clone())
        .bind(m.surface.clone())
        .bind(m.id.clone())
        .bind(n)
        .bind(m.max_abs)
        .bind(m.mean_abs)
        .bind(deviations)
        .bind(points)
        .bind(now_ms())
        .execute(&self.db)
        .await
        .context("cannot store the measurement")?
        .rows_affected();
        if inserted == 1 {
            return Ok(Inserted::Created);
        }
        // The id is taken (by a retry of this upload or by another one): compare the data.
        let row = sqlx::query(
            "SELECT deviations, points FROM measurements \
             WHERE machine = $1 AND surface = $2 AND id = $3",
        )
        .bind(m.machine.clone())
        .bind(m.surface.clone())
        .bind(m.id.clone())
        .fetch_optional(&self.db)
        .await?;
        let Some(row) = row else {
            // Deleted in between: the id was taken when this insert ran, so it is a conflict
            // the client may retry.
            return Ok(Inserted::Different);
        };
        let stored: Vec<u8> = row.try_get(0)?;
        let stored_points: Option<Vec<u8>> = row.try_get(1)?;
        Ok(
            if blob_digest(&stored, stored_points.as_deref()) == digest {
                Inserted::Same
            } else {
                Inserted::Different
            },
        )
    }

    /// The measurement, or `None` if machine, surface or measurement does not exist.
    pub async fn get_measurement(
        &self,
        machine: &str,
        surface: &str,
        id: &str,
    ) -> Result<Option<Measurement>> {
        let row = sqlx::query(
            "SELECT max_abs, mean_abs, deviations, points FROM measurements \
             WHERE machine = $1 AND surface = $2 AND id = $3",
        )
        .bind(machine.to_string())
        .bind(surface.to_string())
        .bind(id.to_string())
        .fetch_optional(&self.db)
        .await?;
        let Some(row) = row else { return Ok(None) };
        let deviations: Vec<u8> = row.try_get(2)?;
        let points: Option<Vec<u8>> = row.try_get(3)?;
        Ok(Some(Measurement {
            id: id.to_string(),
            machine: machine.to_string(),
            surface: surface.to_string(),
            max_abs: row.try_get(0)?,
            mean_abs: row.try_get(1)?,
            deviations: decode_f64s(&deviations)?,
            points: points.as_deref().map(decode_points).transpose()?,
        }))
    }

    /// True when the measurement id is taken on that surface (no arrays are read).
    pub async fn measurement_exists(&self, machine: &str, surface: &str, id: &str) -> Result<bool> {
        let n: i64 = sqlx::query_scalar(
            "SELECT COUNT(*) FROM measurements WHERE machine = $1 AND surface = $2 AND id = $3",
        )
        .bind(machine.to_string())
        .bind(surface.to_string())
        .bind(id.to_string())
        .fetch_one(&self.db)
        .await?;
        Ok(n > 0)
    }

    /// The surface's measurements (without arrays), oldest first.
    pub async fn list_measurements(
        &self,
        machine: &str,
        surface: &str,
    ) -> Result<Vec<MeasurementSummary>> {
        let rows = sqlx::query(
            "SELECT id, n, max_abs, mean_abs, created_at FROM measurements \
             WHERE machine = $1 AND surface = $2 ORDER BY created_at, id",
        )
        .bind(machine.to_string())
        .bind(surface.to_string())
        .fetch_all(&self.db)
        .await?;
        rows.into_iter()
            .map(|row| {
                let n: i64 = row.try_get(1)?;
                Ok(MeasurementSummary {
                    id: row.try_get(0)?,
                    n: usize::try_from(n)?,
                    max_abs: row.try_get(2)?,
                    mean_abs: row.try_get(3)?,
                    created_at_ms: row.try_get(4)?,
                })
            })
            .collect()
    }

    /// Deletes a measurement and its documents (keys `surface/id` and `surface/id/...`);
    /// returns `false` if it did not exist.
    pub async fn delete_measurement(&self, machine: &str, surface: &str, id: &str) -> Result<bool> {
        let mut tx = self.db.begin().await?;
        let key = format!("{surface}/{id}");
        sqlx::query(
            "DELETE FROM docs WHERE machine = $1 AND (key = $2 OR key LIKE $3 ESCAPE '\\')",
        )
        .bind(machine.to_string())
        .bind(key.clone())
        .bind(format!("{}/%", key.replace('_', "\\_")))
        .execute(&mut *tx)
        .await?;
        let n =
            sqlx::query("DELETE FROM measurements WHERE machine = $1 AND surface = $2 AND id = $3")
                .bind(machine.to_string())
                .bind(surface.to_string())
                .bind(id.to_string())
                .execute(&mut *tx)
                .await?
                .rows_affected();
        tx.commit().await?;
        Ok(n > 0)
    }
}

/// SHA-256 of a measurement's arrays as stored (deviations, then a marker and the points), so
/// an insert that met a taken id compares without keeping a copy of its BLOBs.
fn blob_digest(deviations: &[u8], points: Option<&[u8]>) -> [u8; 32] {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    h.update((deviations.len() as u64).to_le_bytes());
    h.update(deviations);
    match points {
        Some(p) => {
            h.update([1]);
            h.update(p);
        }
        None => h.update([0]),
    }
    h.finalize().into()
}
