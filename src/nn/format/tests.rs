//! Unit tests of `crate::nn::format`.

use super::super::{Init, Regressor};
use super::*;

#[test]
fn corrupt_truncated_and_future_files_are_rejected() {
    let mlp = Mlp::new(
        &[3, 8, 3],
        Activation::Sigmoid,
        Activation::Identity,
        Init::Xavier,
        4,
    )
    .unwrap();
    let reg = Regressor::new(mlp, ZScore::identity(3), ZScore::identity(3)).unwrap();
    let good = reg.to_bytes();
    assert!(Regressor::from_bytes(&good).is_ok());
    let mut flipped = good.clone();
    flipped[40] ^= 1;
    assert!(
        matches!(Regressor::from_bytes(&flipped), Err(Error::Format(m)) if m.contains("checksum"))
    );
    assert!(Regressor::from_bytes(&good[..good.len() - 9]).is_err());
    assert!(Regressor::from_bytes(b"nope").is_err());
    let mut future = good[..good.len() - 8].to_vec();
    future[4..8].copy_from_slice(&2u32.to_le_bytes());
    let h = fnv1a(&future);
    future.extend_from_slice(&h.to_le_bytes());
    assert!(
        matches!(Regressor::from_bytes(&future), Err(Error::Format(m)) if m.contains("version 2"))
    );
}
