//! Rebuilding a degraded tree off the frame.
//!
//! A refitted tree that has grown too costly (see [`RefitOutcome`]) is rebuilt from
//! scratch, and built where the frame waits for it that rebuild is a hitch: in a city with
//! 10,000 vehicles driving, the cluster BVH's 22,000 items took 7–9 ms to rebuild every
//! 2.5 s of animation, three frames' worth. So the rebuild runs on a background thread
//! from a copy of the boxes at the update that asked for it, while the frames go on with the
//! old tree refitted (still exact, a little slower to traverse); [`rebuild_lag`] updates
//! later (8 for a tree of up to 8,191 items, more for larger trees) the new tree is put in
//! place and refitted to the boxes of that moment. This is the "prepare in the background,
//! swap at a fixed point" scheme of physics engines' broad phases (Jolt Physics'
//! `BroadPhaseQuadTree::UpdatePrepare`/`UpdateFinalize`, the PhysX pruner's tree rebuilt
//! across frames).
//!
//! The swap comes at a fixed count of updates, not when the thread happens to finish (the
//! update waits for it then), so which tree a frame culls with, and every counter that
//! follows from it, is the same in every run and for any number of threads. The background
//! thread is one for the process, in a rayon pool of its own: the build's parallel loops run
//! there one after another instead of taking the frame's workers. It comes on top of them:
//! a run capped to one worker (`--threads 1`) still builds on a second core while a
//! rebuild is under way, and culls with the same trees as a run on any number of workers.

use std::fmt;
use std::sync::{mpsc, Mutex, OnceLock};

use super::policy::{cost_ratio, RefitOutcome, REBUILD_RATIO};

/// Updates from the one that starts a background rebuild to the one that puts its tree in
/// place, for trees of fewer than [`LAG_ITEMS`] items (see [`rebuild_lag`]). The build must
/// be done by then or that update waits: a 22,000-item cluster BVH took 10.5–11.5 ms on the
/// background thread beside frames using both cores, four frames of a street walk.
pub const REBUILD_LAG: u32 = 8;

/// Items per further update of lag (see [`rebuild_lag`]).
pub const LAG_ITEMS: usize = 8192;

/// The updates a background rebuild of a tree over `items` items is given before its tree
/// is put in place: [`REBUILD_LAG`], plus one per [`LAG_ITEMS`] items, since the build's
/// time grows with the items and so, in practice, does a frame's. The 1.14 million
/// clusters of `city:100000000` build in about 0.5 s on two threads; 147 updates of its
/// 17 ms street frames leave the one background thread 2.5 s.
pub fn rebuild_lag(items: usize) -> u32 {
    REBUILD_LAG.saturating_add((items / LAG_ITEMS).try_into().unwrap_or(u32::MAX))
}

/// The rebuild under way off the frame of a tree of type `T`, if any.
pub(crate) struct Background<T> {
    job: Option<Job<T>>,
}

struct Job<T> {
    /// The tree and its SAH cost. Behind a lock only so that the owner stays `Sync` (one
    /// thread receives).
    result: Mutex<mpsc::Receiver<(T, f32)>>,
    /// Updates before the tree is due.
    left: u32,
    /// The refit's cost ratio that started the build.
    trigger: f32,
}

impl<T> Default for Background<T> {
    fn default() -> Self {
        Background { job: None }
    }
}

/// A copy does not share the build under way: it starts its own when it needs one.
impl<T> Clone for Background<T> {
    fn clone(&self) -> Self {
        Background::default()
    }
}

impl<T> fmt::Debug for Background<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.job {
            Some(j) => write!(f, "Background(due in {} updates)", j.left),
            None => f.write_str("Background(idle)"),
        }
    }
}

impl<T: Send + 'static> Background<T> {
    /// One update of `tree` (built with SAH cost `build_cost`) to the item boxes `boxes`,
    /// by the rule of [`RefitOutcome`] with the rebuild off the frame:
    ///
    /// * when this update is the one a background build is due at, its tree is put in
    ///   place (waiting for it if need be) and refitted by `refit_all`, or built here and
    ///   now when the boxes no longer fit it (a box changed kind since);
    /// * otherwise the tree is refitted by `refit` (its SAH cost, `None` when the boxes no
    ///   longer fit it: then it is rebuilt here and now, and a build under way is dropped);
    ///   beyond [`REBUILD_RATIO`] a build from a copy of `boxes` is started on the
    ///   background thread, unless one is under way already (or no thread can be had: then
    ///   it is rebuilt here and now).
    ///
    /// `fresh` builds a tree and its SAH cost from boxes.
    pub fn update<B: Clone + Send + 'static>(
        &mut self,
        (tree, build_cost): (&mut T, &mut f32),
        boxes: &[B],
        refit_all: impl FnOnce(&mut T, &[B]) -> Option<f32>,
        refit: impl FnOnce(&mut T) -> Option<f32>,
        fresh: impl Fn(&[B]) -> (T, f32) + Copy + Send + 'static,
    ) -> RefitOutcome {
        if let Some(((t, cost), trigger)) = self.due() {
            (*tree, *build_cost) = (t, cost);
            if refit_all(tree, boxes).is_none() {
                (*tree, *build_cost) = fresh(boxes);
            }
            return RefitOutcome::Rebuilt { cost_ratio: trigger };
        }
        let r = match refit(tree).map(|c| cost_ratio(c, *build_cost)) {
            Some(r) if r <= REBUILD_RATIO => return RefitOutcome::Refitted { cost_ratio: r },
            Some(r) => r,
            None => {
                self.job = None;
                return RefitOutcome::decide(None, || (*tree, *build_cost) = fresh(boxes));
            }
        };
        if self.job.is_some() {
            return RefitOutcome::Rebuilding { cost_ratio: r };
        }
        let Some(pool) = pool() else {
            return RefitOutcome::decide(Some(r), || (*tree, *build_cost) = fresh(boxes));
        };
        let (send, result) = mpsc::channel();
        let snapshot = boxes.to_vec();
        pool.spawn(move || {
            // The receiver is gone when the tree was dropped or replaced meanwhile.
            let _ = send.send(fresh(&snapshot));
        });
        self.job = Some(Job { result: Mutex::new(result), left: rebuild_lag(boxes.len()), trigger: r });
        RefitOutcome::Rebuilding { cost_ratio: r }
    }

    /// Counts one update, and when it is the one the build under way is due at, waits for
    /// it and returns the tree and its cost with the ratio that started it. `None`
    /// otherwise, and when the build failed (its thread panicked): the rule then starts
    /// another.
    fn due(&mut self) -> Option<((T, f32), f32)> {
        let job = self.job.as_mut()?;
        job.left = job.left.saturating_sub(1);
        if job.left > 0 {
            return None;
        }
        let job = self.job.take()?;
        let tree = job.result.into_inner().ok()?.recv().ok()?;
        Some((tree, job.trigger))
    }
}

/// The process's background thread for rebuilds (`None` when the system gives no thread).
fn pool() -> Option<&'static rayon::ThreadPool> {
    static POOL: OnceLock<Option<rayon::ThreadPool>> = OnceLock::new();
    POOL.get_or_init(|| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .thread_name(|_| "sightline-rebuild".into())
            // A panicking build drops its sender: `due` then reports no tree, and the
            // owner's rule starts another at its next update.
            .panic_handler(|_| {})
            .build()
            .ok()
    })
    .as_ref()
}
