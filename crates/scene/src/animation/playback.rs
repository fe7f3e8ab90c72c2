//! The scene's animations laid out for playing them frame after frame.
//!
//! An [`Animation`] keeps each sampler's key times and values in vectors of their own, behind
//! the animation's channel list: sampling ten thousand animated vehicles follows three
//! pointers per channel to memory scattered over the heap, and pays a cache miss at each.
//! A [`Playback`] copies what playing needs into a few flat arrays, in the order playing
//! reads them — per node pose the channels, their key times, their values — so one frame's
//! sampling walks memory forward, as the hardware prefetcher likes.
//!
//! Two more things are done once here instead of every frame, as animation systems in games
//! do (Gregory, *Game Engine Architecture*, 3rd ed., §12.4 "Clips" and §12.6 on pose
//! extraction): each animation's duration is precomputed, and consecutive channels of one
//! node whose key times are equal (a glTF file's samplers often share their input accessor;
//! the built-in traffic's translation and rotation keys do) share one key track, searched
//! once per pose. Each track remembers the key interval it was last found in, so that time
//! moving forward costs one or two comparisons instead of a binary search (`locate`); the
//! answer never depends on it, so a frame is the same whatever was played before.
//!
//! The copy is made on the first [`Scene::animate`] after the scene's animations change
//! ([`Scene::animations_mut`], [`Scene::add_animation`], loading, instantiating) and kept
//! until they change again; [`Animation::apply`] makes one for the single animation.

use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{Quat, Vec3};
use rayon::prelude::*;

use super::sampler::{interpolate, locate, Interpolation, Sampler, Span};
use super::{Animation, Curve, Keyframe, Property, Wrap};
use crate::{NodeId, Result, Scene, Transform};

/// The components of one node's TRS set by its channels; `None`: keep the node's.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct Pose {
    pub translation: Option<Vec3>,
    pub rotation: Option<Quat>,
    pub scale: Option<Vec3>,
}

