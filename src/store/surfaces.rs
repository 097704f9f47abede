//! Nominal surfaces: a `nu × nv` grid of points and outward unit normals per machine.

use anyhow::{Context, Result};
use serde::Serialize;
use sqlx::Row;

use super::codec::{decode_points, encode_points};
use super::database::{Store, now_ms};

/// A nominal surface grid. Point `k` is `(iu, iv)` with `k = iv*nu + iu` (u runs fastest);
/// lengths in mm; normals are unit and point out of the material.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Surface {
    /// Machine id.
    pub machine: String,
    /// Surface id.
    pub surface: String,
    /// Grid points along u.
    pub nu: usize,
    /// Grid points along v.
    pub nv: usize,
    /// Nominal points, mm, `nu*nv` of them.
    pub points: Vec<[f64; 3]>,
    /// Outward unit normals, `nu*nv` of them.
    pub normals: Vec<[f64; 3]>,
    /// Ball-end tool radius in mm, if given.
    pub tool_radius: Option<f64>,
}

/// One line of a machine's surface list.
#[derive(Clone, Debug, Serialize)]
pub struct SurfaceSummary {
    /// Surface id.
    pub id: String,
    /// Grid points along u.
    pub nu: usize,
    /// Grid points along v.
    pub nv: usize,
    /// Ball-end tool radius in mm, if given.
    pub tool_radius: Option<f64>,
    /// Number of stored measurements.
    pub measurements: usize,
}

fn to_usize(x: i64) -> Result<usize> {
    usize::try_from(x).context("negative count in the database")
}

fn to_i64(x: usize) -> i64 {
    i64::try_from(x).unwrap_or(i64::MAX)
}

impl Store {
    /// Creates or replaces a surface; `extra` is the rest of the PUT body (kept verbatim).
    /// Returns `true` when created. The machine must exist (checked by the caller).
    pub async fn put_surface(&self, s: &Surface, extra: &serde_json::Value) -> Result<bool> {
        let now = now_ms();
        let points = encode_points(&s.points);
        let normals = encode_points(&s.normals);
        // Insert first, update when the id is taken: two PUTs of a new surface that race both
        // succeed (one creates, the other replaces).
        let mut tx = self.db.begin().await?;
        let created = sqlx::query(
            "INSERT INTO surfaces (machine, id, nu, nv, points, normals, tool_radius, extra, \
             created_at, updated_at) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10) \
             ON CONFLICT (machine, id) DO NOTHING",
        )
        .bind(s.machine.clone())
        .bind(s.surface.clone())
        .bind(to_i64(s.nu))
        .bind(to_i64(s.nv))
        .bind(points.clone())
        .bind(normals.clone())
        .bind(s.tool_radius)
        .bind(extra.to_string())
        .bind(now)
        .bind(now)
        .execute(&mut *tx)
        .await?
        .rows_affected()
            == 1;
        if !created {
            sqlx::query(
                "UPDATE surfaces SET nu = $1, nv = $2, points = $3, normals = $4, \
                 tool_radius = $5, extra = $6, updated_at = $7 WHERE machine = $8 AND id = $9",
            )
            .bind(to_i64(s.nu))
            .bind(to_i64(s.nv))
            .bind(points)
            .bind(normals)
            .bind(s.tool_radius)
            .bind(extra.to_string())
            .bind(now)
            .bind(s.machine.clone())
            .bind(s.surface.clone())
            .execute(&mut *tx)
            .await?;
        }
        tx.commit().await?;
        self.surfaces.forget(&s.machine, &s.surface);
        Ok(created)
    }

