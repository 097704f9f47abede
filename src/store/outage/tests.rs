//! Unit tests of the outage classification: which database errors are a cut connection or
//! a pool wait (answered 503 with Retry-After) and which are not.

use super::*;

#[test]
fn cut_connections_and_pool_waits_are_outages() {
    let reset = sqlx::Error::Io(std::io::Error::from(std::io::ErrorKind::ConnectionReset));
    assert!(matches!(
        classify(&reset),
        Some(DatabaseOutage::ConnectionLost(_))
    ));
    assert!(matches!(
        classify(&sqlx::Error::PoolTimedOut),
        Some(DatabaseOutage::Busy(_))
    ));
    assert!(matches!(
        classify(&sqlx::Error::Protocol("unexpected end of message".into())),
        Some(DatabaseOutage::ConnectionLost(_))
    ));
    // A bug or a missing row is not an outage.
    assert_eq!(classify(&sqlx::Error::RowNotFound), None);
    assert_eq!(classify(&sqlx::Error::ColumnNotFound("x".into())), None);
}

#[test]
fn the_outage_is_found_behind_context() {
    let err = anyhow::Error::from(sqlx::Error::Io(std::io::Error::from(
        std::io::ErrorKind::UnexpectedEof,
    )))
    .context("cannot record the job")
    .context("queueing");
    let outage = database_outage(&err).unwrap();
    assert!(outage.to_string().contains("retry"), "{outage}");
    assert_eq!(database_outage(&anyhow::anyhow!("a plain failure")), None);
}

#[test]
fn sqlstates_of_a_terminated_or_starting_server_are_outages() {
    // pg_terminate_backend, a crash, a starting server, class 08, too many clients
    for code in ["57P01", "57P02", "57P03", "08006", "08003"] {
        assert!(
            matches!(
                classify_code(code, "m"),
                Some(DatabaseOutage::ConnectionLost(_))
            ),
            "{code}"
        );
    }
    assert!(matches!(
        classify_code("53300", "m"),
        Some(DatabaseOutage::Busy(_))
    ));
    assert!(matches!(
        classify_code("40001", "m"),
        Some(DatabaseOutage::Conflict(_))
    ));
    // SQLite BUSY (5), BUSY_SNAPSHOT (517), LOCKED (6)
    for code in ["5", "517", "6"] {
        assert!(
            matches!(classify_code(code, "m"), Some(DatabaseOutage::Busy(_))),
            "{code}"
        );
    }
    // unique violation, syntax error, SQLite CONSTRAINT (19)
    for code in ["23505", "42601", "19", "2067"] {
        assert_eq!(classify_code(code, "m"), None, "{code}");
    }
}
