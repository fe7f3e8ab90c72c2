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
//! do (Gregory, *Game Engine Architecture*, 3rd ed., ch. 12 on clips and pose extraction):
//! each animation's duration is precomputed, and consecutive channels of one node whose key
//! times are equal (a glTF file's samplers often share their input accessor; the built-in
//! traffic's translation and rotation keys do) store them once. And each channel keeps the
//! key interval its last time fell in, with the two key values interpolating there reads
//! (a `Segment`, in an array in channel order): while time stays in the interval — nearly
//! every frame, for keys seconds apart — a channel reads its segment and nothing else, so
//! sampling streams through two arrays in order. When time leaves it, the interval after it
//! is tried before a binary search (`locate`). The answer never depends on what was kept:
//! a frame is the same bits whatever was played before (test).
//!
//! The copy is made on the first [`Scene::animate`](crate::Scene::animate) after the
//! scene's animations change ([`Scene::animations_mut`](crate::Scene::animations_mut), or
//! removing a node some channel drives) and kept until they change again;
//! [`Scene::add_animation`](crate::Scene::add_animation) (loading and instantiating too)
//! extends it.
//! [`Animation::apply`] plays one animation from its own samplers, with no copy.

use std::ops::Range;

use glam::{Quat, Vec3, Vec4};
use rayon::prelude::*;

use super::sampler::{interpolate, locate, Interpolation, Sampler, Span};
use super::{Animation, Curve, Keyframe, Property, Wrap};
use crate::NodeId;

/// The components of one node's TRS set by its channels; `None`: keep the node's.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct Pose {
    pub translation: Option<Vec3>,
    pub rotation: Option<Quat>,
    pub scale: Option<Vec3>,
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

/// One channel: what it drives, where its keys are, and whose time it plays.
#[derive(Debug)]
struct Channel {
    property: Property,
    interpolation: Interpolation,
    /// The animation ([`Playback::clips`]) whose local time the channel plays.
    clip: u32,
    /// The channel's key times in [`Keys::times`] (shared with the run's channel before it
    /// when equal).
    times: Range<u32>,
    /// Start of the channel's values in [`Keys::vec3s`] (translation, scale) or
    /// [`Keys::quats`] (rotation).
    values: u32,
}

/// Every channel's key times and values, one array of each kind.
#[derive(Debug, Default)]
struct Keys {
    times: Vec<f32>,
    vec3s: Vec<Vec3>,
    quats: Vec<Quat>,
}

/// The key interval a channel's last time fell in, with the two key values interpolating in
/// it reads (vectors with w = 0, quaternions as xyzw): while time stays in the interval, a
/// channel reads this and nothing else. Not kept for CUBICSPLINE, which reads tangents too.
#[derive(Debug, Clone, Copy)]
struct Segment {
    /// The interval's key times; NaN when there is none (every comparison fails).
    t0: f32,
    t1: f32,
    /// The interval's first key; kept as the search hint when `t0` is NaN.
    k: u32,
    v0: Vec4,
    v1: Vec4,
}

impl Segment {
    const NONE: Segment = Segment { t0: f32::NAN, t1: f32::NAN, k: 0, v0: Vec4::ZERO, v1: Vec4::ZERO };

    /// Whether `t` falls in the interval exactly as [`locate`] would place it there (in the
    /// first interval only after the first key: at it, `locate` answers the key itself).
    fn holds(&self, t: f32) -> bool {
        t < self.t1 && (self.t0 < t || (self.t0 == t && self.k > 0))
    }
}

