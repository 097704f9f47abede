//! Splitting a core's work over scoped threads: the thread count, a static split into
//! contiguous chunks (batches of equal cost: network inference, step errors), a dynamic queue
//! (items of very different cost: gap effect fits) and a two-task join.
//!
//! Written here rather than with rayon: the cores need three small patterns, and a global
//! pool would compete with the service's own bounded worker pool (`jobs`) for the same cores.

use std::sync::atomic::{AtomicUsize, Ordering};

/// Threads to use when a caller asks for `asked` (0 = the machine's available
/// parallelism, 1 when that cannot be read).
pub fn resolve_threads(asked: usize) -> usize {
    if asked == 0 {
        std::thread::available_parallelism().map_or(1, |t| t.get())
    } else {
        asked
    }
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
    std::thread::scope(|s| {
        let handles: Vec<_> = items
            .chunks(per)
            .enumerate()
            .map(|(c, chunk)| s.spawn(move || f(c * per, chunk)))
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
    std::thread::scope(|s| {
        let handles: Vec<_> = input
            .chunks(in_per)
            .zip(output.chunks_mut(out_per))
            .map(|(xc, yc)| s.spawn(move || f(xc, yc)))
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
        return items.iter().map(|&x| f(x)).collect();
    }
    let next = AtomicUsize::new(0);
    let mut out: Vec<Option<R>> = (0..items.len()).map(|_| None).collect();
    let collected: Vec<Vec<(usize, R)>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        if i >= items.len() {
                            break;
                        }
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
    std::thread::scope(|s| {
        let handle = s.spawn(background);
        let b = foreground();
        (handle.join(), b)
    })
}

fn join_or_resume<R>(h: std::thread::ScopedJoinHandle<'_, R>) -> R {
    h.join()
        .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
}

#[cfg(test)]
mod tests;
