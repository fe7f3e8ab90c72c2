//! A resumable front-to-back walk of the loose octree (Greene's octree walk, Greene, Kass
//! & Miller 1993), in batches: the occlusion culler draws a batch, refreshes its z-pyramid
//! and continues the walk where it stopped, testing the rest against the new pyramid. The
//! order is that of [`LooseOctree::traverse_front_to_back`]: outside-list objects first,
//! then at each octant its own objects (nearest first) before its children (nearest octant
//! first).

use glam::Vec3;
use sightline_scene::Aabb;

use super::{octant, LooseOctree, NONE, ORDER};
use crate::{AabbExt, BoxKind, Frustum, PlaneMask, Visible, ALL_PLANES};

/// A pending step of the walk.
#[derive(Debug, Clone, Copy)]
enum Step {
    /// An octant, with the frustum planes its parent was not yet inside of.
    Node(u32, PlaneMask),
    /// An object, with its octant's plane mask.
    Object(u32, PlaneMask),
}

/// The state of a front-to-back walk of one [`LooseOctree`], resumed batch after batch by
/// [`OctreeCursor::next_batch`] (the octree must not change in between).
#[derive(Debug, Clone)]
pub struct OctreeCursor {
    stack: Vec<Step>,
    frustum: Option<Frustum>,
    eye: Vec3,
    scratch: Vec<(f32, u32)>,
}

impl OctreeCursor {
    /// Starts a walk of `octree` for `eye`, culling against `frustum` when given.
    pub fn new(octree: &LooseOctree, frustum: Option<&Frustum>, eye: Vec3) -> Self {
        let mut c =
            Self { stack: vec![Step::Node(0, ALL_PLANES)], frustum: frustum.copied(), eye, scratch: Vec::new() };
        c.push_objects(octree, octree.outside_head, ALL_PLANES);
        c
    }

    /// True when the walk has finished.
    pub fn is_done(&self) -> bool {
        self.stack.is_empty()
    }

    /// Pushes the objects of the list starting at `head` so that the nearest pops first.
    fn push_objects(&mut self, octree: &LooseOctree, head: u32, mask: PlaneMask) {
        self.scratch.clear();
        let mut o = head;
        while o != NONE {
            self.scratch.push((octree.objects[o as usize].aabb.distance_squared(self.eye), o));
            o = octree.objects[o as usize].next;
        }
        self.scratch.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        self.stack.extend(self.scratch.iter().rev().map(|&(_, o)| Step::Object(o, mask)));
    }

    /// Continues the walk: `possibly_visible(box)` is asked for every octant's loose cube and
    /// every object box that passes the frustum (false skips it, and an octant's whole
    /// subtree); visible objects are appended to `out` until it has grown by `max_items`.
    /// Returns true when more may remain.
    pub fn next_batch(
        &mut self,
        octree: &LooseOctree,
        mut possibly_visible: impl FnMut(&Aabb) -> bool,
        max_items: usize,
        out: &mut Vec<Visible>,
    ) -> bool {
        let max = max_items.max(1);
        let mut emitted = 0usize;
        while let Some(step) = self.stack.pop() {
            match step {
                Step::Object(o, mut m) => {
                    let b = &octree.objects[o as usize].aabb;
                    if Frustum::excludes(self.frustum.as_ref(), b, &mut m) {
                        continue;
                    }
                    if !possibly_visible(b) {
                        continue;
                    }
                    let inside = self.frustum.is_some() && m == 0 && b.kind() == BoxKind::Finite;
                    out.push(Visible { index: o, inside });
                    emitted += 1;
                    if emitted >= max {
                        return !self.stack.is_empty();
                    }
                }
                Step::Node(i, mut mask) => {
                    let Some(n) = octree.nodes.get(i as usize) else { continue };
                    if n.subtree == 0 {
                        continue;
                    }
                    let cube = octree.loose(i);
                    if Frustum::excludes(self.frustum.as_ref(), &cube, &mut mask) {
                        continue;
                    }
                    if !possibly_visible(&cube) {
                        continue;
                    }
                    let (children, center, head) = (n.children, n.center, n.head);
                    if children != NONE {
                        let s = octant(center, self.eye);
                        // Farthest first, so that the nearest pops first.
                        for k in ORDER.iter().rev() {
                            self.stack.push(Step::Node(children + (s ^ k) as u32, mask));
                        }
                    }
                    // The octant's own objects go before its children.
                    self.push_objects(octree, head, mask);
                }
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Visit;
    use sightline_scene::rng::Rng;
    use sightline_scene::{Angle, Camera, LookAt};

    /// Batch after batch, with boxes skipped along the way, the cursor visits and emits
    /// exactly what the one-call walk does, in the same order.
    #[test]
    fn cursor_in_batches_equals_the_callback_walk() {
        let mut rng = Rng::new(8);
        let boxes: Vec<Aabb> = (0..3000)
            .map(|_| {
                let c = Vec3::new(rng.range(-150.0, 150.0), rng.range(-5.0, 30.0), rng.range(-150.0, 150.0));
                let e = Vec3::splat(rng.range(0.1, 6.0));
                Aabb::new(c - e, c + e)
            })
            .collect();
        let octree = LooseOctree::from_boxes(&boxes, 6);
        for (k, (eye, target)) in
            [(Vec3::new(0.0, 2.0, 0.0), Vec3::new(10.0, 2.0, 3.0)), (Vec3::new(-200.0, 90.0, 40.0), Vec3::ZERO)]
                .into_iter()
                .enumerate()
        {
            let cam = Camera::perspective(
                &LookAt { eye, target, up: Vec3::Y, fovy: Angle::degrees(60.0), near: 0.1, far: 500.0 },
                16.0 / 9.0,
            )
            .unwrap();
            let frustum = Frustum::from_camera(&cam);
            // Skip a pseudo-random quarter of the boxes asked about (the same ones both ways).
            let skip = |b: &Aabb| ((b.min.x * 7.3 + b.max.z * 3.1).abs() as u32).is_multiple_of(4);
            for f in [None, Some(&frustum)] {
                let mut want = Vec::new();
                octree.traverse_front_to_back(
                    f,
                    eye,
                    |b| if skip(b) { Visit::Skip } else { Visit::Continue },
                    |v| {
                        want.push(v);
                        Visit::Continue
                    },
                );
                let mut cursor = OctreeCursor::new(&octree, f, eye);
                let (mut got, mut batch) = (Vec::new(), 1);
                while cursor.next_batch(&octree, |b| !skip(b), batch, &mut got) {
                    batch = (batch * 2).min(64);
                }
                assert!(cursor.is_done());
                assert_eq!(got.len(), want.len(), "camera {k}");
                for (g, w) in got.iter().zip(&want) {
                    assert_eq!((g.index, g.inside), (w.index, w.inside), "camera {k}");
                }
                assert!(want.len() > 50, "camera {k} sees {}", want.len());
            }
        }
    }
}
