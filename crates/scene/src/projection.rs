//! Projections to OpenGL clip space (−w ≤ x, y, z ≤ w; near → z_ndc = −1).
//!
//! * Perspective: glFrustum's matrix (as the OpenGL specification defines it) for the window
//!   l, r, b, t on the near plane (symmetric when made from a vertical field of view and an
//!   aspect ratio).
//! * Orthographic: glOrtho's matrix.
//! * Oblique parallel: a shear of view space that slides each depth plane sideways by
//!   `cot(β)·depth` in screen direction φ, followed by the orthographic matrix; β is the angle
//!   between projectors and the projection plane (cavalier β = 45°, cabinet β = arctan 2 ≈
//!   63.4°, so receding lines keep full / half length).
//! * Axonometric views (isometric, dimetric, trimetric) are orthographic projections seen
//!   along a direction chosen from the foreshortening of the three axes: for unit axis
//!   images of length f_x, f_y, f_z, the view direction d has d_i² = 1 − f_i² (and so
//!   f_x² + f_y² + f_z² = 2). See [`crate::views`].

use glam::{DMat4, DVec2, DVec3, DVec4};

use crate::{Angle, Error, Result};

/// A projection from view space to clip space. Construct with the checked functions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// A perspective projection through the window `[left, right] × [bottom, top]` on the
    /// plane z = −near (asymmetric frusta allowed).
    Perspective {
        /// Window at the near plane.
        left: f32,
        /// Window at the near plane.
        right: f32,
        /// Window at the near plane.
        bottom: f32,
        /// Window at the near plane.
        top: f32,
        /// Near plane distance, > 0.
        near: f32,
        /// Far plane distance, > near.
        far: f32,
    },
    /// An orthographic (or, with `shear` ≠ 0, oblique parallel) projection of the box
    /// `[left, right] × [bottom, top] × [−far, −near]` (sheared).
    Parallel {
        /// Box in view x.
        left: f32,
        /// Box in view x.
        right: f32,
        /// Box in view y.
        bottom: f32,
        /// Box in view y.
        top: f32,
        /// Near plane distance, ≥ 0.
        near: f32,
        /// Far plane distance, > near.
        far: f32,
        /// Oblique shear: view x and y move by `shear · (−z)` before the orthographic map
        /// (zero for orthographic; `cot β · (cos φ, sin φ)` for oblique).
        shear: [f32; 2],
    },
}

impl Projection {
    /// A symmetric perspective projection from a vertical field of view and an aspect ratio
    /// (width / height).
    pub fn perspective(fovy: Angle, aspect: f32, near: f32, far: f32) -> Result<Self> {
        let fovy = fovy.to_radians();
        if !(fovy > 0.0 && fovy < std::f32::consts::PI) {
            return Err(Error::InvalidCamera(format!(
                "vertical field of view {} degrees is not in (0, 180)",
                fovy.to_degrees()
            )));
        }
        if !(aspect > 0.0 && aspect.is_finite()) {
            return Err(Error::InvalidCamera(format!("aspect ratio {aspect} must be positive (zero-size viewport?)")));
        }
        let t = (near as f64 * (fovy as f64 * 0.5).tan()) as f32;
        let r = t * aspect;
        Self::frustum(-r, r, -t, t, near, far)
    }

    /// An asymmetric perspective projection with the window l, r, b, t at the near plane.
    pub fn frustum(left: f32, right: f32, bottom: f32, top: f32, near: f32, far: f32) -> Result<Self> {
        let p = Projection::Perspective { left, right, bottom, top, near, far };
        p.validate()?;
        Ok(p)
    }

    /// An orthographic projection of the view-space box l, r, b, t, near, far.
    pub fn orthographic(left: f32, right: f32, bottom: f32, top: f32, near: f32, far: f32) -> Result<Self> {
        let p = Projection::Parallel { left, right, bottom, top, near, far, shear: [0.0, 0.0] };
        p.validate()?;
        Ok(p)
    }

