//! Compact binary model format (little-endian), version 1:
//!
//! ```text
//! "TCNN" | u32 version | u32 L | u32 sizes[L] | u8 activation[L-1]
//! | f64 x_mean[sizes0] | f64 x_std[sizes0] | f64 y_mean[out] | f64 y_std[out]
//! | per layer: f64 W (column-major, out x in) | f64 b[out]
//! | u32 metadata length | metadata UTF-8 | u64 FNV-1a of everything before
//! ```
//! The model store adds its own sha256 on top; the FNV checksum makes the format safe on its own.

use nalgebra::{DMatrix, DVector};

use super::activation::Activation;
use super::error::{Error, Result};
use super::mlp::{Dense, Mlp};
use super::scaler::ZScore;

/// Version written by this build; older versions are read, newer ones rejected.
pub const FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 4] = b"TCNN";
/// Guards against absurd allocations when decoding hostile files.
const MAX_LAYER: usize = 1 << 16;

fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

pub(crate) fn encode(mlp: &Mlp, xs: &ZScore, ys: &ZScore, metadata: &str) -> Vec<u8> {
    let sizes = mlp.sizes();
    let mut out = Vec::with_capacity(
        64 + 8 * (mlp.n_parameters() + 2 * (xs.cols() + ys.cols())) + metadata.len(),
    );
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&(sizes.len() as u32).to_le_bytes());
    for s in &sizes {
        out.extend_from_slice(&(*s as u32).to_le_bytes());
    }
    for l in &mlp.layers {
        out.push(l.activation.code());
    }
    let mut put = |v: &[f64]| {
        v.iter()
            .for_each(|x| out.extend_from_slice(&x.to_le_bytes()))
    };
    put(&xs.mean);
    put(&xs.std);
    put(&ys.mean);
    put(&ys.std);
    for l in &mlp.layers {
        put(l.w.as_slice());
        put(l.b.as_slice());
    }
    out.extend_from_slice(&(metadata.len() as u32).to_le_bytes());
    out.extend_from_slice(metadata.as_bytes());
    let h = fnv1a(&out);
    out.extend_from_slice(&h.to_le_bytes());
    out
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.b.len())
            .ok_or_else(|| {
                Error::Format(format!(
                    "truncated: needs {} more bytes at offset {}",
                    n, self.pos
                ))
            })?;
        let s = &self.b[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }
    fn f64s(&mut self, n: usize) -> Result<Vec<f64>> {
        let raw = self.take(
            n.checked_mul(8)
                .ok_or_else(|| Error::Format("size overflow".into()))?,
        )?;
        let v: Vec<f64> = raw
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        if v.iter().any(|x| !x.is_finite()) {
            return Err(Error::Format("non-finite parameter".into()));
        }
        Ok(v)
    }
}

pub(crate) fn decode(bytes: &[u8]) -> Result<(Mlp, ZScore, ZScore, String)> {
    if bytes.len() < 4 + 4 + 8 || &bytes[..4] != MAGIC {
        return Err(Error::Format(
            "not a truecut network file (bad magic)".into(),
        ));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 8);
    if fnv1a(body) != u64::from_le_bytes(tail.try_into().expect("8 bytes")) {
        return Err(Error::Format(
            "checksum mismatch: the file is corrupt".into(),
        ));
    }
    let mut r = Reader { b: body, pos: 4 };
    let version = r.u32()?;
    if version == 0 || version > FORMAT_VERSION {
        return Err(Error::Format(format!(
            "version {version} is not supported (this build reads 1..={FORMAT_VERSION})"
        )));
    }
    let nl = r.u32()? as usize;
    if !(2..=64).contains(&nl) {
        return Err(Error::Format(format!("{nl} layer sizes")));
    }
    let sizes = (0..nl)
        .map(|_| r.u32().map(|s| s as usize))
        .collect::<Result<Vec<_>>>()?;
    if sizes.iter().any(|&s| s == 0 || s > MAX_LAYER) {
        return Err(Error::Format(format!("bad layer sizes {sizes:?}")));
    }
    let acts = r
        .take(nl - 1)?
        .iter()
        .map(|c| {
            Activation::from_code(*c)
                .ok_or_else(|| Error::Format(format!("unknown activation code {c}")))
        })
        .collect::<Result<Vec<_>>>()?;
    let (ni, no) = (sizes[0], sizes[nl - 1]);
    let xs = ZScore {
        mean: r.f64s(ni)?,
        std: r.f64s(ni)?,
    };
    let ys = ZScore {
        mean: r.f64s(no)?,
        std: r.f64s(no)?,
    };
    if xs.std.iter().chain(&ys.std).any(|s| *s <= 0.0) {
        return Err(Error::Format("scaler standard deviation <= 0".into()));
    }
    let mut layers = Vec::with_capacity(nl - 1);
    for (i, act) in acts.into_iter().enumerate() {
        let (din, dout) = (sizes[i], sizes[i + 1]);
        let w = DMatrix::from_vec(dout, din, r.f64s(din * dout)?);
        let b = DVector::from_vec(r.f64s(dout)?);
        layers.push(Dense {
            w,
            b,
            activation: act,
        });
    }
    let ml = r.u32()? as usize;
    let metadata = String::from_utf8(r.take(ml)?.to_vec())
        .map_err(|_| Error::Format("metadata is not UTF-8".into()))?;
    if r.pos != body.len() {
        return Err(Error::Format(format!(
            "{} trailing bytes",
            body.len() - r.pos
        )));
    }
    Ok((Mlp { layers }, xs, ys, metadata))
}

#[cfg(test)]
mod tests;
