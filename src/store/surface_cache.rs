//! The nominal surfaces that uploads pair their points with, shared between requests.
//!
//! A probe upload of points is paired with its surface's nominal points and normals (48 bytes
//! a grid point). Loaded per request, eight concurrent uploads of a 3.9-million-point surface
//! held eight copies (1.4 GiB) beside their own arrays. Here one copy per surface is kept
//! behind an `Arc`, bounded in bytes (least recently used first out), and checked against the
//! database on every use: the row's `(updated_at, nu, nv)` must still be the cached one, so a
//! surface replaced or deleted through another instance is read afresh. A replacement
//! through this instance drops the entry at once ([`SurfaceCache::forget`]), which also covers
//! two replacements within the same millisecond.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use super::surfaces::Surface;

/// What a cached surface was read as: its row's `updated_at` (Unix ms), `nu` and `nv`.
pub(crate) type Stamp = (i64, usize, usize);

/// Most bytes of nominal arrays kept (points and normals, 48 bytes a grid point): 256 MiB,
/// e.g. one 5.6-million-point surface or many small ones.
pub(crate) const CACHE_BYTES: usize = 256 << 20;

#[derive(Debug, Default)]
struct Entries {
    /// (machine, surface) → (stamp, surface, last use).
    map: HashMap<(String, String), (Stamp, Arc<Surface>, u64)>,
    /// Use counter (the LRU clock).
    clock: u64,
}

/// Surfaces shared between requests (see the module docs). Cheap to clone.
#[derive(Clone, Debug)]
pub(crate) struct SurfaceCache {
    entries: Arc<Mutex<Entries>>,
    /// Most bytes kept ([`CACHE_BYTES`] by default).
    limit: usize,
    /// Held while a missing surface is read, so concurrent requests for it read it once.
    pub(crate) loading: Arc<tokio::sync::Mutex<()>>,
}

/// Bytes of a surface's arrays.
fn bytes_of(s: &Surface) -> usize {
    (s.points.len() + s.normals.len()) * 24
}

impl Default for SurfaceCache {
    fn default() -> Self {
        Self::with_limit(CACHE_BYTES)
    }
}

impl SurfaceCache {
    /// An empty cache keeping at most `limit` bytes of arrays.
    pub(crate) fn with_limit(limit: usize) -> SurfaceCache {
        SurfaceCache {
            entries: Arc::default(),
            limit,
            loading: Arc::default(),
        }
    }

    /// The cached surface if it was read with `stamp`; a stale entry is dropped.
    pub(crate) fn get(&self, machine: &str, surface: &str, stamp: Stamp) -> Option<Arc<Surface>> {
        let mut e = self.entries.lock().unwrap_or_else(|p| p.into_inner());
        e.clock += 1;
        let clock = e.clock;
        let key = (machine.to_string(), surface.to_string());
        match e.map.get_mut(&key) {
            Some((s, surf, used)) if *s == stamp => {
                *used = clock;
                Some(surf.clone())
            }
            Some(_) => {
                e.map.remove(&key);
                None
            }
            None => None,
        }
    }

    /// Keeps `surf` (read with `stamp`) unless it alone is over the limit; the least
    /// recently used entries leave until the total fits.
    pub(crate) fn put(&self, stamp: Stamp, surf: Arc<Surface>) {
        let size = bytes_of(&surf);
        if size > self.limit {
            return;
        }
        let mut e = self.entries.lock().unwrap_or_else(|p| p.into_inner());
        e.clock += 1;
        let clock = e.clock;
        let key = (surf.machine.clone(), surf.surface.clone());
        e.map.insert(key, (stamp, surf, clock));
        loop {
            let total: usize = e.map.values().map(|(_, s, _)| bytes_of(s)).sum();
            if total <= self.limit {
                break;
            }
            let oldest = e
                .map
                .iter()
                .min_by_key(|(_, (_, _, used))| *used)
                .map(|(k, _)| k.clone());
            match oldest {
                Some(k) => e.map.remove(&k),
                None => break,
            };
        }
    }

    /// Drops the surface's entry (it was replaced or deleted through this instance).
    pub(crate) fn forget(&self, machine: &str, surface: &str) {
        let mut e = self.entries.lock().unwrap_or_else(|p| p.into_inner());
        e.map.remove(&(machine.to_string(), surface.to_string()));
    }
}

#[cfg(test)]
mod tests;
