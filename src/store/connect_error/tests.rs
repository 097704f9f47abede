//! Unit tests of `crate::store::connect_error`: which failures the wait loop retries, and
//! the sentences. The real refusals (a wrong root, a plain connection to a TLS-only
//! server) are in `tests/api/pg_tls.rs`.

use std::borrow::Cow;
use std::io;

use rustls::CertificateError;
use rustls::pki_types::ServerName;
use sqlx::error::{DatabaseError, ErrorKind};

use super::{Attempt, ConnectError, TlsProblem, check_tls_files, classify, query_param};

/// A failed handshake as rustls' `complete_io` hands it to sqlx: an `InvalidData` I/O
/// error around the rustls error.
fn handshake_error(e: rustls::Error) -> sqlx::Error {
    sqlx::Error::Io(io::Error::new(io::ErrorKind::InvalidData, e))
}

fn cert_error(e: CertificateError) -> sqlx::Error {
    handshake_error(rustls::Error::InvalidCertificate(e))
}

/// A server's error answer with SQLSTATE `code`.
#[derive(Debug)]
struct Answer {
    code: &'static str,
    message: &'static str,
}

impl std::fmt::Display for Answer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.message)
    }
}

impl std::error::Error for Answer {}

impl DatabaseError for Answer {
    fn message(&self) -> &str {
        self.message
    }
    fn code(&self) -> Option<Cow<'_, str>> {
        Some(Cow::Borrowed(self.code))
    }
    fn as_error(&self) -> &(dyn std::error::Error + Send + Sync + 'static) {
        self
    }
    fn as_error_mut(&mut self) -> &mut (dyn std::error::Error + Send + Sync + 'static) {
        self
    }
    fn into_error(self: Box<Self>) -> Box<dyn std::error::Error + Send + Sync + 'static> {
        self
    }
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

fn answer(code: &'static str, message: &'static str) -> sqlx::Error {
    sqlx::Error::Database(Box::new(Answer { code, message }))
}

#[test]
fn a_database_not_up_yet_is_retried() {
    for kind in [
        io::ErrorKind::ConnectionRefused,
        io::ErrorKind::ConnectionReset,
        io::ErrorKind::TimedOut,
        io::ErrorKind::NotFound,
    ] {
        let e = sqlx::Error::Io(io::Error::from(kind));
        assert_eq!(classify(&e), Attempt::Unreachable, "{kind:?}");
    }
    // A name not resolved yet (compose starts the database's container later).
    let e = sqlx::Error::Io(io::Error::other("failed to lookup address information"));
    assert_eq!(classify(&e), Attempt::Unreachable);
    assert_eq!(classify(&sqlx::Error::PoolTimedOut), Attempt::Unreachable);
    let starting = answer("57P03", "the database system is starting up");
    assert_eq!(classify(&starting), Attempt::Unreachable);
}

#[test]
fn a_refused_certificate_is_not_retried() {
    let cases = [
        (
            cert_error(CertificateError::UnknownIssuer),
            TlsProblem::UnknownIssuer,
        ),
        (
            cert_error(CertificateError::NotValidForName),
            TlsProblem::WrongHost,
        ),
        (
            cert_error(CertificateError::NotValidForNameContext {
                expected: ServerName::try_from("db.example").unwrap(),
                presented: vec!["DnsName(\"localhost\")".into()],
            }),
            TlsProblem::WrongHost,
        ),
        (cert_error(CertificateError::Expired), TlsProblem::Dates),
        (cert_error(CertificateError::NotValidYet), TlsProblem::Dates),
        (
            cert_error(CertificateError::BadSignature),
            TlsProblem::BadCertificate,
        ),
        (
            cert_error(CertificateError::Revoked),
            TlsProblem::BadCertificate,
        ),
        (
            handshake_error(rustls::Error::AlertReceived(
                rustls::AlertDescription::CertificateRequired,
            )),
            TlsProblem::ServerAlert,
        ),
        (
            handshake_error(rustls::Error::PeerIncompatible(
                rustls::PeerIncompatible::Tls12NotOffered,
            )),
            TlsProblem::Other,
        ),
    ];
    for (e, problem) in cases {
        assert_eq!(classify(&e), Attempt::Tls(problem), "{e}");
    }
}

#[test]
fn the_drivers_own_tls_errors_are_not_retried() {
    // sqlx-postgres' words when sslmode requires TLS and the server answers 'N'.
    let e = sqlx::Error::Tls("server does not support TLS".into());
    assert_eq!(classify(&e), Attempt::Tls(TlsProblem::ServerWithoutTls));
    let e = sqlx::Error::Tls("Invalid certificate file: /etc/ca.crt".into());
    assert_eq!(classify(&e), Attempt::Tls(TlsProblem::Other));
    let e = sqlx::Error::Tls(Box::new(rustls::Error::InvalidCertificate(
        CertificateError::UnknownIssuer,
    )));
    assert_eq!(classify(&e), Attempt::Tls(TlsProblem::UnknownIssuer));
}

