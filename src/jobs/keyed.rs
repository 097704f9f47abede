//! The id a job submission must take when it is the retry of a request whose first try may
//! have recorded it: the HTTP door derives it from the request's `Idempotency-Key` and sets it
//! for the request's task ([`with_keyed_id`]); [`super::JobPool::enqueue`] and
//! [`super::JobPool::submit`] take it (once) instead of a fresh id, so a second try of the
//! same logical request finds the job the first recorded instead of queueing a twin.

use std::cell::RefCell;
use std::future::Future;

tokio::task_local! {
    static KEYED_ID: RefCell<Option<String>>;
}

/// Runs `f` with `id` as the id of the first job it submits.
pub async fn with_keyed_id<F: Future>(id: String, f: F) -> F::Output {
    KEYED_ID.scope(RefCell::new(Some(id)), f).await
}

/// The keyed id, if the running task has one not yet used (taken: a second job of the same
/// request gets a fresh id).
pub(super) fn take_keyed_id() -> Option<String> {
    KEYED_ID
        .try_with(|cell| cell.borrow_mut().take())
        .ok()
        .flatten()
}
