//! Unit tests of `crate::storeels`.

use super::*;

#[test]
fn container_round_trip_and_every_corruption_is_detected() {
    let payload: Vec<u8> = (0..1000u32).flat_map(|i| i.to_le_bytes()).collect();
    let file = encode_model(&payload);
    let p = Path::new("m.tcm");
    assert_eq!(decode_model(&file, p).unwrap(), payload);
    // Any single flipped byte, in header or payload, is an error.
    for i in (0..file.len())
        .step_by(97)
        .chain([0, 9, 13, 25, file.len() - 1])
    {
        let mut bad = file.clone();
        bad[i] ^= 0x40;
        assert!(
            decode_model(&bad, p).is_err(),
            "flip at byte {i} not detected"
        );
    }
    assert!(decode_model(&file[..file.len() - 1], p).is_err());
    assert!(decode_model(&file[..10], p).is_err());
}

#[test]
fn path_components_are_ids() {
    assert!(check_component("kind", "..").is_err());
    assert!(check_component("kind", "a/b").is_err());
    assert!(check_component("kind", "").is_err());
    assert!(check_component("kind", "step-error.v2").is_ok());
}
