//! Least-squares circles in a plane: the algebraic fit (Kåsa 1976), used only as the start,
//! and the orthogonal (geometric) fit that ISO 230-4 means by "the least-squares circle".
//!
//! The algebraic fit minimises Σ (|p_i − c|² − r²)², which weights each point by about
//! (2r)² and biases the centre and radius when the points cover part of the circle or carry
//! noise (Chernov 2010 ch. 5); ISO 230-4:2005 §3.2 defines the least-squares circle by the
//! sum of squared radial (orthogonal) distances, Σ (|p_i − c| − r)², which is what
//! [`fit_circle`] minimises, by Levenberg–Marquardt from the algebraic start. Written here:
//! the two small fits are simpler than any dependency.

use nalgebra::{Matrix3, Vector3};

use super::error::Error;

/// A circle in the plane, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circle {
    /// Centre [x, y], mm.
    pub centre: [f64; 2],
    /// Radius, mm.
    pub radius: f64,
}

impl Circle {
    /// The sum of squared orthogonal distances Σ (|p_i − c| − r)² of `points`, mm².
    pub fn orthogonal_cost(&self, points: &[[f64; 2]]) -> f64 {
        points
            .iter()
            .map(|p| {
                let d = (p[0] - self.centre[0]).hypot(p[1] - self.centre[1]) - self.radius;
                d * d
            })
            .sum()
    }
}

fn check(field: &'static str, points: &[[f64; 2]]) -> Result<(), Error> {
    if let Some(index) = points
        .iter()
        .position(|p| !(p[0].is_finite() && p[1].is_finite()))
    {
        return Err(Error::NonFinite {
            field: field.to_string(),
            index,
        });
    }
    if points.len() < 3 {
        return Err(Error::Degenerate {
            field,
            reason: format!("{} points; a circle needs at least 3", points.len()),
        });
    }
    Ok(())
}

/// The algebraic least-squares circle (Kåsa 1976): minimises Σ (x² + y² + D x + E y + F)²
/// over D, E, F (a linear problem), centre (−D/2, −E/2), radius sqrt(|c|² − F). Points are
/// centred on their mean first for conditioning. Errors: fewer than 3 points, non-finite
/// coordinates, collinear points.
///
/// Reference: Kåsa 1976; Chernov 2010 ch. 5 (its bias).
///
/// Known bad cases: biased (radius too small, centre pulled towards the arc) on short arcs
/// and noisy points; use [`fit_circle`] for the ISO figures.
pub fn fit_circle_kasa(field: &'static str, points: &[[f64; 2]]) -> Result<Circle, Error> {
    check(field, points)?;
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p[0]).sum::<f64>() / n;
    let my = points.iter().map(|p| p[1]).sum::<f64>() / n;
    let mut ata = Matrix3::zeros();
    let mut atb = Vector3::zeros();
    for p in points {
        let (x, y) = (p[0] - mx, p[1] - my);
        let row = Vector3::new(x, y, 1.0);
        ata += row * row.transpose();
        atb -= row * (x * x + y * y);
    }
    let sol = ata.lu().solve(&atb).ok_or_else(|| Error::Degenerate {
        field,
        reason: "the points are coincident or collinear".into(),
    })?;
    let (cx, cy) = (-0.5 * sol[0], -0.5 * sol[1]);
    let r2 = cx * cx + cy * cy - sol[2];
    if !(r2.is_finite() && r2 > 0.0) {
        return Err(Error::Degenerate {
            field,
            reason: "the points are collinear".into(),
        });
    }
    Ok(Circle {
        centre: [cx + mx, cy + my],
        radius: r2.sqrt(),
    })
}

/// The orthogonal least-squares circle: minimises Σ (|p_i − c| − r)² over the centre c and
/// radius r (mm) by Levenberg–Marquardt on (c_x, c_y, r), started from [`fit_circle_kasa`],
/// until the step is below 1e-13 of the radius. At the minimum r = mean |p_i − c| and
/// Σ (|p_i − c| − r) (p_i − c)/|p_i − c| = 0.
///
/// Reference: ISO 230-4:2005 §3.2 (least-squares circle); Chernov 2010 ch. 4 (geometric fit,
/// Levenberg–Marquardt).
///
/// Known bad cases: a short arc with large noise has a flat cost along the line through
/// the arc's centre; the fit then stops where the step is small, not at a unique centre.
pub fn fit_circle(field: &'static str, points: &[[f64; 2]]) -> Result<Circle, Error> {
    let start = fit_circle_kasa(field, points)?;
    let mut p = Vector3::new(start.centre[0], start.centre[1], start.radius);
    let residuals = |p: &Vector3<f64>| -> (Matrix3<f64>, Vector3<f64>, f64) {
        let mut jtj = Matrix3::zeros();
        let mut jtr = Vector3::zeros();
        let mut cost = 0.0;
        for q in points {
            let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
            let rho = dx.hypot(dy).max(f64::MIN_POSITIVE);
            let r = rho - p[2];
            let j = Vector3::new(-dx / rho, -dy / rho, -1.0);
            jtj += j * j.transpose();
            jtr += j * r;
            cost += r * r;
        }
        (jtj, jtr, cost)
    };
    let mut lambda = 1e-6;
    let (mut jtj, mut jtr, mut cost) = residuals(&p);
    for _ in 0..200 {
        let mut a = jtj;
        for k in 0..3 {
            a[(k, k)] *= 1.0 + lambda;
        }
        let Some(step) = a.lu().solve(&(-jtr)) else {
            break;
        };
        let trial = p + step;
        let (tj, tr, tc) = residuals(&trial);
        if tc <= cost {
            p = trial;
            (jtj, jtr, cost) = (tj, tr, tc);
            lambda = (lambda * 0.1).max(1e-12);
            if step.norm() <= 1e-13 * p[2].abs().max(1.0) {
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e12 {
                break;
            }
        }
    }
    if !(p[2].is_finite() && p[2] > 0.0) {
        return Err(Error::Degenerate {
            field,
            reason: "the fit did not converge to a finite radius".into(),
        });
    }
    Ok(Circle {
        centre: [p[0], p[1]],
        radius: p[2],
    })
}
