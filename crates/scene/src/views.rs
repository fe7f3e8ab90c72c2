//! Ready-made parallel views: axonometric presets and the CAD multiview set.
//!
//! An axonometric view is an orthographic projection along a direction d chosen so that
//! the unit x, y, z axes appear with lengths f_x, f_y, f_z: the image of axis i has length
//! `sqrt(1 − d_i²)`, so `d_i = sqrt(1 − f_i²)` and the foreshortenings must satisfy
//! `f_x² + f_y² + f_z² = 2`. Isometric: all equal (√(2/3) ≈ 0.816); dimetric: two equal;
//! trimetric: all different.

use glam::Vec3;

use crate::{Aabb, Angle, Camera, Error, Projection, Result, View};

/// Which axonometric view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Axonometric {
    /// All three axes equally foreshortened.
    Isometric,
    /// x and z equally foreshortened, y with the given factor in (0, 1].
    Dimetric {
        /// Foreshortening of the vertical axis.
        fy: f32,
    },
    /// Three chosen foreshortenings; their squares must sum to 2.
    Trimetric {
        /// Foreshortening of x.
        fx: f32,
        /// Foreshortening of y.
        fy: f32,
        /// Foreshortening of z.
        fz: f32,
    },
}

impl Axonometric {
    /// The foreshortening factors (f_x, f_y, f_z).
    pub fn foreshortening(&self) -> Result<Vec3> {
        let f = match *self {
            Axonometric::Isometric => Vec3::splat((2.0f32 / 3.0).sqrt()),
            Axonometric::Dimetric { fy } => {
                if !(fy > 0.0 && fy <= 1.0) {
                    return Err(Error::InvalidCamera(format!("dimetric foreshortening {fy} is not in (0, 1]")));
                }
                let fxz = ((2.0 - fy * fy) / 2.0).sqrt();
                Vec3::new(fxz, fy, fxz)
            }
            Axonometric::Trimetric { fx, fy, fz } => Vec3::new(fx, fy, fz),
        };
        let s = f.length_squared();
        if !f.is_finite() || f.cmple(Vec3::ZERO).any() || f.cmpgt(Vec3::ONE).any() || (s - 2.0).abs() > 1e-3 {
            return Err(Error::InvalidCamera(format!(
                "foreshortenings {f} must lie in (0, 1] with squares summing to 2 (they sum to {s})"
            )));
        }
        Ok(f)
    }

    /// The unit direction from the scene towards the viewer (first octant: +x, +y, +z).
    pub fn toward_viewer(&self) -> Result<Vec3> {
        let f = self.foreshortening()?;
        Ok((Vec3::ONE - f * f).max(Vec3::ZERO).map(f32::sqrt).normalize())
    }

    /// An orthographic camera that frames `bounds` with this view at the given aspect ratio.
    pub fn camera(&self, bounds: &Aabb, aspect: f32) -> Result<Camera> {
        parallel_camera(bounds, self.toward_viewer()?, Vec3::Y, aspect)
    }
}

/// An orthographic camera that looks at `bounds` from direction `toward_viewer`, framing the
/// whole box.
pub fn parallel_camera(bounds: &Aabb, toward_viewer: Vec3, up: Vec3, aspect: f32) -> Result<Camera> {
    if !bounds.is_finite() {
        return Err(Error::InvalidCamera("cannot frame an empty or non-finite box".into()));
    }
    let c = bounds.center();
    let r = (bounds.extent().length() * 0.5).max(1e-3);
    let view = View::look_along(c + toward_viewer * (2.0 * r), -toward_viewer, up)?;
    let (hw, hh) = if aspect >= 1.0 { (r * aspect, r) } else { (r, r / aspect) };
    Camera::new(view, Projection::orthographic(-hw, hw, -hh, hh, 0.0, 4.0 * r)?)
}

/// The direction from a scene's center to the eye of its three-quarter view: front-right,
/// 45° around the vertical from +z, 28° above the horizon.
pub fn three_quarter_direction() -> Vec3 {
    let (azimuth, elevation) = (std::f32::consts::FRAC_PI_4, 28f32.to_radians());
    Vec3::new(azimuth.sin() * elevation.cos(), elevation.sin(), azimuth.cos() * elevation.cos())
}

/// A perspective camera that sees the whole of `bounds` from its three-quarter view
/// ([`three_quarter_direction`]): the box's bounding sphere fits inside both the vertical and
/// the horizontal field of view (`fovy` vertical, at aspect ratio `aspect`), and the near and
/// far planes enclose it.
pub fn framing_camera(bounds: &Aabb, fovy: Angle, aspect: f32) -> Result<Camera> {
    if !bounds.is_finite() || !(bounds.extent().length() < 1e30) {
        return Err(Error::InvalidCamera(format!(
            "cannot frame the scene: its bounds (min {}, max {}) are empty or not finite",
            bounds.min, bounds.max
        )));
    }
    if !(aspect > 0.0 && aspect.is_finite()) {
        return Err(Error::InvalidCamera(format!("aspect ratio {aspect} is not a positive number")));
    }
    let c = bounds.center();
    let r = (bounds.extent().length() * 0.5).max(1e-3);
    let half_y = fovy.to_radians() * 0.5;
    let half_x = (half_y.tan() * aspect).atan();
    let dist = r / half_y.min(half_x).sin() * 1.05;
    let eye = c + three_quarter_direction() * dist;
    let near = ((dist - r) * 0.9).max(dist * 1e-3);
    Camera::new(View::look_at(eye, c, Vec3::Y)?, Projection::perspective(fovy, aspect, near, (dist + r) * 1.5)?)
}

