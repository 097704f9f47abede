//! Splitting a core's work over scoped threads: the thread count, a static split into
//! contiguous chunks (batches of equal cost: network inference, step errors), a dynamic queue
//! (items of very different cost: gap effect fits), a two-task join, and a two-thread
//! lockstep exchange (iterations too short for a thread or a futex per step: VMD's sweeps),
//! and the test of whether a second thread would find a free core ([`core_free`]: the
//! process's own busy threads, [`busy`], and the machine's runnable threads).
//!
//! Written here rather than with rayon: the cores need three small patterns, and a global
//! pool would compete with the service's own bounded worker pool (`jobs`) for the same cores.

use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};
use std::thread::Thread;
use std::time::{Duration, Instant};

/// Threads to use when a caller asks for `asked` (0 = the machine's available
/// parallelism, 1 when that cannot be read).
pub fn resolve_threads(asked: usize) -> usize {
    if asked == 0 {
        std::thread::available_parallelism().map_or(1, |t| t.get())
    } else {
        asked
    }
}

/// Threads of the process doing numeric work now, each counted once ([`busy`]).
static BUSY: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Whether this thread is counted in [`BUSY`] (so nested [`busy`] guards count it once).
    static COUNTED: Cell<bool> = const { Cell::new(false) };
}

/// Counts the calling thread as busy with numeric work until dropped ([`busy`]). Not `Send`:
/// it must drop on the thread it counts.
pub struct Busy {
    counted: bool,
    _here: std::marker::PhantomData<*const ()>,
}

/// Counts the calling thread in the process-wide number of threads doing numeric work
/// ([`busy_threads`]) until the guard drops; a thread already counted is not counted again.
/// Every piece of work of the service's worker pool (through [`super::stop::run`]), every
/// decomposition and every scoped thread of this module enters it, so the count covers
/// work of every kind.
pub fn busy() -> Busy {
    let counted = !COUNTED.with(|c| c.replace(true));
    if counted {
        BUSY.fetch_add(1, Ordering::Relaxed);
    }
    Busy {
        counted,
        _here: std::marker::PhantomData,
    }
}

impl Drop for Busy {
    fn drop(&mut self) {
        if self.counted {
            BUSY.fetch_sub(1, Ordering::Relaxed);
            COUNTED.with(|c| c.set(false));
        }
    }
}

/// Threads of the process doing numeric work now (see [`busy`]).
pub fn busy_threads() -> usize {
    BUSY.load(Ordering::Relaxed)
}

/// Threads runnable on the whole machine at this instant, the caller included: the fourth
/// field's numerator of Linux's `/proc/loadavg` (`nr_running`, not an average). `None` where
/// it cannot be read (another system, a sandbox).
pub fn machine_runnable() -> Option<usize> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    parse_runnable(&text)
}

/// The runnable count of a `/proc/loadavg` line (`"0.52 0.31 0.20 3/181 8642"` → 3).
fn parse_runnable(text: &str) -> Option<usize> {
    text.split_whitespace()
        .nth(3)?
        .split('/')
        .next()?
        .parse()
        .ok()
}

/// Whether a second thread started now would find a core of its own: the machine has two
/// or more cores, this process's busy threads ([`busy_threads`], the caller among them)
/// leave one free, and so does the machine (its runnable threads, [`machine_runnable`],
/// the caller among them, number fewer than its cores). A split whose threads wait on each
/// other (VMD's lockstep sweeps) only pays when this holds: with every core taken, the
/// partner waits for a time slice at each exchange. A snapshot; a load that comes later is
/// met by [`Lockstep`]'s parking wait.
pub fn core_free() -> bool {
    let cores = resolve_threads(0);
    let mine = busy_threads().max(1);
    cores >= 2 && mine < cores && machine_runnable().is_none_or(|r| r.max(mine) < cores)
}

/// Items per chunk when `n` items are split over `threads` threads (0 = all cores), but at
/// least `min_chunk` (below that a thread costs more than it saves).
pub fn chunk_len(n: usize, threads: usize, min_chunk: usize) -> usize {
    n.div_ceil(resolve_threads(threads).max(1)).max(min_chunk)
}

/// `f(offset, chunk)` on consecutive chunks of `per` items (`per ≥ 1`), one scoped thread
/// per chunk, results in chunk order; a single chunk runs on the calling thread.
/// A panic in a worker is resumed on the calling thread.
pub fn map_chunks<T: Sync, R: Send>(
    items: &[T],
    per: usize,
    f: impl Fn(usize, &[T]) -> R + Sync,
) -> Vec<R> {
    if items.len() <= per {
        return vec![f(0, items)];
    }
    let f = &f;
    let stop = &super::stop::current();
    std::thread::scope(|s| {
        let handles: Vec<_> = items
            .chunks(per)
            .enumerate()
            .map(|(c, chunk)| {
                s.spawn(move || {
                    let _stop = super::stop::install(stop.clone());
                    let _busy = busy();
                    f(c * per, chunk)
                })
            })
            .collect();
        handles.into_iter().map(join_or_resume).collect()
    })
}

