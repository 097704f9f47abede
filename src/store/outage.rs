//! Which database failures are an outage rather than a bug: the connection was cut
//! (failover, network blip, `pg_terminate_backend`), the server is shutting down or starting,
//! no connection could be had in time, or a transaction lost a race it may retry. `api`
//! answers those 503 with `Retry-After` (the request may be sent again as it was), and the
//! job workers retry the write instead of failing the job. The pool reconnects by itself:
//! a connection found dead is dropped when it is next lent, and a new one is opened.

/// The database is unreachable for now; the same request may be retried.
#[non_exhaustive]
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DatabaseOutage {
    /// The connection broke or the server ended it (I/O error, SQLSTATE class 08, 57P01..3).
    #[error("the connection to the database was lost ({0}); retry the request")]
    ConnectionLost(String),
    /// No connection came free (or could be opened) within the pool's wait.
    #[error("no database connection came free in time ({0}); retry the request")]
    Busy(String),
    /// The transaction lost a race with another (serialisation failure, deadlock).
    #[error("the database aborted the transaction to resolve a conflict ({0}); retry it")]
    Conflict(String),
}

/// The outage behind `err`, if a cause in its chain is one (see [`DatabaseOutage`]).
pub fn database_outage(err: &anyhow::Error) -> Option<DatabaseOutage> {
    err.chain()
        .find_map(|cause| cause.downcast_ref::<sqlx::Error>().and_then(classify))
}

/// The outage a sqlx error is, if any.
pub(crate) fn classify(e: &sqlx::Error) -> Option<DatabaseOutage> {
    use DatabaseOutage as O;
    match e {
        sqlx::Error::Io(io) => Some(O::ConnectionLost(io.to_string())),
        sqlx::Error::Tls(t) => Some(O::ConnectionLost(t.to_string())),
        // A reply cut mid-message reads as a malformed one.
        sqlx::Error::Protocol(p) => Some(O::ConnectionLost(p.clone())),
        sqlx::Error::WorkerCrashed => {
            Some(O::ConnectionLost("the connection's worker ended".into()))
        }
        sqlx::Error::PoolTimedOut => Some(O::Busy("the pool's wait ran out".into())),
        sqlx::Error::PoolClosed => Some(O::Busy("the pool is closed".into())),
        sqlx::Error::Database(d) => classify_code(d.code().as_deref()?, d.message()),
        _ => None,
    }
}

/// PostgreSQL SQLSTATE class 08 (connection exception), 57P01 (admin shutdown, what
/// `pg_terminate_backend` sends), 57P02 (crash shutdown), 57P03 (cannot connect now), 53300
/// (too many connections), 40001 (serialisation failure) and 40P01 (deadlock); SQLite 5
/// (BUSY) and 6 (LOCKED), also inside an extended code (low byte).
fn classify_code(code: &str, message: &str) -> Option<DatabaseOutage> {
    use DatabaseOutage as O;
    let what = message.to_string();
    if code.len() == 5 {
        return match code {
            c if c.starts_with("08") => Some(O::ConnectionLost(what)),
            "57P01" | "57P02" | "57P03" => Some(O::ConnectionLost(what)),
            "53300" => Some(O::Busy(what)),
            "40001" | "40P01" => Some(O::Conflict(what)),
            _ => None,
        };
    }
    match code.parse::<u32>().ok()? & 0xff {
        5 | 6 => Some(O::Busy(what)),
        _ => None,
    }
}

#[cfg(test)]
mod tests;