/// An oblique parallel camera (cavalier when `receding` is 1, cabinet when 0.5) that looks
/// at the front (+z side) of `bounds`, receding lines drawn at 45° up and to the right, the
/// window grown by the receding depth so that the whole box is seen.
pub fn oblique_camera(bounds: &Aabb, receding: f32, aspect: f32) -> Result<Camera> {
    if !bounds.is_finite() {
        return Err(Error::InvalidCamera("cannot frame an empty or non-finite box".into()));
    }
    let c = bounds.center();
    let e = bounds.extent().max(Vec3::splat(1e-3)) * 0.5;
    let view = View::look_along(c + Vec3::Z * (2.0 * e.z + 1.0), Vec3::NEG_Z, Vec3::Y)?;
    // A point d behind the front moves by receding·d·(cos 45°, sin 45°) on screen.
    let shift = receding * 2.0 * e.z * std::f32::consts::FRAC_1_SQRT_2;
    let (mut hw, mut hh) = (e.x + shift * 0.5, e.y + shift * 0.5);
    if hw / hh < aspect {
        hw = hh * aspect;
    } else {
        hh = hw / aspect;
    }
    // The shear is measured from the eye's plane: the box's center, 2·e.z + 1 in front of
    // the eye, lands that much off the axis.
    let k = receding * std::f32::consts::FRAC_1_SQRT_2;
    let (cx, cy) = (k * (2.0 * e.z + 1.0), k * (2.0 * e.z + 1.0));
    let phi = std::f32::consts::FRAC_PI_4;
    let (l, r, b, t) = (cx - hw, cx + hw, cy - hh, cy + hh);
    let (near, far) = (1.0, 4.0 * e.z + 2.0);
    let projection = if receding >= 0.75 {
        Projection::cavalier(l, r, b, t, near, far, phi)?
    } else {
        Projection::cabinet(l, r, b, t, near, far, phi)?
    };
    Camera::new(view, projection)
}

/// The multiview set of CAD programs.
#[derive(Debug, Clone, Copy)]
pub struct Multiview {
    /// Looking down −y, with −z up on screen.
    pub top: Camera,
    /// Looking along −z (from +z), y up.
    pub front: Camera,
    /// Looking along −x (from +x), y up.
    pub side: Camera,
    /// A perspective three-quarter view.
    pub perspective: Camera,
}

impl Multiview {
    /// Top, front, side and a perspective view framing `bounds`, each for the given aspect.
    pub fn new(bounds: &Aabb, aspect: f32) -> Result<Self> {
        let top = parallel_camera(bounds, Vec3::Y, Vec3::NEG_Z, aspect)?;
        let front = parallel_camera(bounds, Vec3::Z, Vec3::Y, aspect)?;
        let side = parallel_camera(bounds, Vec3::X, Vec3::Y, aspect)?;
        let c = bounds.center();
        let r = (bounds.extent().length() * 0.5).max(1e-3);
        let dir = Vec3::new(1.0, 0.8, 1.2).normalize();
        let fovy = Angle::degrees(40.0);
        let dist = r / (fovy.to_radians() * 0.5).sin();
        let view = View::look_at(c + dir * dist, c, Vec3::Y)?;
        let perspective =
            Camera::new(view, Projection::perspective(fovy, aspect, (dist - r).max(dist * 1e-3), dist + r)?)?;
        Ok(Self { top, front, side, perspective })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image_len(cam: &Camera, axis: Vec3) -> f32 {
        let m = cam.view.view_from_world();
        let a = m.transform_vector3(axis);
        a.truncate().length()
    }

    #[test]
    fn axonometric_foreshortening_is_as_asked() {
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        for (kind, want) in [
            (Axonometric::Isometric, Vec3::splat((2.0f32 / 3.0).sqrt())),
            (Axonometric::Dimetric { fy: 0.5 }, Vec3::new((1.75f32 / 2.0).sqrt(), 0.5, (1.75f32 / 2.0).sqrt())),
            (
                Axonometric::Trimetric { fx: 0.9, fy: 0.8, fz: (2.0f32 - 0.81 - 0.64).sqrt() },
                Vec3::new(0.9, 0.8, 0.55f32.sqrt()),
            ),
        ] {
            let cam = kind.camera(&b, 1.0).unwrap();
            let got = Vec3::new(image_len(&cam, Vec3::X), image_len(&cam, Vec3::Y), image_len(&cam, Vec3::Z));
            assert!((got - want).abs().max_element() < 1e-4, "{kind:?}: {got} vs {want}");
        }
        assert!(Axonometric::Trimetric { fx: 1.0, fy: 1.0, fz: 1.0 }.camera(&b, 1.0).is_err());
    }

    #[test]
    fn multiview_axes() {
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let m = Multiview::new(&b, 1.0).unwrap();
        assert!((m.top.view.forward() - Vec3::NEG_Y).length() < 1e-6);
        assert!((m.front.view.forward() - Vec3::NEG_Z).length() < 1e-6);
        assert!((m.side.view.forward() - Vec3::NEG_X).length() < 1e-6);
        assert!(m.perspective.projection.is_perspective());
    }
}