    /// An oblique parallel projection: projectors meet the image plane at angle `beta`
    /// (radians, in (0, 90°]) and receding lines are drawn in screen direction `phi`.
    #[allow(clippy::too_many_arguments)] // glOrtho's six numbers plus the two angles
    pub fn oblique(
        left: f32,
        right: f32,
        bottom: f32,
        top: f32,
        near: f32,
        far: f32,
        beta: f32,
        phi: f32,
    ) -> Result<Self> {
        if !(beta > 0.0 && beta <= std::f32::consts::FRAC_PI_2) {
            return Err(Error::InvalidCamera(format!("oblique angle {} degrees is not in (0, 90]", beta.to_degrees())));
        }
        let k = 1.0 / beta.tan();
        let p = Projection::Parallel { left, right, bottom, top, near, far, shear: [k * phi.cos(), k * phi.sin()] };
        p.validate()?;
        Ok(p)
    }

    /// Cavalier projection (β = 45°: receding lines keep their full length).
    pub fn cavalier(left: f32, right: f32, bottom: f32, top: f32, near: f32, far: f32, phi: f32) -> Result<Self> {
        Self::oblique(left, right, bottom, top, near, far, std::f32::consts::FRAC_PI_4, phi)
    }

    /// Cabinet projection (β = arctan 2 ≈ 63.4°: receding lines at half length).
    pub fn cabinet(left: f32, right: f32, bottom: f32, top: f32, near: f32, far: f32, phi: f32) -> Result<Self> {
        Self::oblique(left, right, bottom, top, near, far, 2f32.atan(), phi)
    }

    /// Checks the parameters: finite, non-empty window, 0 < near < far (0 ≤ near for
    /// parallel projections).
    pub fn validate(&self) -> Result<()> {
        let (l, r, b, t, n, f, perspective) = self.bounds();
        if ![l, r, b, t, n, f].iter().all(|x| x.is_finite()) {
            return Err(Error::InvalidCamera(format!("projection parameters must be finite: {self:?}")));
        }
        if let Projection::Parallel { shear, .. } = self {
            if !shear[0].is_finite() || !shear[1].is_finite() {
                return Err(Error::InvalidCamera("oblique shear is not finite".into()));
            }
        }
        // Near first: a perspective window made from a field of view is scaled by near, so
        // near = 0 would otherwise be reported as an empty window.
        if perspective && n <= 0.0 {
            return Err(Error::InvalidCamera(format!("near = {n}: a perspective projection needs near > 0")));
        }
        if l >= r || b >= t {
            return Err(Error::InvalidCamera(format!(
                "empty window: left {l} ≥ right {r} or bottom {b} ≥ top {t} (zero-size viewport?)"
            )));
        }
        if n < 0.0 {
            return Err(Error::InvalidCamera(format!("near = {n} is negative")));
        }
        if n >= f {
            return Err(Error::InvalidCamera(format!("near = {n} must be smaller than far = {f}")));
        }
        Ok(())
    }

    /// (left, right, bottom, top, near, far, is_perspective).
    pub fn bounds(&self) -> (f32, f32, f32, f32, f32, f32, bool) {
        match *self {
            Projection::Perspective { left, right, bottom, top, near, far } => {
                (left, right, bottom, top, near, far, true)
            }
            Projection::Parallel { left, right, bottom, top, near, far, .. } => {
                (left, right, bottom, top, near, far, false)
            }
        }
    }

