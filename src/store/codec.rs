//! Little-endian `f64` BLOB encoding of number arrays (the storage layout of grids and
//! deviations; 8 bytes a value, no per-row overhead).

use anyhow::{Result, bail};

/// Encodes `xs` as consecutive little-endian IEEE-754 doubles.
pub fn encode_f64s(xs: &[f64]) -> Vec<u8> {
    let mut out = Vec::with_capacity(xs.len() * 8);
    for x in xs {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out
}

/// Decodes a BLOB written by [`encode_f64s`]; errors if its length is not a multiple of 8.
pub fn decode_f64s(bytes: &[u8]) -> Result<Vec<f64>> {
    if bytes.len() % 8 != 0 {
        bail!(
            "stored array has {} bytes, not a multiple of 8",
            bytes.len()
        );
    }
    Ok(bytes
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("chunk of 8")))
        .collect())
}

/// Encodes points as `x0 y0 z0 x1 ...` little-endian doubles.
pub fn encode_points(pts: &[[f64; 3]]) -> Vec<u8> {
    let mut out = Vec::with_capacity(pts.len() * 24);
    for p in pts {
        for c in p {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    out
}

/// Decodes a BLOB written by [`encode_points`]; errors if its length is not a multiple of 24.
pub fn decode_points(bytes: &[u8]) -> Result<Vec<[f64; 3]>> {
    if bytes.len() % 24 != 0 {
        bail!(
            "stored point array has {} bytes, not a multiple of 24",
            bytes.len()
        );
    }
    // Straight from the bytes (no flat copy in between: a surface's arrays are large).
    let f = |b: &[u8]| f64::from_le_bytes(b.try_into().expect("8 bytes"));
    Ok(bytes
        .chunks_exact(24)
        .map(|c| [f(&c[0..8]), f(&c[8..16]), f(&c[16..24])])
        .collect())
}

#[cfg(test)]
mod tests;
