//! One pass of the VMD iteration over the spectrum (the "sweep"): every mode's Wiener update
//! of every bin, with the per-mode sums that the centre frequencies and the stopping rule
//! need. A portable kernel (f64 arithmetic whatever the storage) and one AVX2+FMA kernel
//! written once over the lane type (`super::lanes::Lanes`: 4 f64 or 8 f32 per register).
//!
//! Written here (no crate): the loop is specific to VMD's coefficient form (see
//! `super::admm`); it is the hot loop of every decomposition, bound by memory and division
//! throughput, hence the blocking (a block of bins stays in L1 while all K modes update it),
//! the f32 storage for long spectra and the explicit SIMD.

#[cfg(target_arch = "x86_64")]
use super::lanes::Lanes;

/// Bins per cache block of the sweep.
pub(super) const BLOCK: usize = 512;

/// Per-mode sums of one sweep: Σν|û_k|², Σ|û_k|², Σ|Δû_k|².
#[derive(Clone)]
pub(super) struct Sums {
    pub(super) num: Vec<f64>,
    pub(super) den: Vec<f64>,
    pub(super) dif: Vec<f64>,
}

impl Sums {
    pub(super) fn new(k: usize) -> Self {
        Self {
            num: vec![0.0; k],
            den: vec![0.0; k],
            dif: vec![0.0; k],
        }
    }

    /// Adds `o` mode by mode.
    pub(super) fn add(&mut self, o: &Sums) {
        for i in 0..self.num.len() {
            self.num[i] += o.num[i];
            self.den[i] += o.den[i];
            self.dif[i] += o.dif[i];
        }
    }
}

/// Number type of the iteration: f64, or f32 for long spectra.
pub(super) trait Real: Copy + Default + Send + Sync {
    fn to64(self) -> f64;
    fn from64(v: f64) -> Self;
}

impl Real for f64 {
    #[inline(always)]
    fn to64(self) -> f64 {
        self
    }
    #[inline(always)]
    fn from64(v: f64) -> Self {
        v
    }
}

impl Real for f32 {
    #[inline(always)]
    fn to64(self) -> f64 {
        self as f64
    }
    #[inline(always)]
    fn from64(v: f64) -> Self {
        v as f32
    }
}

/// A sweep over one contiguous bin range: coefficients c_k, |f̂|², target (1 − l/2, `None`
/// = 1), bin frequencies, ω, α; adds to the sums.
pub(super) type Kernel<C> = fn(&mut [&mut [C]], &[C], Option<&[C]>, &[C], &[f64], f64, &mut Sums);

/// The VMD sweep's kernel on this CPU: `avx2-fma` (x86-64 with AVX2 and FMA: the
/// intrinsics below, IEEE operations only, so the same bits on any maker's CPU for a given
/// build) or `portable` (plain Rust, whose last bits differ from the other's: no fused
/// multiply-add). A decomposition names it, so two answers whose bits differ can tell why.
pub fn kernel() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            return "avx2-fma";
        }
    }
    "portable"
}

/// The f64 kernel: AVX2+FMA (4 bins per instruction) when available, else portable.
pub(super) fn kernel_f64(
    c: &mut [&mut [f64]],
    power: &[f64],
    target: Option<&[f64]>,
    freqs: &[f64],
    omega: &[f64],
    alpha: f64,
    sums: &mut Sums,
) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU supports the features the function is compiled for.
            unsafe { sweep_avx2(c, power, target, freqs, omega, alpha, sums) };
            return;
        }
    }
    sweep_generic(c, power, target, freqs, omega, alpha, sums)
}

/// The f32 kernel: AVX2+FMA (8 bins per instruction) when available, else portable (f32
/// storage, f64 arithmetic).
pub(super) fn kernel_f32(
    c: &mut [&mut [f32]],
    power: &[f32],
    target: Option<&[f32]>,
    freqs: &[f32],
    omega: &[f64],
    alpha: f64,
    sums: &mut Sums,
) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU supports the features the function is compiled for.
            unsafe { sweep_avx2(c, power, target, freqs, omega, alpha, sums) };
            return;
        }
    }
    sweep_generic(c, power, target, freqs, omega, alpha, sums)
}

/// Running total Σ_k c_k over bins start..start+len into `tot`.
#[inline(always)]
fn block_total<C: Real>(c: &[&mut [C]], start: usize, tot: &mut [f64]) {
    let len = tot.len();
    tot.fill(0.0);
    for ck in c {
        for (t, v) in tot.iter_mut().zip(&ck[start..start + len]) {
            *t += v.to64();
        }
    }
}