/// The animations of a scene, flattened for playing (see the module documentation).
#[derive(Debug, Default)]
pub(crate) struct Playback {
    clips: Vec<Clip>,
    runs: Vec<Run>,
    channels: Vec<Channel>,
    keys: Keys,
    /// Per channel, the key interval last used.
    segments: Vec<Segment>,
    /// Per clip, its local time at the time last played.
    clip_times: Vec<f32>,
    /// Per channel, its value at the time last played (vectors with w = 0, quaternions as
    /// xyzw).
    values: Vec<Vec4>,
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
        for anim in animations {
            p.push(anim);
        }
        p
    }

    /// Lays out one more animation, played after the others (a scene that adds an animation
    /// extends its layout instead of making it again).
    pub(crate) fn push(&mut self, anim: &Animation) {
        let clip = self.clips.len() as u32;
        self.clips.push(Clip { wrap: anim.wrap, duration: anim.duration() });
        for run in anim.runs() {
            let first = self.channels.len() as u32;
            let mut last: Option<(&[f32], Range<u32>)> = None;
            for c in &anim.channels[run.clone()] {
                let (times, interpolation) = match &c.curve {
                    Curve::Translation(s) | Curve::Scale(s) => (s.times(), s.interpolation()),
                    Curve::Rotation(s) => (s.times(), s.interpolation()),
                };
                // Shared only when equal bit for bit: −0 and +0 key times would give blends
                // of opposite zero signs.
                let same =
                    |a: &[f32]| a.len() == times.len() && a.iter().zip(times).all(|(x, y)| x.to_bits() == y.to_bits());
                let range = match &last {
                    Some((shared, range)) if same(shared) => range.clone(),
                    _ => {
                        let start = self.keys.times.len() as u32;
                        self.keys.times.extend_from_slice(times);
                        let range = start..self.keys.times.len() as u32;
                        last = Some((times, range.clone()));
                        range
                    }
                };
                let values = match &c.curve {
                    Curve::Translation(s) | Curve::Scale(s) => push_values(&mut self.keys.vec3s, s),
                    Curve::Rotation(s) => push_values(&mut self.keys.quats, s),
                };
                let property = c.curve.property();
                self.channels.push(Channel { property, interpolation, clip, times: range, values });
                self.segments.push(Segment::NONE);
            }
            let channels = first..self.channels.len() as u32;
            let target = anim.channels[run.start].target;
            self.runs.push(Run { target, animation: clip as usize, first_channel: run.start, channels });
        }
    }

    /// How many node poses a frame sets.
    pub(crate) fn run_count(&self) -> usize {
        self.runs.len()
    }

    /// Every run with its pose at time `t`, in the order the poses are set (animation by
    /// animation). The channels are sampled first, on the rayon pool in batches of at least
    /// `parallel` channels when given.
    pub(crate) fn sample(&mut self, t: f32, parallel: Option<usize>) -> impl Iterator<Item = (&Run, Pose)> {
        let Playback { clips, runs, channels, keys, segments, clip_times, values } = self;
        let local = |c: &Clip| c.local_time(t);
        match parallel {
            Some(batch) => clips.par_iter().with_min_len(batch).map(local).collect_into_vec(clip_times),
            None => {
                clip_times.clear();
                clip_times.extend(clips.iter().map(local));
            }
        }
        let clip_times = &*clip_times;
        let value = |(c, seg): (&Channel, &mut Segment)| keys.value(c, seg, clip_times[c.clip as usize]);
        match parallel {
            Some(batch) => {
                channels.par_iter().zip(segments.par_iter_mut()).with_min_len(batch).map(value).collect_into_vec(values)
            }
            None => {
                values.clear();
                values.extend(channels.iter().zip(segments.iter_mut()).map(value));
            }
        }
        let (channels, values) = (&*channels, &*values);
        runs.iter().map(move |run| {
            let mut pose = Pose::default();
            for i in run.channels.start as usize..run.channels.end as usize {
                let v = values[i];
                match channels[i].property {
                    Property::Translation => pose.translation = Some(v.truncate()),
                    Property::Rotation => pose.rotation = Some(Quat::from_vec4(v)),
                    Property::Scale => pose.scale = Some(v.truncate()),
                }
            }
            (run, pose)
        })
    }
}

impl Keys {
    /// The value of channel `c` at its local time `t`, from its segment when `t` is still
    /// in it, else from its keys (the segment then moves to where `t` fell).
    fn value(&self, c: &Channel, seg: &mut Segment, t: f32) -> Vec4 {
        if seg.holds(t) {
            // What `locate` and `interpolate` do with the interval's two keys, the same bits
            // (written out here: the general `interpolate` on a two-key slice costs a fifth
            // of the whole animate step in bounds checks and the CUBICSPLINE branch).
            let Span::Between { s, .. } = Span::between(0, seg.t0, seg.t1, t) else { unreachable!() };
            return match (c.interpolation, c.property) {
                (Interpolation::Step, _) => seg.v0,
                (_, Property::Rotation) => {
                    Vec4::from(Quat::linear(Quat::from_vec4(seg.v0), Quat::from_vec4(seg.v1), s))
                }
                _ => Vec3::linear(seg.v0.truncate(), seg.v1.truncate(), s).extend(0.0),
            };
        }
        let times = &self.times[c.times.start as usize..c.times.end as usize];
        let span = locate(times, t, seg.k as usize);
        let n = times.len() * c.interpolation.values_per_key();
        let at = c.values as usize;
        let (value, next) = match c.property {
            Property::Rotation => sample_keys(&self.quats[at..at + n], c.interpolation, times, span, Vec4::from),
            _ => sample_keys(&self.vec3s[at..at + n], c.interpolation, times, span, |v| v.extend(0.0)),
        };
        *seg = next;
        value
    }
}

