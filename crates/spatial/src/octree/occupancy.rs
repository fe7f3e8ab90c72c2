//! The debug linearization of an occupancy octree as a string over {X, E, S}: a cube that is
//! entirely solid is `S`, entirely empty `E`, and a mixed one `X` followed by its eight
//! octants' strings, in pre-order (the classic linear octree notation; Samet, "The Design and
//! Analysis of Spatial Data Structures", 1990). Octant `k` has bit 0 = upper half in x,
//! bit 1 = upper half in y, bit 2 = upper half in z, so octants are listed in the order
//! (−x −y −z), (+x −y −z), (−x +y −z), (+x +y −z), (−x −y +z), …

/// The occupancy of a cube.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Occupancy {
    /// Nothing inside (`E`).
    Empty,
    /// Entirely filled (`S`).
    Solid,
    /// Partly filled (`X`, followed by the eight octants).
    Mixed,
}

impl Occupancy {
    /// The letter of the linearization.
    pub fn letter(self) -> char {
        match self {
            Occupancy::Empty => 'E',
            Occupancy::Solid => 'S',
            Occupancy::Mixed => 'X',
        }
    }
}

/// Linearizes the occupancy of a `2^levels`-voxel-wide grid given by `solid(x, y, z)`
/// (`levels` capped at 10). Bounded recursion: depth `levels`.
pub fn occupancy_string(levels: u32, solid: impl Fn(u32, u32, u32) -> bool) -> String {
    let levels = levels.min(10);
    let mut out = String::new();
    linearize(&solid, [0, 0, 0], 1 << levels, &mut out);
    out
}

/// Appends the cube at `o` of side `size`; returns its occupancy.
fn linearize(solid: &impl Fn(u32, u32, u32) -> bool, o: [u32; 3], size: u32, out: &mut String) -> Occupancy {
    if size == 1 {
        let occ = if solid(o[0], o[1], o[2]) { Occupancy::Solid } else { Occupancy::Empty };
        out.push(occ.letter());
        return occ;
    }
    let mark = out.len();
    out.push('X');
    let h = size / 2;
    let mut kinds = [Occupancy::Mixed; 8];
    for (k, kind) in kinds.iter_mut().enumerate() {
        let c = [
            o[0] + if k & 1 != 0 { h } else { 0 },
            o[1] + if k & 2 != 0 { h } else { 0 },
            o[2] + if k & 4 != 0 { h } else { 0 },
        ];
        *kind = linearize(solid, c, h, out);
    }
    if kinds.iter().all(|&k| k == kinds[0]) && kinds[0] != Occupancy::Mixed {
        out.truncate(mark);
        out.push(kinds[0].letter());
        return kinds[0];
    }
    Occupancy::Mixed
}

/// Parses a linearization back into a `2^levels`-wide voxel grid (index
/// `x + y·n + z·n²`), or `None` when the string is malformed for that size.
pub fn occupancy_voxels(levels: u32, s: &str) -> Option<Vec<bool>> {
    let levels = levels.min(10);
    let n = 1usize << levels;
    let mut grid = vec![false; n * n * n];
    let mut chars = s.chars();
    // Explicit stack of (origin, size).
    let mut stack = vec![([0usize; 3], n)];
    while let Some((o, size)) = stack.pop() {
        match chars.next()? {
            'E' => {}
            'S' => {
                for z in o[2]..o[2] + size {
                    for y in o[1]..o[1] + size {
                        for x in o[0]..o[0] + size {
                            grid[x + y * n + z * n * n] = true;
                        }
                    }
                }
            }
            'X' if size > 1 => {
                let h = size / 2;
                for k in (0..8).rev() {
                    let c = [
                        o[0] + if k & 1 != 0 { h } else { 0 },
                        o[1] + if k & 2 != 0 { h } else { 0 },
                        o[2] + if k & 4 != 0 { h } else { 0 },
                    ];
                    stack.push((c, h));
                }
            }
            _ => return None,
        }
    }
    chars.next().is_none().then_some(grid)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simple_strings() {
        assert_eq!(occupancy_string(1, |_, _, _| true), "S");
        assert_eq!(occupancy_string(2, |_, _, _| false), "E");
        assert_eq!(occupancy_string(1, |x, y, z| x + y + z == 0), "XSEEEEEEE");
        // The lower half in y is solid: octants with bit 1 clear.
        assert_eq!(occupancy_string(2, |_, y, _| y < 2), "XSSEESSEE");
        // One voxel in a 4³ grid.
        assert_eq!(occupancy_string(2, |x, y, z| (x, y, z) == (3, 0, 0)), "XEXESEEEEEEEEEEEE");
    }

    #[test]
    fn round_trip() {
        let f = |x: u32, y: u32, z: u32| (x * x + y * y + z * z) < 40 || (x > 5 && z < 2);
        let s = occupancy_string(3, f);
        let g = occupancy_voxels(3, &s).unwrap();
        for z in 0..8 {
            for y in 0..8 {
                for x in 0..8 {
                    assert_eq!(g[(x + y * 8 + z * 64) as usize], f(x, y, z));
                }
            }
        }
        assert!(occupancy_voxels(3, "XS").is_none());
        assert!(occupancy_voxels(0, "X").is_none());
    }
}