/// `f(input chunk, output chunk)` over matching chunks of `input` (`in_per` items each) and
/// `output` (`out_per` items each), one scoped thread per chunk pair, results in order; a
/// single pair runs on the calling thread. For row-major batches: `in_per = rows × inputs`,
/// `out_per = rows × outputs`.
pub fn zip_chunks_mut<A: Sync, B: Send, R: Send>(
    input: &[A],
    in_per: usize,
    output: &mut [B],
    out_per: usize,
    f: impl Fn(&[A], &mut [B]) -> R + Sync,
) -> Vec<R> {
    if input.len() <= in_per && output.len() <= out_per {
        return vec![f(input, output)];
    }
    let f = &f;
    let stop = &super::stop::current();
    std::thread::scope(|s| {
        let handles: Vec<_> = input
            .chunks(in_per)
            .zip(output.chunks_mut(out_per))
            .map(|(xc, yc)| {
                s.spawn(move || {
                    let _stop = super::stop::install(stop.clone());
                    let _busy = busy();
                    f(xc, yc)
                })
            })
            .collect();
        handles.into_iter().map(join_or_resume).collect()
    })
}

/// `f` over `items` on up to `threads` scoped threads (clamped to 1..=items), each taking the
/// next unstarted item from a shared counter, results in item order. For items whose costs
/// differ a lot, where a static split would leave threads idle.
pub fn map_dynamic<T: Sync + Copy, R: Send>(
    items: &[T],
    threads: usize,
    f: impl Fn(T) -> R + Sync,
) -> Vec<R> {
    let threads = threads.clamp(1, items.len().max(1));
    if threads == 1 {
        return items
            .iter()
            .map(|&x| {
                super::stop::check();
                f(x)
            })
            .collect();
    }
    let next = AtomicUsize::new(0);
    let mut out: Vec<Option<R>> = (0..items.len()).map(|_| None).collect();
    let stop = &super::stop::current();
    let collected: Vec<Vec<(usize, R)>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let _stop = super::stop::install(stop.clone());
                    let _busy = busy();
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        if i >= items.len() {
                            break;
                        }
                        super::stop::check();
                        mine.push((i, f(items[i])));
                    }
                    mine
                })
            })
            .collect();
        handles.into_iter().map(join_or_resume).collect()
    });
    for (i, r) in collected.into_iter().flatten() {
        out[i] = Some(r);
    }
    out.into_iter()
        .map(|r| r.expect("every item evaluated"))
        .collect()
}

/// Runs `background` on a scoped thread while `foreground` runs on the calling thread;
/// returns both results, the background one as `Err` if it panicked.
pub fn join<A: Send, B>(
    background: impl FnOnce() -> A + Send,
    foreground: impl FnOnce() -> B,
) -> (std::thread::Result<A>, B) {
    let stop = super::stop::current();
    std::thread::scope(|s| {
        let handle = s.spawn(move || {
            let _stop = super::stop::install(stop);
            let _busy = busy();
            background()
        });
        let b = foreground();
        (handle.join(), b)
    })
}

/// Two threads iterating in lockstep, each over its half of the data, that must combine a
/// small per-iteration result (VMD's per-mode sums) before either can go on. Each step is a
/// few microseconds, so the wait spins ([`std::hint::spin_loop`]) for up to
/// [`Lockstep::SPIN`], then parks the thread until the partner arrives: a partner that was
/// descheduled (another process took its core) is then not spun against, and the waiting
/// side's core goes idle, where the scheduler can run the partner at once.
///
/// `exchange(side, step, mine)` publishes `mine` for `step`, waits for the other side's value
/// of the same step and returns `(side 0's, side 1's)`: both sides see the same pair, so a
/// deterministic combination of it is bit-identical on both. Values are double-buffered by the
/// step's parity, so one barrier per step suffices: a side cannot publish step s + 2 before the
/// other has passed step s + 1, i.e. finished reading step s.
///
/// If a side panics or returns early, its [`LockstepGuard`] marks the exchange abandoned and
/// the other side's next wait panics instead of waiting forever.
pub struct Lockstep<T> {
    slots: [[Mutex<Option<T>>; 2]; 2],
    arrived: AtomicUsize,
    generation: AtomicUsize,
    abandoned: AtomicBool,
    /// Each side's thread, known once it has waited (to unpark it).
    threads: [OnceLock<Thread>; 2],
    /// Whether each side is parked (or about to be) in [`Lockstep::wait`].
    parked: [AtomicBool; 2],
    /// Waits that parked, both sides together (see [`Lockstep::parks`]).
    parks: AtomicUsize,
}

