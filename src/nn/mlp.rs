//! The multi-layer perceptron: dense layers, batch forward pass.

use nalgebra::{DMatrix, DMatrixView, DMatrixViewMut, DVector};
use rand::SeedableRng;
use rand::rngs::Xoshiro256PlusPlus;

use super::activation::Activation;
use super::error::{Error, Result, check_finite};
use super::fast::Packed;
use super::init::Init;
use crate::numeric::parallel;

/// Samples per forward block: keeps every layer's block in L1/L2 while letting gemm amortise.
const BLOCK: usize = 256;

/// One fully connected layer: `a = f(W x + b)` (Zhang et al. 2023 eqs. 2–3).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Dense {
    /// Weights, `out x in`.
    pub(crate) w: DMatrix<f64>,
    /// Biases, `out`.
    pub(crate) b: DVector<f64>,
    pub(crate) activation: Activation,
}

/// A fully connected feed-forward network. Samples are rows of row-major `f64` slices
/// (`n x n_inputs` in, `n x n_outputs` out).
#[derive(Clone, Debug, PartialEq)]
pub struct Mlp {
    pub(crate) layers: Vec<Dense>,
}

impl Mlp {
    /// Builds a network with layer sizes `sizes` (input first, output last), `hidden` on every
    /// hidden layer and `output` on the last one, weights drawn by `init` from `seed`.
    ///
    /// Example: the step-error network of Zhang et al. 2023 is `&[62, 28, 20, 1]`, ReLU, Identity;
    /// the volumetric network of Xiang et al. 2019 and Wang, Dai & Hong is `&[3, 8, 3]`, Sigmoid,
    /// Identity. Errors: fewer than 2 sizes or a size of 0.
    pub fn new(
        sizes: &[usize],
        hidden: Activation,
        output: Activation,
        init: Init,
        seed: u64,
    ) -> Result<Self> {
        if sizes.len() < 2 {
            return Err(Error::TooFewLayers(sizes.len()));
        }
        if let Some(index) = sizes.iter().position(|&s| s == 0) {
            return Err(Error::EmptyLayer { index });
        }
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let last = sizes.len() - 2;
        let layers = sizes
            .windows(2)
            .enumerate()
            .map(|(i, pair)| {
                let (w, b) = init.draw(pair[0], pair[1], &mut rng);
                Dense {
                    w,
                    b,
                    activation: if i == last { output } else { hidden },
                }
            })
            .collect();
        Ok(Mlp { layers })
    }

    /// Layer sizes, input first.
    pub fn sizes(&self) -> Vec<usize> {
        let mut s = vec![self.n_inputs()];
        s.extend(self.layers.iter().map(|l| l.w.nrows()));
        s
    }

    /// Activation of each non-input layer.
    pub fn activations(&self) -> Vec<Activation> {
        self.layers.iter().map(|l| l.activation).collect()
    }

    /// Number of inputs per sample.
    pub fn n_inputs(&self) -> usize {
        self.layers[0].w.ncols()
    }

    /// Number of outputs per sample.
    pub fn n_outputs(&self) -> usize {
        self.layers[self.layers.len() - 1].w.nrows()
    }

    /// Number of trainable parameters (weights + biases).
    pub fn n_parameters(&self) -> usize {
        self.layers.iter().map(|l| l.w.len() + l.b.len()).sum()
    }

    /// Forward pass of one sample (`n_inputs` values) to `n_outputs` values, no dropout.
    pub fn predict_one(&self, x: &[f64]) -> Result<Vec<f64>> {
        self.predict(x)
    }

    /// Forward pass of `n` samples (row-major `n x n_inputs`) to row-major `n x n_outputs`,
    /// on the calling thread. No dropout (inverted dropout needs no rescaling at inference).
    ///
    /// Reference: Zhang et al. 2023 eq. 12 (weighted sum in matrix form) and eq. 3.
    /// Errors: a length that is not a multiple of `n_inputs`, non-finite inputs.
    pub fn predict(&self, x: &[f64]) -> Result<Vec<f64>> {
        let n = self.check_input(x)?;
        let mut out = vec![0.0; n * self.n_outputs()];
        Packed::new(self).forward(x, &mut out);
        Ok(out)
    }

