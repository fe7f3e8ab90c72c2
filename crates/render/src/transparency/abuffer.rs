//! The A-buffer: per-pixel lists of the blended fragments in front of the opaque surface,
//! sorted by depth and composited back to front. The reference for transparency.
//!
//! Carpenter, "The A-buffer, an antialiased hidden surface method", SIGGRAPH 1984, keeps at
//! each pixel a list of the fragments that reach it and resolves the list once everything
//! is drawn. Carpenter's fragments also carry a 4×8 coverage bit mask for antialiasing;
//! here a fragment is a pixel center the triangle covers (the z-buffer's sampling), so this
//! is the A-buffer's per-pixel fragment list without its subpixel coverage masks.
//!
//! 1. The opaque (and masked) surfaces are drawn by the z-buffer and shaded first.
//! 2. Every blended triangle is walked; a fragment that passes the depth test against the
//!    opaque surface (LESS, ties to the smaller ID) is shaded at once (its color and alpha)
//!    and appended to the band's fragment list with its pixel, depth key and triangle ID.
//! 3. The list is ordered by pixel with a counting sort into one pool: per-pixel counts,
//!    their prefix sums as each pixel's head, then a scatter. No list per pixel: three flat
//!    arrays per band.
//! 4. Each pixel's fragments are sorted by depth, ties by triangle ID (the z-buffer's order,
//!    so coplanar surfaces are neither lost nor doubled), and composited back to front over
//!    the opaque color with the "over" operator (Porter & Duff 1984).
//!
//! The ID and depth planes then hold the nearest surface, blended or opaque. Memory grows
//! with the fragments kept, which is bounded by [`MAX_ABUFFER_FRAGMENTS`].

use std::sync::atomic::{AtomicU64, Ordering};

use crate::depth::{with_codec, DepthCodec, DepthFormat};
use crate::edge::Tri;
use crate::raster::kernel::wins;
use crate::shading::ShadingMode;

use super::blend::over_all;
use super::surface::Surfaces;
use super::walk::{walk, Band};
use super::LayerCounts;

/// The most fragments one A-buffer frame keeps (32 bytes each at the peak): beyond it the
/// frame fails with [`Error::TooManyFragments`](crate::Error::TooManyFragments) rather than
/// exhaust memory.
pub const MAX_ABUFFER_FRAGMENTS: u64 = 1 << 24;

/// One fragment of a list.
#[derive(Debug, Clone, Copy, Default)]
struct Fragment {
    /// Pixel index within the band.
    pixel: u32,
    key: u32,
    id: u32,
    rgba: [u8; 4],
}

/// Collects, sorts and composites the blended triangles `tris` in `band`. `kept` counts the
/// fragments kept by every band; a band stops (returning `None`) once it passes
/// [`MAX_ABUFFER_FRAGMENTS`].
pub(crate) fn resolve_band<'t>(
    band: &mut Band,
    tris: impl Iterator<Item = &'t Tri>,
    surfaces: &Surfaces,
    fmt: DepthFormat,
    kept: &AtomicU64,
) -> Option<LayerCounts> {
    with_codec!(fmt, resolve_in::<_>(band, tris, surfaces, kept))
}

fn resolve_in<'t, D: DepthCodec>(
    band: &mut Band,
    tris: impl Iterator<Item = &'t Tri>,
    surfaces: &Surfaces,
    kept: &AtomicU64,
) -> Option<LayerCounts> {
    let shading = surfaces.opts.mode != ShadingMode::None;
    let mut counts = LayerCounts::default();
    // 2. Collect.
    let mut list: Vec<Fragment> = Vec::new();
    let mut hint = 0;
    for t in tris {
        let mut surface = None;
        let before = list.len();
        walk::<D>(t, band.span(), |x, y, key| {
            let i = band.index(x, y);
            counts.drawn += 1;
            if !wins(key, t.id, D::FORMAT.key_of_stored(band.depth[i]), band.ids[i]) {
                return;
            }
            let Some(s) = surface.get_or_insert_with(|| surfaces.get(t.id, &mut hint)) else { return };
            let rgba = if shading { surfaces.color(s, x, y) } else { [0; 4] };
            list.push(Fragment { pixel: i as u32, key, id: t.id, rgba });
        });
        let added = (list.len() - before) as u64;
        if kept.fetch_add(added, Ordering::Relaxed) + added > MAX_ABUFFER_FRAGMENTS {
            return None;
        }
    }
    if list.is_empty() {
        return Some(counts);
    }
    // 3. Counting sort by pixel: counts, heads (prefix sums), scatter into the pool.
    let n = band.ids.len();
    let mut heads = vec![0u32; n + 1];
    for f in &list {
        heads[f.pixel as usize + 1] += 1;
    }
    for p in 0..n {
        heads[p + 1] += heads[p];
    }
    let mut cursor = heads[..n].to_vec();
    let mut pool = vec![Fragment::default(); list.len()];
    for f in &list {
        let c = &mut cursor[f.pixel as usize];
        pool[*c as usize] = *f;
        *c += 1;
    }
    drop(list);
    // 4. Sort each pixel's fragments by depth (ties by ID) and composite back to front.
    for p in 0..n {
        let frags = &mut pool[heads[p] as usize..heads[p + 1] as usize];
        if frags.is_empty() {
            continue;
        }
        frags.sort_unstable_by_key(|f| (f.key, f.id));
        counts.pixel(frags.len() as u32);
        if shading {
            band.color[p] = over_all(frags.iter().rev().map(|f| f.rgba), band.color[p]);
        }
        band.ids[p] = frags[0].id;
        band.depth[p] = D::decode(frags[0].key);
    }
    counts.layers = counts.max;
    Some(counts)
}
