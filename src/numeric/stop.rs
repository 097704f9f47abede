//! Stopping long work early (issue 25, "cancelling frees the worker"): a should-stop check
//! installed for the duration of one computation ([`run`]) that the cores poll between
//! units of work ([`check`]: a VMD iteration, an EMD sift, a smoother's λ trial, a gap
//! effect fit, a volumetric fold, a training batch).
//!
//! The check is a plain `Fn() -> bool` (the worker pool gives one that reads the job's
//! cancellation flag); it lives in a thread-local slot for the run, and
//! [`super::parallel`] hands it on to the scoped threads a core splits its work over, so a
//! core needs no extra parameter threaded through every function. When the check says
//! stop, [`check`] unwinds (without the panic hook: no message is printed) to [`run`], which
//! answers the typed [`Stopped`]. Nothing partial escapes: the computation's values are
//! dropped on the way out, and the cores hold no state between calls.
//!
//! Outside [`run`] (tests, the CLI) [`check`] never stops anything.

use std::cell::RefCell;
use std::panic::{AssertUnwindSafe, catch_unwind, resume_unwind};
use std::sync::Arc;

/// A should-stop check: true once the computation must end. Called between units of work,
/// so it must be cheap (an atomic load).
pub type Check = Arc<dyn Fn() -> bool + Send + Sync>;

/// The computation was stopped before it finished (its job was cancelled, or it ran longer
/// than it was allowed). Nothing it computed is kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the computation was stopped before it finished")]
pub struct Stopped;

thread_local! {
    static CURRENT: RefCell<Option<Check>> = const { RefCell::new(None) };
}

/// Puts back the slot's previous content when dropped (so runs nest).
pub struct Installed {
    previous: Option<Check>,
}

impl Drop for Installed {
    fn drop(&mut self) {
        let previous = self.previous.take();
        CURRENT.with(|c| *c.borrow_mut() = previous);
    }
}

/// Makes `check` this thread's should-stop check until the returned guard drops.
/// [`super::parallel`] uses it to hand the caller's check on to its scoped threads.
pub fn install(check: Option<Check>) -> Installed {
    let previous = CURRENT.with(|c| std::mem::replace(&mut *c.borrow_mut(), check));
    Installed { previous }
}

/// This thread's should-stop check, if a [`run`] installed one.
pub fn current() -> Option<Check> {
    CURRENT.with(|c| c.borrow().clone())
}

/// True when this thread's check says stop (false outside [`run`]). For loops that must
/// leave cleanly themselves (e.g. agree with a partner thread) rather than unwind.
pub fn requested() -> bool {
    CURRENT.with(|c| c.borrow().as_ref().is_some_and(|f| f()))
}

/// Ends the computation (unwinds to its [`run`]) when its check says stop; does nothing
/// otherwise. The cores call it between units of work.
pub fn check() {
    if requested() {
        resume_unwind(Box::new(Stopped));
    }
}

/// Ends the computation now (unwinds to its [`run`]), e.g. when a partner thread stopped.
pub fn stop_now() -> ! {
    resume_unwind(Box::new(Stopped))
}

/// Runs `f` with `should_stop` as its check: `Ok` with what `f` returned, or `Err(Stopped)`
/// when `f` (or a thread it split its work over) was stopped by [`check`]. Any other panic
/// goes on unwinding, unless the check says stop by then (a thread whose partner stopped
/// may panic on the abandoned exchange): that is a stop too.
pub fn run<T>(should_stop: Check, f: impl FnOnce() -> T) -> Result<T, Stopped> {
    let outcome = {
        let _installed = install(Some(should_stop.clone()));
        // Counted among the process's busy threads (a split elsewhere sees this core taken).
        let _busy = super::parallel::busy();
        catch_unwind(AssertUnwindSafe(f))
    };
    match outcome {
        Ok(v) => Ok(v),
        Err(payload) if payload.is::<Stopped>() || should_stop() => Err(Stopped),
        Err(payload) => resume_unwind(payload),
    }
}

#[cfg(test)]
mod tests;
