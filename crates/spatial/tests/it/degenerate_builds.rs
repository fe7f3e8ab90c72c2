//! BVH builds over coincident and evenly spaced geometry: thousands of copies of one triangle,
//! thousands of instances at one spot, rows of equal gaps. A clustering builder that breaks
//! cost ties badly needs one pass per primitive there (quadratic time) and, for coincident
//! boxes, builds a chain as deep as the input is long. The checks are structural — a valid
//! tree of logarithmic depth, and culling that reports exactly the boxes a one-by-one test
//! reports — so they fail on such a build without timing anything.

use glam::{Affine3A, Vec3};
use sightline_scene::{Aabb, Angle, Camera, LookAt};
use sightline_spatial::bvh::wide::{InstanceRecord, WideBlas, WideTlas};
use sightline_spatial::*;

const N: usize = 20_000;

const PRESETS: [BvhPreset; 4] = [BvhPreset::Fastest, BvhPreset::VeryFast, BvhPreset::Fast, BvhPreset::Medium];

const TRIANGLE: [Vec3; 3] = [Vec3::ZERO, Vec3::X, Vec3::Y];

/// Twice the depth of a balanced binary tree over `n` items, plus a little: a chain or a
/// comb of `n` items is far deeper.
fn depth_bound(n: usize) -> usize {
    2 * (usize::BITS - n.leading_zeros()) as usize + 4
}

/// Every item whose box a frustum test does not reject, sorted: what culling must return.
fn one_by_one(boxes: &[Aabb], frustum: &Frustum) -> Vec<u32> {
    (0..boxes.len() as u32).filter(|&i| frustum.classify(&boxes[i as usize]) != Containment::Outside).collect()
}

fn culled(bvh: &Bvh, frustum: &Frustum) -> Vec<u32> {
    let mut out = Vec::new();
    bvh.cull_with(frustum, CullOptions::default(), &mut out);
    let mut ids: Vec<u32> = out.iter().map(|v| v.index).collect();
    ids.sort_unstable();
    ids
}

/// Looks at the origin from the front, seeing part of the row along +x.
fn frustum() -> Frustum {
    let look = LookAt {
        eye: Vec3::new(40.0, 3.0, 30.0),
        target: Vec3::new(40.0, 0.0, 0.0),
        up: Vec3::Y,
        fovy: Angle::degrees(60.0),
        near: 0.1,
        far: 500.0,
    };
    let cam = Camera::perspective(&look, 1.5).expect("a valid camera");
    Frustum::from_camera(&cam)
}

/// Half the boxes on one spot (inside the view), half in a row with equal gaps along +x
/// (partly inside).
fn mixed_boxes() -> Vec<Aabb> {
    let spot = Aabb::new(Vec3::new(38.0, 0.0, 0.0), Vec3::new(39.0, 1.0, 0.0));
    (0..N)
        .map(|i| {
            if i % 2 == 0 {
                spot
            } else {
                let x = (i / 2) as f32 * 0.25 - 500.0;
                Aabb::new(Vec3::new(x, 0.0, 0.0), Vec3::new(x + 0.125, 0.125, 0.125))
            }
        })
        .collect()
}

#[test]
fn coincident_triangles_build_shallow_valid_trees() {
    let positions = TRIANGLE.to_vec();
    let indices: Vec<u32> = [0, 1, 2].repeat(N);
    for preset in PRESETS {
        let tree = TriangleBvh::from_triangles(&positions, &indices, preset);
        tree.bvh().validate().unwrap();
        assert_eq!(tree.bvh().items().len(), N);
        assert!(tree.bvh().depth() as usize <= depth_bound(N), "{preset:?}: depth {}", tree.bvh().depth());
    }
    let blas = WideBlas::build(N, |_| TRIANGLE);
    blas.bvh().validate(N).unwrap();
    assert!(blas.bvh().depth() <= depth_bound(N), "wide BLAS depth {}", blas.bvh().depth());
}

#[test]
fn coincident_instances_build_shallow_valid_trees() {
    let boxes = vec![Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0)); N];
    for preset in PRESETS {
        let tree = InstanceBvh::build(&boxes, preset);
        tree.bvh().validate().unwrap();
        assert!(tree.bvh().depth() as usize <= depth_bound(N), "{preset:?}: depth {}", tree.bvh().depth());
    }
    let blases = vec![WideBlas::build(1, |_| TRIANGLE)];
    let records = (0..N as u32).map(|i| InstanceRecord::placed(0, i, 1 + i, Affine3A::IDENTITY)).collect();
    let tlas = WideTlas::build(records, &blases);
    tlas.bvh().validate(N).unwrap();
    assert!(tlas.bvh().depth() <= depth_bound(N), "wide TLAS depth {}", tlas.bvh().depth());
}

#[test]
fn half_coincident_half_evenly_spaced_builds_and_culls_exactly() {
    let boxes = mixed_boxes();
    let f = frustum();
    let expected = one_by_one(&boxes, &f);
    assert!(expected.len() > N / 2 && expected.len() < N, "the view sees part of the row: {}", expected.len());
    for preset in PRESETS {
        let tree = InstanceBvh::build(&boxes, preset);
        tree.bvh().validate().unwrap();
        assert!(tree.bvh().depth() as usize <= depth_bound(N), "{preset:?}: depth {}", tree.bvh().depth());
        assert_eq!(culled(tree.bvh(), &f), expected, "{preset:?}");
    }
    let blases = vec![WideBlas::build(1, |_| TRIANGLE)];
    let records = boxes
        .iter()
        .enumerate()
        .map(|(i, b)| InstanceRecord::placed(0, i as u32, 1, Affine3A::from_translation(b.min)))
        .collect();
    let tlas = WideTlas::build(records, &blases);
    tlas.bvh().validate(N).unwrap();
    assert!(tlas.bvh().depth() <= depth_bound(N), "wide TLAS depth {}", tlas.bvh().depth());
}

#[test]
fn coincident_builds_are_deterministic() {
    let boxes = mixed_boxes();
    let a = InstanceBvh::build(&boxes, BvhPreset::Fast);
    let b = InstanceBvh::build(&boxes, BvhPreset::Fast);
    assert_eq!(a.bvh().items(), b.bvh().items());
    assert_eq!(a.bvh().nodes(), b.bvh().nodes());
}
