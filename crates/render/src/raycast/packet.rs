//! Ray packets: the 64 rays of an 8 × 8 pixel tile in structure-of-arrays lanes, the beam
//! (frustum) that bounds them, and the per-lane hit records.
//!
//! Coherent packets follow Wald, Slusallek, Benthin & Wagner 2001 ("Interactive Rendering
//! with Coherent Ray Tracing"): rays that start together are traversed together, so one node
//! fetch serves many rays and the per-ray work runs in SIMD lanes. Lanes are grouped in
//! chunks of 16 (one AVX-512 register, two AVX2 registers) so that plain loops over a chunk
//! vectorize. The beam is the four planes through the tile's corner rays, for frustum
//! culling of whole subtrees (Reshetov, Soupikov & Hurley 2005, "Multi-Level Ray Tracing
//! Algorithm"); it is taken at the tile's pixel *corners*, half a pixel outside the outermost
//! pixel centers, which makes the culling safe against rounding.
//!
//! The shape was measured (the exported 10^6-triangle city, 1280 × 720, two threads, runs
//! alternated): a chunk is two rows of the tile, 8 × 2 pixels. With 4 × 4 chunks the aerial
//! path took 7–11% longer and the street path 25–28%; with 16 × 4 tiles of 16 × 1 chunks,
//! 16–21% and 14–16% longer; and with 4 × 4 packets of one chunk (Embree's fastest packet
//! shape) the aerial path took 52–54% longer, and 20–30% longer even at 640 × 360, where
//! rays part ways most.

use glam::{Affine3A, Vec3A, Vec4};

use super::shear::shear_of;

/// Lanes per chunk.
pub(crate) const CHUNK: usize = 16;
/// Chunks per packet.
pub(crate) const CHUNKS: usize = 4;
/// Rays per packet.
pub(crate) const LANES: usize = CHUNK * CHUNKS;
/// Tile side in pixels: a packet is a TILE × TILE block, lane = row · TILE + column.
pub(crate) const TILE: u32 = 8;

/// One f32 per lane, chunk-major.
pub(crate) type Lf = [[f32; CHUNK]; CHUNKS];
/// One u32 per lane, chunk-major.
pub(crate) type Lu = [[u32; CHUNK]; CHUNKS];

/// Smallest direction magnitude used for reciprocals: keeps slab distances finite.
const TINY: f32 = 1e-20;

/// The slab-test reciprocal of a direction component, finite for zero components.
#[inline(always)]
pub(crate) fn safe_recip(d: f32) -> f32 {
    let m = if d.abs() < TINY {
        if d.is_sign_negative() {
            -TINY
        } else {
            TINY
        }
    } else {
        d
    };
    1.0 / m
}

/// `Rays::uniform` of a chunk whose lanes do not share one permutation.
pub(crate) const MIXED: u8 = u8::MAX;

/// The permutation every lane of `perm` has, or [`MIXED`].
#[inline(always)]
fn uniform_perm(perm: &[u32; CHUNK]) -> u8 {
    let p = perm[0];
    if perm.iter().fold(true, |all, &q| all & (q == p)) {
        p as u8
    } else {
        MIXED
    }
}

/// Bit mask of the lanes of chunk `c` inside `mask`.
#[inline(always)]
pub(crate) fn chunk_bits(mask: u64, c: usize) -> u64 {
    (mask >> (c * CHUNK)) & 0xFFFF
}

/// The rays of a packet.
#[derive(Clone)]
pub(crate) struct Rays {
    /// Origins x, y, z.
    pub o: [Lf; 3],
    /// Directions x, y, z (not normalized; t is shared by all spaces).
    pub d: [Lf; 3],
    /// Safe reciprocals of the directions.
    pub r: [Lf; 3],
    /// Shear constants `Sx`, `Sy`, `Sz` of the watertight triangle test ([`shear_of`]).
    pub s: [Lf; 3],
    /// Axis permutation of each lane (an index into [`super::shear::AXES`]), in 32-bit lanes
    /// like the other per-lane values: stored as bytes, one per lane, they kept `derive_chunk`
    /// from vectorizing and read back as a vector through a failed store forward (about a
    /// tenth of a frame's work outside tracing).
    pub perm: [[u32; CHUNK]; CHUNKS],
    /// Per chunk, the permutation all its lanes share, or [`MIXED`].
    pub uniform: [u8; CHUNKS],
    /// The common origin when every lane starts at the same point.
    pub shared: Option<Vec3A>,
}

