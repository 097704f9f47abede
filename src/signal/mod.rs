//! Machining-error decomposition (Chen et al. 2024): VMD, EMD, wavelet denoising, penalised
//! smoothing, correlation screening and the coarse-to-fine pipeline, in 1-D and on 2-D grids.

pub mod carrier;
pub mod coarse_to_fine;
pub mod decompose;
pub mod emd;
pub mod error;
mod fft;
pub mod field2d;
pub mod flyers;
pub mod screen;
pub mod spline;
pub mod vmd;
pub mod wavelet;
pub mod whittaker;

pub use coarse_to_fine::{CoarseToFineParams, CoarseToFineResult, coarse_to_fine};
pub use decompose::{Components, DecomposeParams, Decomposition, Method, decompose};
pub use error::Error;
pub use field2d::Order;
pub use flyers::FlyerParams;
