//! Playing animations: sample every channel at one time and set the targeted nodes' local
//! transforms (see the parent module for the rules on time and untargeted components).
//!
//! The new local transform of a node is set by the code [`Scene::set_local_transform`] runs
//! (given only the components its channels set), so the node is marked dirty (and whatever
//! else the scene records about edits happens) exactly as for an edit made by hand.

use super::playback::{Playback, Pose};
use super::{Animation, Curve};
use crate::{Error, NodeId, Result, Scene};

/// From this many node poses on, they are sampled on several threads.
const PARALLEL_POSES: usize = 1024;

impl Animation {
    /// Sets the local transforms of the nodes this animation targets to their values at
    /// time `t` (seconds; see [`Animation::local_time`] for times outside the keys). Returns
    /// how many node transforms were set. The nodes are marked dirty: call
    /// [`Scene::update_transforms`] before drawing.
    ///
    /// Errors: a non-finite `t`; a channel aimed at a node no longer in `scene` (the other
    /// channels are still applied, the error names the first such channel).
    pub fn apply(&self, scene: &mut Scene, t: f32) -> Result<usize> {
        finite_time(std::slice::from_ref(self), t)?;
        let local = self.local_time(t);
        let mut out = Outcome::default();
        for run in self.runs() {
            let mut pose = Pose::default();
            for c in &self.channels[run.clone()] {
                match &c.curve {
                    Curve::Translation(s) => pose.translation = Some(s.sample(local)),
                    Curve::Rotation(s) => pose.rotation = Some(s.sample(local)),
                    Curve::Scale(s) => pose.scale = Some(s.sample(local)),
                }
            }
            out.set(scene, (self, run.start), self.channels[run.start].target, &pose);
        }
        out.result()
    }
}

/// An error unless `t` is finite (named after the first animation).
fn finite_time(animations: &[Animation], t: f32) -> Result<()> {
    match animations.first() {
        Some(a) if !t.is_finite() => {
            Err(Error::Animation { name: a.name.clone(), why: format!("time {t} is not finite") })
        }
        _ => Ok(()),
    }
}

/// Poses set so far, and the first that could not be.
#[derive(Default)]
struct Outcome {
    set: usize,
    first_error: Option<Error>,
}

impl Outcome {
    /// Lays `pose` over `target`, the node that channel `first` of `a` (and those after it in
    /// its run) drives, and sets it; a failure is kept (the first one) naming the animation
    /// and channel.
    #[inline(always)]
    fn set(&mut self, scene: &mut Scene, (a, first): (&Animation, usize), target: NodeId, pose: &Pose) {
        match scene.set_local_components(target, pose.translation, pose.rotation, pose.scale) {
            Ok(()) => self.set += 1,
            Err(e) => self.fail(a, first, e),
        }
    }

    #[cold]
    fn fail(&mut self, a: &Animation, first: usize, e: Error) {
        if self.first_error.is_none() {
            let why = format!("channel {first} ({}): {e}", a.channels[first].curve.property());
            self.first_error = Some(Error::Animation { name: a.name.clone(), why });
        }
    }

    fn result(self) -> Result<usize> {
        match self.first_error {
            Some(e) => Err(e),
            None => Ok(self.set),
        }
    }
}

/// Plays `animations` (laid out as `playback`) in order at time `t`: every node pose is
/// sampled first (in parallel when there are many), then the poses are laid over the nodes'
/// current transforms and set one after another, in the animations' order, so that a later
/// animation wins exactly where it sets a component.
fn play(animations: &[Animation], playback: &mut Playback, scene: &mut Scene, t: f32) -> Result<usize> {
    finite_time(animations, t)?;
    let parallel = playback.run_count() >= PARALLEL_POSES;
    let mut out = Outcome::default();
    for (run, pose) in playback.sample(t, parallel.then_some(PARALLEL_POSES / 4)) {
        out.set(scene, (&animations[run.animation], run.first_channel), run.target, &pose);
    }
    out.result()
}

impl Scene {
    /// Plays every animation of the scene at time `t` (seconds): sets the local transforms
    /// their channels target (each animation wraps time as its [`crate::animation::Wrap`]
    /// says; animations later in [`Scene::animations`] win where two drive the same
    /// component). Returns the number of node transforms set. Call
    /// [`Scene::update_transforms`] before drawing.
    ///
    /// Errors as [`Animation::apply`] (channels aimed at nodes removed with
    /// [`Scene::remove_node`] are dropped first, not reported); every animation is applied
    /// before the first error is returned.
    pub fn animate(&mut self, t: f32) -> Result<usize> {
        if std::mem::take(&mut self.dead_channels) {
            self.drop_dead_animation_channels();
        }
        let animations = std::mem::take(self.animations_keeping_playback());
        let mut playback = self.playback.take().unwrap_or_else(|| Playback::new(&animations));
        let result = play(&animations, &mut playback, self, t);
        *self.animations_keeping_playback() = animations;
        self.playback = Some(playback);
        result
    }

    /// The longest [`Animation::duration`] of the scene's animations (0 without any).
    pub fn animation_duration(&self) -> f32 {
        self.animations().iter().map(Animation::duration).fold(0.0, f32::max)
    }

    /// Drops the animation channels whose target node is gone (after
    /// [`Scene::remove_node`]), and animations left without channels; returns how many
    /// channels were dropped.
    pub fn drop_dead_animation_channels(&mut self) -> usize {
        // Removing a node no channel drives keeps the layout for playing.
        if self.animations().iter().all(|a| a.channels.iter().all(|c| self.node(c.target).is_some())) {
            return 0;
        }
        let animations = std::mem::take(self.animations_mut());
        let mut dropped = 0;
        let kept = animations
            .into_iter()
            .filter_map(|mut a| {
                let before = a.channels.len();
                a.channels.retain(|c| self.node(c.target).is_some());
                dropped += before - a.channels.len();
                (!a.channels.is_empty() || before == 0).then_some(a)
            })
            .collect();
        *self.animations_mut() = kept;
        dropped
    }
}
