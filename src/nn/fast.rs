//! Inference kernel: blocks of samples in feature-major layout so the inner loop runs over
//! samples (contiguous, SIMD-friendly), compiled twice — portable, and with AVX2+FMA picked at
//! run time. gemm libraries pack their operands per call, which costs more than the arithmetic
//! for layers this small (tens of neurons).

use super::activation::Activation;
use super::mlp::Mlp;

/// Samples per block: 32 f64 accumulators = 8 AVX2 registers.
const B: usize = 32;

struct PackedLayer {
    /// Row-major `out x in`.
    w: Vec<f64>,
    b: Vec<f64>,
    din: usize,
    dout: usize,
    act: Activation,
}

/// A network's weights laid out for [`Packed::forward`].
pub(crate) struct Packed {
    layers: Vec<PackedLayer>,
    widest: usize,
}

impl Packed {
    pub(crate) fn new(mlp: &Mlp) -> Self {
        let layers: Vec<PackedLayer> = mlp
            .layers
            .iter()
            .map(|l| {
                let (dout, din) = l.w.shape();
                let w = (0..dout)
                    .flat_map(|r| (0..din).map(move |c| (r, c)))
                    .map(|(r, c)| l.w[(r, c)])
                    .collect();
                PackedLayer {
                    w,
                    b: l.b.as_slice().to_vec(),
                    din,
                    dout,
                    act: l.activation,
                }
            })
            .collect();
        let widest = layers.iter().map(|l| l.din.max(l.dout)).max().unwrap_or(1);
        Packed { layers, widest }
    }

    /// Forward pass of row-major `x` (`n x in`) into row-major `out` (`n x out`); shapes checked
    /// by the caller.
    pub(crate) fn forward(&self, x: &[f64], out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU supports AVX2 and FMA (checked just above).
                unsafe { forward_avx2(self, x, out) };
                return;
            }
        }
        forward_generic(self, x, out);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn forward_avx2(p: &Packed, x: &[f64], out: &mut [f64]) {
    forward_generic(p, x, out)
}

#[inline(always)]
fn forward_generic(p: &Packed, x: &[f64], out: &mut [f64]) {
    let ni = p.layers[0].din;
    let no = p.layers[p.layers.len() - 1].dout;
    let n = x.len() / ni;
    let mut a = vec![0.0; p.widest * B];
    let mut c = vec![0.0; p.widest * B];
    let mut start = 0;
    while start < n {
        let rows = (n - start).min(B);
        // Transpose the block into feature-major a[i * B + s]; the padding rows stay 0.
        for s in 0..B {
            if s < rows {
                let row = &x[(start + s) * ni..(start + s + 1) * ni];
                for (i, v) in row.iter().enumerate() {
                    a[i * B + s] = *v;
                }
            } else {
                for i in 0..ni {
                    a[i * B + s] = 0.0;
                }
            }
        }
        for l in &p.layers {
            for j in 0..l.dout {
                let mut acc = [l.b[j]; B];
                let wr = &l.w[j * l.din..(j + 1) * l.din];
                for (i, wi) in wr.iter().enumerate() {
                    let xr: &[f64; B] = a[i * B..(i + 1) * B].try_into().expect("block row");
                    for s in 0..B {
                        acc[s] = wi.mul_add(xr[s], acc[s]);
                    }
                }
                let dst = &mut c[j * B..(j + 1) * B];
                match l.act {
                    Activation::Relu => {
                        for s in 0..B {
                            dst[s] = acc[s].max(0.0);
                        }
                    }
                    Activation::Identity => dst.copy_from_slice(&acc),
                    act => {
                        for s in 0..B {
                            dst[s] = act.apply(acc[s]);
                        }
                    }
                }
            }
            std::mem::swap(&mut a, &mut c);
        }
        for s in 0..rows {
            for k in 0..no {
                out[(start + s) * no + k] = a[k * B + s];
            }
        }
        start += rows;
    }
}

/// Samples per block of the f32 kernel: a multiple of every tile height below (8, 4, 3, 2), and
/// small enough that a block's activations (48 x 67 f32 = 13 kB) stay in L1.
const B32: usize = 48;
/// Outputs per register tile: 4 AVX vectors of 8 f32.
const TILE: usize = 32;

#[derive(Clone, Debug, PartialEq)]
struct Layer32 {
    /// Transposed weights, padded to whole vectors and cut into tiles of up to [`TILE`] outputs:
    /// tile t holds `din` rows of `width_t` values, row i = `W[32 t .. 32 t + width_t, i]`.
    w: Vec<f32>,
    /// Biases padded to `dout_pad`.
    b: Vec<f32>,
    din: usize,
    dout: usize,
    /// `dout` rounded up to a multiple of 8: the row stride of this layer's activations.
    dout_pad: usize,
    act: Activation,
}

