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
