//! Unit tests of `crate::store::codec`.

use super::*;

#[test]
fn round_trip_is_bit_exact() {
    let xs = [0.0, -0.0, 1.5e-300, -7.25, f64::MAX, 0.1 + 0.2];
    let back = decode_f64s(&encode_f64s(&xs)).unwrap();
    assert_eq!(
        xs.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        back.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    );
    let pts = [[1.0, 2.0, 3.0], [-4.0, 5.5, 1e-9]];
    assert_eq!(decode_points(&encode_points(&pts)).unwrap(), pts.to_vec());
}

#[test]
fn truncated_blob_is_an_error() {
    assert!(decode_f64s(&[0u8; 12]).is_err());
    assert!(decode_points(&[0u8; 16]).is_err());
}
