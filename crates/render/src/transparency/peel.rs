//! Depth peeling: order-independent transparency with nothing but z-buffer passes.
//!
//! Everitt, "Interactive Order-Independent Transparency", NVIDIA, 2001 (after Mammen,
//! "Transparency and Antialiasing Algorithms Implemented with the Virtual Pixel Maps
//! Technique", IEEE CG&A 1989): pass k draws every blended triangle with an ordinary
//! z-buffer test plus a second test against the depth that pass k − 1 kept, so that it
//! keeps, per pixel, the nearest fragment *strictly behind* the previous layer. Pass 1
//! finds the nearest blended surface, pass 2 the second nearest, and so on; each layer is
//! composited front to back ("under", see [`super::blend`]) as soon as it is found.
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
//! * A band stops early after a pass that finds no layer anywhere in it.
//!
//! Each pass rasterizes every blended triangle again: the cost is (layers + 1) × the
//! blended fragments, against the A-buffer's one walk and a sort, but the memory is a fixed
//! few planes, whatever the depth complexity.

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

/// Per-pixel state of the passes (flat planes over the band).
struct Planes {
    /// The opaque surface's depth key.
    opaque: Vec<u32>,
    /// The last layer peeled: depth key and ID ((0, 0) before the first: every fragment
    /// lies behind it, IDs being at least 1).
    last_key: Vec<u32>,
    last_id: Vec<u32>,
    /// This pass's z-buffer.
    key: Vec<u32>,
    id: Vec<u32>,
    rgba: Vec<[u8; 4]>,
    /// The fragments in front of the opaque surface (counted in the first pass).
    fragments: Vec<u32>,
    /// The front-to-back sums.
    under: Vec<Under>,
}

fn peel_in<'t, D: DepthCodec>(
    band: &mut Band,
    tris: impl Iterator<Item = &'t Tri> + Clone,
    layers: u32,
    surfaces: &Surfaces,
) -> LayerCounts {
    let shading = surfaces.opts.mode != ShadingMode::None;
    let n = band.ids.len();
    let opaque: Vec<u32> = band.depth.iter().map(|&d| D::FORMAT.key_of_stored(d)).collect();
    let mut p = Planes {
        last_key: vec![0; n],
        last_id: vec![0; n],
        key: opaque.clone(),
        id: band.ids.to_vec(),
        rgba: vec![[0; 4]; n],
        fragments: vec![0; n],
        under: vec![Under::default(); n],
        opaque,
    };
    let mut counts = LayerCounts::default();
    let (mut first_id, mut first_key) = (band.ids.to_vec(), p.opaque.clone());
    let mut hint = 0;
    for pass in 0..layers {
        // The pass's z-buffer starts from the opaque surface.
        p.key.copy_from_slice(&p.opaque);
        p.id.copy_from_slice(band.ids);
        for t in tris.clone() {
            let mut surface = None;
            walk::<D>(t, band.span(), |x, y, key| {
                let i = band.index(x, y);
                counts.drawn += 1;
                // In front of the opaque surface and strictly behind the last layer ...
                if !wins(key, t.id, p.opaque[i], band.ids[i]) || !wins(p.last_key[i], p.last_id[i], key, t.id) {
                    return;
                }
                if pass == 0 {
                    p.fragments[i] += 1;
                }
                // ... and nearer than this pass's best so far.
                if !wins(key, t.id, p.key[i], p.id[i]) {
                    return;
                }
                let Some(s) = surface.get_or_insert_with(|| surfaces.get(t.id, &mut hint)) else { return };
                p.key[i] = key;
                p.id[i] = t.id;
                if shading {
                    p.rgba[i] = surfaces.color(s, x, y);
                }
            });
        }
        // Composite the layer found (pixels whose pass z-buffer left the opaque surface).
        let mut found = false;
        for i in 0..n {
            if p.id[i] == band.ids[i] && p.key[i] == p.opaque[i] {
                continue;
            }
            found = true;
            p.under[i].add(p.rgba[i]);
            (p.last_key[i], p.last_id[i]) = (p.key[i], p.id[i]);
            if pass == 0 {
                (first_key[i], first_id[i]) = (p.key[i], p.id[i]);
            }
        }
        if !found {
            break;
        }
        counts.layers = pass + 1;
    }
    for i in 0..n {
        let f = p.fragments[i];
        if f == 0 {
            continue;
        }
        counts.pixel(f);
        counts.short += (f > counts.layers) as u64;
        if shading {
            band.color[i] = p.under[i].resolve(band.color[i]);
        }
        band.ids[i] = first_id[i];
        band.depth[i] = D::decode(first_key[i]);
    }
    counts
}
