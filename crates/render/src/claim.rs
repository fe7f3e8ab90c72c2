//! Work handed out one item at a time: one worker per thread claims the next item from a
//! shared counter until none is left.
//!
//! Rayon's adaptive split of an indexed iterator gives each thread long runs of
//! neighboring items that it works through alone. When item costs differ by orders of
//! magnitude, as the tiles and rows of a street view do (sky against facades), one thread
//! then sits idle while the other finishes a costly run it cannot hand over. Claiming item
//! by item, costliest first where the caller can tell, keeps both busy to the end; each
//! worker keeps its own scratch (buffers, caches) across the items it claims.
//!
//! The calling worker, once no item is left to claim, does not wait for the others the way
//! a rayon join does (a few rounds of `sched_yield`, then sleep until woken): it spins
//! until the items claimed by others are done, running pool jobs meanwhile. The wait is
//! one item long at most, and a draw batch of the occlusion walk makes two such parallel
//! steps: sleeping and being woken cost tens of microseconds each time, which made small
//! batches slower than the draws they save.
//!
//! Items whose buffers are reused from one call to the next (the geometry stage's chunks,
//! drawn into batch after batch) can be handed out by worker instead ([`Claim::ByWorker`]):
//! item `k` goes first to the worker whose pool index is `k mod T`, and a worker that has
//! run out of its own takes the others' that are left. Each chunk's buffers then stay in
//! one core's cache, instead of moving to whichever core claimed the chunk this time.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// How [`for_each_claimed`] hands items out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Claim {
    /// In the order given, each to the worker that asks next.
    InOrder,
    /// Item `k` first to the worker of pool index `k mod T`, each worker's in order; then
    /// the rest to whoever asks (see the module docs).
    ByWorker,
}

/// Runs `f(scratch, item)` on every item, in parallel on the current rayon pool, items
/// claimed as `claim` says; returns the scratch of every worker that claimed one (made by
/// `scratch` at its first item), for the caller to reduce.
pub(crate) fn for_each_claimed<T: Send, S: Send>(
    items: impl IntoIterator<Item = T>,
    claim: Claim,
    scratch: impl Fn() -> S + Sync,
    f: impl Fn(&mut S, T) + Sync,
) -> Vec<S> {
    let slots: Vec<Mutex<Option<T>>> = items.into_iter().map(|t| Mutex::new(Some(t))).collect();
    let threads = rayon::current_num_threads().max(1);
    let workers = threads.min(slots.len());
    // The items as `strides` interleaved runs (item k in run k mod strides), each with the
    // index of its next unclaimed item. By worker, one run per thread of the pool whatever
    // the item count, so that item k goes to the same worker from call to call.
    let strides = if claim == Claim::ByWorker { threads } else { 1 };
    let next: Vec<AtomicUsize> = (0..strides).map(AtomicUsize::new).collect();
    // A worker's own run first, then the others'.
    let claim_next = |own: usize| {
        (0..strides).find_map(|d| {
            let k = next[(own + d) % strides].fetch_add(strides, Ordering::Relaxed);
            (k < slots.len()).then_some(k)
        })
    };
    let done = Mutex::new(Vec::new());
    let work = || {
        let own = rayon::current_thread_index().unwrap_or(0) % strides;
        // Claim before making scratch: a worker that starts late finds nothing and stops.
        let Some(mut k) = claim_next(own) else { return };
        let mut s = scratch();
        loop {
            // Each index is claimed once, so the slot is always full; a poisoned lock (a
            // panic in another worker) only skips the item, and the panic propagates.
            if let Some(item) = slots[k].lock().ok().and_then(|mut o| o.take()) {
                f(&mut s, item);
            }
            match claim_next(own) {
                Some(n) => k = n,
                None => break,
            }
        }
        if let Ok(mut d) = done.lock() {
            d.push(s);
        }
    };
    // Spawned workers not finished yet (including those not started).
    let running = AtomicUsize::new(0);
    rayon::scope(|sc| {
        for _ in 1..workers {
            running.fetch_add(1, Ordering::Relaxed);
            sc.spawn(|_| {
                work();
                running.fetch_sub(1, Ordering::Release);
            });
        }
        work();
        // Every item is claimed: spin until the others finish theirs (see the module docs),
        // running pool jobs (a spawned worker not started yet is one, and finds nothing).
        while running.load(Ordering::Acquire) > 0 {
            match rayon::yield_now() {
                Some(rayon::Yield::Executed) => {}
                Some(rayon::Yield::Idle) => std::hint::spin_loop(),
                None => break,
            }
        }
    });
    done.into_inner().unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::{for_each_claimed, Claim};

    /// Every item is visited exactly once, either way of claiming, on any pool size and
    /// for any item count, and the workers' scratches together saw them all.
    #[test]
    fn visits_every_item_once() {
        for claim in [Claim::InOrder, Claim::ByWorker] {
            for threads in [1, 2, 5] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                for n in [1, 3, 1000] {
                    let mut items: Vec<u32> = vec![0; n];
                    let sums = pool.install(|| {
                        for_each_claimed(
                            items.iter_mut().enumerate(),
                            claim,
                            Vec::new,
                            |seen: &mut Vec<usize>, (i, v)| {
                                *v += 1;
                                seen.push(i);
                            },
                        )
                    });
                    assert!(items.iter().all(|&v| v == 1), "{claim:?}, {threads} threads, {n} items");
                    let mut seen: Vec<usize> = sums.into_iter().flatten().collect();
                    seen.sort_unstable();
                    assert_eq!(seen, (0..n).collect::<Vec<_>>(), "{claim:?}, {threads} threads, {n} items");
                }
            }
            let none: Vec<()> = for_each_claimed(Vec::<u8>::new(), claim, || (), |_, _| {});
            assert!(none.is_empty());
        }
    }

    /// By worker, each worker takes its own items first, in order: with every item held up
    /// until both workers have started, worker `w` of two claims item `w` first, and its
    /// own items (`k mod 2 = w`) in increasing order.
    #[test]
    fn by_worker_gives_each_worker_its_own_items_first() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        use std::sync::Mutex;
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let started = AtomicUsize::new(0);
        let log = Mutex::new(Vec::new());
        pool.install(|| {
            for_each_claimed(
                0..8usize,
                Claim::ByWorker,
                || started.fetch_add(1, Ordering::SeqCst),
                |_, k| {
                    // Both workers claim their first item before either finishes one.
                    while started.load(Ordering::SeqCst) < 2 {
                        std::hint::spin_loop();
                    }
                    log.lock().unwrap().push((rayon::current_thread_index().unwrap(), k));
                },
            );
        });
        let log = log.into_inner().unwrap();
        for w in [0, 1] {
            let mine: Vec<usize> = log.iter().filter(|e| e.0 == w).map(|e| e.1).collect();
            assert_eq!(mine.first(), Some(&w), "worker {w}: {log:?}");
            let own: Vec<usize> = mine.iter().copied().filter(|k| k % 2 == w).collect();
            assert!(own.windows(2).all(|p| p[0] < p[1]), "worker {w}: {log:?}");
        }
    }
}
