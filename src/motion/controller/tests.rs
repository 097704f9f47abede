//! Tests of the controller definition: what each kind defaults to, and the sentences of its
//! refusals.

use serde_json::json;

use super::*;
use crate::motion::def::MachineDef;

fn limits(controller: serde_json::Value) -> Result<ControllerLimits, Error> {
    let def = json!({"kinematics": "xyz", "controller": controller});
    MachineDef::from_value(&def).map(|d| d.controller.unwrap().limits().unwrap())
}

#[test]
fn linuxcnc_caps_segments_by_default_and_the_others_do_not() {
    let l = limits(json!({"kind": "linuxcnc"})).unwrap();
    assert_eq!(
        l,
        ControllerLimits {
            segment_cap: true,
            block_rate_hz: None,
            lookahead_blocks: None
        }
    );
    for kind in ["grbl", "fanuc", "generic"] {
        assert_eq!(
            limits(json!({"kind": kind})).unwrap(),
            ControllerLimits::default()
        );
    }
    let l =
        limits(json!({"kind": "linuxcnc", "segment_cap": false, "lookahead_blocks": 40})).unwrap();
    assert!(!l.segment_cap && l.lookahead_blocks == Some(40));
    let l =
        limits(json!({"kind": "generic", "segment_cap": true, "block_rate_hz": 1000.0})).unwrap();
    assert!(l.segment_cap && l.block_rate_hz == Some(1000.0));
}

#[test]
fn refusals_say_what_to_write() {
    let e = limits(json!({"kind": "grbl", "block_rate_hz": -1})).unwrap_err();
    assert_eq!(
        e.to_string(),
        "controller.block_rate_hz: must be > 0 and at most 1000000 (blocks per second the \
         controller reads and plans), got -1"
    );
    let e = limits(json!({"kind": "grbl", "lookahead_blocks": 0})).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("controller.lookahead_blocks: must be in 1..100000"),
        "{e}"
    );
    let e = limits(json!({"kind": "haas"})).unwrap_err().to_string();
    assert!(
        e.contains("linuxcnc") && e.contains("grbl") && e.contains("generic"),
        "{e}"
    );
}