    /// The same projection for a viewport of another `aspect` (width / height): the
    /// vertical extent is kept and the horizontal one set to `aspect` times it, about the
    /// same center, so a file's camera keeps its vertical field of view in any image size
    /// (what glTF asks of a viewer whose viewport differs from the camera's `aspectRatio`).
    pub fn with_aspect(&self, aspect: f32) -> Result<Self> {
        if !(aspect > 0.0 && aspect.is_finite()) {
            return Err(Error::InvalidCamera(format!("aspect ratio {aspect} must be positive (zero-size viewport?)")));
        }
        let mut p = *self;
        let (l, r, b, t) = match &mut p {
            Projection::Perspective { left, right, bottom, top, .. }
            | Projection::Parallel { left, right, bottom, top, .. } => (left, right, bottom, top),
        };
        let (center, half) = ((*l as f64 + *r as f64) * 0.5, (*t as f64 - *b as f64) * 0.5 * aspect as f64);
        (*l, *r) = ((center - half) as f32, (center + half) as f32);
        p.validate()?;
        Ok(p)
    }

    /// True for perspective projections.
    pub fn is_perspective(&self) -> bool {
        matches!(self, Projection::Perspective { .. })
    }

    /// Near plane distance.
    pub fn near(&self) -> f32 {
        self.bounds().4
    }

    /// Far plane distance.
    pub fn far(&self) -> f32 {
        self.bounds().5
    }

    /// `clip_from_view` in f64.
    pub fn clip_from_view_f64(&self) -> DMat4 {
        let (l, r, b, t, n, f, _) = self.bounds();
        let (l, r, b, t, n, f) = (l as f64, r as f64, b as f64, t as f64, n as f64, f as f64);
        match self {
            Projection::Perspective { .. } => DMat4::from_cols(
                DVec4::new(2.0 * n / (r - l), 0.0, 0.0, 0.0),
                DVec4::new(0.0, 2.0 * n / (t - b), 0.0, 0.0),
                DVec4::new((r + l) / (r - l), (t + b) / (t - b), -(f + n) / (f - n), -1.0),
                DVec4::new(0.0, 0.0, -2.0 * f * n / (f - n), 0.0),
            ),
            Projection::Parallel { shear, .. } => {
                let ortho = DMat4::from_cols(
                    DVec4::new(2.0 / (r - l), 0.0, 0.0, 0.0),
                    DVec4::new(0.0, 2.0 / (t - b), 0.0, 0.0),
                    DVec4::new(0.0, 0.0, -2.0 / (f - n), 0.0),
                    DVec4::new(-(r + l) / (r - l), -(t + b) / (t - b), -(f + n) / (f - n), 1.0),
                );
                // x += sx·(−z), y += sy·(−z)
                let h = DMat4::from_cols(
                    DVec4::X,
                    DVec4::Y,
                    DVec4::new(-shear[0] as f64, -shear[1] as f64, 1.0, 0.0),
                    DVec4::W,
                );
                ortho * h
            }
        }
    }

    /// `clip_from_view` in f32.
    pub fn clip_from_view(&self) -> glam::Mat4 {
        self.clip_from_view_f64().as_mat4()
    }

