//! Unit tests of the storage classification and probes.

use super::*;

#[test]
fn full_read_only_and_forbidden_io_errors_are_classified() {
    let err = |code| {
        anyhow::Error::new(std::io::Error::from_raw_os_error(code))
            .context("cannot write model file x")
    };
    assert!(matches!(
        storage_failure(&err(28)),
        Some(StorageFailure::Full(_))
    ));
    assert!(matches!(
        storage_failure(&err(122)),
        Some(StorageFailure::Full(_))
    ));
    assert!(matches!(
        storage_failure(&err(30)),
        Some(StorageFailure::ReadOnly(_))
    ));
    assert!(matches!(
        storage_failure(&err(13)),
        Some(StorageFailure::Forbidden(_))
    ));
    assert_eq!(storage_failure(&err(2)), None);
    assert_eq!(storage_failure(&anyhow::anyhow!("a bug")), None);
    let sentence = storage_failure(&err(28)).unwrap().to_string();
    assert!(sentence.contains("cannot write model file x"), "{sentence}");
    assert!(sentence.contains("Free space"), "{sentence}");
}

#[test]
fn database_codes_are_classified() {
    assert!(matches!(
        classify_db_code(Some("13"), "full"),
        Some(StorageFailure::Full(_))
    ));
    assert!(matches!(
        classify_db_code(Some("8"), "ro"),
        Some(StorageFailure::ReadOnly(_))
    ));
    // SQLITE_READONLY_DBMOVED = 8 | (4 << 8)
    assert!(matches!(
        classify_db_code(Some("1032"), "ro"),
        Some(StorageFailure::ReadOnly(_))
    ));
    assert!(matches!(
        classify_db_code(Some("53100"), "pg"),
        Some(StorageFailure::Full(_))
    ));
    assert!(matches!(
        classify_db_code(Some("25006"), "pg"),
        Some(StorageFailure::ReadOnly(_))
    ));
    assert_eq!(classify_db_code(Some("23505"), "unique"), None);
    assert_eq!(classify_db_code(Some("19"), "constraint"), None);
    assert_eq!(classify_db_code(None, "?"), None);
}

#[test]
fn a_writable_dir_probes_clean_and_reports_its_room() {
    let dir = tempfile::tempdir().unwrap();
    let state = state_of(dir.path());
    assert!(state.writable, "{state:?}");
    assert!(state.free_bytes.is_some_and(|b| b > 0));
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "the probe is removed"
    );
    check_data_dir(&dir.path().join("new")).unwrap();
}

#[test]
fn a_data_dir_that_cannot_be_made_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a-file");
    std::fs::write(&file, b"x").unwrap();
    let err = check_data_dir(&file.join("data")).unwrap_err().to_string();
    assert!(err.contains("a-file/data"), "{err}");
    assert!(err.contains("--data-dir"), "{err}");
    let state = state_of(&file);
    assert!(!state.writable);
    assert!(state.detail.is_some());
}
