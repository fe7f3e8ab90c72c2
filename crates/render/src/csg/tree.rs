//! CSG trees: an expression builder with a transform on every node, compiled to a flat
//! postorder program that a ray evaluates with a stack of span lists (Roth 1982).
//!
//! Compiling composes the transforms down each path, so every primitive carries the one
//! matrix that maps object-space rays into its canonical space and the inverse transpose that
//! maps its normals back. Evaluation allocates nothing once the scratch buffers have grown.

use glam::{DAffine3, DMat3, DVec3, Vec3};

use super::interval::{combine, Op, Span};
use super::primitive::Shape;

/// A CSG expression: a primitive or a Boolean of two expressions, each placed by an affine
/// transform (`parent_from_node`).
#[derive(Debug, Clone, PartialEq)]
pub struct Csg {
    node: Node,
    transform: DAffine3,
}

#[derive(Debug, Clone, PartialEq)]
enum Node {
    Prim(Shape),
    Op(Op, Box<Csg>, Box<Csg>),
}

impl Csg {
    /// A canonical primitive with an identity transform.
    pub fn primitive(shape: Shape) -> Self {
        Self { node: Node::Prim(shape), transform: DAffine3::IDENTITY }
    }
    /// A sphere of radius `r` around `center`.
    pub fn sphere(center: Vec3, r: f32) -> Self {
        Self::primitive(Shape::Sphere).scaled(Vec3::splat(r)).translated(center)
    }
    /// An axis-aligned box between `min` and `max`.
    pub fn cuboid(min: Vec3, max: Vec3) -> Self {
        Self::primitive(Shape::Cube).scaled((max - min) * 0.5).translated((min + max) * 0.5)
    }
    /// A capped cylinder of radius `r` from `a` to `b`.
    pub fn cylinder(a: Vec3, b: Vec3, r: f32) -> Self {
        Self::along_axis(Shape::Cylinder, a, b, r)
    }
    /// A capped cone with base radius `r` at `base` and its apex at `apex`.
    pub fn cone(base: Vec3, apex: Vec3, r: f32) -> Self {
        Self::along_axis(Shape::Cone, base, apex, r)
    }

    fn along_axis(shape: Shape, a: Vec3, b: Vec3, r: f32) -> Self {
        let axis = (b - a).as_dvec3();
        let len = axis.length();
        let y = if len > 0.0 { axis / len } else { DVec3::Y };
        let helper = if y.x.abs() < 0.9 { DVec3::X } else { DVec3::Z };
        let x = helper.cross(y).normalize();
        let z = x.cross(y);
        let m = DAffine3::from_cols(x * r as f64, y * len * 0.5, z * r as f64, ((a + b) * 0.5).as_dvec3());
        Self::primitive(shape).transformed_f64(m)
    }

    /// Applies `m` after the node's current transform.
    pub fn transformed(self, m: glam::Affine3A) -> Self {
        self.transformed_f64(DAffine3::from_cols(
            m.matrix3.x_axis.as_dvec3(),
            m.matrix3.y_axis.as_dvec3(),
            m.matrix3.z_axis.as_dvec3(),
            m.translation.as_dvec3(),
        ))
    }
    fn transformed_f64(mut self, m: DAffine3) -> Self {
        self.transform = m * self.transform;
        self
    }
    /// Moves the node by `v`.
    pub fn translated(self, v: Vec3) -> Self {
        self.transformed_f64(DAffine3::from_translation(v.as_dvec3()))
    }
    /// Scales the node about the origin.
    pub fn scaled(self, s: Vec3) -> Self {
        self.transformed_f64(DAffine3::from_scale(s.as_dvec3()))
    }
    /// Rotates the node about the origin.
    pub fn rotated(self, q: glam::Quat) -> Self {
        self.transformed_f64(DAffine3::from_quat(q.as_dquat()))
    }

    fn op(op: Op, a: Csg, b: Csg) -> Self {
        Self { node: Node::Op(op, Box::new(a), Box::new(b)), transform: DAffine3::IDENTITY }
    }
    /// Points in `self` or `other`.
    pub fn union(self, other: Csg) -> Self {
        Self::op(Op::Union, self, other)
    }
    /// Points in both.
    pub fn intersect(self, other: Csg) -> Self {
        Self::op(Op::Intersection, self, other)
    }
    /// Points in `self` but not in `other`.
    pub fn subtract(self, other: Csg) -> Self {
        Self::op(Op::Difference, self, other)
    }

