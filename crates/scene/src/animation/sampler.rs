//! Keyframe samplers: key times, key values and an interpolation mode, validated once so
//! that sampling never fails (glTF 2.0 specification, "Animations": `animation.sampler`).
//!
//! The rules checked when a sampler is made — the ones a file can break:
//!
//! * at least one key (two for CUBICSPLINE, as the specification requires);
//! * key times finite and strictly increasing;
//! * as many values as keys — three per key for CUBICSPLINE, stored in the specification's
//!   order: in-tangent, value, out-tangent;
//! * every value finite; a rotation key value (not a tangent) of non-zero length. Rotation
//!   key values are normalized here, so a file's slightly-off unit quaternions do not skew
//!   the interpolation.
//!
//! Sampling at time `t` clamps: before the first key it gives the first key's value, after
//! the last key the last key's value (the specification leaves time outside the keys to the
//! implementation; clamping is what its sample viewer does). Inside, a binary search finds
//! the key interval (a player that remembers the last interval tries it and the next one
//! first) and [`Keyframe`] interpolates (see the `interpolate` module).

use super::interpolate::Keyframe;

/// How a sampler fills the time between keys (glTF `animation.sampler.interpolation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// Hold each key's value until the next key.
    Step,
    /// Straight-line blend; rotations by shortest-path slerp.
    Linear,
    /// Cubic Hermite segments with per-key in- and out-tangents.
    CubicSpline,
}

impl Interpolation {
    /// The name glTF uses (`STEP`, `LINEAR`, `CUBICSPLINE`).
    pub fn gltf_name(self) -> &'static str {
        match self {
            Interpolation::Step => "STEP",
            Interpolation::Linear => "LINEAR",
            Interpolation::CubicSpline => "CUBICSPLINE",
        }
    }

    /// Values stored per key: 3 for CUBICSPLINE (in-tangent, value, out-tangent), else 1.
    pub fn values_per_key(self) -> usize {
        match self {
            Interpolation::CubicSpline => 3,
            _ => 1,
        }
    }
}

/// Key times, key values and how to interpolate between them; valid by construction.
#[derive(Debug, Clone, PartialEq)]
pub struct Sampler<T: Keyframe> {
    times: Vec<f32>,
    values: Vec<T>,
    interpolation: Interpolation,
}

impl<T: Keyframe> Sampler<T> {
    /// A sampler from key times (seconds) and values; for [`Interpolation::CubicSpline`]
    /// `values` holds three entries per key: in-tangent, value, out-tangent.
    ///
    /// Errors (a sentence saying what is wrong, for the caller to prefix with the animation
    /// and channel): no keys, a non-finite or non-increasing time, a value count that does
    /// not match, a non-finite value, a zero-length rotation.
    pub fn new(times: Vec<f32>, mut values: Vec<T>, interpolation: Interpolation) -> Result<Self, String> {
        let per = interpolation.values_per_key();
        let min_keys = if interpolation == Interpolation::CubicSpline { 2 } else { 1 };
        if times.len() < min_keys {
            return Err(format!(
                "{} {} needs at least {min_keys} key(s), the sampler has {}",
                interpolation.gltf_name(),
                if min_keys == 1 { "interpolation" } else { "interpolation (per the specification)" },
                times.len()
            ));
        }
        if let Some(k) = times.iter().position(|t| !t.is_finite()) {
            return Err(format!("key time {k} is {}, not a finite number", times[k]));
        }
        if let Some(k) = times.windows(2).position(|w| !(w[1] > w[0])) {
            return Err(format!(
                "key times are not strictly increasing: time {} is {} after time {k} = {}",
                k + 1,
                times[k + 1],
                times[k]
            ));
        }
        if Some(values.len()) != times.len().checked_mul(per) {
            return Err(format!(
                "{} keys need {} output values with {} interpolation, the sampler has {}",
                times.len(),
                times.len().saturating_mul(per),
                interpolation.gltf_name(),
                values.len()
            ));
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("output value {i} is {:?}: not finite", values[i]));
        }
        // The key values proper (the middle of each CUBICSPLINE triple).
        for k in 0..times.len() {
            let i = k * per + per / 2;
            values[i] = values[i].normalized_key().ok_or_else(|| format!("key {k}'s rotation has zero length"))?;
        }
        Ok(Self { times, values, interpolation })
    }

    /// The key times, strictly increasing.
    pub fn times(&self) -> &[f32] {
        &self.times
    }
    /// The stored values (three per key for CUBICSPLINE: in-tangent, value, out-tangent).
    pub fn values(&self) -> &[T] {
        &self.values
    }
    /// The interpolation mode.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }
    /// Time of the first key.
    pub fn start(&self) -> f32 {
        self.times[0]
    }
    /// Time of the last key.
    pub fn end(&self) -> f32 {
        self.times[self.times.len() - 1]
    }

    /// The value at time `t` (seconds), clamped to the first and last keys outside them; a
    /// NaN time gives the first key's value.
    pub fn sample(&self, t: f32) -> T {
        interpolate(&self.values, self.interpolation, locate(&self.times, t, 0))
    }
}

