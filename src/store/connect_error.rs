//! Why the first connection to the database failed, and whether waiting can mend it.
//!
//! [`Store::open_waiting`](super::Store::open_waiting) retries while the database does not
//! answer (a compose file starts it beside the instances). A TLS failure does not heal by
//! waiting: a server certificate that does not chain to `sslrootcert`, a host name the
//! certificate does not list, a server without TLS, a `pg_hba.conf` that takes this host only
//! with (or only without) TLS, a certificate file that cannot be read. Those fail at once,
//! with a sentence naming what to check. sqlx reports a refused certificate as an I/O error
//! (rustls' `InvalidData` from the handshake), which the wait loop took for "not up yet";
//! [`classify`] looks inside it.

use std::io;

use sqlx::postgres::{PgConnectOptions, PgSslMode};

/// What a failed connection attempt tells the wait loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Attempt {
    /// No answer yet (refused, reset, name not resolved yet, timed out, starting up): retry.
    Unreachable,
    /// TLS could not be set up, or the server's TLS policy refused this connection: fail at once.
    Tls(TlsProblem),
    /// Any other answer (bad password, unknown database): fail at once.
    Refused,
}

/// What went wrong with TLS to the database, each with what to check ([`TlsProblem::hint`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum TlsProblem {
    /// The server's certificate does not chain to a trusted root (`sslrootcert`, else the
    /// system's roots).
    UnknownIssuer,
    /// The certificate does not list the host of the URL (`sslmode=verify-full` checks it).
    WrongHost,
    /// The certificate is expired or not yet valid.
    Dates,
    /// Any other fault of the certificate (signature, encoding, revoked, critical extension).
    BadCertificate,
    /// The server ended the handshake with an alert (it may want a client certificate).
    ServerAlert,
    /// `sslmode` asks for TLS and the server does not speak it (`ssl = off`).
    ServerWithoutTls,
    /// `pg_hba.conf` has no entry for this host, user and database without TLS (the server
    /// takes them only over TLS, `hostssl`, or not at all).
    TlsRequired,
    /// `pg_hba.conf` has no entry for this host, user and database over TLS (`hostnossl` only).
    TlsRefusedByServer,
    /// Any other TLS failure (a root file that is not PEM, no protocol in common).
    Other,
}

impl TlsProblem {
    /// What the operator should check or change, as a sentence.
    pub fn hint(self) -> &'static str {
        match self {
            TlsProblem::UnknownIssuer => {
                "the server's certificate is not signed by a CA this instance trusts: set \
                 sslrootcert in the URL to the file of the CA that signed it \
                 (?sslmode=verify-full&sslrootcert=/path/ca.crt), or check that the file \
                 named is that CA"
            }
            TlsProblem::WrongHost => {
                "the host in the URL is not a name the server's certificate lists \
                 (sslmode=verify-full checks it): connect by a name or address in the \
                 certificate's subjectAltName, or reissue the certificate for this host"
            }
            TlsProblem::Dates => {
                "the server's certificate is expired or not yet valid: renew it, or check \
                 the clocks of this host and the database's"
            }
            TlsProblem::BadCertificate => {
                "the server's certificate was refused: check the certificate the server sends \
                 (ssl_cert_file) and the CA in sslrootcert"
            }
            TlsProblem::ServerAlert => {
                "the server ended the TLS handshake: see its log; it may want a client \
                 certificate (sslcert and sslkey in the URL)"
            }
            TlsProblem::ServerWithoutTls => {
                "the server does not accept TLS (ssl = off in its postgresql.conf) while the \
                 URL's sslmode requires it: turn ssl on at the server, or lower sslmode only \
                 if the network between them is trusted"
            }
            TlsProblem::TlsRequired => {
                "the server's pg_hba.conf has no entry for this host, user and database \
                 without TLS: if it takes them over TLS only (hostssl), set \
                 sslmode=verify-full&sslrootcert=/path/ca.crt in the URL instead of \
                 sslmode=disable; otherwise add an entry for them"
            }
            TlsProblem::TlsRefusedByServer => {
                "the server's pg_hba.conf has no entry for this host, user and database over \
                 TLS (hostnossl only): add a hostssl entry, or set sslmode=disable only if \
                 the network between them is trusted"
            }
            TlsProblem::Other => {
                "check sslmode in the URL, that sslrootcert is the CA's certificate in PEM, \
                 and the server's TLS settings"
            }
        }
    }
}

/// Opening the database failed for a reason that waiting does not mend.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConnectError {
    /// TLS to the database failed, or its TLS policy refused the connection.
    #[error("TLS to the database ({url}) failed: {}", problem.hint())]
    Tls {
        /// The database URL, password hidden.
        url: String,
        /// What went wrong.
        problem: TlsProblem,
        /// The driver's error.
        #[source]
        source: sqlx::Error,
    },
    /// A certificate or key file that the database URL (or `PGSSLROOTCERT`, `PGSSLCERT`,
    /// `PGSSLKEY`) names cannot be read.
    #[error(
        "cannot read {param} file '{path}' for TLS to the database ({url}): give the path of \
         a PEM file this process may read"
    )]
    TlsFile {
        /// The database URL, password hidden.
        url: String,
        /// `sslrootcert`, `sslcert` or `sslkey`.
        param: &'static str,
        /// The path as given.
        path: String,
        /// Why it cannot be read.
        #[source]
        source: io::Error,
    },
}

