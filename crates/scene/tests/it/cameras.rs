//! Cameras people can read: `LookAt` with named fields, the unit of the field of view in its
//! type, and errors that name the field at fault.

use glam::Vec3;
use sightline_scene::path::CameraKey;
use sightline_scene::*;

use crate::support::assert_mentions;

fn look() -> LookAt {
    LookAt { eye: Vec3::new(0.0, 2.0, 10.0), target: Vec3::ZERO, fovy: Angle::degrees(50.0), ..LookAt::default() }
}

#[test]
fn a_look_at_camera_matches_the_view_and_projection_it_names() {
    let cam = Camera::perspective(&look(), 1.5).unwrap();
    let want = Camera::new(
        View::look_at(Vec3::new(0.0, 2.0, 10.0), Vec3::ZERO, Vec3::Y).unwrap(),
        Projection::perspective(Angle::radians(50f32.to_radians()), 1.5, 0.1, 1000.0).unwrap(),
    )
    .unwrap();
    assert_eq!(cam, want);
    // The target projects to the center of the image.
    let c = cam.clip_from_world() * Vec3::ZERO.extend(1.0);
    assert!((c.x / c.w).abs() < 1e-6 && (c.y / c.w).abs() < 1e-6);
    // Degrees and radians are one angle.
    assert_eq!(Angle::degrees(90.0).to_radians(), std::f32::consts::FRAC_PI_2);
    assert!((Angle::radians(std::f32::consts::PI).to_degrees() - 180.0).abs() < 1e-4);
}

#[test]
fn camera_keys_and_look_ats_are_the_same_camera() {
    let key = CameraKey::from_look_at(&look());
    assert_eq!(key.fovy_deg, 50.0);
    assert_eq!(key.camera(1.5).unwrap(), Camera::perspective(&look(), 1.5).unwrap());
    assert_eq!(key.look_at().eye, look().eye);
}

#[test]
fn each_bad_field_is_named() {
    let cases: [(LookAt, &[&str]); 10] = [
        (LookAt { eye: Vec3::new(f32::NAN, 0.0, 0.0), ..look() }, &["LookAt.eye", "not finite"]),
        (LookAt { target: Vec3::INFINITY, ..look() }, &["LookAt.target", "not finite"]),
        (LookAt { up: Vec3::new(0.0, f32::NAN, 0.0), ..look() }, &["LookAt.up", "not finite"]),
        (LookAt { target: look().eye, ..look() }, &["LookAt.target", "eye", "no view direction"]),
        (LookAt { eye: Vec3::Y * 5.0, target: Vec3::ZERO, ..look() }, &["LookAt.up", "parallel"]),
        (LookAt { up: Vec3::ZERO, ..look() }, &["LookAt.up", "zero"]),
        (LookAt { near: 0.0, ..look() }, &["LookAt.near", "> 0"]),
        (LookAt { far: 0.05, ..look() }, &["LookAt.far", "greater than near"]),
        (LookAt { fovy: Angle::degrees(180.0), ..look() }, &["LookAt.fovy", "180 degrees", "(0, 180)"]),
        (LookAt { fovy: Angle::radians(f32::NAN), ..look() }, &["LookAt.fovy"]),
    ];
    for (bad, parts) in cases {
        let e = Camera::perspective(&bad, 1.0).unwrap_err();
        assert!(matches!(e, Error::InvalidCamera(_)), "{e}");
        assert_mentions(&e.to_string(), parts);
    }
    assert_mentions(&Camera::perspective(&look(), 0.0).unwrap_err().to_string(), &["aspect", "zero-size viewport"]);
    assert_mentions(
        &Projection::perspective(Angle::degrees(0.0), 1.0, 0.1, 10.0).unwrap_err().to_string(),
        &["field of view", "0 degrees"],
    );
}