/// A network laid out for the single-precision inference kernel [`Packed32::forward`]: f32
/// weights (converted once), the input z-score and the output affine map kept in f64.
///
/// Why f32 is enough: the inputs are z-scored in f64 first (so every layer sees O(1) values,
/// never the cancellation of folding a scaler into f32 weights), and f32's 6e-8 relative error,
/// summed over a few dozen terms a layer, is ~1e-6 of the scaled output — well below the
/// networks' own error (tenths of a µm on µm-sized step errors; a unit test bounds it on the
/// study's data). The speed: 8 f32 lanes per AVX register instead of 4 f64, half the memory.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Packed32 {
    layers: Vec<Layer32>,
    /// `x_s = (x - mean) * inv_std`, per input, repeated for the [`B32`] rows of a block.
    tile_mean: Vec<f64>,
    tile_inv_std: Vec<f64>,
    n_inputs: usize,
    /// `y = y_s * out_scale + out_shift`, per output.
    out_scale: Vec<f64>,
    out_shift: Vec<f64>,
    /// Widest padded activation row.
    widest: usize,
}

impl Packed32 {
    /// Packs `mlp` (weights in scaled units) with its input scaler `(mean, std)` and an output
    /// affine map `(scale, shift)` applied in f64 after the last layer.
    pub(crate) fn new(mlp: &Mlp, input: (&[f64], &[f64]), output: (&[f64], &[f64])) -> Self {
        let layers: Vec<Layer32> = mlp
            .layers
            .iter()
            .map(|l| {
                let (dout, din) = l.w.shape();
                let dout_pad = dout.div_ceil(8) * 8;
                let mut w = Vec::with_capacity(din * dout_pad);
                for t0 in (0..dout_pad).step_by(TILE) {
                    let width = (dout_pad - t0).min(TILE);
                    for i in 0..din {
                        w.extend(
                            (t0..t0 + width)
                                .map(|j| if j < dout { l.w[(j, i)] as f32 } else { 0.0 }),
                        );
                    }
                }
                let b = (0..dout_pad)
                    .map(|j| if j < dout { l.b[j] as f32 } else { 0.0 })
                    .collect();
                Layer32 {
                    w,
                    b,
                    din,
                    dout,
                    dout_pad,
                    act: l.activation,
                }
            })
            .collect();
        let n_in = mlp.n_inputs();
        let widest = layers
            .iter()
            .map(|l| l.dout_pad)
            .chain([n_in])
            .max()
            .unwrap_or(1);
        Packed32 {
            layers,
            tile_mean: input.0.repeat(B32),
            tile_inv_std: input
                .1
                .iter()
                .map(|s| 1.0 / s)
                .collect::<Vec<_>>()
                .repeat(B32),
            n_inputs: n_in,
            out_scale: output.0.to_vec(),
            out_shift: output.1.to_vec(),
            widest,
        }
    }

    /// Forward pass of row-major `x` (`n x in`, f64, physical units) into row-major `out`
    /// (`n x out`); shapes checked by the caller. Returns false when `x` holds a non-finite
    /// value (checked on the way, while converting; `out` is then unspecified).
    pub(crate) fn forward(&self, x: &[f64], out: &mut [f64]) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU supports AVX2 and FMA (checked just above).
                return unsafe { forward32_avx2(self, x, out) };
            }
        }
        forward32::<false>(self, x, out)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn forward32_avx2(p: &Packed32, x: &[f64], out: &mut [f64]) -> bool {
    forward32::<true>(p, x, out)
}

/// The f32 forward pass; `SIMD` selects the AVX2+FMA register tiles (only ever true inside
/// [`forward32_avx2`]).
#[inline(always)]
fn forward32<const SIMD: bool>(p: &Packed32, x: &[f64], out: &mut [f64]) -> bool {
    let ni = p.n_inputs;
    let no = p.out_scale.len();
    let n = x.len() / ni;
    let mut a = vec![0.0f32; p.widest * B32];
    let mut c = vec![0.0f32; p.widest * B32];
    const EXP: u64 = 0x7FF0_0000_0000_0000;
    const EXP_LSB: u64 = 0x0010_0000_0000_0000;
    let mut bad = 0u64;
    let mut start = 0;
    while start < n {
        let rows = (n - start).min(B32);
        // Scale in f64 and convert; rows past the end of x stay as they were (their outputs
        // are dropped).
        // One flat loop over the block (the scaler tiled to the block's length), with the
        // finiteness test on the bits: `(bits & EXP) + EXP_LSB` carries into the sign bit
        // exactly for inf and NaN.
        let len = rows * ni;
        let zipped = a[..len]
            .iter_mut()
            .zip(&x[start * ni..start * ni + len])
            .zip(&p.tile_mean[..len])
            .zip(&p.tile_inv_std[..len]);
        for (((d, &v), &mu), &is) in zipped {
            bad |= (v.to_bits() & EXP) + EXP_LSB;
            *d = ((v - mu) * is) as f32;
        }
        let mut stride = ni;
        for l in &p.layers {
            dense32::<SIMD>(l, &a, stride, &mut c);
            if !matches!(l.act, Activation::Relu | Activation::Identity) {
                for row in c.chunks_exact_mut(l.dout_pad) {
                    for v in &mut row[..l.dout] {
                        *v = l.act.apply(*v as f64) as f32;
                    }
                }
            }
            stride = l.dout_pad;
            std::mem::swap(&mut a, &mut c);
        }
        for s in 0..rows {
            let o = &mut out[(start + s) * no..(start + s + 1) * no];
            let y = &a[s * stride..s * stride + no];
            for k in 0..no {
                o[k] = y[k] as f64 * p.out_scale[k] + p.out_shift[k];
            }
        }
        start += rows;
    }
    bad >> 63 == 0
}

