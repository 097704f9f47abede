//! Unit tests of `crate::volumetric::data`.

use super::*;

fn grid_data(n: [usize; 3]) -> VolumetricData {
    let mut d = VolumetricData {
        nodes: vec![],
        errors: vec![],
    };
    for iz in 0..n[2] {
        for iy in 0..n[1] {
            for ix in 0..n[0] {
                d.nodes
                    .push([ix as f64 * 10.0, iy as f64 * 20.0, iz as f64 * 5.0]);
                d.errors.push([0.0; 3]);
            }
        }
    }
    d
}

#[test]
fn detects_shuffled_grid_and_rejects_missing_node() {
    let mut d = grid_data([3, 4, 2]);
    d.nodes.reverse();
    let g = d.grid().unwrap();
    assert_eq!(g.levels[1], vec![0.0, 20.0, 40.0, 60.0]);
    assert_eq!(d.nodes[g.node_of[1 + 3 * (2 + 4)]], [10.0, 40.0, 5.0]);
    let mut e = grid_data([3, 4, 2]);
    e.nodes.pop();
    e.errors.pop();
    assert!(matches!(e.grid(), Err(Error::NotAGrid { .. })));
}

#[test]
fn validate_names_the_bad_field() {
    let mut d = grid_data([2, 2, 2]);
    d.errors[3][1] = f64::NAN;
    assert_eq!(
        d.validate(8),
        Err(Error::NonFinite {
            field: "errors",
            index: 3
        })
    );
    let mut f = grid_data([2, 2, 2]);
    for p in &mut f.nodes {
        p[2] = 1.0;
    }
    assert_eq!(f.validate(8), Err(Error::FlatAxis { axis: 'z' }));
    let g = VolumetricData {
        nodes: vec![[0.0; 3]],
        errors: vec![],
    };
    assert!(matches!(g.validate(1), Err(Error::LengthMismatch { .. })));
}

#[test]
fn csv_reads_columns_in_any_order() {
    let d = VolumetricData::from_csv("dz,x_mm,y,z,dx,dy\n0.003,1,2,3,0.001,0.002\n\n").unwrap();
    assert_eq!(d.nodes, vec![[1.0, 2.0, 3.0]]);
    assert_eq!(d.errors, vec![[0.001, 0.002, 0.003]]);
    let e = VolumetricData::from_csv("x,y,z,dx,dy,dz\n1,2,3,nan,0,0\n").unwrap_err();
    assert!(matches!(e, Error::Csv { line: 2, .. }), "{e}");
    assert!(VolumetricData::from_csv("x,y,z\n1,2,3\n").is_err());
}