impl Rays {
    /// All-zero rays.
    pub fn new() -> Self {
        Self {
            o: [[[0.0; CHUNK]; CHUNKS]; 3],
            d: [[[0.0; CHUNK]; CHUNKS]; 3],
            r: [[[0.0; CHUNK]; CHUNKS]; 3],
            s: [[[f32::NAN; CHUNK]; CHUNKS]; 3],
            perm: [[0; CHUNK]; CHUNKS],
            uniform: [0; CHUNKS],
            shared: None,
        }
    }

    /// Sets lane `i`.
    #[inline]
    pub fn set(&mut self, i: usize, o: Vec3A, d: Vec3A) {
        let (c, j) = (i / CHUNK, i % CHUNK);
        for a in 0..3 {
            self.o[a][c][j] = o[a];
            self.d[a][c][j] = d[a];
        }
        self.derive_lane(c, j);
        self.uniform[c] = uniform_perm(&self.perm[c]);
    }

    /// Computes lane (c, j)'s reciprocals and shear from its direction.
    #[inline(always)]
    fn derive_lane(&mut self, c: usize, j: usize) {
        let d = [self.d[0][c][j], self.d[1][c][j], self.d[2][c][j]];
        let (p, sh) = shear_of(d);
        for a in 0..3 {
            self.r[a][c][j] = safe_recip(d[a]);
            self.s[a][c][j] = sh[a];
        }
        self.perm[c][j] = p as u32;
    }

    /// Computes the reciprocals, shears and permutations of chunk `c` from its directions
    /// (after the directions of a whole chunk are written).
    #[inline(always)]
    pub fn derive_chunk(&mut self, c: usize) {
        for j in 0..CHUNK {
            self.derive_lane(c, j);
        }
        self.uniform[c] = uniform_perm(&self.perm[c]);
    }

    /// Origin of lane `i`.
    #[inline(always)]
    pub fn origin(&self, i: usize) -> Vec3A {
        let (c, j) = (i / CHUNK, i % CHUNK);
        Vec3A::new(self.o[0][c][j], self.o[1][c][j], self.o[2][c][j])
    }

    /// Direction of lane `i`.
    #[inline(always)]
    pub fn dir(&self, i: usize) -> Vec3A {
        let (c, j) = (i / CHUNK, i % CHUNK);
        Vec3A::new(self.d[0][c][j], self.d[1][c][j], self.d[2][c][j])
    }

    /// Writes into `out` the lanes of `mask`'s chunks mapped by `m` (a `local_from_world`
    /// matrix): origins as points, directions as vectors, so t is unchanged; reciprocals and
    /// shears follow the mapped directions.
    #[inline(always)]
    pub fn transform_into(&self, m: &Affine3A, mask: u64, out: &mut Rays) {
        let a = m.matrix3.to_cols_array();
        let t = m.translation.to_array();
        out.shared = self.shared.map(|o| m.transform_point3a(o));
        for c in 0..CHUNKS {
            if chunk_bits(mask, c) == 0 {
                continue;
            }
            match out.shared {
                Some(o) => {
                    for ax in 0..3 {
                        out.o[ax][c] = [o[ax]; CHUNK];
                    }
                }
                None => {
                    let (ox, oy, oz) = (&self.o[0][c], &self.o[1][c], &self.o[2][c]);
                    for j in 0..CHUNK {
                        let (x, y, z) = (ox[j], oy[j], oz[j]);
                        out.o[0][c][j] = a[0] * x + a[3] * y + a[6] * z + t[0];
                        out.o[1][c][j] = a[1] * x + a[4] * y + a[7] * z + t[1];
                        out.o[2][c][j] = a[2] * x + a[5] * y + a[8] * z + t[2];
                    }
                }
            }
            let (dx, dy, dz) = (&self.d[0][c], &self.d[1][c], &self.d[2][c]);
            for j in 0..CHUNK {
                let (x, y, z) = (dx[j], dy[j], dz[j]);
                out.d[0][c][j] = a[0] * x + a[3] * y + a[6] * z;
                out.d[1][c][j] = a[1] * x + a[4] * y + a[7] * z;
                out.d[2][c][j] = a[2] * x + a[5] * y + a[8] * z;
            }
            out.derive_chunk(c);
        }
    }
}

