//! Two-level packet tracing: the TLAS over instances, then each instance's BLAS with the
//! packet mapped into its local space, then the primitives of each leaf: quads (two
//! triangles tested at once) or lone triangles, whichever the BLAS stores.
//!
//! Closest-hit queries (`ANY = false`) keep the nearest hit per lane; any-hit queries
//! (`ANY = true`, shadow rays) close a lane at its first hit and stop when all are closed.

use sightline_spatial::bvh::wide::{BlasPrims, BlasQuad, BlasTriangle, WideBlas, WideTlas};
use sightline_spatial::prefetch_all;

use super::isa::Isa;
use super::packet::{chunk_bits, BeamPlanes, Hits, Rays, CHUNK, CHUNKS};
use super::traverse::{traverse, Entry};
use super::triangle::{
    intersect_general, intersect_quad_general, intersect_quad_shared, intersect_shared, shared_setup, Job,
};

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
    /// Scratch with stacks allocated for trees of the given depths (`depth + 4` entries;
    /// they grow as needed).
    pub fn new(tlas_depth: usize, blas_depth: usize) -> Self {
        Self {
            local: Rays::new(),
            tlas_stack: Vec::with_capacity(tlas_depth + 4),
            blas_stack: Vec::with_capacity(blas_depth + 4),
        }
    }
}

/// Tests the lanes of `mask` against the primitives of one BLAS leaf (a hit records the
/// triangle as `WideBlas::triangle` names it).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn leaf<const ANY: bool>(
    blas: &WideBlas,
    rays: &Rays,
    hits: &mut Hits,
    first: u32,
    count: u32,
    mask: u64,
    inst: u32,
    first_id: u32,
    cull: f32,
) -> u64 {
    let job = Job { c: 0, bits: 0, inst, prim: 0, gid: first_id, cull };
    match blas.prims() {
        BlasPrims::Quads(q) => quad_leaf::<ANY>(q, rays, hits, first, count, mask, job),
        BlasPrims::Triangles(t) => triangle_leaf::<ANY>(t, rays, hits, first, count, mask, job),
    }
}

/// The lanes hit when `$e` (the lanes of chunk `$c` hit, given its active lanes `$bits`)
/// runs on each chunk with active lanes in `$mask`. A macro, not a closure: the kernels
/// must inline into straight loops to vectorize.
macro_rules! over_chunks {
    ($mask:expr, |$c:ident, $bits:ident| $e:expr) => {{
        let mut got = 0u64;
        for $c in 0..CHUNKS {
            let $bits = chunk_bits($mask, $c);
            if $bits != 0 {
                got |= $e << ($c * CHUNK);
            }
        }
        got
    }};
}

/// With `ANY`, moves the lanes a record hit (`got`) from `mask` to `done`: true when no lane
/// is left. Closest-hit lanes stay until the leaf ends.
#[inline(always)]
fn retire<const ANY: bool>(got: u64, done: &mut u64, mask: &mut u64) -> bool {
    if ANY {
        *done |= got;
        *mask &= !got;
    }
    ANY && *mask == 0
}

/// The axis permutation of the first active chunk of `mask`: usually every chunk's.
#[inline(always)]
fn common_perm(rays: &Rays, mask: u64) -> u8 {
    rays.uniform[(mask.trailing_zeros() as usize / CHUNK).min(CHUNKS - 1)]
}

/// [`leaf`] over lone triangles; `base` holds the instance, the instance's first ID (as
/// `gid`) and the facing rule.
#[inline(always)]
fn triangle_leaf<const ANY: bool>(
    tris: &[BlasTriangle],
    rays: &Rays,
    hits: &mut Hits,
    first: u32,
    count: u32,
    mut mask: u64,
    base: Job,
) -> u64 {
    let mut done = 0u64;
    let end = first.saturating_add(count).min(tris.len() as u32);
    let common = common_perm(rays, mask);
    for k in first..end {
        let rec = &tris[k as usize];
        let gid = base.gid.wrapping_add(rec.index);
        let job = |c, bits| Job { c, bits, prim: k, gid, ..base };
        let got = match rays.shared {
            Some(o) => {
                let s = shared_setup(&rec.corners, o, common);
                over_chunks!(mask, |c, bits| intersect_shared::<ANY>(&s, rays, hits, job(c, bits)))
            }
            None => over_chunks!(mask, |c, bits| intersect_general::<ANY>(&rec.corners, rays, hits, job(c, bits))),
        };
        if retire::<ANY>(got, &mut done, &mut mask) {
            break;
        }
    }
    done
}

/// [`leaf`] over quads (a hit records triangle 2 · slot + half).
#[inline(always)]
fn quad_leaf<const ANY: bool>(
    quads: &[BlasQuad],
    rays: &Rays,
    hits: &mut Hits,
    first: u32,
    count: u32,
    mut mask: u64,
    base: Job,
) -> u64 {
    let mut done = 0u64;
    let end = first.saturating_add(count).min(quads.len() as u32);
    let common = common_perm(rays, mask);
    for k in first..end {
        let q = &quads[k as usize];
        let gid = [base.gid.wrapping_add(q.index[0]), base.gid.wrapping_add(q.index[1])];
        let a = |c, bits| Job { c, bits, prim: 2 * k, gid: gid[0], ..base };
        let ab = |c, bits| [a(c, bits), Job { c, bits, prim: 2 * k + 1, gid: gid[1], ..base }];
        let got = match (rays.shared, q.is_pair()) {
            (Some(o), true) => {
                let s = shared_setup(&q.corners, o, common);
                over_chunks!(mask, |c, bits| intersect_quad_shared::<ANY>(&s, rays, hits, ab(c, bits)))
            }
            (Some(o), false) => {
                let s = shared_setup(&q.triangle(0), o, common);
                over_chunks!(mask, |c, bits| intersect_shared::<ANY>(&s, rays, hits, a(c, bits)))
            }
            (None, true) => {
                over_chunks!(mask, |c, bits| intersect_quad_general::<ANY>(&q.corners, rays, hits, ab(c, bits)))
            }
            (None, false) => {
                over_chunks!(mask, |c, bits| intersect_general::<ANY>(&q.triangle(0), rays, hits, a(c, bits)))
            }
        };
        if retire::<ANY>(got, &mut done, &mut mask) {
            break;
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

/// Asks for the cache lines of a leaf's primitives (see `traverse`'s `soon`).
#[inline(always)]
fn prefetch_leaf(blas: &WideBlas, first: u32, count: u32) {
    let (s, e) = (first as usize, first as usize + count as usize);
    match blas.prims() {
        BlasPrims::Quads(q) => prefetch_all(q.get(s..e).unwrap_or_default()),
        BlasPrims::Triangles(t) => prefetch_all(t.get(s..e).unwrap_or_default()),
    }
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
