//! Keeping the pool's other workers awake through short serial steps.
//!
//! A rayon worker that finds no work spins for a few rounds and then sleeps; the next
//! parallel step has to wake it (a futex call and a reschedule), and until then its share
//! of the work waits. The front-to-back occlusion walk alternates a serial step (finding
//! the next batch, 0.1–0.5 ms) with parallel ones (drawing it) tens of times per frame, so
//! the workers would fall asleep before every batch: on a 2-core machine a batch that
//! takes 33 µs back to back took 93 µs after 300 µs of serial work. [`join_helping`] runs
//! such a frame beside one helper that does not go idle: it runs side work that can stop
//! and resume (the frame's count of clusters in the frustum), serving the frame's parallel
//! jobs as they come, and then runs those jobs or spins until the frame ends (at most
//! [`MAX_SPIN`] at a time without a job). The cores are idle during the serial steps
//! anyway; this is the "active" wait policy of OpenMP runtimes, limited to the work that
//! needs it.
//!
//! The occluder pass draws every cluster, so its walk does not wait for the pyramid: one
//! worker finds the next batch while the others draw the current one, and the finder, once
//! done, helps draw the same way.
//!
//! A world's update before a frame (propagating the edits, the culler's sync: moving its
//! clusters, refitting its BVH) is a run of short parallel steps between serial ones too,
//! and runs the same way ([`with_helper_awake`]). On the traffic city with every vehicle
//! moving (`examples/moving_cost`), moving frames took 1.36–1.41× as long as parked ones
//! against 1.39–1.45× before, in each of four alternated runs. Posing the animations, kept
//! awake the same way, measured no gain, and is not.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The longest a worker spins for one serial step; past it, it may sleep.
pub(crate) const MAX_SPIN: Duration = Duration::from_millis(2);

/// `rayon::join(a, b)`, except that the worker which runs `b` does not go idle when `b` is
/// done: until `a` returns it runs the pool's pending jobs (those `a`'s parallel steps
/// spawn) or spins, for at most [`MAX_SPIN`] at a time without a job. `a` alternates short
/// serial steps with parallel ones; a worker that slept through a serial step would be
/// woken late for the next parallel one.
///
/// `b` gets `poll`, which runs one of the pool's pending jobs if there is one and says
/// whether `a` has returned: work in `b` that can stop and resume calls it often, so that
/// `a`'s parallel steps find their helper at once and `b` stops when `a` is done.
pub(crate) fn join_helping<RA: Send, RB: Send>(
    a: impl FnOnce() -> RA + Send,
    b: impl FnOnce(&dyn Fn() -> bool) -> RB + Send,
) -> (RA, RB) {
    let done = AtomicBool::new(false);
    rayon::join(
        || {
            let r = a();
            done.store(true, Ordering::Release);
            r
        },
        || {
            let poll = || {
                rayon::yield_now();
                done.load(Ordering::Acquire)
            };
            let r = b(&poll);
            help_until(&done, MAX_SPIN);
            r
        },
    )
}

/// Runs `f`, a run of serial steps and short parallel ones, with the pool's other worker
/// kept awake meanwhile ([`join_helping`] with no side work).
pub(crate) fn with_helper_awake<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    join_helping(f, |_| ()).0
}

/// Runs pending jobs of the current pool, or spins, until `done` is set (true) or `limit`
/// has passed since the last job ran (false). Outside a pool it returns false at once.
fn help_until(done: &AtomicBool, limit: Duration) -> bool {
    let mut idle = Instant::now();
    while !done.load(Ordering::Acquire) {
        match rayon::yield_now() {
            Some(rayon::Yield::Executed) => idle = Instant::now(),
            Some(rayon::Yield::Idle) if idle.elapsed() < limit => std::hint::spin_loop(),
            _ => return false,
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// A spinner lets go when the step ends, and gives up at its limit when it does not
    /// (at once outside a pool).
    #[test]
    fn spinners_let_go_when_the_step_ends() {
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        two.install(|| {
            let done = Arc::new(AtomicBool::new(false));
            let d = Arc::clone(&done);
            let setter = std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(1));
                d.store(true, Ordering::Release);
            });
            assert!(help_until(&done, Duration::from_secs(60)));
            setter.join().unwrap();
            assert!(!help_until(&AtomicBool::new(false), Duration::from_micros(100)));
        });
        assert!(!help_until(&AtomicBool::new(false), Duration::from_secs(60)), "outside a pool: no wait");
    }

    /// `join_helping` gives both results whether or not another worker takes `b`; `b`'s
    /// `poll` says when `a` has returned (at once when `b` runs after `a` on one thread),
    /// and runs `a`'s jobs meanwhile, so that both workers share `a`'s parallel step.
    #[test]
    fn join_helping_runs_both_and_helps() {
        use rayon::prelude::*;
        use std::sync::Mutex;
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let workers = Mutex::new(std::collections::HashSet::new());
            let (sum, b) = pool.install(|| {
                join_helping(
                    || {
                        (0..64u64)
                            .into_par_iter()
                            .map(|i| {
                                workers.lock().unwrap().insert(rayon::current_thread_index());
                                std::thread::sleep(Duration::from_micros(500));
                                i * i
                            })
                            .sum::<u64>()
                    },
                    |poll| {
                        let mut polls = 0u64;
                        while !poll() {
                            polls += 1;
                        }
                        polls
                    },
                )
            });
            assert_eq!(sum, (0..64u64).map(|i| i * i).sum::<u64>());
            assert_eq!(workers.lock().unwrap().len(), threads, "{threads} threads");
            if threads == 1 {
                assert_eq!(b, 0, "b runs after a: done at the first poll");
            }
        }
        // The flag set by a pending job of the pool: the helper runs it, then returns.
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        two.install(|| {
            let done = Arc::new(AtomicBool::new(false));
            let d = Arc::clone(&done);
            rayon::spawn(move || {
                std::thread::sleep(Duration::from_millis(1));
                d.store(true, Ordering::Release);
            });
            assert!(help_until(&done, Duration::from_secs(60)));
        });
    }
}