    /// A view-space ray through an NDC point: (origin, direction). Perspective: from the eye
    /// through the point on the near plane; parallel: from the near plane along the
    /// (possibly oblique) projector.
    pub fn view_ray(&self, ndc: DVec2) -> (DVec3, DVec3) {
        let (l, r, b, t, n, _, _) = self.bounds();
        let (l, r, b, t, n) = (l as f64, r as f64, b as f64, t as f64, n as f64);
        let x = l + (ndc.x + 1.0) * 0.5 * (r - l);
        let y = b + (ndc.y + 1.0) * 0.5 * (t - b);
        match self {
            Projection::Perspective { .. } => (DVec3::ZERO, DVec3::new(x / n, y / n, -1.0)),
            Projection::Parallel { shear, .. } => {
                // The sheared point (x', y') = (x + sx·d, y + sy·d) at depth d must equal the
                // window point, so the projector moves by (−sx, −sy) per unit of depth.
                let (sx, sy) = (shear[0] as f64, shear[1] as f64);
                (DVec3::new(x - sx * n, y - sy * n, -n), DVec3::new(-sx, -sy, -1.0))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_zero_is_named_as_the_cause() {
        for near in [0.0, -0.0, -1.0] {
            let e = Projection::perspective(Angle::radians(1.0), 1.5, near, 100.0).unwrap_err().to_string();
            assert!(e.contains("near") && e.contains("> 0"), "{e}");
            assert!(!e.contains("empty window"), "{e}");
        }
    }
    use glam::DVec3;

    #[test]
    fn frustum_corners_map_to_ndc_cube_corners() {
        let (l, r, b, t, n, f) = (-0.3, 0.5, -0.2, 0.4, 0.7, 40.0);
        let p = Projection::frustum(l, r, b, t, n, f).unwrap().clip_from_view_f64();
        for (i, &d) in [n, f].iter().enumerate() {
            let s = d / n;
            for (x, y, nx, ny) in [(l, b, -1.0, -1.0), (r, b, 1.0, -1.0), (l, t, -1.0, 1.0), (r, t, 1.0, 1.0)] {
                let c = p * DVec4::new((x * s) as f64, (y * s) as f64, -d as f64, 1.0);
                let ndc = c.truncate() / c.w;
                let want = DVec3::new(nx, ny, if i == 0 { -1.0 } else { 1.0 });
                assert!((ndc - want).abs().max_element() < 1e-6, "{ndc} vs {want}");
            }
        }
        let o = Projection::orthographic(l, r, b, t, n, f).unwrap().clip_from_view_f64();
        let c = o * DVec4::new(r as f64, t as f64, -f as f64, 1.0);
        assert!((c.truncate() - DVec3::ONE).abs().max_element() < 1e-9);
    }

    #[test]
    fn perspective_preserves_depth_order() {
        let p = Projection::perspective(Angle::radians(1.0), 1.5, 0.1, 1000.0).unwrap().clip_from_view_f64();
        let dir = DVec3::new(0.3, -0.2, -1.0);
        let mut last = -2.0;
        for k in 1..2000 {
            let d = 0.1 + k as f64 * 0.49;
            let c = p * (dir * d).extend(1.0);
            let z = c.z / c.w;
            assert!(z > last, "depth order broken at {d}");
            last = z;
        }
    }

    #[test]
    fn invalid_projections_are_errors() {
        assert!(Projection::perspective(Angle::radians(1.0), 1.0, 0.0, 10.0).is_err());
        assert!(Projection::perspective(Angle::radians(1.0), 1.0, -1.0, 10.0).is_err());
        assert!(Projection::perspective(Angle::radians(1.0), 1.0, 10.0, 10.0).is_err());
        assert!(Projection::perspective(Angle::radians(1.0), 0.0, 1.0, 10.0).is_err());
        assert!(Projection::perspective(Angle::radians(f32::NAN), 1.0, 1.0, 10.0).is_err());
        assert!(Projection::orthographic(1.0, 1.0, 0.0, 1.0, 0.0, 1.0).is_err());
        assert!(Projection::oblique(-1.0, 1.0, -1.0, 1.0, 0.0, 1.0, 0.0, 0.0).is_err());
    }

    #[test]
    fn cavalier_keeps_receding_length_and_cabinet_halves_it() {
        for (p, want) in [
            (Projection::cavalier(-1.0, 1.0, -1.0, 1.0, 0.0, 10.0, 0.0).unwrap(), 1.0),
            (Projection::cabinet(-1.0, 1.0, -1.0, 1.0, 0.0, 10.0, 0.0).unwrap(), 0.5),
        ] {
            let m = p.clip_from_view_f64();
            // A unit step along −z moves the image by `want` (in view units; NDC scale is 1 here).
            let a = m * DVec4::new(0.0, 0.0, -1.0, 1.0);
            let b = m * DVec4::new(0.0, 0.0, -2.0, 1.0);
            assert!(((b.x - a.x) - want).abs() < 1e-6 && (b.y - a.y).abs() < 1e-6);
        }
    }
}
