//! Fixtures shared by the modules of this test binary.

use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};
use sightline::scene::path::CameraKey;
use sightline::scene::{Camera, Scene};

/// A look-at camera key with +y up.
pub fn camera_key(eye: [f32; 3], target: [f32; 3], fovy_deg: f32, near: f32, far: f32) -> CameraKey {
    CameraKey { eye, target, up: [0.0, 1.0, 0.0], fovy_deg, near, far }
}

/// An example program cargo built beside this test: `<target>/<profile>/examples/NAME` (the
/// test runs from `<target>/<profile>/deps`).
pub fn example_binary(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("the test knows its own path");
    let profile_dir = exe.parent().and_then(Path::parent).expect("the test runs from <target>/<profile>/deps");
    let bin = profile_dir.join("examples").join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        bin.is_file(),
        "{} is missing: `cargo test` builds the examples; after a narrower command run `cargo build --example {name}`",
        bin.display()
    );
    bin
}

/// Where two triangle-ID buffers of one frame differ ([`differences`]).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Differences {
    /// Pixels that the rasterizer's vertex snapping explains: the centre lies within
    /// [`SNAP_SLACK`] of an edge of the triangle either buffer shows there, or both triangles
    /// cover it at depths closer than snapping can move them. Both are right.
    pub snapping: u64,
    /// Pixels where a triangle shown has a vertex at or behind the eye plane, so that it
    /// cannot be placed on the screen to tell.
    pub unplaced: u64,
    /// Every other pixel that differs: a triangle missing, or the wrong one in front.
    pub unexplained: u64,
}

/// Sorts the pixels where two triangle-ID buffers of one frame (`w` × `h`, rows top down, as
/// [`Framebuffer::ids`](sightline::render::Framebuffer) stores them, drawn from `scene`
/// through `camera`) differ, by whether the rasterizer's vertex snapping explains them.
///
/// The rasterizer snaps vertices to 1/256 pixel; a ray caster sees the exact triangles.
/// Snapping moves an edge by up to √2/512 pixel, so where an edge runs through pixel centres
/// (a horizontal edge on a row of centres) the two may give a whole row to the triangles on
/// either side of it. It also tilts a triangle's depth plane, by |∇z| |δ| at most inside it
/// for a vertex moved by δ: for a sliver seen edge-on, whose depth changes fast across the
/// screen, enough to put it behind the surface it lies on.
pub fn differences(scene: &Scene, camera: &Camera, a: &[u32], b: &[u32], w: u32, h: u32) -> Differences {
    assert_eq!((a.len(), b.len()), ((w * h) as usize, (w * h) as usize), "buffers of {w} × {h}");
    let instances = scene.instances();
    let clip_from_world = camera.clip_from_world_f64();
    // The triangle with ID `id` in window coordinates (pixels, depth 0..1): Ok(None) for the
    // background, Err(()) when a vertex is not in front of the eye.
    let window = |id: u32| -> Result<Option<[DVec3; 3]>, ()> {
        let Some(index) = id.checked_sub(1) else { return Ok(None) }; // triangle k writes k + 1
        let k = instances.partition_point(|i| i.first_triangle <= index) - 1;
        let inst = &instances[k];
        let mesh = scene.mesh(inst.mesh).expect("an instance's mesh");
        let mut out = [DVec3::ZERO; 3];
        for (o, p) in out.iter_mut().zip(mesh.triangle_positions((index - inst.first_triangle) as usize)) {
            let c = clip_from_world * inst.world_from_local.transform_point3(p).as_dvec3().extend(1.0);
            if c.w <= 0.0 {
                return Err(());
            }
            let n = c.truncate() / c.w;
            *o = DVec3::new((n.x + 1.0) * 0.5 * w as f64, (1.0 - n.y) * 0.5 * h as f64, (n.z + 1.0) * 0.5);
        }
        Ok(Some(out))
    };
    let mut d = Differences::default();
    for (k, (&x, &y)) in a.iter().zip(b).enumerate() {
        if x == y {
            continue;
        }
        let p = DVec2::new((k as u32 % w) as f64 + 0.5, (k as u32 / w) as f64 + 0.5);
        match (window(x), window(y)) {
            (Ok(s), Ok(t)) => {
                let near_edge = |t: Option<[DVec3; 3]>| {
                    t.is_some_and(|v| {
                        (0..3).any(|i| distance_to_segment(p, v[i].truncate(), v[(i + 1) % 3].truncate()) <= SNAP_SLACK)
                    })
                };
                let reordered = match (depth_at(s, p), depth_at(t, p)) {
                    (Some((zs, slack_s)), Some((zt, slack_t))) => (zs - zt).abs() <= slack_s + slack_t,
                    _ => false,
                };
                if near_edge(s) || near_edge(t) || reordered {
                    d.snapping += 1;
                } else {
                    d.unexplained += 1;
                }
            }
            _ => d.unplaced += 1,
        }
    }
    d
}

/// How far (in pixels) an edge may lie from a pixel centre and still be taken for passing
/// through it: 1/256 pixel, the rasterizer's subpixel step, which bounds its snapping
/// (√2/512) with room for rounding.
pub const SNAP_SLACK: f64 = 1.0 / 256.0;

/// The depth of a window-space triangle at `p`, which it covers, and how far snapping its
/// vertices by up to [`SNAP_SLACK`] can move it there (|∇z| · [`SNAP_SLACK`], plus a few
/// f32 ulps of depth): `None` for the background or when `p` is outside.
fn depth_at(t: Option<[DVec3; 3]>, p: DVec2) -> Option<(f64, f64)> {
    let [a, b, c] = t?;
    let cross = |u: DVec2, v: DVec2| u.x * v.y - u.y * v.x;
    let (ab, ac, ap) = (b.truncate() - a.truncate(), c.truncate() - a.truncate(), p - a.truncate());
    let area = cross(ab, ac);
    let (l1, l2) = (cross(ap, ac) / area, cross(ab, ap) / area);
    let l0 = 1.0 - l1 - l2;
    if !(l0 >= 0.0 && l1 >= 0.0 && l2 >= 0.0) {
        return None; // outside, or seen exactly edge-on (NaN)
    }
    // ∇z of the plane through the three vertices; moving vertex j by δ moves the depth at
    // p by λⱼ ∇z·δ, at most |∇z| |δ| in all since the λⱼ sum to 1.
    let (dz1, dz2) = (b.z - a.z, c.z - a.z);
    let grad = DVec2::new(dz1 * ac.y - dz2 * ab.y, dz2 * ab.x - dz1 * ac.x) / area;
    Some((l0 * a.z + l1 * b.z + l2 * c.z, grad.length() * SNAP_SLACK + 8.0 * f32::EPSILON as f64))
}

/// Distance from `p` to the segment `a`–`b`.
fn distance_to_segment(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let s = if len2 > 0.0 { ((p - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    p.distance(a + ab * s)
}