/// `c[s] = act(b + W a[s])` for the [`B32`] samples of a block (`a` rows `stride` apart, `c` rows
/// `dout_pad` apart), one register tile of outputs at a time.
#[inline(always)]
fn dense32<const SIMD: bool>(l: &Layer32, a: &[f32], stride: usize, c: &mut [f32]) {
    let relu = l.act == Activation::Relu;
    let mut w_off = 0;
    for t0 in (0..l.dout_pad).step_by(TILE) {
        let width = (l.dout_pad - t0).min(TILE);
        let w = &l.w[w_off..w_off + l.din * width];
        let b = &l.b[t0..t0 + width];
        #[cfg(target_arch = "x86_64")]
        if SIMD {
            // SAFETY: only reached from `forward32_avx2` (AVX2 and FMA present); every pointer
            // offset below stays inside `a` (B32 rows of `stride` >= din), `w` (din rows of
            // `width`), `b` (`width`) and `c` (B32 rows of dout_pad >= t0 + width).
            unsafe {
                let (ap, wp, bp) = (a.as_ptr(), w.as_ptr(), b.as_ptr());
                let cp = c.as_mut_ptr().add(t0);
                let (din, cs) = (l.din, l.dout_pad);
                match width / 8 {
                    1 => tiles::<1, 8>(ap, stride, din, wp, bp, cp, cs, relu),
                    2 => tiles::<2, 4>(ap, stride, din, wp, bp, cp, cs, relu),
                    3 => tiles::<3, 3>(ap, stride, din, wp, bp, cp, cs, relu),
                    _ => tiles::<4, 2>(ap, stride, din, wp, bp, cp, cs, relu),
                }
            }
            w_off += l.din * width;
            continue;
        }
        for s in 0..B32 {
            let row = &a[s * stride..s * stride + l.din];
            let mut acc = [0.0f32; TILE];
            acc[..width].copy_from_slice(b);
            for (i, &v) in row.iter().enumerate() {
                let wr = &w[i * width..(i + 1) * width];
                for j in 0..width {
                    acc[j] += v * wr[j];
                }
            }
            let dst = &mut c[s * l.dout_pad + t0..s * l.dout_pad + t0 + width];
            for j in 0..width {
                dst[j] = if relu { acc[j].max(0.0) } else { acc[j] };
            }
        }
        w_off += l.din * width;
    }
}

/// All [`B32`] samples of a block through one tile of `NV` x 8 outputs, `S` samples at a time:
/// `S x NV` accumulator registers, each weight vector loaded once per input and used by `S`
/// FMAs, each input broadcast once and used by `NV`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)] // register tiles by index
unsafe fn tiles<const NV: usize, const S: usize>(
    a: *const f32,
    stride: usize,
    din: usize,
    w: *const f32,
    b: *const f32,
    c: *mut f32,
    c_stride: usize,
    relu: bool,
) {
    use std::arch::x86_64::*;
    // SAFETY (whole body): see the caller; AVX2 and FMA are enabled by the caller's
    // target_feature, into which this is always inlined.
    unsafe {
        let zero = _mm256_setzero_ps();
        let mut bias = [zero; NV];
        for v in 0..NV {
            bias[v] = _mm256_loadu_ps(b.add(8 * v));
        }
        for s0 in (0..B32).step_by(S) {
            let mut acc = [[zero; NV]; S];
            for s in 0..S {
                acc[s] = bias;
            }
            let rows: [*const f32; S] = std::array::from_fn(|s| a.add((s0 + s) * stride));
            for i in 0..din {
                let mut wv = [zero; NV];
                for v in 0..NV {
                    wv[v] = _mm256_loadu_ps(w.add(i * NV * 8 + 8 * v));
                }
                for s in 0..S {
                    let xb = _mm256_broadcast_ss(&*rows[s].add(i));
                    for v in 0..NV {
                        acc[s][v] = _mm256_fmadd_ps(xb, wv[v], acc[s][v]);
                    }
                }
            }
            for s in 0..S {
                for v in 0..NV {
                    let r = if relu {
                        _mm256_max_ps(acc[s][v], zero)
                    } else {
                        acc[s][v]
                    };
                    _mm256_storeu_ps(c.add((s0 + s) * c_stride + 8 * v), r);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
