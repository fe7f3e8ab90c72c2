//! Keeping the pool's other workers awake through a short serial step.
//!
//! A rayon worker that finds no work spins for a few rounds and then sleeps; the next
//! parallel step has to wake it (a futex call and a reschedule), and until then its share
//! of the work waits. The front-to-back occlusion walk alternates a serial step (finding
//! the next batch, 0.1–0.5 ms) with a parallel one (drawing it) tens of times per frame, so
//! the workers fall asleep before every batch: on a 2-core machine a batch that takes
//! 33 µs back to back took 93 µs after 300 µs of serial work. While the serial step runs,
//! [`KeepAwake`] gives every other worker a job that spins until the step ends, at most
//! [`MAX_SPIN`]: the cores are idle then anyway, and they start the batch at once. This is
//! the "active" wait policy of OpenMP runtimes, limited to the steps that need it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The longest a worker spins for one serial step; past it, it may sleep.
pub(crate) const MAX_SPIN: Duration = Duration::from_millis(2);

/// Keeps the current pool's other workers spinning until dropped (see the module docs).
pub(crate) struct KeepAwake {
    done: Option<Arc<AtomicBool>>,
}

impl KeepAwake {
    /// Starts a spinning job for every other worker of the current rayon pool (none on a
    /// one-thread pool).
    pub(crate) fn start() -> Self {
        let others = rayon::current_num_threads().saturating_sub(1);
        if others == 0 {
            return Self { done: None };
        }
        let done = Arc::new(AtomicBool::new(false));
        for _ in 0..others {
            let d = Arc::clone(&done);
            rayon::spawn(move || {
                spin_until(&d, MAX_SPIN);
            });
        }
        Self { done: Some(done) }
    }
}

/// Spins until `done` is set (true) or `limit` has passed (false).
fn spin_until(done: &AtomicBool, limit: Duration) -> bool {
    let t = Instant::now();
    loop {
        if done.load(Ordering::Acquire) {
            return true;
        }
        if t.elapsed() >= limit {
            return false;
        }
        std::hint::spin_loop();
    }
}

impl Drop for KeepAwake {
    fn drop(&mut self) {
        if let Some(d) = &self.done {
            d.store(true, Ordering::Release);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spinner lets go when the step ends, and gives up at its limit when it does not;
    /// a one-thread pool gets none (its only worker is the one doing the step), a
    /// two-thread pool one, released when the guard drops.
    #[test]
    fn spinners_let_go_when_the_step_ends() {
        let done = Arc::new(AtomicBool::new(false));
        let d = Arc::clone(&done);
        let setter = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(1));
            d.store(true, Ordering::Release);
        });
        assert!(spin_until(&done, Duration::from_secs(60)));
        setter.join().unwrap();
        assert!(!spin_until(&AtomicBool::new(false), Duration::from_micros(100)));

        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        one.install(|| assert!(KeepAwake::start().done.is_none()));
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        two.install(|| {
            let awake = KeepAwake::start();
            let flag = Arc::clone(awake.done.as_ref().unwrap());
            assert!(!flag.load(Ordering::Acquire));
            drop(awake);
            assert!(flag.load(Ordering::Acquire));
        });
    }
}
