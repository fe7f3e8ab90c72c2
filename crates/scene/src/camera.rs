//! Cameras: a look-at view (the u, v, w camera frame of Shirley & Marschner, *Fundamentals of
//! Computer Graphics*, "Viewing") and a projection. The everyday perspective camera is
//! described by a [`LookAt`] with named fields (the field of view an [`Angle`], so its unit is
//! in the type).
//!
//! View space is right-handed with the camera at the origin looking down −z:
//! `w = −gaze/|gaze|`, `u = up × w / |up × w|`, `v = w × u` (gluLookAt's basis).
//! `clip_from_world = clip_from_view · view_from_world` is formed in f64 and rounded once, so
//! that vertices land on the same 1/256-pixel grid points as in a double-precision reference.

use glam::{Affine3A, DMat4, DVec3, Mat4, Vec2, Vec3};

use crate::{Angle, Error, Projection, Result};

/// A camera position and orientation: eye plus the orthonormal basis u (right), v (up),
/// w (backwards, opposite to the gaze).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Center of projection (or of the view for parallel projections).
    pub eye: Vec3,
    /// Right.
    pub u: Vec3,
    /// Up.
    pub v: Vec3,
    /// Backwards: the camera looks along −w.
    pub w: Vec3,
}

impl View {
    /// Looks from `eye` towards `target` with `up` as the approximate up direction.
    ///
    /// Errors when eye and target coincide, when `up` is parallel to the gaze or zero, or when
    /// anything is NaN or infinite.
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> Result<Self> {
        Self::look_along(eye, target - eye, up)
    }

    /// Looks from `eye` along `gaze` (any length) with `up` as the approximate up direction.
    pub fn look_along(eye: Vec3, gaze: Vec3, up: Vec3) -> Result<Self> {
        if !eye.is_finite() || !gaze.is_finite() || !up.is_finite() {
            return Err(Error::InvalidCamera(format!("eye {eye}, gaze {gaze} and up {up} must be finite")));
        }
        let (ed, gd, ud) = (eye.as_dvec3(), gaze.as_dvec3(), up.as_dvec3());
        if gd.length_squared() == 0.0 {
            return Err(Error::InvalidCamera("gaze is zero: eye and target coincide".into()));
        }
        let w = -gd.normalize();
        let uxw = ud.cross(w);
        if uxw.length() <= 1e-9 * ud.length().max(1e-300) {
            return Err(Error::InvalidCamera(format!("up {up} is zero or parallel to the gaze {gaze}")));
        }
        let u = uxw.normalize();
        let v = w.cross(u);
        let _ = ed;
        Ok(Self { eye, u: u.as_vec3(), v: v.as_vec3(), w: w.as_vec3() })
    }

    /// The gaze direction (−w).
    pub fn forward(&self) -> Vec3 {
        -self.w
    }

    /// `view_from_world` in f64: rows u, v, w and translation −(u·e, v·e, w·e).
    pub fn view_from_world_f64(&self) -> DMat4 {
        let (u, v, w, e) = (self.u.as_dvec3(), self.v.as_dvec3(), self.w.as_dvec3(), self.eye.as_dvec3());
        DMat4::from_cols(
            glam::DVec4::new(u.x, v.x, w.x, 0.0),
            glam::DVec4::new(u.y, v.y, w.y, 0.0),
            glam::DVec4::new(u.z, v.z, w.z, 0.0),
            glam::DVec4::new(-u.dot(e), -v.dot(e), -w.dot(e), 1.0),
        )
    }

    /// `view_from_world` as an affine matrix.
    pub fn view_from_world(&self) -> Affine3A {
        Affine3A::from_mat4(self.view_from_world_f64().as_mat4())
    }

    /// `world_from_view`: columns u, v, w and the eye.
    pub fn world_from_view(&self) -> Affine3A {
        Affine3A::from_cols(self.u.into(), self.v.into(), self.w.into(), self.eye.into())
    }
}

/// A perspective camera described by what a person says: where the eye is, what it looks at,
/// which way is up, how wide it sees, and the depth range.
///
/// ```
/// use glam::Vec3;
/// use sightline_scene::{Angle, Camera, LookAt};
/// let look = LookAt { eye: Vec3::new(0.0, 2.0, 10.0), fovy: Angle::degrees(50.0), ..LookAt::default() };
/// let camera = Camera::perspective(&look, 16.0 / 9.0)?;
/// # Ok::<(), sightline_scene::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LookAt {
    /// Center of projection.
    pub eye: Vec3,
    /// A point on the line of sight.
    pub target: Vec3,
    /// The approximate up direction (not parallel to `target − eye`).
    pub up: Vec3,
    /// Vertical field of view, in (0°, 180°).
    pub fovy: Angle,
    /// Near plane distance, > 0.
    pub near: f32,
    /// Far plane distance, > near.
    pub far: f32,
}