    /// Like [`Mlp::predict`] but writing into `out` (length `n * n_outputs`).
    pub fn predict_into(&self, x: &[f64], out: &mut [f64]) -> Result<()> {
        let n = self.check_input(x)?;
        if out.len() != n * self.n_outputs() {
            return Err(Error::Shape {
                what: "prediction output",
                expected: n * self.n_outputs(),
                got: out.len(),
            });
        }
        Packed::new(self).forward(x, out);
        Ok(())
    }

    /// Like [`Mlp::predict`], split over up to `threads` OS threads (scoped; 0 means the
    /// machine's available parallelism). Worth it from about 10,000 samples.
    pub fn predict_parallel(&self, x: &[f64], threads: usize) -> Result<Vec<f64>> {
        let n = self.check_input(x)?;
        let (ni, no) = (self.n_inputs(), self.n_outputs());
        let mut out = vec![0.0; n * no];
        let per = parallel::chunk_len(n, threads, 4096);
        let packed = Packed::new(self);
        parallel::zip_chunks_mut(x, per * ni, &mut out, per * no, |xc, oc| {
            packed.forward(xc, oc)
        });
        Ok(out)
    }

    fn check_input(&self, x: &[f64]) -> Result<usize> {
        let n = self.rows(x)?;
        check_finite("network input", x)?;
        Ok(n)
    }

    /// Samples in a row-major input `x`; an error if its length is not a multiple of the
    /// input size.
    pub(crate) fn rows(&self, x: &[f64]) -> Result<usize> {
        let ni = self.n_inputs();
        if x.len() % ni != 0 {
            return Err(Error::Shape {
                what: "network input (multiple of the input size)",
                expected: ni,
                got: x.len(),
            });
        }
        Ok(x.len() / ni)
    }

    /// Forward pass in blocks of [`BLOCK`] samples; `x` and `out` already checked.
    pub(crate) fn forward_blocks(&self, x: &[f64], out: &mut [f64]) {
        let ni = self.n_inputs();
        let no = self.n_outputs();
        let widest = self.layers.iter().map(|l| l.w.nrows()).max().unwrap_or(1);
        let mut ping = vec![0.0; widest * BLOCK];
        let mut pong = vec![0.0; widest * BLOCK];
        for (xb, ob) in x.chunks(BLOCK * ni).zip(out.chunks_mut(BLOCK * no)) {
            let rows = xb.len() / ni;
            let last = self.layers.len() - 1;
            for (l, layer) in self.layers.iter().enumerate() {
                let (din, dout) = (layer.w.ncols(), layer.w.nrows());
                // Input of layer l is x (l = 0) or the block written by layer l-1 into `ping`.
                let (src, dst): (&[f64], &mut [f64]) = if l == 0 {
                    (
                        xb,
                        if l == last {
                            &mut *ob
                        } else {
                            &mut pong[..dout * rows]
                        },
                    )
                } else if l == last {
                    (&ping[..din * rows], &mut *ob)
                } else {
                    (&ping[..din * rows], &mut pong[..dout * rows])
                };
                dense_forward(layer, src, rows, dst);
                if l != last {
                    std::mem::swap(&mut ping, &mut pong);
                }
            }
        }
    }
}

/// `dst = f(W src + b)` for `rows` samples stored as columns (column-major = row-major rows).
#[inline]
pub(crate) fn dense_forward(layer: &Dense, src: &[f64], rows: usize, dst: &mut [f64]) {
    let (din, dout) = (layer.w.ncols(), layer.w.nrows());
    let xin = DMatrixView::from_slice(src, din, rows);
    let mut z = DMatrixViewMut::from_slice(dst, dout, rows);
    z.gemm(1.0, &layer.w, &xin, 0.0);
    let b = layer.b.as_slice();
    match layer.activation {
        Activation::Relu => {
            for col in dst.chunks_exact_mut(dout) {
                for (v, bi) in col.iter_mut().zip(b) {
                    *v = (*v + bi).max(0.0);
                }
            }
        }
        act => {
            for col in dst.chunks_exact_mut(dout) {
                for (v, bi) in col.iter_mut().zip(b) {
                    *v = act.apply(*v + bi);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
