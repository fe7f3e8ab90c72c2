//! Span lists along a ray and their Boolean combination.
//!
//! Roth 1982 ("Ray Casting for Modeling Solids", CGIP 18): a ray meets each solid in a sorted
//! list of disjoint spans [enter, exit]; a union, intersection or difference node combines
//! its children's lists by sweeping their boundaries in order and tracking whether the ray is
//! inside each operand. For two overlapping spans (A, B) and (C, D) with A < C < B < D:
//! union (A, D), intersection (C, B), difference (A, C).
//!
//! Every boundary carries the outward surface normal of the solid it bounds. A boundary of
//! the result inherits the normal of the operand whose crossing changed the result, flipped
//! when that operand is subtracted (its inside becomes the result's outside). Boundaries at
//! the same t are processed together, so touching spans merge under union and vanish under
//! intersection, and zero-length spans (tangent rays) disappear: the operations are
//! regularized.

use glam::DVec3;

/// Where a ray crosses a surface: the ray parameter and the outward unit normal there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// Ray parameter.
    pub t: f64,
    /// Outward normal of the solid whose boundary this is.
    pub normal: DVec3,
}

impl Crossing {
    /// A crossing at `t` with `normal`.
    pub fn new(t: f64, normal: DVec3) -> Self {
        Self { t, normal }
    }
}

/// A piece of the ray inside a solid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    /// Where the ray enters.
    pub enter: Crossing,
    /// Where it leaves (`exit.t ≥ enter.t`).
    pub exit: Crossing,
}

impl Span {
    /// A span between two crossings.
    pub fn new(enter: Crossing, exit: Crossing) -> Self {
        Self { enter, exit }
    }
}

/// A Boolean operation of constructive solid geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Op {
    /// Points in either operand.
    Union,
    /// Points in both operands.
    Intersection,
    /// Points in the first operand and not in the second.
    Difference,
}

impl Op {
    /// Inside the result, given inside-ness of the operands.
    #[inline]
    pub fn apply(self, a: bool, b: bool) -> bool {
        match self {
            Op::Union => a || b,
            Op::Intersection => a && b,
            Op::Difference => a && !b,
        }
    }
}

/// The boundaries of a span list in order: boundary `2k` enters span k, `2k + 1` leaves it.
#[inline]
fn boundary(list: &[Span], k: usize) -> Option<Crossing> {
    let s = list.get(k / 2)?;
    Some(if k.is_multiple_of(2) { s.enter } else { s.exit })
}

