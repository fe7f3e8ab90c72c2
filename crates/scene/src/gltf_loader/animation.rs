//! glTF animations, skins and morph targets (glTF 2.0 specification, sections "Animations",
//! "Skins" and "Morph Targets").
//!
//! Each `animation` becomes an [`Animation`] with [`Wrap::Clamp`](crate::animation::Wrap):
//! each channel's target node is the scene node loaded for that glTF node, its sampler's
//! `input` accessor gives the key times (seconds) and its `output` accessor the values —
//! VEC3 for translation and scale, VEC4 (x, y, z, w; float or normalized integers) for
//! rotation, three per key for CUBICSPLINE. The accessors are read by the same bounds-checked
//! code as vertex data.
//!
//! Bad animation data never fails the load (only the cap on decoded data,
//! [`LoadOptions::max_decoded_bytes`], does): the channel is skipped with a warning that names
//! the animation, the channel and its target, and says what is wrong — a target node that
//! does not exist or is not in the loaded scene, an unknown path or interpolation, a sampler
//! that does not exist, an accessor that cannot be read, input and output counts that
//! disagree, key times that are not finite or not strictly increasing, NaN or infinite
//! values (the rules of [`Sampler::new`]). An animation left with no channel is dropped.
//! `weights` channels (morph target weights) are skipped with a warning.
//!
//! Skins and morph targets are not supported: skinned nodes and meshes with morph targets are
//! drawn in the bind pose (the mesh as stored), with one warning each listing them.

use super::*;
use crate::animation::{Animation, Channel, Curve, Interpolation, Keyframe, Property, Sampler};
use json::animation::{Interpolation as GltfInterpolation, Property as GltfProperty};

/// The first few labels of a list, for a warning.
fn list(labels: &[String]) -> String {
    let mut s = labels.iter().take(5).cloned().collect::<Vec<_>>().join(", ");
    if labels.len() > 5 {
        s.push_str(", ...");
    }
    s
}

/// The bytes a copy of `c` holds: its key times and values.
fn curve_bytes(c: &Curve) -> u64 {
    let (times, values) = match c {
        Curve::Translation(s) | Curve::Scale(s) => (s.times().len(), std::mem::size_of_val(s.values())),
        Curve::Rotation(s) => (s.times().len(), std::mem::size_of_val(s.values())),
    };
    (times * 4 + values) as u64
}