/// The value at `span` of one channel's `values`, and the segment to keep for the next time.
fn sample_keys<T: Keyframe>(
    values: &[T],
    interpolation: Interpolation,
    times: &[f32],
    span: Span,
    wide: impl Fn(T) -> Vec4,
) -> (Vec4, Segment) {
    let value = wide(interpolate(values, interpolation, span));
    let segment = match span {
        // One value per key for STEP and LINEAR: key k is values[k].
        Span::Between { k, .. } if interpolation != Interpolation::CubicSpline => {
            Segment { t0: times[k], t1: times[k + 1], k: k as u32, v0: wide(values[k]), v1: wide(values[k + 1]) }
        }
        _ => Segment { k: span.hint() as u32, ..Segment::NONE },
    };
    (value, segment)
}

impl Animation {
    /// The runs of consecutive channels with one target: each makes one node's pose.
    pub(super) fn runs(&self) -> impl Iterator<Item = Range<usize>> + '_ {
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
        // The first value is −0: a blend at the first key's time gives +0, the key itself −0.
        let vecs: Vec<Vec3> = (0..n)
            .map(|i| Vec3::new(i as f32, (i * i) as f32 * 0.1, 1.0 - i as f32) * (i.min(1) as f32 * 2.0 - 1.0))
            .collect();
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
    fn equal_key_times_are_stored_once_per_run() {
        let keys = [0.0, 1.0, 2.0];
        let shared = Playback::new(&[animation(&keys, 3, Interpolation::Linear, true, Wrap::Clamp)]);
        let apart = Playback::new(&[animation(&keys, 3, Interpolation::Linear, false, Wrap::Clamp)]);
        // Translation, rotation and scale with one set of times: stored once per node.
        assert_eq!((shared.runs.len(), shared.keys.times.len()), (3, 9));
        // Rotation on times of its own between two channels on `keys`: three sets per node.
        assert_eq!(apart.keys.times.len(), 27);
    }

    #[test]
    fn key_times_differing_in_the_sign_of_a_zero_are_not_shared() {
        // At t = −0 both channels sit in the interval starting at their zero key; blending
        // from −0 and from +0 gives zeros of opposite signs in the result.
        let v = vec![Vec3::splat(-1.0), Vec3::new(-0.0, 5.0, 0.0), Vec3::ONE];
        let plus = Sampler::new(vec![-1.0, 0.0, 1.0], v.clone(), Interpolation::Linear).unwrap();
        let minus = Sampler::new(vec![-1.0, -0.0, 1.0], v, Interpolation::Linear).unwrap();
        let a = Animation::new("zeros")
            .with_channel(node(0), Curve::Translation(plus.clone()))
            .with_channel(node(0), Curve::Scale(minus.clone()));
        let mut p = Playback::new(std::slice::from_ref(&a));
        assert_eq!(p.keys.times.len(), 6, "two tracks");
        for t in [-0.0, 0.0, 0.5, -0.5] {
            let (_, pose) = p.sample(t, None).next().unwrap();
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            assert_eq!(bits(pose.translation.unwrap()), bits(plus.sample(t)), "t {t}");
            assert_eq!(bits(pose.scale.unwrap()), bits(minus.sample(t)), "t {t}");
        }
    }

    proptest! {
        /// Played at random times, forward, backward, on the keys themselves and twice at one
        /// time, serially and in parallel, the playback's poses are the samplers' own bits:
        /// the kept intervals never change an answer.
        #[test]
        fn poses_equal_the_samplers(
            gaps in prop::collection::vec(0.01f32..3.0, 2..12),
            times in prop::collection::vec(-5.0f32..40.0, 1..40),
            mode in 0usize..3,
            shared: bool,
            looped: bool,
            parallel: bool,
        ) {
            let keys: Vec<f32> = gaps.iter().scan(-1.0, |t, g| { *t += g; Some(*t) }).collect();
            let interpolation = [Interpolation::Step, Interpolation::Linear, Interpolation::CubicSpline][mode];
            let wrap = if looped { Wrap::Loop } else { Wrap::Clamp };
            let a = animation(&keys, 2, interpolation, shared, wrap);
            let mut p = Playback::new(std::slice::from_ref(&a));
            let mut sorted = times.clone();
            sorted.extend(keys.iter().flat_map(|&k| [k, k, k.next_down(), k.next_up(), 1.5 * k]));
            sorted.sort_by(f32::total_cmp);
            let order = times.iter().chain(&sorted).chain(sorted.iter().rev()).copied().chain([f32::NAN, 0.5]);
            for t in order {
                for (run, pose) in p.sample(t, parallel.then_some(1)) {
                    let got = (pose.translation.unwrap(), pose.rotation.unwrap(), pose.scale.unwrap());
                    let want = direct(&a, run.target, t);
                    prop_assert_eq!(got.0.to_array().map(f32::to_bits), want.0.to_array().map(f32::to_bits), "t {}", t);
                    prop_assert_eq!(got.1.to_array().map(f32::to_bits), want.1.to_array().map(f32::to_bits), "t {}", t);
                    prop_assert_eq!(got.2.to_array().map(f32::to_bits), want.2.to_array().map(f32::to_bits), "t {}", t);
                }
            }
        }
    }
}