/// Appends `op(a, b)` to `out`. Both inputs must be sorted, disjoint span lists; so is the
/// result.
pub fn combine(op: Op, a: &[Span], b: &[Span], out: &mut Vec<Span>) {
    let (mut i, mut j) = (0usize, 0usize);
    let (mut in_a, mut in_b) = (false, false);
    let mut inside = false;
    let mut enter = Crossing::new(0.0, DVec3::ZERO);
    loop {
        let t = match (boundary(a, i), boundary(b, j)) {
            (None, None) => break,
            (Some(x), None) => x.t,
            (None, Some(y)) => y.t,
            (Some(x), Some(y)) => {
                if x.t <= y.t {
                    x.t
                } else {
                    y.t
                }
            }
        };
        // Consume every boundary at t from both lists.
        let (was_a, was_b) = (in_a, in_b);
        let (mut last_a, mut last_b) = (None, None);
        while let Some(c) = boundary(a, i).filter(|c| c.t == t) {
            in_a = !in_a;
            last_a = Some(c);
            i += 1;
        }
        while let Some(c) = boundary(b, j).filter(|c| c.t == t) {
            in_b = !in_b;
            last_b = Some(c);
            j += 1;
        }
        if last_a.is_none() && last_b.is_none() {
            break; // t is NaN: malformed input, stop rather than loop
        }
        let now = op.apply(in_a, in_b);
        if now == inside {
            continue;
        }
        // Which operand made the result change? A alone, if its change alone would do it.
        let by_a = in_a != was_a && op.apply(in_a, was_b) != inside;
        let normal = match (by_a, last_a, last_b) {
            (true, Some(c), _) => c.normal,
            (_, _, Some(c)) if in_b != was_b => {
                if op == Op::Difference {
                    -c.normal
                } else {
                    c.normal
                }
            }
            (_, Some(c), _) => c.normal,
            (_, None, Some(c)) => c.normal,
            (_, None, None) => DVec3::ZERO,
        };
        let c = Crossing::new(t, normal);
        if now {
            enter = c;
        } else {
            out.push(Span::new(enter, c));
        }
        inside = now;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(a: f64, b: f64) -> Span {
        Span::new(Crossing::new(a, DVec3::NEG_X), Crossing::new(b, DVec3::X))
    }
    fn sb(a: f64, b: f64) -> Span {
        Span::new(Crossing::new(a, DVec3::NEG_Y), Crossing::new(b, DVec3::Y))
    }
    fn run(op: Op, a: &[Span], b: &[Span]) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        combine(op, a, b, &mut out);
        out.iter().map(|s| (s.enter.t, s.exit.t)).collect()
    }

    #[test]
    fn overlapping_spans() {
        let (a, b) = ([s(1.0, 3.0)], [sb(2.0, 4.0)]);
        assert_eq!(run(Op::Union, &a, &b), [(1.0, 4.0)]);
        assert_eq!(run(Op::Intersection, &a, &b), [(2.0, 3.0)]);
        assert_eq!(run(Op::Difference, &a, &b), [(1.0, 2.0)]);
        assert_eq!(run(Op::Difference, &b, &a), [(3.0, 4.0)]);
    }

    #[test]
    fn disjoint_spans() {
        let (a, b) = ([s(1.0, 2.0)], [sb(3.0, 4.0)]);
        assert_eq!(run(Op::Union, &a, &b), [(1.0, 2.0), (3.0, 4.0)]);
        assert_eq!(run(Op::Intersection, &a, &b), []);
        assert_eq!(run(Op::Difference, &a, &b), [(1.0, 2.0)]);
    }

    #[test]
    fn touching_spans() {
        let (a, b) = ([s(1.0, 2.0)], [sb(2.0, 3.0)]);
        assert_eq!(run(Op::Union, &a, &b), [(1.0, 3.0)]);
        assert_eq!(run(Op::Intersection, &a, &b), []);
        assert_eq!(run(Op::Difference, &a, &b), [(1.0, 2.0)]);
        // Same span: union is itself, difference is empty.
        assert_eq!(run(Op::Union, &a, &a), [(1.0, 2.0)]);
        assert_eq!(run(Op::Difference, &a, &a), []);
        assert_eq!(run(Op::Intersection, &a, &a), [(1.0, 2.0)]);
    }

    #[test]
    fn nested_spans() {
        let (outer, inner) = ([s(1.0, 6.0)], [sb(2.0, 3.0)]);
        assert_eq!(run(Op::Union, &outer, &inner), [(1.0, 6.0)]);
        assert_eq!(run(Op::Intersection, &outer, &inner), [(2.0, 3.0)]);
        assert_eq!(run(Op::Difference, &outer, &inner), [(1.0, 2.0), (3.0, 6.0)]);
        assert_eq!(run(Op::Difference, &inner, &outer), []);
        // Many spans against one.
        let many = [s(0.0, 1.0), s(2.0, 3.0), s(4.0, 5.0)];
        assert_eq!(run(Op::Intersection, &many, &[sb(0.5, 4.5)]), [(0.5, 1.0), (2.0, 3.0), (4.0, 4.5)]);
        assert_eq!(run(Op::Union, &many, &[sb(0.5, 4.5)]), [(0.0, 5.0)]);
        assert_eq!(run(Op::Union, &many, &[]), [(0.0, 1.0), (2.0, 3.0), (4.0, 5.0)]);
        assert_eq!(run(Op::Intersection, &many, &[]), []);
    }

    #[test]
    fn normals_follow_the_operand_and_flip_for_subtracted_parts() {
        let mut out = Vec::new();
        combine(Op::Difference, &[s(1.0, 6.0)], &[sb(2.0, 3.0)], &mut out);
        // First span leaves A where B begins: B's entry normal flipped.
        assert_eq!(out[0].enter.normal, DVec3::NEG_X);
        assert_eq!(out[0].exit.normal, DVec3::Y);
        // Second span re-enters at B's exit: flipped B exit normal.
        assert_eq!(out[1].enter.normal, DVec3::NEG_Y);
        assert_eq!(out[1].exit.normal, DVec3::X);
        out.clear();
        combine(Op::Intersection, &[s(1.0, 3.0)], &[sb(2.0, 4.0)], &mut out);
        assert_eq!((out[0].enter.normal, out[0].exit.normal), (DVec3::NEG_Y, DVec3::X));
    }

    #[test]
    fn zero_length_spans_vanish() {
        assert_eq!(run(Op::Union, &[s(2.0, 2.0)], &[]), []);
        assert_eq!(run(Op::Union, &[s(1.0, 2.0)], &[sb(5.0, 5.0)]), [(1.0, 2.0)]);
    }
}