impl Pose {
    /// The node's new local transform: the sampled components over its current ones, as the
    /// scene keeps them ([`Scene::local_transform`]: the TRS as last set, so a zero or
    /// negative scale keeps its rotation and its mirrored axes frame after frame).
    pub(crate) fn over(&self, scene: &Scene, node: NodeId) -> Result<Transform> {
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

/// What playing one animation needs besides its channels.
#[derive(Debug)]
struct Clip {
    wrap: Wrap,
    /// [`Animation::duration`], computed once.
    duration: f32,
}

impl Clip {
    /// [`Animation::local_time`] with the precomputed duration (the same arithmetic).
    fn local_time(&self, t: f32) -> f32 {
        match self.wrap {
            Wrap::Clamp => t,
            Wrap::Loop if self.duration > 0.0 => t.rem_euclid(self.duration),
            Wrap::Loop => 0.0,
        }
    }
}

/// One node pose: the consecutive channels of one animation aimed at one node.
#[derive(Debug)]
pub(crate) struct Run {
    /// The node posed.
    pub target: NodeId,
    /// Index of the animation in the list played.
    pub animation: usize,
    /// Index of the run's first channel in that animation (for messages).
    pub first_channel: usize,
    /// The run's channels in [`Playback::channels`].
    channels: Range<u32>,
}

/// Key times shared by consecutive channels of one run, with the interval last found.
#[derive(Debug)]
struct Track {
    times: Range<u32>,
    /// The key interval the last sampled time fell in: where the next search starts. Only
    /// the run owning the track touches it, so relaxed order is enough (the atomic only lets
    /// poses be sampled in parallel through a shared reference).
    hint: AtomicUsize,
}

/// One channel: what it drives, on which key track, with which values.
#[derive(Debug)]
struct Channel {
    property: Property,
    interpolation: Interpolation,
    track: u32,
    /// Start of the channel's values in `vec3s` (translation, scale) or `quats` (rotation).
    values: u32,
}

/// The animations of a scene, flattened for playing (see the module documentation).
#[derive(Debug, Default)]
pub(crate) struct Playback {
    clips: Vec<Clip>,
    runs: Vec<Run>,
    channels: Vec<Channel>,
    tracks: Vec<Track>,
    times: Vec<f32>,
    vec3s: Vec<Vec3>,
    quats: Vec<Quat>,
    /// The poses last sampled, one per run (kept to reuse the allocation).
    poses: Vec<Pose>,
}

/// Appends `s`'s values to `store`, returning where they start.
fn push_values<T: Keyframe>(store: &mut Vec<T>, s: &Sampler<T>) -> u32 {
    let at = store.len() as u32;
    store.extend_from_slice(s.values());
    at
}

impl Playback {
    /// The flat copy of `animations` (played in this order).
    pub(crate) fn new(animations: &[Animation]) -> Playback {
        let mut p = Playback::default();
        for (a, anim) in animations.iter().enumerate() {
            p.clips.push(Clip { wrap: anim.wrap, duration: anim.duration() });
            for run in anim.runs() {
                let first = p.channels.len() as u32;
                let mut last_times: Option<&[f32]> = None;
                for c in &anim.channels[run.clone()] {
                    let (times, interpolation) = match &c.curve {
                        Curve::Translation(s) | Curve::Scale(s) => (s.times(), s.interpolation()),
                        Curve::Rotation(s) => (s.times(), s.interpolation()),
                    };
                    if last_times != Some(times) {
                        let start = p.times.len() as u32;
                        p.times.extend_from_slice(times);
                        p.tracks.push(Track { times: start..p.times.len() as u32, hint: AtomicUsize::new(0) });
                        last_times = Some(times);
                    }
                    let values = match &c.curve {
                        Curve::Translation(s) | Curve::Scale(s) => push_values(&mut p.vec3s, s),
                        Curve::Rotation(s) => push_values(&mut p.quats, s),
                    };
                    let track = p.tracks.len() as u32 - 1;
                    p.channels.push(Channel { property: c.curve.property(), interpolation, track, values });
                }
                let channels = first..p.channels.len() as u32;
                let target = anim.channels[run.start].target;
                p.runs.push(Run { target, animation: a, first_channel: run.start, channels });
            }
        }
        p
    }

    /// The node poses, in the order they are set (animation by animation).
    pub(crate) fn runs(&self) -> &[Run] {
        &self.runs
    }

    /// Every run with its pose at time `t`, in the order of [`Playback::runs`]; sampled on
    /// the rayon pool in batches of at least `parallel` runs when given.
    pub(crate) fn sample(&mut self, t: f32, parallel: Option<usize>) -> impl Iterator<Item = (&Run, &Pose)> {
        let mut poses = std::mem::take(&mut self.poses);
        match parallel {
            Some(batch) => {
                self.runs.par_iter().with_min_len(batch).map(|r| self.pose(r, t)).collect_into_vec(&mut poses)
            }
            None => {
                poses.clear();
                poses.extend(self.runs.iter().map(|r| self.pose(r, t)));
            }
        }
        self.poses = poses;
        self.runs.iter().zip(&self.poses)
    }

    /// The pose `run` gives its node when the animations play at time `t`.
    pub(crate) fn pose(&self, run: &Run, t: f32) -> Pose {
        let t = self.clips[run.animation].local_time(t);
        let mut pose = Pose::default();
        let mut found: Option<(u32, Span)> = None;
        for c in &self.channels[run.channels.start as usize..run.channels.end as usize] {
            let track = &self.tracks[c.track as usize];
            let times = &self.times[track.times.start as usize..track.times.end as usize];
            let span = match found {
                Some((k, span)) if k == c.track => span,
                _ => {
                    let span = locate(times, t, track.hint.load(Ordering::Relaxed));
                    track.hint.store(span.hint(), Ordering::Relaxed);
                    found = Some((c.track, span));
                    span
                }
            };
            let n = times.len() * c.interpolation.values_per_key();
            let at = c.values as usize;
            match c.property {
                Property::Translation => {
                    pose.translation = Some(interpolate(&self.vec3s[at..at + n], c.interpolation, span))
                }
                Property::Rotation => pose.rotation = Some(interpolate(&self.quats[at..at + n], c.interpolation, span)),
                Property::Scale => pose.scale = Some(interpolate(&self.vec3s[at..at + n], c.interpolation, span)),
            }
        }
        pose
    }
}

impl Animation {
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

#[cfg(test)]
mod tests {
    use proptest::prelude::*;
    use slotmap::KeyData;

    use super::*;

    fn node(i: u64) -> NodeId {
        NodeId::from(KeyData::from_ffi((1u64 << 32) | i))
    }

    /// An animation of `nodes` nodes, each with a translation, rotation and scale channel;
    /// `shared` makes the rotation reuse the translation's key times.
    fn animation(keys: &[f32], nodes: u64, interpolation: Interpolation, shared: bool, wrap: Wrap) -> Animation {
        let per = interpolation.values_per_key();
        let n = keys.len() * per;
        let vecs: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f32, (i * i) as f32 * 0.1, 1.0 - i as f32)).collect();
        let quats: Vec<Quat> = (0..n).map(|i| Quat::from_rotation_y(i as f32 * 0.7)).collect();
        let other: Vec<f32> = keys.iter().map(|k| k * 1.5).collect();
        let mut a = Animation::new("test").with_wrap(wrap);
        for i in 0..nodes {
            let r_keys = if shared { keys.to_vec() } else { other.clone() };
            a = a
                .with_channel(
                    node(i),
                    Curve::Translation(Sampler::new(keys.to_vec(), vecs.clone(), interpolation).unwrap()),
                )
                .with_channel(node(i), Curve::Rotation(Sampler::new(r_keys, quats.clone(), interpolation).unwrap()))
                .with_channel(node(i), Curve::Scale(Sampler::new(keys.to_vec(), vecs.clone(), interpolation).unwrap()));
        }
        a
    }

    /// The pose as the animation's own samplers give it.
    fn direct(a: &Animation, node: NodeId, t: f32) -> (Vec3, Quat, Vec3) {
        let t = a.local_time(t);
        let mut out = (Vec3::NAN, Quat::NAN, Vec3::NAN);
        for c in a.channels.iter().filter(|c| c.target == node) {
            match &c.curve {
                Curve::Translation(s) => out.0 = s.sample(t),
                Curve::Rotation(s) => out.1 = s.sample(t),
                Curve::Scale(s) => out.2 = s.sample(t),
            }
        }
        out
    }

    #[test]
    fn shared_key_times_make_one_track() {
        let keys = [0.0, 1.0, 2.0];
        let shared = Playback::new(&[animation(&keys, 3, Interpolation::Linear, true, Wrap::Clamp)]);
        let apart = Playback::new(&[animation(&keys, 3, Interpolation::Linear, false, Wrap::Clamp)]);
        // Translation and rotation share; scale has the same times again: still one track.
        assert_eq!((shared.runs.len(), shared.tracks.len()), (3, 3));
        assert_eq!(apart.tracks.len(), 9);
        assert_eq!(shared.times.len(), 9);
    }

    proptest! {
        /// Played forward, backward and at random, the playback's poses equal the samplers'
        /// own: the remembered interval never changes an answer.
        #[test]
        fn poses_equal_the_samplers(
            gaps in prop::collection::vec(0.01f32..3.0, 2..12),
            times in prop::collection::vec(-5.0f32..40.0, 1..40),
            mode in 0usize..3,
            shared: bool,
            looped: bool,
        ) {
            let keys: Vec<f32> = gaps.iter().scan(-1.0, |t, g| { *t += g; Some(*t) }).collect();
            let interpolation = [Interpolation::Step, Interpolation::Linear, Interpolation::CubicSpline][mode];
            let wrap = if looped { Wrap::Loop } else { Wrap::Clamp };
            let a = animation(&keys, 2, interpolation, shared, wrap);
            let p = Playback::new(std::slice::from_ref(&a));
            let mut sorted = times.clone();
            sorted.sort_by(f32::total_cmp);
            for t in times.iter().chain(&sorted).chain(sorted.iter().rev()).copied().chain([f32::NAN]) {
                for run in p.runs() {
                    let pose = p.pose(run, t);
                    let got = (pose.translation.unwrap(), pose.rotation.unwrap(), pose.scale.unwrap());
                    let want = direct(&a, run.target, t);
                    prop_assert_eq!(got.0.to_array(), want.0.to_array());
                    prop_assert_eq!(got.1.to_array(), want.1.to_array());
                    prop_assert_eq!(got.2.to_array(), want.2.to_array());
                }
            }
        }
    }
}
