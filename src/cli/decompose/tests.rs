//! Unit tests of `crate::cli::decompose`.

use super::*;

#[test]
fn reads_csv_and_json() {
    assert_eq!(read_signal("0.1\n0.2\n").unwrap(), vec![0.1, 0.2]);
    assert_eq!(
        read_signal("x,deviation\n1,0.5\n2,-0.5\n").unwrap(),
        vec![0.5, -0.5]
    );
    assert_eq!(read_signal("[1, 2.5]").unwrap(), vec![1.0, 2.5]);
    assert_eq!(read_signal("{\"deviations\": [3]}").unwrap(), vec![3.0]);
    assert!(read_signal("deviation\nabc\n").is_err());
    assert!(read_signal("").is_err());
}
