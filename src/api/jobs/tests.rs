//! Tests of the job list cursor.

use super::*;

#[test]
fn cursors_read_back_and_earlier_ones_name_their_job() {
    assert_eq!(parse_cursor(&cursor(42)), Some(Cursor::Seq(42)));
    // A cursor of a release before migration 0007: hex of `created_at ms:id`.
    let old = hex::encode("1764800000000:job-7");
    assert_eq!(parse_cursor(&old), Some(Cursor::Job("job-7".into())));
    for bad in [
        "",
        "zz",
        &hex::encode("seq:x"),
        &hex::encode("12"),
        &hex::encode("x:y"),
    ] {
        assert_eq!(parse_cursor(bad), None, "{bad}");
    }
}