/// Where a time falls among a sampler's keys.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Span {
    /// On key `k`'s value: before the first key (or a NaN time), after the last, or the only key.
    Key(usize),
    /// Between keys `k` and `k + 1`: `s ∈ [0, 1]` of the way, over `td` seconds.
    Between { k: usize, s: f32, td: f32 },
}

impl Span {
    /// Time `t` between key `k` at `t0` and key `k + 1` at `t1`.
    #[inline]
    pub(crate) fn between(k: usize, t0: f32, t1: f32, t: f32) -> Span {
        let td = t1 - t0;
        Span::Between { k, s: ((t - t0) / td).clamp(0.0, 1.0), td }
    }

    /// The key interval to try first at the next time (see [`locate`]).
    pub(crate) fn hint(self) -> usize {
        match self {
            Span::Key(k) | Span::Between { k, .. } => k,
        }
    }
}

/// Where `t` falls among the strictly increasing key `times` (at least one). `hint` is
/// where an earlier time fell ([`Span::hint`]): an animation played forward falls in that
/// interval or the next, which are tried before the binary search. The answer does not
/// depend on the hint.
pub(crate) fn locate(times: &[f32], t: f32, hint: usize) -> Span {
    let last = times.len() - 1;
    if !(t > times[0]) {
        return Span::Key(0);
    }
    if t >= times[last] {
        return Span::Key(last);
    }
    // times[k] <= t < times[k + 1], with 0 <= k < last.
    let within = |k: usize| k < last && times[k] <= t && t < times[k + 1];
    let k = if within(hint) {
        hint
    } else if within(hint + 1) {
        hint + 1
    } else {
        times.partition_point(|&x| x <= t) - 1
    };
    Span::between(k, times[k], times[k + 1], t)
}

