//! Local transforms: translation, unit-quaternion rotation and non-uniform scale.
//!
//! A node stores its local transform as an `Affine3A` (`parent_from_local`), so a matrix with
//! shear set from a file is kept exactly; [`Transform`] is the TRS way to make one.

use glam::{Affine3A, Mat4, Quat, Vec3};

use crate::{Error, Result};

/// Translation, rotation and scale, applied in the order scale, rotate, translate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    /// Translation.
    pub translation: Vec3,
    /// Rotation; normalized when converted to a matrix.
    pub rotation: Quat,
    /// Per-axis scale.
    pub scale: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Transform {
    /// No translation, rotation or scale.
    pub const IDENTITY: Transform = Transform { translation: Vec3::ZERO, rotation: Quat::IDENTITY, scale: Vec3::ONE };

    /// A pure translation.
    pub fn from_translation(t: Vec3) -> Self {
        Self { translation: t, ..Self::IDENTITY }
    }
    /// A pure rotation.
    pub fn from_rotation(r: Quat) -> Self {
        Self { rotation: r, ..Self::IDENTITY }
    }
    /// A pure scale.
    pub fn from_scale(s: Vec3) -> Self {
        Self { scale: s, ..Self::IDENTITY }
    }
    /// Builder-style translation.
    pub fn with_translation(mut self, t: Vec3) -> Self {
        self.translation = t;
        self
    }
    /// Builder-style rotation.
    pub fn with_rotation(mut self, r: Quat) -> Self {
        self.rotation = r;
        self
    }
    /// Builder-style scale.
    pub fn with_scale(mut self, s: Vec3) -> Self {
        self.scale = s;
        self
    }

    /// The matrix `T * R * S`; errors on NaN/inf components or a zero quaternion.
    pub fn to_affine(&self, what: &str) -> Result<Affine3A> {
        self.normalized(what).map(|t| t.matrix())
    }

    /// This transform with its rotation made unit; errors on NaN/inf components or a zero
    /// quaternion (`what` names the thing in the error).
    pub fn normalized(&self, what: &str) -> Result<Transform> {
        match self.unit_rotation() {
            Ok(rotation) => Ok(Transform { rotation, ..*self }),
            Err(why) => Err(Error::InvalidTransform { what: what.to_string(), why: why.to_string() }),
        }
    }

    /// The rotation made unit, or why the transform is invalid (a NaN or infinite
    /// component, a zero quaternion). Only the quaternion comes back, in a register: a whole
    /// `Transform` in a `Result`, its `Vec3`s written in 4-byte pieces and read back in 8,
    /// made every pose set by an animation wait on the stores (seen in `perf`).
    #[inline]
    pub(crate) fn unit_rotation(&self) -> std::result::Result<Quat, &'static str> {
        if !self.translation.is_finite() || !self.scale.is_finite() || !self.rotation.is_finite() {
            return Err("a component is NaN or infinite");
        }
        let len = self.rotation.length();
        if len < 1e-6 {
            return Err("rotation quaternion has zero length");
        }
        Ok(self.rotation / len)
    }

    /// The matrix `T * R * S` as it stands (the rotation taken as given).
    pub(crate) fn matrix(&self) -> Affine3A {
        Affine3A::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }

    /// Decomposes an affine matrix (exact when it has no shear). A matrix cannot tell which
    /// axes a negative scale mirrors: the sign goes on x. A zero scale leaves the rotation
    /// undefined: the rotation of the other columns is kept when it can be found, else the
    /// identity (never NaN).
    pub fn from_affine(m: &Affine3A) -> Self {
        let (scale, rotation, translation) = m.to_scale_rotation_translation();
        if rotation.is_finite() {
            return Self { translation, rotation, scale };
        }
        // A zero column: rebuild an orthonormal frame from the others where there are two.
        let [x, y, z] = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis].map(|c| c.try_normalize());
        let frame = match (x, y, z) {
            (Some(x), Some(y), _) => Some((x, y, x.cross(y))),
            (Some(x), None, Some(z)) => Some((x, z.cross(x), z)),
            (None, Some(y), Some(z)) => Some((y.cross(z), y, z)),
            _ => None,
        };
        let rotation = frame
            .and_then(|(x, y, z)| {
                let q = Quat::from_mat3(&glam::Mat3::from_cols(x.into(), y.into(), z.into()));
                q.is_finite().then(|| q.normalize())
            })
            .filter(|q| q.is_finite())
            .unwrap_or(Quat::IDENTITY);
        let scale = Vec3::new(m.matrix3.x_axis.length(), m.matrix3.y_axis.length(), m.matrix3.z_axis.length());
        Self { translation, rotation, scale }
    }
}

/// Checks a matrix given by a caller or a file: every entry finite.
pub fn validate_affine(m: &Affine3A, what: &str) -> Result<()> {
    match affine_fault(m) {
        Some(why) => Err(Error::InvalidTransform { what: what.into(), why: why.into() }),
        None => Ok(()),
    }
}

/// Why `m` cannot be a transform (an entry is NaN or infinite), or `None`: the check of
/// [`validate_affine`] for callers that build the error's `what` only when it fails.
pub(crate) fn affine_fault(m: &Affine3A) -> Option<&'static str> {
    (!m.is_finite()).then_some(NOT_FINITE)
}

/// What is wrong with a matrix that has NaN or infinite entries.
const NOT_FINITE: &str = "matrix has NaN or infinite entries";

/// Converts a 4x4 matrix from a file into an affine one; errors when its last row is not (0,0,0,1).
pub fn affine_from_mat4(m: &Mat4, what: &str) -> Result<Affine3A> {
    let r = m.row(3);
    if !m.is_finite() {
        return Err(Error::InvalidTransform { what: what.into(), why: NOT_FINITE.into() });
    }
    if (r - glam::Vec4::W).abs().max_element() > 1e-6 {
        return Err(Error::InvalidTransform { what: what.into(), why: format!("last row {r} is not (0, 0, 0, 1)") });
    }
    Ok(Affine3A::from_mat4(*m))
}