    /// The surface, or `None` if the machine or surface does not exist.
    ///
    /// Its two arrays are read one at a time and decoded from the row's bytes, so reading a
    /// surface holds at most one array's BLOB (as the driver hands it over) beside the arrays:
    /// a 3.9-million-point surface's points and normals are 88 MiB each. Each read checks the
    /// row's `updated_at`, so a surface replaced meanwhile is read again, never mixed.
    pub async fn get_surface(&self, machine: &str, surface: &str) -> Result<Option<Surface>> {
        for _ in 0..5 {
            let row = sqlx::query(
                "SELECT nu, nv, tool_radius, updated_at FROM surfaces WHERE machine = $1 AND id = $2",
            )
            .bind(machine.to_string())
            .bind(surface.to_string())
            .fetch_optional(&self.db)
            .await?;
            let Some(row) = row else { return Ok(None) };
            let stamp: i64 = row.try_get(3)?;
            let mut arrays = Vec::with_capacity(2);
            for sql in [
                "SELECT updated_at, points FROM surfaces WHERE machine = $1 AND id = $2",
                "SELECT updated_at, normals FROM surfaces WHERE machine = $1 AND id = $2",
            ] {
                let r = sqlx::query(sql)
                    .bind(machine.to_string())
                    .bind(surface.to_string())
                    .fetch_optional(&self.db)
                    .await?;
                let Some(r) = r else { return Ok(None) };
                if r.try_get::<i64, _>(0)? != stamp {
                    break;
                }
                let bytes: &[u8] = r.try_get(1)?;
                arrays.push(decode_points(bytes)?);
            }
            if arrays.len() < 2 {
                continue; // replaced while read: again
            }
            let normals = arrays.pop().expect("two arrays");
            let points = arrays.pop().expect("two arrays");
            return Ok(Some(Surface {
                machine: machine.to_string(),
                surface: surface.to_string(),
                nu: to_usize(row.try_get(0)?)?,
                nv: to_usize(row.try_get(1)?)?,
                points,
                normals,
                tool_radius: row.try_get(2)?,
            }));
        }
        anyhow::bail!("surface '{surface}' of machine '{machine}' kept changing while it was read")
    }

    /// The surface, shared with other requests (one copy per surface: `surface_cache.rs`),
    /// or `None` if the machine or surface does not exist. The row's `(updated_at, nu, nv)` is
    /// read on every call, so a surface replaced through another instance is read afresh.
    pub async fn get_surface_shared(
        &self,
        machine: &str,
        surface: &str,
    ) -> Result<Option<std::sync::Arc<Surface>>> {
        let stamp = |row: &sqlx::any::AnyRow| -> Result<super::surface_cache::Stamp> {
            Ok((
                row.try_get(0)?,
                to_usize(row.try_get(1)?)?,
                to_usize(row.try_get(2)?)?,
            ))
        };
        let sql = "SELECT updated_at, nu, nv FROM surfaces WHERE machine = $1 AND id = $2";
        let read_stamp = || async {
            let row = sqlx::query(sql)
                .bind(machine.to_string())
                .bind(surface.to_string())
                .fetch_optional(&self.db)
                .await?;
            row.as_ref().map(stamp).transpose()
        };
        let Some(now) = read_stamp().await? else {
            self.surfaces.forget(machine, surface);
            return Ok(None);
        };
        if let Some(s) = self.surfaces.get(machine, surface, now) {
            return Ok(Some(s));
        }
        // One reader per miss: requests arriving together wait and then share its copy.
        let _loading = self.surfaces.loading.lock().await;
        let Some(now) = read_stamp().await? else {
            return Ok(None);
        };
        if let Some(s) = self.surfaces.get(machine, surface, now) {
            return Ok(Some(s));
        }
        let Some(s) = self.get_surface(machine, surface).await? else {
            return Ok(None);
        };
        let s = std::sync::Arc::new(s);
        // Kept only if the row did not change while it was read.
        if read_stamp().await? == Some(now) {
            self.surfaces.put(now, s.clone());
        }
        Ok(Some(s))
    }

