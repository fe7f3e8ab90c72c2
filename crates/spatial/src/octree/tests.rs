use super::*;
use crate::{Containment, CullOptions, FrontToBack, Frustum, FrustumCull, Visit};
use sightline_scene::rng::Rng;
use sightline_scene::{Angle, Camera, LookAt};

fn random_box(rng: &mut Rng) -> Aabb {
    let c = Vec3::new(rng.range(-100.0, 100.0), rng.range(-20.0, 20.0), rng.range(-100.0, 100.0));
    // Mostly small, some large objects.
    let s = if rng.below(10) == 0 { rng.range(5.0, 40.0) } else { rng.range(0.05, 2.0) };
    let e = Vec3::new(rng.range(0.2, 1.0), rng.range(0.2, 1.0), rng.range(0.2, 1.0)) * s;
    Aabb::new(c - e, c + e)
}

#[test]
fn ten_thousand_moves_then_every_object_is_found_once() {
    let mut rng = Rng::new(42);
    let n = 500u32;
    let mut boxes: Vec<Aabb> = (0..n).map(|_| random_box(&mut rng)).collect();
    let mut t = LooseOctree::new(&Aabb::new(Vec3::splat(-100.0), Vec3::splat(100.0)), 6);
    for (i, b) in boxes.iter().enumerate() {
        t.insert(i as u32, *b);
    }
    for step in 0..10_000 {
        let id = rng.below(n) as usize;
        let b = match step % 10 {
            // Small move.
            0..=6 => {
                let d = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
                Aabb::new(boxes[id].min + d, boxes[id].max + d)
            }
            // Teleport (sometimes out of the root cube).
            7 | 8 => {
                let mut b = random_box(&mut rng);
                if rng.below(5) == 0 {
                    b = Aabb::new(b.min * 3.0, b.max * 3.0);
                }
                b
            }
            // Remove and re-insert.
            _ => {
                assert!(t.remove(id as u32));
                assert!(!t.remove(id as u32));
                boxes[id]
            }
        };
        boxes[id] = b;
        if step % 10 == 9 {
            t.insert(id as u32, b);
        } else {
            t.update(id as u32, b);
        }
    }
    t.validate().unwrap();
    assert_eq!(t.len(), n as usize);
    let mut out = Vec::new();
    for (i, b) in boxes.iter().enumerate() {
        out.clear();
        t.query_aabb(b, &mut out);
        let hits = out.iter().filter(|&&o| o == i as u32).count();
        assert_eq!(hits, 1, "object {i} found {hits} times");
        // No id twice in one answer, and every answer really intersects.
        let mut sorted = out.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), out.len());
        assert!(out.iter().all(|&o| boxes[o as usize].intersects(b)));
    }
    // Removing everything recycles every block.
    for i in 0..n {
        assert!(t.remove(i));
    }
    t.validate().unwrap();
    assert_eq!(t.node_count(), 1);
}

#[test]
fn frustum_cull_matches_brute_force_and_front_to_back_starts_near() {
    let mut rng = Rng::new(7);
    let boxes: Vec<Aabb> = (0..2000).map(|_| random_box(&mut rng)).collect();
    let t = LooseOctree::from_boxes(&boxes, 7);
    t.validate().unwrap();
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(-80.0, 5.0, -80.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(50.0),
            near: 0.5,
            far: 90.0,
        },
        1.5,
    )
    .unwrap();
    let f = Frustum::from_camera(&cam);
    let brute: Vec<u32> =
        (0..boxes.len() as u32).filter(|&i| f.classify(&boxes[i as usize]) != Containment::Outside).collect();
    for masking in [true, false] {
        let mut out = Vec::new();
        t.cull_with(&f, CullOptions { plane_masking: masking }, &mut out);
        let mut got: Vec<u32> = out.iter().map(|v| v.index).collect();
        got.sort_unstable();
        assert_eq!(got, brute);
        for v in &out {
            if v.inside {
                assert_eq!(f.classify(&boxes[v.index as usize]), Containment::Inside);
            }
        }
    }
    let mut order = Vec::new();
    t.order(cam.view.eye, &mut order);
    assert_eq!(order.len(), boxes.len());
    let d = |i: u32| boxes[i as usize].distance_squared(cam.view.eye).sqrt();
    let head: f32 = order[..200].iter().map(|&i| d(i)).sum::<f32>() / 200.0;
    let tail: f32 = order[1800..].iter().map(|&i| d(i)).sum::<f32>() / 200.0;
    assert!(head * 1.5 < tail, "{head} {tail}");
    // Octant pruning: skipping every cube that lies beyond x > 0 never yields objects there
    // (unless they are in the outside list, which has no cube).
    let mut seen = Vec::new();
    t.traverse_front_to_back(
        Some(&f),
        cam.view.eye,
        |b| if b.min.x > 0.0 { Visit::Skip } else { Visit::Continue },
        |v| {
            seen.push(v.index);
            Visit::Continue
        },
    );
    assert!(seen.iter().all(|&i| boxes[i as usize].min.x <= 0.0));
}