/// The value at `span` of a sampler's `values` (three per key for CUBICSPLINE: in-tangent,
/// value, out-tangent).
pub(crate) fn interpolate<T: Keyframe>(values: &[T], interpolation: Interpolation, span: Span) -> T {
    let per = interpolation.values_per_key();
    let key = |k: usize| values[k * per + per / 2];
    match (span, interpolation) {
        (Span::Key(k), _) | (Span::Between { k, .. }, Interpolation::Step) => key(k),
        (Span::Between { k, s, .. }, Interpolation::Linear) => T::linear(key(k), key(k + 1), s),
        (Span::Between { k, s, td }, Interpolation::CubicSpline) => {
            let (v0, out0) = (values[3 * k + 1], values[3 * k + 2]);
            let (in1, v1) = (values[3 * k + 3], values[3 * k + 4]);
            T::hermite(v0, out0, v1, in1, s, td)
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::{Quat, Vec3};

    use super::*;

    fn v(x: f32) -> Vec3 {
        Vec3::new(x, 0.0, 0.0)
    }

    #[test]
    fn step_linear_and_clamping() {
        let times = vec![1.0, 2.0, 4.0];
        let values = vec![v(10.0), v(20.0), v(0.0)];
        let step = Sampler::new(times.clone(), values.clone(), Interpolation::Step).unwrap();
        let lin = Sampler::new(times, values, Interpolation::Linear).unwrap();
        // Before the first key and after the last: clamped.
        assert_eq!((step.sample(0.0), lin.sample(-5.0)), (v(10.0), v(10.0)));
        assert_eq!((step.sample(9.0), lin.sample(4.0)), (v(0.0), v(0.0)));
        // STEP holds key 1 over [2, 4); exactly on a key, that key's value.
        assert_eq!((step.sample(2.0), step.sample(3.99)), (v(20.0), v(20.0)));
        // LINEAR at 3.0: halfway from 20 to 0 → 10; at 1.25: 10 + 0.25·10 = 12.5.
        assert_eq!(lin.sample(3.0), v(10.0));
        assert_eq!(lin.sample(1.25), v(12.5));
        assert_eq!(lin.sample(f32::NAN), v(10.0));
    }

    #[test]
    fn cubic_uses_the_tangents_between_the_keys() {
        // Keys at 0 and 2 with values 0 and 1, out-tangent of key 0 = 1/s, in-tangent of
        // key 1 = 0. At t = 1 (s = 0.5, td = 2): h00 = 0.5, h10 = 0.125, h01 = 0.5, h11 = −0.125
        // → 0 + 2·0.125·1 + 0.5·1 + 0 = 0.75. The in-tangent of key 0 and the out-tangent of
        // key 1 (set to 100) must not matter.
        let values = vec![v(100.0), v(0.0), v(1.0), v(0.0), v(1.0), v(100.0)];
        let s = Sampler::new(vec![0.0, 2.0], values, Interpolation::CubicSpline).unwrap();
        assert!((s.sample(1.0).x - 0.75).abs() < 1e-6, "{}", s.sample(1.0));
        assert_eq!(s.sample(5.0), v(1.0));
    }

    #[test]
    fn bad_samplers_are_refused() {
        let two = vec![v(0.0), v(1.0)];
        let e = |r: Result<Sampler<Vec3>, String>| r.unwrap_err();
        assert!(e(Sampler::new(vec![], vec![], Interpolation::Linear)).contains("at least 1"));
        assert!(e(Sampler::new(vec![0.0], vec![v(0.0); 3], Interpolation::CubicSpline)).contains("at least 2"));
        assert!(e(Sampler::new(vec![1.0, 1.0], two.clone(), Interpolation::Linear)).contains("strictly increasing"));
        assert!(e(Sampler::new(vec![0.0, f32::NAN], two.clone(), Interpolation::Linear)).contains("finite"));
        assert!(e(Sampler::new(vec![0.0, 1.0, 2.0], two.clone(), Interpolation::Step)).contains("need 3 output"));
        assert!(e(Sampler::new(vec![0.0, 1.0], two, Interpolation::CubicSpline)).contains("need 6 output"));
        assert!(e(Sampler::new(vec![0.0], vec![v(f32::INFINITY)], Interpolation::Step)).contains("not finite"));
        let zero = Sampler::new(vec![0.0], vec![Quat::from_xyzw(0.0, 0.0, 0.0, 0.0)], Interpolation::Step);
        assert!(zero.unwrap_err().contains("zero length"));
    }

    #[test]
    fn rotation_keys_are_normalized() {
        let s = Sampler::new(vec![0.0], vec![Quat::from_xyzw(0.0, 0.0, 0.0, 2.0)], Interpolation::Linear).unwrap();
        assert_eq!(s.sample(0.0), Quat::IDENTITY);
    }
}
