//! The three interpolations of glTF 2.0 (specification, section "Animations" and Appendix C
//! "Interpolation"), for the two kinds of keyframe value a node's TRS needs: vectors
//! (translation, scale) and unit quaternions (rotation).
//!
//! Between keys `k` and `k + 1`, with `td = t[k+1] − t[k]` and `s = (t − t[k]) / td ∈ [0, 1]`:
//!
//! * STEP: the value of key `k`.
//! * LINEAR: vectors `(1 − s)·v[k] + s·v[k+1]`; quaternions by *spherical* linear
//!   interpolation, as the specification recommends for rotations (Appendix C gives the
//!   formula, from Shoemake, "Animating Rotation with Quaternion Curves", SIGGRAPH 1985):
//!   with `d = q[k]·q[k+1]` and `a = arccos |d|`,
//!   `sin(a(1 − s))/sin(a)·q[k] + sign(d)·sin(a s)/sin(a)·q[k+1]`. The sign flip takes the
//!   shortest path (`q` and `−q` are the same rotation); when `a` is tiny (`|d| > 0.9995`) the
//!   weights are `1 − s` and `sign(d)·s` (sin(a) would divide by almost zero) and the result
//!   is normalized.
//! * CUBICSPLINE: the cubic Hermite segment through `v[k]` and `v[k+1]` with the out-tangent
//!   `b[k]` of key `k` and the in-tangent `a[k+1]` of key `k + 1`, both scaled by `td`
//!   (the file stores tangents per second):
//!   `(2s³ − 3s² + 1)·v[k] + td(s³ − 2s² + s)·b[k] + (−2s³ + 3s²)·v[k+1] + td(s³ − s²)·a[k+1]`.
//!   A quaternion result is normalized, as the specification requires (in the degenerate
//!   case where the blend is zero, the nearer key's rotation is used).

use glam::{Quat, Vec3, Vec4};

/// A value a sampler can interpolate: a translation or scale ([`Vec3`]) or a rotation
/// ([`Quat`]).
pub trait Keyframe: Copy + std::fmt::Debug + PartialEq + Send + Sync + 'static {
    /// Number of floats in one value (3 or 4): what a glTF output accessor holds per element.
    const COMPONENTS: usize;
    /// The value made of `COMPONENTS` floats (glTF order: x, y, z, and w for quaternions).
    fn from_floats(f: &[f32]) -> Self;
    /// True when every component is finite.
    fn is_finite(&self) -> bool;
    /// A key value as sampled: unchanged for vectors, normalized for rotations (`None` for a
    /// zero-length rotation, which is no rotation at all).
    fn normalized_key(self) -> Option<Self>;
    /// LINEAR interpolation between `a` (at `s = 0`) and `b` (at `s = 1`).
    fn linear(a: Self, b: Self, s: f32) -> Self;
    /// The CUBICSPLINE segment: `v0`, `v1` the key values, `out0` the out-tangent of the first
    /// key and `in1` the in-tangent of the second, `td` the key interval in seconds.
    fn hermite(v0: Self, out0: Self, v1: Self, in1: Self, s: f32, td: f32) -> Self;
}

/// The four cubic Hermite basis weights at `s`: for `v0`, `out0` (unscaled), `v1`, `in1`
/// (unscaled).
fn hermite_weights(s: f32) -> [f32; 4] {
    let (s2, s3) = (s * s, s * s * s);
    [2.0 * s3 - 3.0 * s2 + 1.0, s3 - 2.0 * s2 + s, -2.0 * s3 + 3.0 * s2, s3 - s2]
}

impl Keyframe for Vec3 {
    const COMPONENTS: usize = 3;
    fn from_floats(f: &[f32]) -> Self {
        Vec3::new(f[0], f[1], f[2])
    }
    fn is_finite(&self) -> bool {
        Vec3::is_finite(*self)
    }
    fn normalized_key(self) -> Option<Self> {
        Some(self)
    }
    fn linear(a: Self, b: Self, s: f32) -> Self {
        a * (1.0 - s) + b * s
    }
    fn hermite(v0: Self, out0: Self, v1: Self, in1: Self, s: f32, td: f32) -> Self {
        let [h00, h10, h01, h11] = hermite_weights(s);
        v0 * h00 + out0 * (td * h10) + v1 * h01 + in1 * (td * h11)
    }
}