/// Sorts a failed connection attempt for the wait loop.
pub(crate) fn classify(e: &sqlx::Error) -> Attempt {
    match e {
        sqlx::Error::Io(io_err) => match rustls_error(io_err) {
            Some(tls) => Attempt::Tls(tls_problem(tls)),
            None => Attempt::Unreachable,
        },
        sqlx::Error::PoolTimedOut => Attempt::Unreachable,
        sqlx::Error::Tls(inner) => {
            if let Some(tls) = inner.downcast_ref::<rustls::Error>() {
                Attempt::Tls(tls_problem(tls))
            } else if inner.to_string().contains("does not support TLS") {
                Attempt::Tls(TlsProblem::ServerWithoutTls)
            } else {
                Attempt::Tls(TlsProblem::Other)
            }
        }
        sqlx::Error::Database(d) => {
            let code = d.code();
            if code.as_deref() == Some("57P03") {
                // "the database system is starting up"
                Attempt::Unreachable
            } else if code.as_deref() == Some("28000") {
                pg_hba_refusal(d.message())
            } else {
                Attempt::Refused
            }
        }
        _ => Attempt::Refused,
    }
}

/// The rustls error inside an I/O error, where the handshake puts it.
fn rustls_error(e: &io::Error) -> Option<&rustls::Error> {
    e.get_ref()?.downcast_ref::<rustls::Error>()
}

fn tls_problem(e: &rustls::Error) -> TlsProblem {
    use rustls::CertificateError as C;
    match e {
        rustls::Error::InvalidCertificate(cert) => match cert {
            C::UnknownIssuer => TlsProblem::UnknownIssuer,
            C::NotValidForName | C::NotValidForNameContext { .. } => TlsProblem::WrongHost,
            C::Expired
            | C::ExpiredContext { .. }
            | C::NotValidYet
            | C::NotValidYetContext { .. } => TlsProblem::Dates,
            _ => TlsProblem::BadCertificate,
        },
        rustls::Error::AlertReceived(_) => TlsProblem::ServerAlert,
        _ => TlsProblem::Other,
    }
}

/// PostgreSQL's "no pg_hba.conf entry for host ..., user ..., database ..., <encryption>"
/// (SQLSTATE 28000, PostgreSQL 12+; "SSL off"/"SSL on" before) says which kind of connection
/// found no entry; any other 28000 (a role that may not log in) is no TLS matter.
fn pg_hba_refusal(message: &str) -> Attempt {
    if !message.starts_with("no pg_hba.conf entry") {
        return Attempt::Refused;
    }
    let message = message.trim_end();
    if message.ends_with("no encryption") || message.ends_with("SSL off") {
        Attempt::Tls(TlsProblem::TlsRequired)
    } else if message.ends_with("SSL encryption") || message.ends_with("SSL on") {
        Attempt::Tls(TlsProblem::TlsRefusedByServer)
    } else {
        Attempt::Refused
    }
}

/// Checks, before any connection, that the certificate and key files a PostgreSQL URL names
/// can be read when its `sslmode` makes TLS mandatory (`require`, `verify-ca`,
/// `verify-full`): the driver reads them only after the server agreed to TLS, and a missing
/// file then looks like a database not up yet. URL parameters win over `PGSSLROOTCERT`,
/// `PGSSLCERT` and `PGSSLKEY`, as in the driver. Inline PEM values are not files.
pub(crate) fn check_tls_files(url: &str, shown_url: &str) -> Result<(), ConnectError> {
    // A URL the driver cannot parse fails in `connect` with the driver's own sentence.
    let Ok(options) = url.parse::<PgConnectOptions>() else {
        return Ok(());
    };
    if !matches!(
        options.get_ssl_mode(),
        PgSslMode::Require | PgSslMode::VerifyCa | PgSslMode::VerifyFull
    ) {
        return Ok(());
    }
    let params: [(&'static str, &[&str], &str); 3] = [
        (
            "sslrootcert",
            &["sslrootcert", "ssl-root-cert", "ssl-ca"],
            "PGSSLROOTCERT",
        ),
        ("sslcert", &["sslcert", "ssl-cert"], "PGSSLCERT"),
        ("sslkey", &["sslkey", "ssl-key"], "PGSSLKEY"),
    ];
    for (param, names, env) in params {
        let path = query_param(url, names).or_else(|| std::env::var(env).ok());
        let Some(path) = path else { continue };
        if path.trim_start().starts_with("-----BEGIN") {
            continue;
        }
        if let Err(source) = std::fs::File::open(&path) {
            return Err(ConnectError::TlsFile {
                url: shown_url.to_string(),
                param,
                path,
                source,
            });
        }
    }
    Ok(())
}

/// The last value of the first of `names` found in the URL's query, decoded as a form value
/// (`%XX` escapes, `+` for a space), as the driver decodes it.
pub(crate) fn query_param(url: &str, names: &[&str]) -> Option<String> {
    let query = url.split_once('?')?.1;
    let query = query.split_once('#').map_or(query, |(q, _)| q);
    let mut found = None;
    for pair in query.split('&') {
        let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
        if names.contains(&form_decode(key).as_str()) {
            found = Some(form_decode(value));
        }
    }
    found
}

fn form_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'+' => out.push(b' '),
            b'%' => match bytes.get(i + 1..i + 3).and_then(|h| hex_pair(h[0], h[1])) {
                Some(decoded) => {
                    out.push(decoded);
                    i += 2;
                }
                None => out.push(b'%'),
            },
            b => out.push(b),
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn hex_pair(hi: u8, lo: u8) -> Option<u8> {
    let digit = |c: u8| char::from(c).to_digit(16);
    u8::try_from(digit(hi)? * 16 + digit(lo)?).ok()
}

#[cfg(test)]
mod tests;