/// The sweep in AVX2+FMA intrinsics, `C::WIDTH` bins per instruction: storage, running
/// total and arithmetic in `C` (f64, or f32 for long spectra), the per-mode sums of each
/// block reduced to f64 and accumulated there. Same arithmetic as [`sweep_generic`] up to
/// FMA rounding (f64) or f32 rounding (f32); the bins past the last full register go
/// through [`update_bin`] in f64.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn sweep_avx2<C: Lanes>(
    c: &mut [&mut [C]],
    power: &[C],
    target: Option<&[C]>,
    freqs: &[C],
    omega: &[f64],
    alpha: f64,
    sums: &mut Sums,
) {
    let m = power.len();
    let mut tot = [C::default(); BLOCK];
    let ones = [C::from64(1.0); BLOCK];
    // SAFETY: this function is compiled for and only called with AVX2 and FMA.
    let (one, va) = unsafe { (C::splat(C::from64(1.0)), C::splat(C::from64(alpha))) };
    let mut start = 0;
    while start < m {
        let len = BLOCK.min(m - start);
        let end = start + len;
        // Running total Σ_k c_k of the block, in C (f64 for f64 storage, as block_total);
        // started from c_0 (0 + c_0 = c_0 exactly) instead of zero-filled and added to.
        tot[..len].copy_from_slice(&c[0][start..end]);
        for ck in c.iter().skip(1) {
            for (t, &v) in tot[..len].iter_mut().zip(&ck[start..end]) {
                *t = *t + v;
            }
        }
        let tgt = match target {
            Some(t) => &t[start..end],
            None => &ones[..len],
        };
        let full = len / C::WIDTH * C::WIDTH;
        for (k, &om) in omega.iter().enumerate() {
            let ck = c[k][start..end].as_mut_ptr();
            let tp = tot.as_mut_ptr();
            let gp = tgt.as_ptr();
            let pp = power[start..end].as_ptr();
            let nu = freqs[start..end].as_ptr();
            let mut i = 0;
            // SAFETY: AVX2 and FMA are present (see above); i + WIDTH <= full <= len, and
            // every pointer addresses at least len values.
            let (vnum, vden, vdif) = unsafe {
                let vom = C::splat(C::from64(om));
                let mut vnum = C::zero();
                let mut vden = C::zero();
                let mut vdif = C::zero();
                while i < full {
                    let vnu = C::load(nu.add(i));
                    let d = C::sub(vnu, vom);
                    let w = C::recip(C::fmadd(C::mul(va, d), d, one));
                    let vc = C::load(ck.add(i));
                    let o = C::sub(C::load(tp.add(i)), vc);
                    let nc = C::mul(C::sub(C::load(gp.add(i)), o), w);
                    let dc = C::sub(nc, vc);
                    let vp = C::load(pp.add(i));
                    vdif = C::fmadd(C::mul(dc, dc), vp, vdif);
                    let e = C::mul(C::mul(nc, nc), vp);
                    vnum = C::fmadd(vnu, e, vnum);
                    vden = <C as Lanes>::add(vden, e);
                    C::store(ck.add(i), nc);
                    C::store(tp.add(i), <C as Lanes>::add(o, nc));
                    i += C::WIDTH;
                }
                (C::hsum(vnum), C::hsum(vden), C::hsum(vdif))
            };
            sums.num[k] += vnum;
            sums.den[k] += vden;
            sums.dif[k] += vdif;
            for i in full..len {
                let g = start + i;
                let mut t = tot[i].to64();
                update_bin(
                    &mut c[k][g],
                    &mut t,
                    tgt[i].to64(),
                    power[g].to64(),
                    freqs[g].to64(),
                    om,
                    alpha,
                    sums,
                    k,
                );
                tot[i] = C::from64(t);
            }
        }
        start = end;
    }
}

/// One bin's update of a mode: c ← (target − (tot − c))·W(ν) with W(ν) = 1/(1 + α(ν − ω)²);
/// tot and the sums (slot `k`) follow.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn update_bin<C: Real>(
    ck: &mut C,
    tot: &mut f64,
    target: f64,
    power: f64,
    nu: f64,
    om: f64,
    alpha: f64,
    sums: &mut Sums,
    k: usize,
) {
    let old = ck.to64();
    let d = nu - om;
    let w = 1.0 / (1.0 + alpha * d * d);
    let o = *tot - old;
    let nc = (target - o) * w;
    sums.dif[k] += (nc - old) * (nc - old) * power;
    let e = nc * nc * power;
    sums.num[k] += nu * e;
    sums.den[k] += e;
    *ck = C::from64(nc);
    *tot = o + nc;
}

/// The portable sweep (no AVX2): per block of bins, the running total Σ_k c_k, then each
/// mode's Wiener update with the sums in 4 interleaved partial sums (the order of the AVX2
/// f64 kernel); f64 arithmetic whatever the storage.
pub(super) fn sweep_generic<C: Real>(
    c: &mut [&mut [C]],
    power: &[C],
    target: Option<&[C]>,
    freqs: &[C],
    omega: &[f64],
    alpha: f64,
    sums: &mut Sums,
) {
    const L: usize = 4;
    let m = power.len();
    let mut tot = [0.0; BLOCK];
    let mut start = 0;
    while start < m {
        let len = BLOCK.min(m - start);
        let end = start + len;
        block_total(c, start, &mut tot[..len]);
        for (k, &om) in omega.iter().enumerate() {
            let mut lanes = Sums::new(L);
            for (i, t) in tot[..len].iter_mut().enumerate() {
                let g = start + i;
                let tg = target.map_or(1.0, |t| t[g].to64());
                update_bin(
                    &mut c[k][g],
                    t,
                    tg,
                    power[g].to64(),
                    freqs[g].to64(),
                    om,
                    alpha,
                    &mut lanes,
                    i % L,
                );
            }
            sums.num[k] += lanes.num.iter().sum::<f64>();
            sums.den[k] += lanes.den.iter().sum::<f64>();
            sums.dif[k] += lanes.dif.iter().sum::<f64>();
        }
        start = end;
    }
}