/// Above this `|q0·q1|` the two rotations are so close that slerp's `sin(a)` is tiny: the
/// normalized linear blend is used instead.
const SLERP_LINEAR_ABOVE: f32 = 0.9995;

/// Shortest-path spherical linear interpolation (Shoemake 1985, in the form of the glTF 2.0
/// specification's Appendix C).
pub fn slerp(q0: Quat, q1: Quat, s: f32) -> Quat {
    let (a, b) = (Vec4::from(q0), Vec4::from(q1));
    let d = a.dot(b);
    let sign = if d < 0.0 { -1.0 } else { 1.0 };
    let abs_d = d.abs();
    let v = if abs_d > SLERP_LINEAR_ABOVE {
        (a * (1.0 - s) + b * (sign * s)).normalize_or_zero()
    } else {
        let angle = abs_d.min(1.0).acos();
        let inv_sin = 1.0 / angle.sin();
        a * (((1.0 - s) * angle).sin() * inv_sin) + b * (sign * (s * angle).sin() * inv_sin)
    };
    Quat::from_vec4(v)
}

impl Keyframe for Quat {
    const COMPONENTS: usize = 4;
    fn from_floats(f: &[f32]) -> Self {
        Quat::from_xyzw(f[0], f[1], f[2], f[3])
    }
    fn is_finite(&self) -> bool {
        Quat::is_finite(*self)
    }
    fn normalized_key(self) -> Option<Self> {
        Vec4::from(self).try_normalize().map(Quat::from_vec4)
    }
    fn linear(a: Self, b: Self, s: f32) -> Self {
        slerp(a, b, s)
    }
    fn hermite(v0: Self, out0: Self, v1: Self, in1: Self, s: f32, td: f32) -> Self {
        let [h00, h10, h01, h11] = hermite_weights(s);
        let v =
            Vec4::from(v0) * h00 + Vec4::from(out0) * (td * h10) + Vec4::from(v1) * h01 + Vec4::from(in1) * (td * h11);
        // Tangents can cancel the values out; the nearer key stands in for a zero result.
        match v.try_normalize() {
            Some(n) => Quat::from_vec4(n),
            None if s < 0.5 => v0,
            None => v1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slerp_halfway_between_two_y_turns() {
        // Halfway between 0° and 90° about y is 45° about y.
        let q = slerp(Quat::IDENTITY, Quat::from_rotation_y(std::f32::consts::FRAC_PI_2), 0.5);
        assert!(q.angle_between(Quat::from_rotation_y(std::f32::consts::FRAC_PI_4)) < 1e-5, "{q}");
    }

    #[test]
    fn slerp_takes_the_shortest_path() {
        // −q1 is the same rotation as q1: the path must not go the long way round.
        let q1 = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let q = slerp(Quat::IDENTITY, -q1, 0.5);
        assert!(q.angle_between(Quat::from_rotation_y(std::f32::consts::FRAC_PI_4)) < 1e-5, "{q}");
    }

    #[test]
    fn slerp_of_nearly_equal_rotations_is_unit() {
        let q1 = Quat::from_rotation_x(1e-4);
        let q = slerp(Quat::IDENTITY, q1, 0.3);
        assert!((q.length() - 1.0).abs() < 1e-6);
        assert!(q.angle_between(Quat::from_rotation_x(0.3e-4)) < 1e-5);
    }

    #[test]
    fn hermite_with_zero_tangents_is_smoothstep() {
        // s = 0.25: h01 = −2/64 + 3/16 = 10/64 = 0.15625.
        let v = Vec3::hermite(Vec3::ZERO, Vec3::ZERO, Vec3::ONE, Vec3::ZERO, 0.25, 2.0);
        assert!((v - Vec3::splat(0.15625)).abs().max_element() < 1e-6, "{v}");
        // Tangents are scaled by the interval: a slope of 1 per second over td = 2 s, s = 0.5,
        // from 0 to 0 gives td·(s³ − 2s² + s)·1 + td·(s³ − s²)·1 = 2·0.125 − 2·0.125 = 0.
        let w = Vec3::hermite(Vec3::ZERO, Vec3::ONE, Vec3::ZERO, Vec3::ONE, 0.5, 2.0);
        assert!(w.abs().max_element() < 1e-6, "{w}");
    }
}