    /// Compiles the expression. Errors name the first singular or non-finite transform.
    pub fn compile(&self) -> Result<CsgTree, String> {
        let mut tree = CsgTree { prims: Vec::new(), program: Vec::new(), bounds: (DVec3::ZERO, DVec3::ZERO) };
        // Explicit stack: (node, object_from_parent, visited children?)
        let mut bounds: Vec<(DVec3, DVec3)> = Vec::new();
        let mut stack: Vec<(&Csg, DAffine3, bool)> = vec![(self, DAffine3::IDENTITY, false)];
        while let Some((n, parent, expanded)) = stack.pop() {
            let object_from_node = parent * n.transform;
            match &n.node {
                Node::Prim(shape) => {
                    let m = object_from_node;
                    let det = m.matrix3.determinant();
                    if !det.is_finite() || det.abs() <= 1e-300 || !m.translation.is_finite() {
                        return Err(format!("{shape:?} has a singular or non-finite transform"));
                    }
                    let inv = m.inverse();
                    tree.prims.push(Prim {
                        shape: *shape,
                        local_from_object: inv,
                        normal_to_object: inv.matrix3.transpose(),
                    });
                    tree.program.push(Instr::Prim(tree.prims.len() as u32 - 1));
                    bounds.push(unit_box_bounds(&m));
                }
                Node::Op(op, a, b) => {
                    if expanded {
                        tree.program.push(Instr::Op(*op));
                        let bb = bounds.pop().unwrap_or_default();
                        let ba = bounds.pop().unwrap_or_default();
                        bounds.push(match op {
                            Op::Union => (ba.0.min(bb.0), ba.1.max(bb.1)),
                            Op::Intersection => (ba.0.max(bb.0), ba.1.min(bb.1)),
                            Op::Difference => ba,
                        });
                    } else {
                        stack.push((n, parent, true));
                        stack.push((b, object_from_node, false));
                        stack.push((a, object_from_node, false));
                    }
                }
            }
        }
        tree.bounds = bounds.pop().unwrap_or_default();
        Ok(tree)
    }
}

/// Object-space bounds of the canonical [−1, 1]³ box under `m` (Arvo's method).
fn unit_box_bounds(m: &DAffine3) -> (DVec3, DVec3) {
    let e = m.matrix3.x_axis.abs() + m.matrix3.y_axis.abs() + m.matrix3.z_axis.abs();
    (m.translation - e, m.translation + e)
}

#[derive(Debug, Clone)]
struct Prim {
    shape: Shape,
    local_from_object: DAffine3,
    normal_to_object: DMat3,
}

#[derive(Debug, Clone, Copy)]
enum Instr {
    Prim(u32),
    Op(Op),
}

/// A compiled CSG tree in its object space.
#[derive(Debug, Clone)]
pub struct CsgTree {
    prims: Vec<Prim>,
    program: Vec<Instr>,
    bounds: (DVec3, DVec3),
}

/// Reusable buffers for evaluating CSG trees.
#[derive(Debug, Default, Clone)]
pub struct CsgScratch {
    spans: Vec<Span>,
    starts: Vec<usize>,
    tmp: Vec<Span>,
}

impl CsgTree {
    /// Object-space bounds (empty intersections can make min > max).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.bounds
    }

    /// Number of primitives.
    pub fn primitive_count(&self) -> usize {
        self.prims.len()
    }

    /// The root's span list for the object-space ray `o + t·d`, in `scratch` (valid until the
    /// next evaluation); normals are outward and unit length, in object space.
    pub fn spans<'s>(&self, o: DVec3, d: DVec3, scratch: &'s mut CsgScratch) -> &'s [Span] {
        let CsgScratch { spans, starts, tmp } = scratch;
        spans.clear();
        starts.clear();
        for instr in &self.program {
            match *instr {
                Instr::Prim(i) => {
                    starts.push(spans.len());
                    let Some(p) = self.prims.get(i as usize) else {
                        continue;
                    };
                    let lo = p.local_from_object.transform_point3(o);
                    let ld = p.local_from_object.transform_vector3(d);
                    if let Some(mut s) = p.shape.span(lo, ld) {
                        s.enter.normal = (p.normal_to_object * s.enter.normal).normalize_or_zero();
                        s.exit.normal = (p.normal_to_object * s.exit.normal).normalize_or_zero();
                        spans.push(s);
                    }
                }
                Instr::Op(op) => {
                    let (Some(b), Some(a)) = (starts.pop(), starts.pop()) else {
                        break;
                    };
                    tmp.clear();
                    combine(op, &spans[a..b], &spans[b..], tmp);
                    spans.truncate(a);
                    spans.extend_from_slice(tmp);
                    starts.push(a);
                }
            }
        }
        spans
    }
}