impl Default for LookAt {
    /// From (0, 0, 1) towards the origin, +y up, 60° vertical field of view, depth 0.1 to 1000.
    fn default() -> Self {
        Self { eye: Vec3::Z, target: Vec3::ZERO, up: Vec3::Y, fovy: Angle::degrees(60.0), near: 0.1, far: 1000.0 }
    }
}

impl LookAt {
    /// From `eye` towards `target`, with the other fields as [`LookAt::default`].
    pub fn new(eye: Vec3, target: Vec3) -> Self {
        Self { eye, target, ..Self::default() }
    }

    /// Checks every field; the error names the field and what is wrong with it.
    pub fn validate(&self) -> Result<()> {
        let bad = |why: String| Err(Error::InvalidCamera(format!("LookAt.{why}")));
        for (name, v) in [("eye", self.eye), ("target", self.target), ("up", self.up)] {
            if !v.is_finite() {
                return bad(format!("{name} = {v} is not finite"));
            }
        }
        let gaze = self.target - self.eye;
        if gaze == Vec3::ZERO {
            return bad(format!("target = eye = {}: there is no view direction", self.eye));
        }
        if View::look_along(self.eye, gaze, self.up).is_err() {
            return bad(format!("up = {} is zero or parallel to the view direction {gaze}", self.up));
        }
        let fovy = self.fovy.to_degrees();
        if !(fovy > 0.0 && fovy < 180.0) {
            return bad(format!("fovy = {fovy} degrees is not in (0, 180)"));
        }
        if !(self.near > 0.0 && self.near.is_finite()) {
            return bad(format!("near = {} must be > 0 (and finite) for a perspective camera", self.near));
        }
        if !(self.far > self.near && self.far.is_finite()) {
            return bad(format!("far = {} must be finite and greater than near = {}", self.far, self.near));
        }
        Ok(())
    }
}

/// A view plus a projection: everything needed to map world points to clip space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Position and orientation.
    pub view: View,
    /// Projection to OpenGL clip space.
    pub projection: Projection,
}

impl Camera {
    /// A camera from a view and a validated projection.
    pub fn new(view: View, projection: Projection) -> Result<Self> {
        projection.validate()?;
        Ok(Self { view, projection })
    }

    /// The usual perspective camera: a [`LookAt`] seen through a viewport of `aspect` =
    /// width / height. Errors name the [`LookAt`] field that is wrong, or the aspect.
    pub fn perspective(look: &LookAt, aspect: f32) -> Result<Self> {
        look.validate()?;
        if !(aspect > 0.0 && aspect.is_finite()) {
            return Err(Error::InvalidCamera(format!(
                "aspect = {aspect} must be positive and finite (zero-size viewport?)"
            )));
        }
        let view = View::look_at(look.eye, look.target, look.up)?;
        Self::new(view, Projection::perspective(look.fovy, aspect, look.near, look.far)?)
    }

    /// `clip_from_world` in f64 (product formed in double precision).
    pub fn clip_from_world_f64(&self) -> DMat4 {
        self.projection.clip_from_view_f64() * self.view.view_from_world_f64()
    }

    /// `clip_from_world` in f32.
    pub fn clip_from_world(&self) -> Mat4 {
        self.clip_from_world_f64().as_mat4()
    }

    /// `clip_from_local` for an instance: `P · V · M`, formed in f64.
    pub fn clip_from_local(&self, world_from_local: &Affine3A) -> Mat4 {
        Self::clip_from_local_with(&self.clip_from_world_f64(), world_from_local)
    }

    /// [`Camera::clip_from_local`] from a `clip_from_world_f64` computed once for many
    /// instances (the same result bit for bit).
    pub fn clip_from_local_with(clip_from_world: &DMat4, world_from_local: &Affine3A) -> Mat4 {
        (*clip_from_world * Mat4::from(*world_from_local).as_dmat4()).as_mat4()
    }

