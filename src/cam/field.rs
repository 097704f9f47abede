//! The error field a program is compensated against: anything that predicts the
//! positioning error e(p) (mm) of the tool tip at a machine point p (mm). The machine's
//! volumetric map is one ([`VolumetricMap`], Xiang et al. 2019; Wang, Dai & Hong); tests
//! use closed-form fields.

use crate::volumetric::VolumetricMap;

/// A positioning-error field over the machine's working volume.
pub trait ErrorField {
    /// Predicted error e(p) (mm) of the tool tip commanded to machine point `p` (mm): the
    /// tool arrives at p + e(p). Outside the field's box, the error of the nearest point
    /// of the box (as the map's predict route answers).
    fn error_at(&self, p: [f64; 3]) -> [f64; 3];

    /// Whether `p` (mm) lies inside the box the field was measured on.
    fn contains(&self, p: [f64; 3]) -> bool;
}

impl ErrorField for VolumetricMap {
    fn error_at(&self, p: [f64; 3]) -> [f64; 3] {
        VolumetricMap::error_at(self, p)
    }

    fn contains(&self, p: [f64; 3]) -> bool {
        self.bounds.contains(p)
    }
}

/// Two error fields added (a volumetric map and the geometric effects); a point is inside
/// where it is inside both.
pub struct SumField<'a>(pub &'a dyn ErrorField, pub &'a dyn ErrorField);

impl ErrorField for SumField<'_> {
    fn error_at(&self, p: [f64; 3]) -> [f64; 3] {
        let (a, b) = (self.0.error_at(p), self.1.error_at(p));
        [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
    }

    fn contains(&self, p: [f64; 3]) -> bool {
        self.0.contains(p) && self.1.contains(p)
    }
}
