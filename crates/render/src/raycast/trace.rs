//! Two-level packet tracing: the TLAS over instances, then each instance's BLAS with the
//! packet mapped into its local space, then the triangles of each leaf.
//!
//! Closest-hit queries (`ANY = false`) keep the nearest hit per lane; any-hit queries
//! (`ANY = true`, shadow rays) close a lane at its first hit and stop when all are closed.

use sightline_spatial::bvh::wide::{WideBlas, WideTlas};
use sightline_spatial::prefetch_all;

use super::isa::Isa;
use super::packet::{chunk_bits, BeamPlanes, Hits, Rays, CHUNK, CHUNKS};
use super::traverse::{traverse, Entry};
use super::triangle::{intersect_general, intersect_shared, shared_setup, Job};

/// Per-thread scratch space for tracing packets.
pub(crate) struct Scratch {
    /// The packet in the current instance's space.
    pub local: Rays,
    /// Traversal stack of the TLAS.
    pub tlas_stack: Vec<Entry>,
    /// Traversal stack of the BLASes.
    pub blas_stack: Vec<Entry>,
}

impl Scratch {
    /// Scratch with stacks sized for trees of the given depths.
    pub fn new(tlas_depth: usize, blas_depth: usize) -> Self {
        Self {
            local: Rays::new(),
            tlas_stack: Vec::with_capacity(tlas_depth + 4),
            blas_stack: Vec::with_capacity(blas_depth + 4),
        }
    }
}

/// Tests the lanes of `mask` against the triangles of one BLAS leaf.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn leaf<const ANY: bool>(
    blas: &WideBlas,
    rays: &Rays,
    hits: &mut Hits,
    first: u32,
    count: u32,
    mut mask: u64,
    inst: u32,
    first_id: u32,
    cull: f32,
) -> u64 {
    let mut done = 0u64;
    let end = first.saturating_add(count).min(blas.tris().len() as u32);
    // The axis permutation of the first active chunk: usually every chunk's.
    let common = rays.uniform[(mask.trailing_zeros() as usize / CHUNK).min(CHUNKS - 1)];
    for k in first..end {
        let rec = &blas.tris()[k as usize];
        let (tri, gid) = (&rec.corners, first_id.wrapping_add(rec.index));
        let mut got = 0u64;
        match rays.shared {
            Some(o) => {
                let s = shared_setup(tri, o, common);
                for c in 0..CHUNKS {
                    let bits = chunk_bits(mask, c);
                    if bits != 0 {
                        let job = Job { c, bits, inst, prim: k, gid, cull };
                        got |= intersect_shared::<ANY>(&s, rays, hits, job) << (c * CHUNK);
                    }
                }
            }
            None => {
                for c in 0..CHUNKS {
                    let bits = chunk_bits(mask, c);
                    if bits != 0 {
                        let job = Job { c, bits, inst, prim: k, gid, cull };
                        got |= intersect_general::<ANY>(tri, rays, hits, job) << (c * CHUNK);
                    }
                }
            }
        }
        if ANY {
            done |= got;
            mask &= !got;
            if mask == 0 {
                break;
            }
        }
    }
    done
}

/// Traces the lanes of `mask` through TLAS record `ii`'s BLAS (the packet mapped into the
/// instance's space unless its transform is the identity).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn instance<I: Isa, const ANY: bool>(
    blases: &[WideBlas],
    tlas: &WideTlas,
    ii: u32,
    rays: &Rays,
    world: &BeamPlanes,
    backface: bool,
    hits: &mut Hits,
    m: u64,
    local: &mut Rays,
    blas_stack: &mut Vec<Entry>,
) -> u64 {
    let Some(inst) = tlas.instances().get(ii as usize) else {
        return 0;
    };
    let Some(blas) = blases.get(inst.blas as usize) else {
        return 0;
    };
    let (lr, fr): (&Rays, BeamPlanes) = if inst.identity {
        (rays, *world)
    } else {
        rays.transform_into(&inst.local_from_world, m, local);
        (&*local, world.transformed(&inst.world_from_blas))
    };
    let cull = match (backface, inst.mirror) {
        (false, _) => 0.0,
        (true, false) => 1.0,
        (true, true) => -1.0,
    };
    traverse::<I, _, _>(
        blas.bvh(),
        lr,
        hits,
        &fr,
        m,
        blas_stack,
        #[inline(always)]
        |f, n| prefetch_leaf(blas, f, n),
        #[inline(always)]
        |hits, f, n, lm| leaf::<ANY>(blas, lr, hits, f, n, lm, ii, inst.first_id, cull),
    )
}

/// Asks for the cache lines of a leaf's triangles (see `traverse`'s `soon`).
#[inline(always)]
fn prefetch_leaf(blas: &WideBlas, first: u32, count: u32) {
    let (s, e) = (first as usize, first as usize + count as usize);
    prefetch_all(blas.tris().get(s..e).unwrap_or_default());
}

/// Traces the lanes of `mask` through the scene. `frustum` (world space; planes bounding
/// the packet's rays) enables frustum culling; `backface` drops triangles seen from behind. Returns the lanes closed by
/// any-hit queries.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace<I: Isa, const ANY: bool>(
    blases: &[WideBlas],
    tlas: &WideTlas,
    rays: &Rays,
    frustum: &BeamPlanes,
    backface: bool,
    hits: &mut Hits,
    mask: u64,
    s: &mut Scratch,
) -> u64 {
    let world = *frustum;
    let Scratch { local, tlas_stack, blas_stack } = s;
    // A TLAS that is one leaf of one instance (a loaded OBJ: one mesh): its root test only
    // prunes what the BLAS's own root test prunes again, so go to the BLAS directly.
    if let ([only], 1) = (tlas.bvh().order(), tlas.bvh().root().count) {
        return instance::<I, ANY>(blases, tlas, *only, rays, &world, backface, hits, mask, local, blas_stack);
    }
    traverse::<I, _, _>(
        tlas.bvh(),
        rays,
        hits,
        &world,
        mask,
        tlas_stack,
        |_, _| {},
        #[inline(always)]
        |hits, first, count, m| {
            let mut done = 0u64;
            let end = first.saturating_add(count) as usize;
            for k in first as usize..end.min(tlas.bvh().order().len()) {
                let m = m & !done;
                if m == 0 {
                    break;
                }
                let ii = tlas.bvh().order()[k];
                done |= instance::<I, ANY>(blases, tlas, ii, rays, &world, backface, hits, m, local, blas_stack);
            }
            done
        },
    )
}
