//! Angles with their unit in the type: a field of view is written `Angle::degrees(60.0)` or
//! `Angle::radians(1.05)`, never a bare number whose unit the reader must guess.

/// A plane angle. Made from degrees or radians; read back in either unit.
///
/// ```
/// use sightline_scene::Angle;
/// let a = Angle::degrees(180.0);
/// assert!((a.to_radians() - std::f32::consts::PI).abs() < 1e-6);
/// assert_eq!(Angle::radians(0.5).to_radians(), 0.5);
/// ```
#[derive(Debug, Clone, Copy, Default, PartialEq, PartialOrd)]
pub struct Angle {
    radians: f32,
}

impl Angle {
    /// An angle of `degrees` degrees.
    pub fn degrees(degrees: f32) -> Self {
        Self { radians: degrees.to_radians() }
    }

    /// An angle of `radians` radians.
    pub const fn radians(radians: f32) -> Self {
        Self { radians }
    }

    /// The angle in radians.
    pub const fn to_radians(self) -> f32 {
        self.radians
    }

    /// The angle in degrees.
    pub fn to_degrees(self) -> f32 {
        self.radians.to_degrees()
    }
}
