//! Keyframe animation of node transforms, as glTF 2.0 defines it (specification, section
//! "Animations"; interpolation formulas in Appendix C).
//!
//! An [`Animation`] is a named list of [`Channel`]s. A channel drives one component of one
//! node's local TRS — translation, rotation or scale — with a [`Sampler`]: key times, key
//! values and an [`Interpolation`] (STEP, LINEAR, CUBICSPLINE). The property and the value
//! type travel together in a [`Curve`], so a rotation channel cannot carry vectors.
//!
//! Playing ([`Scene::animate`](crate::Scene::animate), [`Animation::apply`]) samples every channel at time `t` and
//! sets the targeted nodes' local transforms through [`Scene::set_local_transform`](crate::Scene::set_local_transform), so they
//! are marked dirty and the next [`Scene::update_transforms`](crate::Scene::update_transforms) propagates them. Components no
//! channel targets keep the node's current value (glTF: "the node's own TRS"): the scene
//! keeps each TRS it was given beside the matrix ([`Scene::local_transform`](crate::Scene::local_transform)), so a zero scale
//! keeps its rotation and a negative one its mirrored axes. Channels of the
//! same node that follow one another are set in one call.
//!
//! Time: the specification measures key times in seconds from the start of the animation
//! and says nothing about time outside the keys. Here each animation has a [`Wrap`]:
//! [`Wrap::Clamp`] (what a loaded glTF file gets) plays `t` as given, holding the first
//! value before the first key and the last value after the last key; [`Wrap::Loop`] plays
//! `t mod duration` (the built-in traffic, whose routes are closed loops). An animation's
//! [`Animation::duration`] is the time of its last key.

mod interpolate;
mod play;
mod playback;
mod sampler;

use glam::{Quat, Vec3};

pub use interpolate::{slerp, Keyframe};
pub(crate) use playback::Playback;
pub use sampler::{Interpolation, Sampler};

use crate::NodeId;

/// Which component of a node's local TRS a channel drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Property {
    /// The translation.
    Translation,
    /// The rotation (a unit quaternion).
    Rotation,
    /// The per-axis scale.
    Scale,
}

impl std::fmt::Display for Property {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Property::Translation => "translation",
            Property::Rotation => "rotation",
            Property::Scale => "scale",
        })
    }
}

/// A sampler together with the property it drives.
#[derive(Debug, Clone, PartialEq)]
pub enum Curve {
    /// Drives the translation.
    Translation(Sampler<Vec3>),
    /// Drives the rotation.
    Rotation(Sampler<Quat>),
    /// Drives the scale.
    Scale(Sampler<Vec3>),
}

impl Curve {
    /// The property driven.
    pub fn property(&self) -> Property {
        match self {
            Curve::Translation(_) => Property::Translation,
            Curve::Rotation(_) => Property::Rotation,
            Curve::Scale(_) => Property::Scale,
        }
    }
    /// The interpolation of the sampler.
    pub fn interpolation(&self) -> Interpolation {
        match self {
            Curve::Translation(s) | Curve::Scale(s) => s.interpolation(),
            Curve::Rotation(s) => s.interpolation(),
        }
    }
    /// Time of the last key.
    pub fn end(&self) -> f32 {
        match self {
            Curve::Translation(s) | Curve::Scale(s) => s.end(),
            Curve::Rotation(s) => s.end(),
        }
    }
}

/// One node component driven by one sampler.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    /// The node whose local transform is set.
    pub target: NodeId,
    /// What is set, and how it changes over time.
    pub curve: Curve,
}

/// What an animation does with a time outside its keys.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Wrap {
    /// Hold the first key's value before it and the last key's value after it.
    #[default]
    Clamp,
    /// Repeat: time `t` plays as `t mod duration` (a negative `t` counts back from the end).
    Loop,
}

/// A named set of channels played together.
#[derive(Debug, Clone, PartialEq)]
pub struct Animation {
    /// Name (from the file, or given by a builder), used in messages.
    pub name: String,
    /// The channels, applied in order (a later channel on the same node component wins).
    pub channels: Vec<Channel>,
    /// Time outside the keys: clamp or loop.
    pub wrap: Wrap,
}

impl Animation {
    /// An animation with no channels that clamps time.
    pub fn new(name: impl Into<String>) -> Self {
        Self { name: name.into(), channels: Vec::new(), wrap: Wrap::Clamp }
    }
    /// Builder-style: sets the wrap mode.
    pub fn with_wrap(mut self, wrap: Wrap) -> Self {
        self.wrap = wrap;
        self
    }
    /// Builder-style: adds a channel.
    pub fn with_channel(mut self, target: NodeId, curve: Curve) -> Self {
        self.channels.push(Channel { target, curve });
        self
    }
    /// The time of the last key over all channels, in seconds (0 without channels).
    pub fn duration(&self) -> f32 {
        self.channels.iter().map(|c| c.curve.end()).fold(0.0, f32::max)
    }
    /// The time at which the channels are sampled when the animation plays at time `t`:
    /// `t` itself for [`Wrap::Clamp`], `t mod duration` for [`Wrap::Loop`] (0 when the
    /// duration is 0).
    pub fn local_time(&self, t: f32) -> f32 {
        match self.wrap {
            Wrap::Clamp => t,
            Wrap::Loop => {
                let d = self.duration();
                if d > 0.0 {
                    t.rem_euclid(d)
                } else {
                    0.0
                }
            }
        }
    }
}