#[test]
fn pg_hba_refusals_name_the_tls_side() {
    // PostgreSQL 15's words (and PostgreSQL 11's).
    let plain = answer(
        "28000",
        "no pg_hba.conf entry for host \"127.0.0.1\", user \"postgres\", database \"test\", no encryption",
    );
    assert_eq!(classify(&plain), Attempt::Tls(TlsProblem::TlsRequired));
    let old = answer(
        "28000",
        "no pg_hba.conf entry for host \"10.0.0.2\", user \"u\", database \"d\", SSL off",
    );
    assert_eq!(classify(&old), Attempt::Tls(TlsProblem::TlsRequired));
    let over_tls = answer(
        "28000",
        "no pg_hba.conf entry for host \"127.0.0.1\", user \"postgres\", database \"test\", SSL encryption",
    );
    assert_eq!(
        classify(&over_tls),
        Attempt::Tls(TlsProblem::TlsRefusedByServer)
    );
    // 28000 for a role that may not log in, a bad password: answers, not TLS.
    let no_login = answer("28000", "role \"reader\" is not permitted to log in");
    assert_eq!(classify(&no_login), Attempt::Refused);
    let password = answer("28P01", "password authentication failed for user \"u\"");
    assert_eq!(classify(&password), Attempt::Refused);
    let unknown_db = answer("3D000", "database \"nope\" does not exist");
    assert_eq!(classify(&unknown_db), Attempt::Refused);
}

#[test]
fn every_sentence_says_what_to_check() {
    let expect = [
        (TlsProblem::UnknownIssuer, "sslrootcert"),
        (TlsProblem::WrongHost, "subjectAltName"),
        (TlsProblem::Dates, "expired"),
        (TlsProblem::BadCertificate, "ssl_cert_file"),
        (TlsProblem::ServerAlert, "sslcert"),
        (TlsProblem::ServerWithoutTls, "ssl = off"),
        (TlsProblem::TlsRequired, "sslmode=verify-full&sslrootcert="),
        (TlsProblem::TlsRefusedByServer, "hostssl"),
        (TlsProblem::Other, "sslmode"),
    ];
    for (problem, needle) in expect {
        let e = ConnectError::Tls {
            url: "postgres://u:***@db.example/truecut".into(),
            problem,
            source: sqlx::Error::PoolTimedOut,
        };
        let sentence = e.to_string();
        assert!(
            sentence
                .starts_with("TLS to the database (postgres://u:***@db.example/truecut) failed: "),
            "{sentence}"
        );
        assert!(sentence.contains(needle), "{problem:?}: {sentence}");
    }
}

#[test]
fn a_missing_root_file_fails_before_connecting_when_tls_is_mandatory() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-ca.crt");
    let missing = missing.display();
    for mode in ["require", "verify-ca", "verify-full"] {
        let url = format!("postgres://u@db.example/t?sslmode={mode}&sslrootcert={missing}");
        let e = check_tls_files(&url, "shown").unwrap_err();
        let ConnectError::TlsFile {
            param, ref path, ..
        } = e
        else {
            panic!("{e}")
        };
        assert_eq!(param, "sslrootcert");
        assert_eq!(path, &missing.to_string());
        let sentence = e.to_string();
        assert!(
            sentence.contains("cannot read sslrootcert file"),
            "{sentence}"
        );
        assert!(sentence.contains("(shown)"), "{sentence}");
    }
    let key = format!("postgres://u@db.example/t?sslmode=verify-full&ssl-key={missing}");
    assert!(matches!(
        check_tls_files(&key, "shown"),
        Err(ConnectError::TlsFile {
            param: "sslkey",
            ..
        })
    ));
    // Not read by the driver without mandatory TLS: no opinion.
    let off = format!("postgres://u@db.example/t?sslmode=disable&sslrootcert={missing}");
    assert!(check_tls_files(&off, "shown").is_ok());
    // A readable file, and an inline PEM, pass.
    let ca = dir.path().join("ca.crt");
    std::fs::write(&ca, "-----BEGIN CERTIFICATE-----\n").unwrap();
    let ok = format!(
        "postgres://u@db.example/t?sslmode=verify-full&sslrootcert={}",
        ca.display()
    );
    assert!(check_tls_files(&ok, "shown").is_ok());
    let inline = "postgres://u@db.example/t?sslmode=verify-full\
                  &sslrootcert=-----BEGIN%20CERTIFICATE-----%0Ax%0A-----END%20CERTIFICATE-----";
    assert!(check_tls_files(inline, "shown").is_ok());
}

#[test]
fn query_params_decode_as_the_driver_does() {
    let url = "postgres://u@h/d?sslmode=verify-full&ssl-root-cert=%2Fetc%2Fmy+ca.crt#frag";
    assert_eq!(
        query_param(url, &["sslrootcert", "ssl-root-cert"]).as_deref(),
        Some("/etc/my ca.crt")
    );
    // The last one wins, as each later pair overrides the earlier in the driver.
    let twice = "postgres://u@h/d?sslrootcert=/a&sslrootcert=/b";
    assert_eq!(query_param(twice, &["sslrootcert"]).as_deref(), Some("/b"));
    assert_eq!(query_param("postgres://u@h/d", &["sslrootcert"]), None);
    assert_eq!(
        query_param("postgres://u@h/d?x=%zz%4", &["x"]).as_deref(),
        Some("%zz%4")
    );
}