    /// The world-space ray through a point given in NDC (x, y in [−1, 1], y up): origin on the
    /// eye for perspective projections, on the near plane for parallel ones; direction not
    /// normalized, scaled so that t = 1 is one unit along the gaze (view depth 1) for
    /// perspective cameras, which reach the near plane at t = near.
    pub fn ray_through_ndc(&self, ndc: Vec2) -> (Vec3, Vec3) {
        let v = &self.view;
        let (u, vv, w) = (v.u.as_dvec3(), v.v.as_dvec3(), v.w.as_dvec3());
        let (o, d) = self.projection.view_ray(ndc.as_dvec2());
        let to_world = |p: DVec3| u * p.x + vv * p.y + w * p.z;
        ((v.eye.as_dvec3() + to_world(o)).as_vec3(), to_world(d).as_vec3())
    }
}

/// The perspective projection onto the plane z = 0 with the center of projection at distance
/// `d` behind it, at (0, 0, −d): `x' = x·d/(z + d)`, `y' = y·d/(z + d)` (w' = z/d + 1); the
/// matrix `M'_per` of Foley, van Dam, Feiner & Hughes, *Computer Graphics: Principles and
/// Practice*, 2nd ed., §6.4.
pub fn projection_onto_plane(d: f32) -> Mat4 {
    use glam::Vec4;
    Mat4::from_cols(Vec4::X, Vec4::Y, Vec4::new(0.0, 0.0, 0.0, 1.0 / d), Vec4::W)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec4;

    #[test]
    fn seeds_projection_onto_plane() {
        let p = projection_onto_plane(12.0) * Vec4::new(1.0, 1.0, 5.0, 1.0);
        let (x, y) = (p.x / p.w, p.y / p.w);
        assert!((x - 12.0 / 17.0).abs() < 1e-6 && (y - 12.0 / 17.0).abs() < 1e-6);
    }

    #[test]
    fn look_at_maps_eye_to_origin_and_target_to_minus_z() {
        let eye = Vec3::new(3.0, 2.0, -7.0);
        let target = Vec3::new(-1.0, 5.0, 4.0);
        let v = View::look_at(eye, target, Vec3::Y).unwrap();
        let m = v.view_from_world();
        assert!(m.transform_point3(eye).length() < 1e-5);
        let t = m.transform_point3(target);
        assert!(t.x.abs() < 1e-4 && t.y.abs() < 1e-4 && t.z < 0.0);
        assert!((t.z + (target - eye).length()).abs() < 1e-4);
        // Orthonormal, right-handed.
        assert!((v.u.cross(v.v) - v.w).length() < 1e-6);
    }

    #[test]
    fn bad_look_at_is_an_error() {
        assert!(View::look_at(Vec3::ZERO, Vec3::ZERO, Vec3::Y).is_err());
        assert!(View::look_at(Vec3::ZERO, Vec3::Y * 3.0, Vec3::Y).is_err());
        assert!(View::look_at(Vec3::ZERO, Vec3::Z, Vec3::ZERO).is_err());
        assert!(View::look_at(Vec3::NAN, Vec3::Z, Vec3::Y).is_err());
        let e = View::look_at(Vec3::ZERO, Vec3::NEG_Y, Vec3::Y).unwrap_err().to_string();
        assert!(e.contains("parallel"), "{e}");
    }

    #[test]
    fn rays_hit_the_projected_point() {
        let cams = [
            Camera::perspective(
                &LookAt { eye: Vec3::new(1.0, 2.0, 3.0), fovy: Angle::degrees(50.0), far: 100.0, ..LookAt::default() },
                1.5,
            )
            .unwrap(),
            Camera::new(
                View::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO, Vec3::Y).unwrap(),
                Projection::orthographic(-2.0, 3.0, -1.0, 2.0, 0.5, 50.0).unwrap(),
            )
            .unwrap(),
            Camera::new(
                View::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO, Vec3::Y).unwrap(),
                Projection::cabinet(-2.0, 2.0, -2.0, 2.0, 0.5, 50.0, 30f32.to_radians()).unwrap(),
            )
            .unwrap(),
        ];
        for cam in cams {
            let m = cam.clip_from_world();
            for p in [Vec3::new(0.3, -0.2, 0.1), Vec3::new(-0.5, 0.4, -0.7)] {
                let c = m * p.extend(1.0);
                let ndc = c.truncate() / c.w;
                let (o, d) = cam.ray_through_ndc(ndc.truncate());
                // p must lie on the ray: (p - o) parallel to d.
                let r = (p - o).cross(d).length() / d.length() / (p - o).length().max(1e-6);
                assert!(r < 1e-4, "{r} for {:?}", cam.projection);
            }
        }
    }
}
