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

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// Runs `f(scratch, item)` on every item, in parallel on the current rayon pool, items
/// claimed in the order given; returns the scratch of every worker that claimed one (made
/// by `scratch` at its first item), for the caller to reduce.
pub(crate) fn for_each_claimed<T: Send, S: Send>(
    items: impl IntoIterator<Item = T>,
    scratch: impl Fn() -> S + Sync,
    f: impl Fn(&mut S, T) + Sync,
) -> Vec<S> {
    let slots: Vec<Mutex<Option<T>>> = items.into_iter().map(|t| Mutex::new(Some(t))).collect();
    let next = AtomicUsize::new(0);
    let done = Mutex::new(Vec::new());
    let work = || {
        // Claim before making scratch: a worker that starts late finds nothing and stops.
        let mut k = next.fetch_add(1, Ordering::Relaxed);
        if k >= slots.len() {
            return;
        }
        let mut s = scratch();
        while let Some(slot) = slots.get(k) {
            k = next.fetch_add(1, Ordering::Relaxed);
            // Each index is claimed once, so the slot is always full; a poisoned lock (a
            // panic in another worker) only skips the item, and the panic propagates.
            if let Some(item) = slot.lock().ok().and_then(|mut o| o.take()) {
                f(&mut s, item);
            }
        }
        if let Ok(mut d) = done.lock() {
            d.push(s);
        }
    };
    // Spawned workers not finished yet (including those not started).
    let running = AtomicUsize::new(0);
    rayon::scope(|sc| {
        for _ in 1..rayon::current_num_threads().min(slots.len()) {
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
    use super::for_each_claimed;

    /// Every item is visited exactly once, on any pool size, and the workers' scratches
    /// together saw them all.
    #[test]
    fn visits_every_item_once() {
        for threads in [1, 2, 5] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut items: Vec<u32> = vec![0; 1000];
            let sums = pool.install(|| {
                for_each_claimed(items.iter_mut().enumerate(), Vec::new, |seen: &mut Vec<usize>, (i, v)| {
                    *v += 1;
                    seen.push(i);
                })
            });
            assert!(items.iter().all(|&v| v == 1), "{threads} threads");
            let mut seen: Vec<usize> = sums.into_iter().flatten().collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..1000).collect::<Vec<_>>(), "{threads} threads");
        }
        let none: Vec<()> = for_each_claimed(Vec::<u8>::new(), || (), |_, _| {});
        assert!(none.is_empty());
    }
}