/// Per-lane search interval and closest hit so far.
///
/// `inst == NO_HIT` means no hit; otherwise `prim` is the leaf-order triangle index in that
/// instance's BLAS, and `e1 / det`, `e2 / det` are the barycentric weights of the triangle's
/// second and third vertices.
#[derive(Clone)]
pub(crate) struct Hits {
    /// Lower end of each lane's interval.
    pub tmin: Lf,
    /// Upper end: the far limit, then the closest hit found.
    pub t: Lf,
    /// Instance of the hit.
    pub inst: Lu,
    /// Leaf-order triangle of the hit.
    pub prim: Lu,
    /// Global triangle ID of the hit (`NO_GID`: none).
    pub gid: Lu,
    /// Edge function weighting vertex 1.
    pub e1: Lf,
    /// Edge function weighting vertex 2.
    pub e2: Lf,
    /// Sum of the three edge functions.
    pub det: Lf,
}

/// `inst` value of a lane without a hit.
pub(crate) const NO_HIT: u32 = u32::MAX;
/// `gid` value of a lane without a hit.
pub(crate) const NO_GID: u32 = u32::MAX;

impl Hits {
    /// Empty intervals, no hits.
    pub fn new() -> Self {
        Self {
            tmin: [[f32::INFINITY; CHUNK]; CHUNKS],
            t: [[f32::NEG_INFINITY; CHUNK]; CHUNKS],
            inst: [[NO_HIT; CHUNK]; CHUNKS],
            prim: [[0; CHUNK]; CHUNKS],
            gid: [[NO_GID; CHUNK]; CHUNKS],
            e1: [[0.0; CHUNK]; CHUNKS],
            e2: [[0.0; CHUNK]; CHUNKS],
            det: [[1.0; CHUNK]; CHUNKS],
        }
    }

    /// Opens lane `i` on `[tmin, tmax]` with no hit.
    #[inline]
    pub fn open(&mut self, i: usize, tmin: f32, tmax: f32) {
        let (c, j) = (i / CHUNK, i % CHUNK);
        self.tmin[c][j] = tmin;
        self.t[c][j] = tmax;
        self.inst[c][j] = NO_HIT;
        self.gid[c][j] = NO_GID;
    }

    /// (tmin, t) of lane `i`.
    #[inline(always)]
    pub fn range(&self, i: usize) -> (f32, f32) {
        let (c, j) = (i / CHUNK, i % CHUNK);
        (self.tmin[c][j], self.t[c][j])
    }
}

/// The four corner rays of a packet, in cyclic order around the tile (a test reference:
/// the ray caster reads its packets' planes from `CameraRays::frustum`).
#[cfg(test)]
#[derive(Debug, Clone, Copy)]
pub(crate) struct Beam {
    /// Corner origins.
    pub o: [Vec3A; 4],
    /// Corner directions.
    pub d: [Vec3A; 4],
}

#[cfg(test)]
impl Beam {
    /// The beam mapped by `local_from_world`.
    pub fn transformed(&self, m: &Affine3A) -> Beam {
        Beam { o: self.o.map(|p| m.transform_point3a(p)), d: self.d.map(|v| m.transform_vector3a(v)) }
    }

    /// The four side planes, oriented inwards; culling is off when they are degenerate.
    pub fn frustum(&self) -> BeamPlanes {
        let mut f = BeamPlanes { on: true, n: [[0.0; 4]; 3], c: [0.0; 4] };
        let q = (0..4).map(|k| self.o[k] + self.d[k]).sum::<Vec3A>() * 0.25;
        for k in 0..4 {
            let (a, b) = (k, (k + 1) % 4);
            let p1 = self.o[a];
            // Perspective: o_a = o_b, n = d_a × d_b. Parallel: d_a = d_b, n = d × (o_b − o_a).
            let mut n = self.d[a].cross(self.o[b] + self.d[b] - p1);
            let mut c = -n.dot(p1);
            if n.dot(q) + c < 0.0 {
                n = -n;
                c = -c;
            }
            if !(n.is_finite() && c.is_finite()) || n.length_squared() == 0.0 {
                f.on = false;
            }
            for ax in 0..3 {
                f.n[ax][k] = n[ax];
            }
            f.c[k] = c;
        }
        f
    }
}

/// Four planes `n·x + c ≥ 0` bounding a packet's rays.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BeamPlanes {
    /// False: cull nothing.
    pub on: bool,
    /// Plane normals, SoA over the four planes.
    pub n: [[f32; 4]; 3],
    /// Plane offsets.
    pub c: [f32; 4],
}