impl<T: Clone> Lockstep<T> {
    /// Longest spin before a waiting side parks. The partner normally arrives within a few
    /// microseconds (the two halves of a sweep cost the same); longer means it lost its core.
    pub const SPIN: Duration = Duration::from_micros(50);

    /// Longest single park (a safety net: the partner unparks the waiter when it arrives).
    const PARK: Duration = Duration::from_millis(1);

    /// An exchange for two sides.
    pub fn new() -> Self {
        Self {
            slots: Default::default(),
            arrived: AtomicUsize::new(0),
            generation: AtomicUsize::new(0),
            abandoned: AtomicBool::new(false),
            threads: Default::default(),
            parked: Default::default(),
            parks: AtomicUsize::new(0),
        }
    }

    /// A guard for one side: abandons the exchange when dropped while its thread panics, or
    /// when [`LockstepGuard::leave`] was not called.
    pub fn guard(&self) -> LockstepGuard<'_, T> {
        LockstepGuard {
            lockstep: self,
            left: false,
        }
    }

    /// How many waits so far outlasted [`Lockstep::SPIN`] and parked (both sides): 0 or
    /// nearly so when each side has a core of its own.
    pub fn parks(&self) -> usize {
        self.parks.load(Ordering::Relaxed)
    }

    /// Publishes `mine` as side `side`'s value of `step`; returns both sides' values of that
    /// step once the other side has published too.
    pub fn exchange(&self, side: usize, step: usize, mine: T) -> (T, T) {
        let parity = step % 2;
        *self.slots[parity][side]
            .lock()
            .unwrap_or_else(|p| p.into_inner()) = Some(mine);
        self.wait(side);
        let read = |s: usize| {
            self.slots[parity][s]
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .clone()
                .expect("both sides published before the barrier opened")
        };
        (read(0), read(1))
    }

    /// The two-party barrier: the second to arrive opens it for both and unparks the first
    /// if it parked.
    fn wait(&self, side: usize) {
        let generation = self.generation.load(Ordering::Acquire);
        if self.arrived.fetch_add(1, Ordering::AcqRel) == 1 {
            self.arrived.store(0, Ordering::Relaxed);
            // SeqCst against the waiter's `parked` store and `generation` load: either it
            // sees the new generation and does not park, or this sees it parked.
            self.generation.fetch_add(1, Ordering::SeqCst);
            self.unpark(1 - side);
            return;
        }
        let opened = || self.generation.load(Ordering::SeqCst) != generation;
        let start = Instant::now();
        let mut spins = 0u32;
        while !opened() {
            self.check_abandoned();
            spins = spins.wrapping_add(1);
            if spins % 64 != 0 || start.elapsed() < Self::SPIN {
                std::hint::spin_loop();
                continue;
            }
            self.threads[side].get_or_init(std::thread::current);
            self.parks.fetch_add(1, Ordering::Relaxed);
            while !opened() {
                self.parked[side].store(true, Ordering::SeqCst);
                if opened() {
                    break;
                }
                std::thread::park_timeout(Self::PARK);
                self.check_abandoned();
            }
            self.parked[side].store(false, Ordering::Relaxed);
            return;
        }
    }

    /// Unparks side `side` if it is parked in [`Lockstep::wait`].
    fn unpark(&self, side: usize) {
        if self.parked[side].swap(false, Ordering::SeqCst) {
            if let Some(t) = self.threads[side].get() {
                t.unpark();
            }
        }
    }

    /// Panics (or stops quietly, for a stopped job) when the other side abandoned the exchange.
    fn check_abandoned(&self) {
        if self.abandoned.load(Ordering::Acquire) {
            if super::stop::requested() {
                // The other side was stopped (a cancelled job): stop too, quietly.
                super::stop::stop_now();
            }
            panic!("the other side of a lockstep exchange stopped");
        }
    }
}

impl<T: Clone> Default for Lockstep<T> {
    fn default() -> Self {
        Self::new()
    }
}

/// See [`Lockstep::guard`].
pub struct LockstepGuard<'a, T> {
    lockstep: &'a Lockstep<T>,
    left: bool,
}

impl<T> LockstepGuard<'_, T> {
    /// This side has finished normally (after its last exchange).
    pub fn leave(mut self) {
        self.left = true;
    }
}

impl<T> Drop for LockstepGuard<'_, T> {
    fn drop(&mut self) {
        if !self.left {
            let l = self.lockstep;
            l.abandoned.store(true, Ordering::Release);
            // Wake a parked partner so it sees the abandonment now, not after its park.
            for t in l.threads.iter().filter_map(OnceLock::get) {
                t.unpark();
            }
        }
    }
}

fn join_or_resume<R>(h: std::thread::ScopedJoinHandle<'_, R>) -> R {
    h.join()
        .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
}

#[cfg(test)]
mod tests;