impl Loader<'_> {
    /// Converts the file's animations into [`Scene::animations`], and warns about skins and
    /// morph targets. Call after the nodes are built. Fails only past
    /// [`LoadOptions::max_decoded_bytes`]; a bad channel is skipped with a warning.
    pub(super) fn load_animations(&mut self) -> std::result::Result<(), String> {
        let root = self.root;
        for (a, anim) in root.animations.iter().enumerate() {
            let label = label("animation", a, anim.name.as_deref());
            let mut out = Animation::new(anim.name.clone().unwrap_or_else(|| format!("animation {a}")));
            for (c, ch) in anim.channels.iter().enumerate() {
                let node = ch.target.node.value();
                let target = match (&ch.target.path, root.nodes.get(node)) {
                    (Checked::Valid(p), Some(_)) => format!("{} of {}", path_name(*p), node_label(root, node)),
                    (Checked::Valid(p), None) => format!("{} of node {node}", path_name(*p)),
                    (Checked::Invalid, _) => format!("node {node}"),
                };
                match self.channel(anim, ch) {
                    Ok(channels) => out.channels.extend(channels),
                    Err(why) if self.over_budget.get() => return Err(format!("{label} channel {c} ({target}): {why}")),
                    Err(why) => {
                        self.scene.warnings.push(format!("{label} channel {c} ({target}): {why}; channel skipped"))
                    }
                }
            }
            if !out.channels.is_empty() {
                self.scene.add_animation(out);
            }
        }
        self.warn_bind_pose();
        Ok(())
    }

    /// The channel `ch` aimed at each scene node made for its glTF node (one per copy of a
    /// node shared by several parents).
    fn channel(
        &self,
        anim: &json::Animation,
        ch: &json::animation::Channel,
    ) -> std::result::Result<Vec<Channel>, String> {
        let root = self.root;
        let property = match ch.target.path {
            Checked::Valid(GltfProperty::Translation) => Property::Translation,
            Checked::Valid(GltfProperty::Rotation) => Property::Rotation,
            Checked::Valid(GltfProperty::Scale) => Property::Scale,
            Checked::Valid(GltfProperty::MorphTargetWeights) => {
                return Err("morph target weights are not animated (morph targets are drawn in the bind pose)".into())
            }
            Checked::Invalid => {
                return Err("unknown target path (expected translation, rotation, scale or weights)".into())
            }
        };
        let node = ch.target.node.value();
        let targets = match self.node_ids.get(node) {
            None => return Err(format!("the target node {node} does not exist")),
            Some(ids) if ids.is_empty() => {
                return Err(format!("the target {} is not in the loaded scene", node_label(root, node)))
            }
            Some(ids) => ids,
        };
        let s = ch.sampler.value();
        let sampler = anim.samplers.get(s).ok_or_else(|| format!("sampler {s} does not exist"))?;
        let interpolation = match sampler.interpolation {
            Checked::Valid(GltfInterpolation::Step) => Interpolation::Step,
            Checked::Valid(GltfInterpolation::Linear) => Interpolation::Linear,
            Checked::Valid(GltfInterpolation::CubicSpline) => Interpolation::CubicSpline,
            Checked::Invalid => return Err(format!("sampler {s} has an unknown interpolation")),
        };
        let (input, output) = (sampler.input.value(), sampler.output.value());
        let (times, _) = self.read_accessor(input, &[Type::Scalar], "animation input")?;
        let times: Vec<f32> = times.into_iter().map(|t| t as f32).collect();
        let curve = match property {
            Property::Translation => Curve::Translation(self.sampler(output, Type::Vec3, times, interpolation)?),
            Property::Rotation => Curve::Rotation(self.sampler(output, Type::Vec4, times, interpolation)?),
            Property::Scale => Curve::Scale(self.sampler(output, Type::Vec3, times, interpolation)?),
        };
        // Each copy of a shared node gets the curve again.
        let copies = targets.len() as u64 - 1;
        self.charge(
            copies.saturating_mul(curve_bytes(&curve)),
            format_args!("copying its curve to {copies} more copies of the node"),
        )?;
        Ok(targets.iter().map(|&target| Channel { target, curve: curve.clone() }).collect())
    }

    /// Reads the output accessor and makes the sampler (the rules of [`Sampler::new`]).
    fn sampler<T: Keyframe>(
        &self,
        output: usize,
        ty: Type,
        times: Vec<f32>,
        interpolation: Interpolation,
    ) -> std::result::Result<Sampler<T>, String> {
        let (raw, _) = self.read_accessor(output, &[ty], "animation output")?;
        let floats: Vec<f32> = raw.into_iter().map(|x| x as f32).collect();
        let values = floats.chunks_exact(T::COMPONENTS).map(T::from_floats).collect();
        Sampler::new(times, values, interpolation)
            .map_err(|e| format!("input accessor and output accessor {output}: {e}"))
    }

    /// One warning for the loaded nodes with a skin, one for the meshes with morph targets:
    /// both are drawn in the bind pose.
    fn warn_bind_pose(&mut self) {
        let root = self.root;
        let mut skinned = Vec::new();
        let mut morphed = Vec::new();
        let mut seen_mesh = vec![false; root.meshes.len()];
        for (i, node) in root.nodes.iter().enumerate() {
            if self.node_ids.get(i).is_none_or(Vec::is_empty) {
                continue;
            }
            if node.skin.is_some() {
                skinned.push(node_label(root, i));
            }
            let Some(m) = node.mesh.map(|m| m.value()) else { continue };
            let Some(mesh) = root.meshes.get(m) else { continue };
            let has_targets = mesh.primitives.iter().any(|p| p.targets.as_ref().is_some_and(|t| !t.is_empty()));
            if has_targets && !std::mem::replace(&mut seen_mesh[m], true) {
                morphed.push(label("mesh", m, mesh.name.as_deref()));
            }
        }
        if !skinned.is_empty() {
            self.scene.warnings.push(format!(
                "{} skinned node(s) drawn in the bind pose (skins are not supported): {}",
                skinned.len(),
                list(&skinned)
            ));
        }
        if !morphed.is_empty() {
            self.scene.warnings.push(format!(
                "{} mesh(es) with morph targets drawn in the bind pose (morph targets are not supported): {}",
                morphed.len(),
                list(&morphed)
            ));
        }
    }
}

/// The glTF name of a channel's target path.
fn path_name(p: GltfProperty) -> &'static str {
    match p {
        GltfProperty::Translation => "translation",
        GltfProperty::Rotation => "rotation",
        GltfProperty::Scale => "scale",
        GltfProperty::MorphTargetWeights => "weights",
    }
}