impl BeamPlanes {
    /// A frustum that culls nothing.
    pub const OFF: BeamPlanes = BeamPlanes { on: false, n: [[0.0; 4]; 3], c: [0.0; 4] };

    /// True when the box lies entirely outside one of the planes (beyond rounding).
    #[cfg(test)]
    pub fn culls(&self, lo: &[f32; 3], hi: &[f32; 3]) -> bool {
        if !self.on {
            return false;
        }
        let mut out = false;
        for k in 0..4 {
            let mut dist = self.c[k];
            let mut mag = self.c[k].abs();
            for ax in 0..3 {
                let n = self.n[ax][k];
                let p = if n >= 0.0 { hi[ax] } else { lo[ax] };
                dist += n * p;
                mag += (n * p).abs();
            }
            out |= dist < -1e-6 * mag;
        }
        out
    }
}

impl BeamPlanes {
    /// The planes in the space `world_from_local` maps from: `n·(M y + t) + c` becomes
    /// `(Mᵀ n)·y + (n·t + c)`.
    pub fn transformed(&self, world_from_local: &Affine3A) -> BeamPlanes {
        if !self.on {
            return *self;
        }
        let m = world_from_local.matrix3;
        let t = world_from_local.translation;
        let mut out = *self;
        for k in 0..4 {
            let n = Vec3A::new(self.n[0][k], self.n[1][k], self.n[2][k]);
            let nl = m.transpose() * n;
            out.c[k] = n.dot(t) + self.c[k];
            for a in 0..3 {
                out.n[a][k] = nl[a];
            }
            out.on &= nl.is_finite() && out.c[k].is_finite();
        }
        out
    }

    /// The beam of rays that all run along `dir` from the `origins`: the four planes
    /// parallel to `dir` around the origins' footprint on a plane across `dir`, padded by
    /// `pad` (for shadow rays towards a directional light).
    pub fn parallel(dir: Vec3A, origins: impl Iterator<Item = Vec3A>, pad: f32) -> BeamPlanes {
        let d = dir.normalize_or_zero();
        if d == Vec3A::ZERO {
            return BeamPlanes::OFF;
        }
        let helper = if d.x.abs() < 0.9 { Vec3A::X } else { Vec3A::Y };
        let u = helper.cross(d).normalize();
        let v = d.cross(u);
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for o in origins {
            for (k, axis) in [u, v].iter().enumerate() {
                let p = o.dot(*axis);
                lo[k] = lo[k].min(p);
                hi[k] = hi[k].max(p);
            }
        }
        if !(lo[0] <= hi[0] && lo[1] <= hi[1]) {
            return BeamPlanes::OFF;
        }
        // n·x + c ≥ 0 inside: x·u ≥ lo, −x·u ≥ −hi, and the same for v.
        let planes = [(u, -(lo[0] - pad)), (-u, hi[0] + pad), (v, -(lo[1] - pad)), (-v, hi[1] + pad)];
        let mut f = BeamPlanes { on: true, n: [[0.0; 4]; 3], c: [0.0; 4] };
        for (k, (n, c)) in planes.into_iter().enumerate() {
            for a in 0..3 {
                f.n[a][k] = n[a];
            }
            f.c[k] = c;
            f.on &= c.is_finite();
        }
        f
    }

