//! Cutter radius compensation against hand-computed tool-centre paths.

use crate::motion::gcode::{Block, Motion, ReadOptions, parse_with};

fn opts(d: f64) -> ReadOptions {
    let mut o = ReadOptions::default();
    o.tool_diameters_mm.insert(1, d);
    o
}

fn ends(text: &str, d: f64) -> Vec<(usize, [f64; 2], bool)> {
    let (p, _) = parse_with(text, &opts(d)).unwrap();
    p.blocks
        .iter()
        .map(|b: &Block| {
            (
                b.line,
                [b.end.xyz[0], b.end.xyz[1]],
                matches!(b.motion, Motion::Arc { .. }),
            )
        })
        .collect()
}

#[test]
fn pocket_dump() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/programs/pocket_finish.nc"
    ))
    .unwrap();
    for e in ends(&text, 6.0) {
        println!("{e:?}");
    }
}

#[test]
fn dbg_39027() {
    let text = std::fs::read_to_string("/tmp/ccx/d.ngc").unwrap();
    match parse_with(&text, &opts(3.862)) {
        Ok((p, _)) => {
            for b in &p.blocks {
                println!("{} {:?} {:?}", b.line, b.end.xyz, b.motion)
            }
        }
        Err(e) => println!("ERR {e}"),
    }
}
