//! Queries on the loose octree: box query, frustum culling, Greene's front-to-back walk.

use glam::Vec3;
use sightline_scene::Aabb;

use super::{octant, LooseOctree, NONE, ORDER};
use crate::{
    AabbExt, BoxKind, Containment, CullCounters, CullOptions, FrontToBack, Frustum, FrustumCull, PlaneMask, Visible,
    Visit, ALL_PLANES,
};

/// The eight octants of a cube centered at `center` in front-to-back order for `eye`
/// (octant bits: 1 = +x, 2 = +y, 4 = +z): the eye's octant, the three sharing a face with
/// it, the three sharing an edge, the opposite one. Along any ray from the eye the octants
/// are met in this order (a valid painter's order for the 2×2×2 grid, read backwards).
pub fn octant_order(center: Vec3, eye: Vec3) -> [u8; 8] {
    let s = octant(center, eye);
    ORDER.map(|k| (s ^ k) as u8)
}

impl LooseOctree {
    /// Appends the ids of every object whose box intersects `query` (unbounded objects
    /// always). Each id at most once.
    pub fn query_aabb(&self, query: &Aabb, out: &mut Vec<u32>) {
        let mut o = self.outside_head;
        while o != NONE {
            let b = &self.objects[o as usize].aabb;
            if b.kind() == BoxKind::Unbounded || b.intersects(query) {
                out.push(o);
            }
            o = self.objects[o as usize].next;
        }
        let mut stack = vec![0u32];
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i as usize];
            if n.subtree == 0 || !self.loose(i).intersects(query) {
                continue;
            }
            let mut o = n.head;
            while o != NONE {
                if self.objects[o as usize].aabb.intersects(query) {
                    out.push(o);
                }
                o = self.objects[o as usize].next;
            }
            if n.children != NONE {
                stack.extend(n.children..n.children + 8);
            }
        }
    }

    /// Frustum culling: appends every object whose box may intersect `frustum`.
    pub fn cull_with(&self, frustum: &Frustum, opts: CullOptions, out: &mut Vec<Visible>) -> CullCounters {
        let mut stats = CullCounters::default();
        let before = out.len();
        let mut tests = 0u32;
        let mut o = self.outside_head;
        while o != NONE {
            let b = &self.objects[o as usize].aabb;
            let mut m = ALL_PLANES;
            stats.boxes_tested += 1;
            if frustum.classify_counted(b, &mut m, &mut 0, &mut tests) != Containment::Outside {
                out.push(Visible { index: o, inside: m == 0 && b.kind() == BoxKind::Finite });
            }
            o = self.objects[o as usize].next;
        }
        let mut stack: Vec<(u32, PlaneMask)> = vec![(0, ALL_PLANES)];
        while let Some((i, parent_mask)) = stack.pop() {
            let n = &self.nodes[i as usize];
            if n.subtree == 0 {
                continue;
            }
            let mut mask = if opts.plane_masking { parent_mask } else { ALL_PLANES };
            if mask != 0 {
                stats.boxes_tested += 1;
                if frustum.classify_counted(&self.loose(i), &mut mask, &mut 0, &mut tests) == Containment::Outside {
                    continue;
                }
            }
            let mut o = n.head;
            while o != NONE {
                let mut m = if opts.plane_masking { mask } else { ALL_PLANES };
                if m != 0 {
                    stats.boxes_tested += 1;
                }
                if m == 0
                    || frustum.classify_counted(&self.objects[o as usize].aabb, &mut m, &mut 0, &mut tests)
                        != Containment::Outside
                {
                    out.push(Visible { index: o, inside: m == 0 });
                }
                o = self.objects[o as usize].next;
            }
            if n.children != NONE {
                stack.extend((n.children..n.children + 8).map(|c| (c, mask)));
            }
        }
        stats.plane_tests = tests as u64;
        stats.visible = (out.len() - before) as u64;
        stats
    }

    /// Front-to-back traversal for `eye`, culled by `frustum` when given (Greene's octree
    /// walk). `node_visit` is asked about every octant's loose cube and every object box that
    /// passes the frustum (`Skip` prunes, `Stop` ends); `item_visit` receives the surviving
    /// objects. Outside-list objects come first; at each node, its own objects (nearest first)
    /// come before its children, which are visited nearest octant first.
    pub fn traverse_front_to_back(
        &self,
        frustum: Option<&Frustum>,
        eye: Vec3,
        mut node_visit: impl FnMut(&Aabb) -> Visit,
        mut item_visit: impl FnMut(Visible) -> Visit,
    ) {
        let mut scratch: Vec<(f32, u32)> = Vec::new();
        // Outside list.
        let mut o = self.outside_head;
        while o != NONE {
            scratch.push((self.objects[o as usize].aabb.distance_squared(eye), o));
            o = self.objects[o as usize].next;
        }
        if !self.emit_sorted(&mut scratch, ALL_PLANES, frustum, &mut node_visit, &mut item_visit) {
            return;
        }
        let mut stack: Vec<(u32, PlaneMask)> = vec![(0, ALL_PLANES)];
        while let Some((i, mut mask)) = stack.pop() {
            let n = self.nodes[i as usize];
            if n.subtree == 0 {
                continue;
            }
            let cube = self.loose(i);
            if Frustum::excludes(frustum, &cube, &mut mask) {
                continue;
            }
            match node_visit(&cube) {
                Visit::Stop => return,
                Visit::Skip => continue,
                Visit::Continue => {}
            }
            scratch.clear();
            let mut o = n.head;
            while o != NONE {
                scratch.push((self.objects[o as usize].aabb.distance_squared(eye), o));
                o = self.objects[o as usize].next;
            }
            if !self.emit_sorted(&mut scratch, mask, frustum, &mut node_visit, &mut item_visit) {
                return;
            }
            if n.children != NONE {
                let s = octant(n.center, eye);
                // Push the farthest first so the nearest pops first.
                for k in ORDER.iter().rev() {
                    stack.push((n.children + (s ^ k) as u32, mask));
                }
            }
        }
    }

    /// Tests and emits objects nearest first; false when a callback said `Stop`.
    fn emit_sorted(
        &self,
        objs: &mut [(f32, u32)],
        mask: PlaneMask,
        frustum: Option<&Frustum>,
        node_visit: &mut impl FnMut(&Aabb) -> Visit,
        item_visit: &mut impl FnMut(Visible) -> Visit,
    ) -> bool {
        objs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(_, o) in objs.iter() {
            let b = &self.objects[o as usize].aabb;
            let mut m = mask;
            if Frustum::excludes(frustum, b, &mut m) {
                continue;
            }
            match node_visit(b) {
                Visit::Stop => return false,
                Visit::Skip => continue,
                Visit::Continue => {}
            }
            let inside = frustum.is_some() && m == 0 && b.kind() == BoxKind::Finite;
            if item_visit(Visible { index: o, inside }) == Visit::Stop {
                return false;
            }
        }
        true
    }
}

impl FrustumCull for LooseOctree {
    fn cull(&self, frustum: &Frustum, out: &mut Vec<Visible>) {
        self.cull_with(frustum, CullOptions::default(), out);
    }
}

impl FrontToBack for LooseOctree {
    fn order(&self, eye: Vec3, out: &mut Vec<u32>) {
        self.traverse_front_to_back(None, eye, |_| Visit::Continue, crate::push_index(out));
    }
}