    /// `BeamPlanes::culls` (the one-box form, kept for the tests) for the four boxes of a
    /// node at once (`[axis][child]` layout), as a 4-bit mask: the center–extent form of
    /// the plane test, `n·c + |n|·e + d < 0`, on four boxes per SIMD operation.
    #[inline(always)]
    pub fn culls4(&self, lo: &[[f32; 4]; 3], hi: &[[f32; 4]; 3]) -> u32 {
        if !self.on {
            return 0;
        }
        let l = [Vec4::from_array(lo[0]), Vec4::from_array(lo[1]), Vec4::from_array(lo[2])];
        let h = [Vec4::from_array(hi[0]), Vec4::from_array(hi[1]), Vec4::from_array(hi[2])];
        let c = [(l[0] + h[0]) * 0.5, (l[1] + h[1]) * 0.5, (l[2] + h[2]) * 0.5];
        let e = [(h[0] - l[0]) * 0.5, (h[1] - l[1]) * 0.5, (h[2] - l[2]) * 0.5];
        let ca = [c[0].abs() + e[0], c[1].abs() + e[1], c[2].abs() + e[2]];
        let mut out = 0u32;
        for k in 0..4 {
            let (nx, ny, nz, d) = (self.n[0][k], self.n[1][k], self.n[2][k], self.c[k]);
            let (ax, ay, az) = (nx.abs(), ny.abs(), nz.abs());
            let dist = c[0] * nx + c[1] * ny + c[2] * nz + (e[0] * ax + e[1] * ay + e[2] * az) + Vec4::splat(d);
            let mag = ca[0] * ax + ca[1] * ay + ca[2] * az + Vec4::splat(d.abs());
            out |= dist.cmplt(mag * -1e-6).bitmask();
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frustum_keeps_boxes_on_corner_rays_and_culls_outside() {
        let o = Vec3A::new(1.0, 2.0, 3.0);
        let d = [
            Vec3A::new(-1.0, -1.0, -1.0),
            Vec3A::new(1.0, -1.0, -1.0),
            Vec3A::new(1.0, 1.0, -1.0),
            Vec3A::new(-1.0, 1.0, -1.0),
        ];
        let beam = Beam { o: [o; 4], d };
        let f = beam.frustum();
        assert!(f.on);
        let at = |p: Vec3A| (p.to_array(), (p + 0.01).to_array());
        let (lo, hi) = at(o + d[2] * 5.0 - 0.005);
        assert!(!f.culls(&lo, &hi));
        let (lo, hi) = at(o + Vec3A::new(0.0, 0.0, -5.0));
        assert!(!f.culls(&lo, &hi));
        let (lo, hi) = at(o + Vec3A::new(6.0, 0.0, -5.0));
        assert!(f.culls(&lo, &hi));
        // Mirrored by a transform: still oriented inwards.
        let m = Affine3A::from_scale(glam::Vec3::new(-1.0, 1.0, 1.0));
        let g = beam.transformed(&m).frustum();
        let (lo, hi) = at(m.transform_point3a(o + Vec3A::new(0.0, 0.0, -5.0)));
        assert!(!g.culls(&lo, &hi));
        // Parallel beam.
        let par = Beam {
            o: [
                Vec3A::new(0.0, 0.0, 0.0),
                Vec3A::new(1.0, 0.0, 0.0),
                Vec3A::new(1.0, 1.0, 0.0),
                Vec3A::new(0.0, 1.0, 0.0),
            ],
            d: [Vec3A::NEG_Z; 4],
        };
        let p = par.frustum();
        assert!(p.on);
        let (lo, hi) = at(Vec3A::new(0.5, 0.5, -100.0));
        assert!(!p.culls(&lo, &hi));
        let (lo, hi) = at(Vec3A::new(1.5, 0.5, -100.0));
        assert!(p.culls(&lo, &hi));
        // Planes mapped into a local space cull the same boxes.
        let w = Affine3A::from_scale_rotation_translation(
            glam::Vec3::new(2.0, 0.5, 1.0),
            glam::Quat::from_rotation_y(0.4),
            glam::Vec3::new(3.0, -1.0, 2.0),
        );
        let local = f.transformed(&w);
        for q in [o + d[2] * 5.0, o + Vec3A::new(0.0, 0.0, -5.0), o + Vec3A::new(6.0, 0.0, -5.0)] {
            let l = w.inverse().transform_point3a(q);
            let (lo, hi) = at(q);
            let (llo, lhi) = ((l - 0.002).to_array(), (l + 0.002).to_array());
            assert_eq!(f.culls(&lo, &hi), local.culls(&llo, &lhi), "{q}");
        }
        // Shadow beams: parallel rays from scattered origins.
        let origins = [Vec3A::new(0.0, 0.0, 0.0), Vec3A::new(2.0, 1.0, 0.0), Vec3A::new(1.0, 3.0, 1.0)];
        let s = BeamPlanes::parallel(Vec3A::new(0.2, 1.0, 0.1), origins.into_iter(), 1e-3);
        for q in origins {
            let (lo, hi) = at(q + Vec3A::new(0.2, 1.0, 0.1) * 7.0);
            assert!(!s.culls(&lo, &hi));
        }
        let (lo, hi) = at(Vec3A::new(10.0, 0.0, 0.0));
        assert!(s.culls(&lo, &hi));
    }
}