#[test]
fn bad_boxes_follow_the_rule() {
    let mut t = LooseOctree::new(&Aabb::EMPTY, 4);
    t.insert(0, Aabb::EMPTY);
    t.insert(1, Aabb::new(Vec3::NAN, Vec3::ONE));
    t.insert(2, Aabb::new(Vec3::ZERO, Vec3::splat(0.1)));
    t.insert(3, Aabb::new(Vec3::splat(1e6), Vec3::splat(1e6 + 1.0)));
    t.validate().unwrap();
    assert_eq!(t.len(), 4);
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.0, 0.0, 5.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 100.0,
        },
        1.0,
    )
    .unwrap();
    let mut out = Vec::new();
    t.cull(&Frustum::from_camera(&cam), &mut out);
    let mut ids: Vec<u32> = out.iter().map(|v| v.index).collect();
    ids.sort_unstable();
    assert_eq!(ids, vec![1, 2]);
    assert!(t.remove(0) && t.remove(1) && t.remove(3));
    t.update(2, Aabb::new(Vec3::NAN, Vec3::NAN));
    t.validate().unwrap();
    // Looking away from everything: nothing but the unbounded object.
    let away = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.0, 0.0, 5.0),
            target: Vec3::new(0.0, 0.0, 10.0),
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 100.0,
        },
        1.0,
    )
    .unwrap();
    out.clear();
    t.cull(&Frustum::from_camera(&away), &mut out);
    assert_eq!(out.iter().map(|v| v.index).collect::<Vec<_>>(), vec![2], "the unbounded object stays");
    // Bounded again, it is culled like any box.
    out.clear();
    t.update(2, Aabb::new(Vec3::ZERO, Vec3::splat(0.1)));
    t.validate().unwrap();
    t.cull(&Frustum::from_camera(&away), &mut out);
    assert!(out.is_empty());
}

#[test]
fn octant_order_is_front_to_back_along_every_ray() {
    let mut rng = Rng::new(3);
    let center = Vec3::new(0.5, -0.25, 1.0);
    for _ in 0..2000 {
        let eye = center + Vec3::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), rng.range(-3.0, 3.0));
        let order = octant_order(center, eye);
        let mut rank = [0usize; 8];
        for (k, &o) in order.iter().enumerate() {
            rank[o as usize] = k;
        }
        let mut sorted = order;
        sorted.sort_unstable();
        assert_eq!(sorted, [0, 1, 2, 3, 4, 5, 6, 7]);
        // Walk a ray from the eye through the 2×2×2 grid [center ± 1]: octants are met in order.
        let dir = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
        let mut last = 0usize;
        for step in 0..4000 {
            let p = eye + dir * (step as f32 * 0.003);
            if (p - center).abs().max_element() > 1.0 {
                continue;
            }
            let r = rank[octant(center, p)];
            assert!(r >= last, "eye {eye} dir {dir}: octant rank went back from {last} to {r}");
            last = r;
        }
    }
}
