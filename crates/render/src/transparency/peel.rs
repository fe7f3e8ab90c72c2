//! Depth peeling: order-independent transparency with nothing but z-buffer passes.
//!
//! Everitt, "Interactive Order-Independent Transparency", NVIDIA, 2001 (after Mammen,
//! "Transparency and Antialiasing Algorithms Implemented with the Virtual Pixel Maps
//! Technique", IEEE CG&A 1989): pass k draws every blended triangle with an ordinary
//! z-buffer test plus a second test against the depth that pass k − 1 kept, so that it
//! keeps, per pixel, the nearest fragment *strictly behind* the previous layer. Pass 1
//! finds the nearest blended surface, pass 2 the second nearest, and so on; each layer is
//! composited front to back ("under", see `blend.rs`) as soon as it is found.
//!
//! * The opaque surface bounds every layer: the z-buffer of each pass starts from the opaque
//!   depth, so a fragment behind it never wins.
//! * "Strictly behind" is the z-buffer's own order: depth key, then triangle ID. A fragment
//!   is behind the last layer when its (key, ID) is greater; the layer is the least such
//!   (key, ID). Coplanar blended surfaces (equal keys) are thus peeled one after the other,
//!   smaller ID first, neither lost nor doubled, and the layers are exactly the A-buffer's
//!   sorted lists, one element per pass.
//! * With at least as many passes as the deepest pixel's blended fragments, the image equals
//!   the A-buffer's (up to the rounding of the compositing order). With fewer, the farthest
//!   layers are missing: they are not drawn at all, and the opaque color shows through
//!   where they would have been.
//! * A band runs as many passes as its deepest pixel needs, at most k.
//!
//! Each pass rasterizes every blended triangle again: the cost is the layers × the blended
//! fragments, against the A-buffer's one walk and a sort, but the memory does not grow with
//! the depth complexity. A first, counting walk finds the pixels with blended fragments in
//! front of the opaque surface and how many (the layers the band needs: no pass is spent
//! finding nothing); the passes keep their state for those pixels only, in flat arrays.

use crate::depth::{with_codec, DepthCodec, DepthFormat};
use crate::edge::Tri;
use crate::raster::kernel::wins;
use crate::shading::ShadingMode;

use super::blend::Under;
use super::surface::Surfaces;
use super::walk::{walk, Band};
use super::LayerCounts;

/// Peels up to `layers` layers of the blended triangles `tris` in `band` and composites them.
pub(crate) fn peel_band<'t>(
    band: &mut Band,
    tris: impl Iterator<Item = &'t Tri> + Clone,
    layers: u32,
    surfaces: &Surfaces,
    fmt: DepthFormat,
) -> LayerCounts {
    with_codec!(fmt, peel_in::<_>(band, tris, layers, surfaces))
}

/// A pixel without blended fragments in front of its opaque surface.
const INACTIVE: u32 = u32::MAX;

/// The passes' state of the active pixels (those with blended fragments in front of the
/// opaque surface), one entry each.
#[derive(Clone, Copy)]
struct Active {
    /// The band pixel.
    pixel: u32,
    /// Blended fragments in front of the opaque surface.
    fragments: u32,
    /// The opaque surface: depth key and ID.
    opaque_key: u32,
    opaque_id: u32,
    /// The last layer peeled ((0, 0) before the first: every fragment lies behind it, IDs
    /// being at least 1).
    last_key: u32,
    last_id: u32,
    /// This pass's z-buffer and the color of its fragment.
    key: u32,
    id: u32,
    rgba: [u8; 4],
    /// The first layer (the nearest blended surface).
    first_key: u32,
    first_id: u32,
    /// The front-to-back sum.
    under: Under,
}

fn peel_in<'t, D: DepthCodec>(
    band: &mut Band,
    tris: impl Iterator<Item = &'t Tri> + Clone,
    layers: u32,
    surfaces: &Surfaces,
) -> LayerCounts {
    let shading = surfaces.opts.mode != ShadingMode::None;
    let mut counts = LayerCounts::default();
    // The counting walk: per pixel, the fragments in front of the opaque surface.
    let mut slot = vec![0u32; band.ids.len()];
    for t in tris.clone() {
        walk::<D>(t, band.span(), |x, y, key| {
            let i = band.index(x, y);
            counts.drawn += 1;
            slot[i] += wins(key, t.id, D::FORMAT.key_of_stored(band.depth[i]), band.ids[i]) as u32;
        });
    }
    let mut active = Vec::new();
    for (i, s) in slot.iter_mut().enumerate() {
        if *s == 0 {
            *s = INACTIVE;
            continue;
        }
        let (key, id) = (D::FORMAT.key_of_stored(band.depth[i]), band.ids[i]);
        active.push(Active {
            pixel: i as u32,
            fragments: *s,
            opaque_key: key,
            opaque_id: id,
            last_key: 0,
            last_id: 0,
            key,
            id,
            rgba: [0; 4],
            first_key: key,
            first_id: id,
            under: Under::default(),
        });
        counts.pixel(*s);
        *s = active.len() as u32 - 1;
    }
    let mut hint = 0;
    for pass in 0..layers.min(counts.max) {
        for t in tris.clone() {
            let mut surface = None;
            walk::<D>(t, band.span(), |x, y, key| {
                counts.drawn += 1;
                let j = slot[band.index(x, y)];
                let Some(a) = active.get_mut(j as usize) else { return };
                // In front of the opaque surface, strictly behind the last layer, and nearer
                // than this pass's best so far (which starts as the opaque surface).
                let (k, id) = (key, t.id);
                if !wins(k, id, a.opaque_key, a.opaque_id)
                    || !wins(a.last_key, a.last_id, k, id)
                    || !wins(k, id, a.key, a.id)
                {
                    return;
                }
                let Some(s) = surface.get_or_insert_with(|| surfaces.get(id, &mut hint)) else { return };
                (a.key, a.id) = (k, id);
                if shading {
                    a.rgba = surfaces.color(s, x, y);
                }
            });
        }
        // Composite the layer found (where the pass's z-buffer left the opaque surface), and
        // start the next pass from the opaque surface again.
        for a in active.iter_mut().filter(|a| (a.key, a.id) != (a.opaque_key, a.opaque_id)) {
            a.under.add(a.rgba);
            (a.last_key, a.last_id) = (a.key, a.id);
            if pass == 0 {
                (a.first_key, a.first_id) = (a.key, a.id);
            }
            (a.key, a.id) = (a.opaque_key, a.opaque_id);
        }
        counts.layers = pass + 1;
    }
    for a in &active {
        let i = a.pixel as usize;
        counts.short += (a.fragments > counts.layers) as u64;
        if shading {
            band.color[i] = a.under.resolve(band.color[i]);
        }
        band.ids[i] = a.first_id;
        band.depth[i] = D::decode(a.first_key);
    }
    counts
}
