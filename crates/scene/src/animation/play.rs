//! Playing animations: sample every channel at one time and set the targeted nodes' local
//! transforms (see the parent module for the rules on time and untargeted components).
//!
//! The new local transform of a node goes through [`Scene::set_local_transform`], so the node
//! is marked dirty (and whatever else the scene records about edits happens) exactly as for an
//! edit made by hand.

use std::ops::Range;

use glam::{Quat, Vec3};
use rayon::prelude::*;

use super::{Animation, Curve};
use crate::{Error, NodeId, Result, Scene, Transform};

/// From this many node poses on, they are sampled on several threads.
const PARALLEL_POSES: usize = 1024;

/// The components of one node's TRS set by consecutive channels; `None`: keep the node's.
#[derive(Default)]
struct Pose {
    translation: Option<Vec3>,
    rotation: Option<Quat>,
    scale: Option<Vec3>,
}

impl Pose {
    fn sample(&mut self, curve: &Curve, t: f32) {
        match curve {
            Curve::Translation(s) => self.translation = Some(s.sample(t)),
            Curve::Rotation(s) => self.rotation = Some(s.sample(t)),
            Curve::Scale(s) => self.scale = Some(s.sample(t)),
        }
    }

    /// The node's new local transform: the sampled components over its current ones, as the
    /// scene keeps them ([`Scene::local_transform`]: the TRS as last set, so a zero or
    /// negative scale keeps its rotation and its mirrored axes frame after frame).
    fn over(&self, scene: &Scene, node: NodeId) -> Result<Transform> {
        let trs = match (self.translation, self.rotation, self.scale) {
            (Some(translation), Some(rotation), Some(scale)) => Transform { translation, rotation, scale },
            (t, r, s) => {
                let current = scene.local_transform(node)?;
                Transform {
                    translation: t.unwrap_or(current.translation),
                    rotation: r.unwrap_or(current.rotation),
                    scale: s.unwrap_or(current.scale),
                }
            }
        };
        Ok(trs)
    }
}

impl Animation {
    /// Sets the local transforms of the nodes this animation targets to their values at
    /// time `t` (seconds; see [`Animation::local_time`] for times outside the keys). Returns
    /// how many node transforms were set. The nodes are marked dirty: call
    /// [`Scene::update_transforms`] before drawing.
    ///
    /// Errors: a non-finite `t`; a channel aimed at a node no longer in `scene` (the other
    /// channels are still applied, the error names the first such channel).
    pub fn apply(&self, scene: &mut Scene, t: f32) -> Result<usize> {
        play(std::slice::from_ref(self), scene, t)
    }

    /// The runs of consecutive channels with one target: each makes one node's pose.
    fn runs(&self) -> impl Iterator<Item = Range<usize>> + '_ {
        let mut first = 0;
        std::iter::from_fn(move || {
            let target = self.channels.get(first)?.target;
            let run = self.channels[first..].iter().take_while(|c| c.target == target).count();
            first += run;
            Some(first - run..first)
        })
    }
}

/// Plays `animations` in order at time `t`: every node pose is sampled first (in parallel
/// when there are many: each curve is its own allocation, so a scene of many animated
/// objects is bound by cache misses that threads overlap), then the poses are laid over
/// the nodes' current transforms and set one after another, in the animations' order, so
/// that a later animation wins exactly where it sets a component.
fn play(animations: &[Animation], scene: &mut Scene, t: f32) -> Result<usize> {
    let mut first_error = None;
    if !t.is_finite() {
        let Some(a) = animations.first() else { return Ok(0) };
        return Err(Error::Animation { name: a.name.clone(), why: format!("time {t} is not finite") });
    }
    let jobs: Vec<(usize, Range<usize>)> =
        animations.iter().enumerate().flat_map(|(k, a)| a.runs().map(move |r| (k, r))).collect();
    let sample = |(k, r): &(usize, Range<usize>)| {
        let a = &animations[*k];
        let t = a.local_time(t);
        let mut pose = Pose::default();
        for c in &a.channels[r.clone()] {
            pose.sample(&c.curve, t);
        }
        pose
    };
    let poses: Vec<Pose> = if jobs.len() >= PARALLEL_POSES {
        jobs.par_iter().with_min_len(PARALLEL_POSES / 4).map(sample).collect()
    } else {
        jobs.iter().map(sample).collect()
    };
    let mut set = 0;
    for ((k, r), pose) in jobs.iter().zip(poses) {
        let first = &animations[*k].channels[r.start];
        match pose.over(scene, first.target).and_then(|t| scene.set_local_transform(first.target, t)) {
            Ok(()) => set += 1,
            Err(e) => {
                first_error.get_or_insert(Error::Animation {
                    name: animations[*k].name.clone(),
                    why: format!("channel {} ({}): {e}", r.start, first.curve.property()),
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
        let animations = std::mem::take(&mut self.animations);
        let result = play(&animations, self, t);
        self.animations = animations;
        result
    }

    /// The longest [`Animation::duration`] of the scene's animations (0 without any).
    pub fn animation_duration(&self) -> f32 {
        self.animations.iter().map(Animation::duration).fold(0.0, f32::max)
    }

    /// Drops the animation channels whose target node is gone (after
    /// [`Scene::remove_node`]), and animations left without channels; returns how many
    /// channels were dropped.
    pub fn drop_dead_animation_channels(&mut self) -> usize {
        let animations = std::mem::take(&mut self.animations);
        let mut dropped = 0;
        self.animations = animations
            .into_iter()
            .filter_map(|mut a| {
                let before = a.channels.len();
                a.channels.retain(|c| self.node(c.target).is_some());
                dropped += before - a.channels.len();
                (!a.channels.is_empty() || before == 0).then_some(a)
            })
            .collect();
        dropped
    }
}
