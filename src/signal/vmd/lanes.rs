//! AVX2 registers as a trait over the lane type: [`Lanes`] for f64 (`__m256d`, 4 lanes)
//! and f32 (`__m256`, 8 lanes), so that one AVX2 sweep body (`super::sweep`) serves both
//! precisions instead of two copies of the same shape with different intrinsics.
//!
//! Written here (no crate): `std::simd` is unstable, and the portable SIMD crates (wide,
//! pulp) would add a dependency for ten one-instruction wrappers. Each method is
//! `#[inline(always)]`, so inside the `avx2,fma` sweep it compiles to the intrinsic itself;
//! checked: the sweep's results were bit-identical to the two hand-written kernels it
//! replaced, at the same speed. Since then the f32 lanes take 1/a from the hardware
//! estimate plus a Newton step ([`Lanes::recip`]) instead of a division.

use super::sweep::Real;
use std::arch::x86_64::*;

/// One AVX2 register of lanes of `Self` and the operations the sweep needs, so that one
/// `super::sweep::sweep_avx2` body serves f64 (`__m256d`, 4 lanes) and f32 (`__m256`, 8
/// lanes). The methods are `#[inline(always)]` wrappers of one intrinsic each: inlined into
/// the `avx2,fma` caller they compile to the same instructions as the intrinsics written
/// there.
///
/// Safety (every method): the CPU supports AVX2 and FMA; `load` and `store` also need
/// [`Lanes::WIDTH`] values readable (writable) at the pointer.
pub(super) trait Lanes: Real + std::ops::Add<Output = Self> {
    /// The register type.
    type V: Copy;
    /// Values per register.
    const WIDTH: usize;
    /// Every lane `v`.
    unsafe fn splat(v: Self) -> Self::V;
    /// Every lane 0.
    unsafe fn zero() -> Self::V;
    /// `WIDTH` values from `p` (unaligned).
    unsafe fn load(p: *const Self) -> Self::V;
    /// `WIDTH` values to `p` (unaligned).
    unsafe fn store(p: *mut Self, v: Self::V);
    /// a + b.
    unsafe fn add(a: Self::V, b: Self::V) -> Self::V;
    /// a − b.
    unsafe fn sub(a: Self::V, b: Self::V) -> Self::V;
    /// a · b.
    unsafe fn mul(a: Self::V, b: Self::V) -> Self::V;
    /// a · b + c with one rounding.
    unsafe fn fmadd(a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// Σ of the lanes in f64, lane 0 first.
    unsafe fn hsum(v: Self::V) -> f64;
    /// 1 / a for a ≥ 1 (the sweep's Wiener denominators): the IEEE division, correctly
    /// rounded, in both widths. Not the f32 hardware estimate (`rcp`) refined by a Newton
    /// step: its 12-bit table is the vendor's own (Intel's and AMD's differ), so the answer's
    /// bits would depend on the CPU's maker (issue 41 item 9).
    unsafe fn recip(a: Self::V) -> Self::V;
}

/// Implements [`Lanes`] for one lane type from its intrinsics.
macro_rules! lanes {
    ($t:ty, $v:ty, $width:literal, $set1:ident, $setzero:ident, $loadu:ident, $storeu:ident,
     $add:ident, $sub:ident, $mul:ident, $fmadd:ident, $recip:expr) => {
        impl Lanes for $t {
            type V = $v;
            const WIDTH: usize = $width;
            #[inline(always)]
            unsafe fn splat(v: Self) -> $v {
                // SAFETY: the caller guarantees AVX (part of AVX2).
                unsafe { $set1(v) }
            }
            #[inline(always)]
            unsafe fn zero() -> $v {
                // SAFETY: the caller guarantees AVX (part of AVX2).
                unsafe { $setzero() }
            }
            #[inline(always)]
            unsafe fn load(p: *const Self) -> $v {
                // SAFETY: the caller guarantees AVX and WIDTH readable values at p.
                unsafe { $loadu(p) }
            }
            #[inline(always)]
            unsafe fn store(p: *mut Self, v: $v) {
                // SAFETY: the caller guarantees AVX and WIDTH writable values at p.
                unsafe { $storeu(p, v) }
            }
            #[inline(always)]
            unsafe fn add(a: $v, b: $v) -> $v {
                // SAFETY: the caller guarantees AVX (part of AVX2).
                unsafe { $add(a, b) }
            }
            #[inline(always)]
            unsafe fn sub(a: $v, b: $v) -> $v {
                // SAFETY: the caller guarantees AVX (part of AVX2).
                unsafe { $sub(a, b) }
            }
            #[inline(always)]
            unsafe fn mul(a: $v, b: $v) -> $v {
                // SAFETY: the caller guarantees AVX (part of AVX2).
                unsafe { $mul(a, b) }
            }
            #[inline(always)]
            unsafe fn fmadd(a: $v, b: $v, c: $v) -> $v {
                // SAFETY: the caller guarantees FMA.
                unsafe { $fmadd(a, b, c) }
            }
            #[inline(always)]
            unsafe fn recip(a: $v) -> $v {
                // SAFETY: the caller guarantees AVX and FMA.
                unsafe { $recip(a) }
            }
            #[inline(always)]
            unsafe fn hsum(v: $v) -> f64 {
                let mut lanes = [<$t>::default(); $width];
                // SAFETY: the caller guarantees AVX; lanes holds WIDTH values.
                unsafe { $storeu(lanes.as_mut_ptr(), v) };
                lanes.iter().map(|&x| x.to64()).sum::<f64>()
            }
        }
    };
}

lanes!(
    f64,
    __m256d,
    4,
    _mm256_set1_pd,
    _mm256_setzero_pd,
    _mm256_loadu_pd,
    _mm256_storeu_pd,
    _mm256_add_pd,
    _mm256_sub_pd,
    _mm256_mul_pd,
    _mm256_fmadd_pd,
    recip_f64
);

lanes!(
    f32,
    __m256,
    8,
    _mm256_set1_ps,
    _mm256_setzero_ps,
    _mm256_loadu_ps,
    _mm256_storeu_ps,
    _mm256_add_ps,
    _mm256_sub_ps,
    _mm256_mul_ps,
    _mm256_fmadd_ps,
    recip_f32
);

/// 1 / a by division (f64 lanes: no fast estimate in AVX2).
///
/// Safety: the CPU supports AVX.
#[inline(always)]
unsafe fn recip_f64(a: __m256d) -> __m256d {
    // SAFETY: the caller guarantees AVX.
    unsafe { _mm256_div_pd(_mm256_set1_pd(1.0), a) }
}

/// 1 / a by division (see [`Lanes::recip`]: the same bits on every x86-64 maker).
///
/// Safety: the CPU supports AVX.
#[inline(always)]
unsafe fn recip_f32(a: __m256) -> __m256 {
    // SAFETY: the caller guarantees AVX.
    unsafe { _mm256_div_ps(_mm256_set1_ps(1.0), a) }
}
