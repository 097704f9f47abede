//! Normal-offset compensation of a probed grid (Chen et al. 2024 §4.3; openapi.yaml
//! `GET /v1/machines/{machine}/surfaces/{surface}/compensation`).

use super::error::Error;

/// Checks one value per grid point, all finite.
pub(crate) fn check_values(field: &'static str, v: &[f64], expected: usize) -> Result<(), Error> {
    if v.len() != expected {
        return Err(Error::LengthMismatch {
            field,
            got: v.len(),
            expected,
        });
    }
    match v.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(Error::NonFinite { field, index }),
        None => Ok(()),
    }
}

/// Checks one point per grid point, all coordinates finite.
pub(crate) fn check_vectors(
    field: &'static str,
    v: &[[f64; 3]],
    expected: usize,
) -> Result<(), Error> {
    if v.len() != expected {
        return Err(Error::LengthMismatch {
            field,
            got: v.len(),
            expected,
        });
    }
    match v.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        Some(index) => Err(Error::NonFinite { field, index }),
        None => Ok(()),
    }
}

/// Compensated points p'_k = p_k − offset_k · n_k (mm): the nominal point moved against its
/// outward normal by the systematic error, so that a machine that leaves `offset` of material
/// there again lands on the nominal surface.
///
/// Reference: Chen et al. 2024 §2 and §4.3 ("compensated along the opposite direction of the outer
/// normal vector"); openapi.yaml `GET /v1/machines/{machine}/surfaces/{surface}/compensation`.
/// Units: mm. Errors: mismatched lengths, non-finite values, zero normals. Known bad cases: offsets
/// comparable to the local radius of curvature (the moved points would cross; not checked,
/// machining errors are µm).
pub fn compensate_points(
    points: &[[f64; 3]],
    normals: &[[f64; 3]],
    offsets: &[f64],
) -> Result<Vec<[f64; 3]>, Error> {
    let n = points.len();
    check_vectors("points", points, n)?;
    check_vectors("normals", normals, n)?;
    check_values("offsets", offsets, n)?;
    if let Some(index) = normals
        .iter()
        .position(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() < 1e-12)
    {
        return Err(Error::ZeroNormal { index });
    }
    Ok(points
        .iter()
        .zip(normals)
        .zip(offsets)
        .map(|((p, nv), o)| [p[0] - o * nv[0], p[1] - o * nv[1], p[2] - o * nv[2]])
        .collect())
}

#[cfg(test)]
mod tests;
