//! Playing animations: sample every channel at one time and set the targeted nodes' local
//! transforms (see the parent module for the rules on time and untargeted components).
//!
//! The new local transform of a node goes through [`Scene::set_local_transform`], so the node
//! is marked dirty (and whatever else the scene records about edits happens) exactly as for an
//! edit made by hand.

use super::playback::Playback;
use super::Animation;
use crate::{Error, Result, Scene};

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
        let one = std::slice::from_ref(self);
        play(one, &mut Playback::new(one), scene, t)
    }
}

/// Plays `animations` (laid out as `playback`) in order at time `t`: every node pose is
/// sampled first (in parallel when there are many), then the poses are laid over the nodes'
/// current transforms and set one after another, in the animations' order, so that a later
/// animation wins exactly where it sets a component.
fn play(animations: &[Animation], playback: &mut Playback, scene: &mut Scene, t: f32) -> Result<usize> {
    if !t.is_finite() {
        let Some(a) = animations.first() else { return Ok(0) };
        return Err(Error::Animation { name: a.name.clone(), why: format!("time {t} is not finite") });
    }
    let parallel = playback.run_count() >= PARALLEL_POSES;
    let mut set = 0;
    let mut first_error = None;
    for (run, pose) in playback.sample(t, parallel.then_some(PARALLEL_POSES / 4)) {
        match pose.over(scene, run.target).and_then(|t| scene.set_local_transform(run.target, t)) {
            Ok(()) => set += 1,
            Err(e) => {
                let a = &animations[run.animation];
                first_error.get_or_insert(Error::Animation {
                    name: a.name.clone(),
                    why: format!(
                        "channel {} ({}): {e}",
                        run.first_channel,
                        a.channels[run.first_channel].curve.property()
                    ),
                });
            }
        }
    }
    match first_error {
        Some(e) => Err(e),
        None => Ok(set),
    }
}

impl Scene {
    /// Plays every animation of the scene at time `t` (seconds): sets the local transforms
    /// their channels target (each animation wraps time as its [`crate::animation::Wrap`]
    /// says; animations later in [`Scene::animations`] win where two drive the same
    /// component). Returns the number of node transforms set. Call
    /// [`Scene::update_transforms`] before drawing.
    ///
    /// Errors as [`Animation::apply`]; every animation is applied before the first error is
    /// returned.
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