    /// The surface's grid size `(nu, nv)` without its arrays, or `None` if the machine or
    /// surface does not exist (the cheap check made before a request body is read).
    pub async fn surface_grid(
        &self,
        machine: &str,
        surface: &str,
    ) -> Result<Option<(usize, usize)>> {
        let row = sqlx::query("SELECT nu, nv FROM surfaces WHERE machine = $1 AND id = $2")
            .bind(machine.to_string())
            .bind(surface.to_string())
            .fetch_optional(&self.db)
            .await?;
        match row {
            None => Ok(None),
            Some(row) => Ok(Some((
                to_usize(row.try_get(0)?)?,
                to_usize(row.try_get(1)?)?,
            ))),
        }
    }

    /// The extra (non-grid) fields of the surface's PUT body, or `None`.
    pub async fn get_surface_extra(
        &self,
        machine: &str,
        surface: &str,
    ) -> Result<Option<serde_json::Value>> {
        let row = sqlx::query("SELECT extra FROM surfaces WHERE machine = $1 AND id = $2")
            .bind(machine.to_string())
            .bind(surface.to_string())
            .fetch_optional(&self.db)
            .await?;
        match row {
            None => Ok(None),
            Some(row) => {
                let text: String = row.try_get(0)?;
                Ok(Some(serde_json::from_str(&text)?))
            }
        }
    }

    /// The machine's surfaces, ordered by id.
    pub async fn list_surfaces(&self, machine: &str) -> Result<Vec<SurfaceSummary>> {
        let rows = sqlx::query(
            "SELECT s.id, s.nu, s.nv, s.tool_radius, \
             (SELECT COUNT(*) FROM measurements m WHERE m.machine = s.machine AND m.surface = s.id) \
             FROM surfaces s WHERE s.machine = $1 ORDER BY s.id",
        )
        .bind(machine.to_string())
        .fetch_all(&self.db)
        .await?;
        rows.into_iter()
            .map(|row| {
                Ok(SurfaceSummary {
                    id: row.try_get(0)?,
                    nu: to_usize(row.try_get(1)?)?,
                    nv: to_usize(row.try_get(2)?)?,
                    tool_radius: row.try_get(3)?,
                    measurements: to_usize(row.try_get(4)?)?,
                })
            })
            .collect()
    }

    /// Number of measurements stored for a surface.
    pub async fn count_measurements(&self, machine: &str, surface: &str) -> Result<usize> {
        let n: i64 = sqlx::query_scalar(
            "SELECT COUNT(*) FROM measurements WHERE machine = $1 AND surface = $2",
        )
        .bind(machine.to_string())
        .bind(surface.to_string())
        .fetch_one(&self.db)
        .await?;
        to_usize(n)
    }

    /// Deletes a surface with its measurements, its documents (keys `surface` and
    /// `surface/...`) and its model files; returns `false` if it did not exist.
    pub async fn delete_surface(&self, machine: &str, surface: &str) -> Result<bool> {
        let mut tx = self.db.begin().await?;
        for sql in [
            "DELETE FROM measurements WHERE machine = $1 AND surface = $2",
            "DELETE FROM model_versions WHERE machine = $1 AND surface = $2",
            "DELETE FROM models WHERE machine = $1 AND surface = $2",
        ] {
            sqlx::query(sql)
                .bind(machine.to_string())
                .bind(surface.to_string())
                .execute(&mut *tx)
                .await?;
        }
        sqlx::query(
            "DELETE FROM docs WHERE machine = $1 AND (key = $2 OR key LIKE $3 ESCAPE '\\')",
        )
        .bind(machine.to_string())
        .bind(surface.to_string())
        .bind(format!("{}/%", surface.replace('_', "\\_")))
        .execute(&mut *tx)
        .await?;
        let n = sqlx::query("DELETE FROM surfaces WHERE machine = $1 AND id = $2")
            .bind(machine.to_string())
            .bind(surface.to_string())
            .execute(&mut *tx)
            .await?
            .rows_affected();
        tx.commit().await?;
        self.surfaces.forget(machine, surface);
        self.models().remove_surface_files(machine, surface).await?;
        Ok(n > 0)
    }
}
