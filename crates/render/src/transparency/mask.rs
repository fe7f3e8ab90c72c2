//! Alpha-tested (cutout) surfaces: glTF's `MASK`, drawn into the z-buffer after the opaque
//! surfaces.
//!
//! A fragment of a masked triangle goes through the z-buffer's depth test (LESS, ties to
//! the smaller triangle ID) against what the opaque pass left; if it would be written, its
//! alpha (base color factor × texture alpha at the pixel's perspective-correct texture
//! coordinates) is compared with the material's cutoff, and only a fragment with alpha at
//! least the cutoff writes its depth and ID. A discarded fragment leaves no trace, so what
//! lies behind the hole shows through, and the frame is then shaded like any other. The
//! depth test is order independent (a total order on depth and ID), so drawing the masked
//! triangles after the opaque ones gives the image drawing them among them would give.
//! This is the alpha test of the OpenGL fixed pipeline (`GL_ALPHA_TEST`, `GL_GEQUAL`) and of
//! the glTF 2.0 specification's "Alpha Coverage" section.

use crate::depth::{with_codec, DepthCodec, DepthFormat};
use crate::edge::Tri;
use crate::raster::kernel::wins;

use super::surface::Surfaces;
use super::walk::{walk, Band};

/// Fragments of one pass: depth-tested, passing the depth test, and passing the alpha test
/// too (written).
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct MaskCount {
    pub tested: u64,
    pub passed: u64,
    pub written: u64,
}

/// Draws the masked triangles `tris` into `band` (depth and IDs), keeping the fragments
/// whose alpha passes their material's cutoff.
pub(crate) fn draw_masked<'t>(
    band: &mut Band,
    tris: impl Iterator<Item = &'t Tri>,
    surfaces: &Surfaces,
    fmt: DepthFormat,
) -> MaskCount {
    with_codec!(fmt, masked_in::<_>(band, tris, surfaces))
}

fn masked_in<'t, D: DepthCodec>(
    band: &mut Band,
    tris: impl Iterator<Item = &'t Tri>,
    surfaces: &Surfaces,
) -> MaskCount {
    let mut n = MaskCount::default();
    let mut hint = 0;
    for t in tris {
        // Prepared on the first fragment that passes the depth test.
        let mut surface = None;
        walk::<D>(t, band.span(), |x, y, key| {
            let i = band.index(x, y);
            n.tested += 1;
            if let Some(c) = band.counts.as_deref_mut() {
                c[i] += 1;
            }
            if !wins(key, t.id, D::FORMAT.key_of_stored(band.depth[i]), band.ids[i]) {
                return;
            }
            n.passed += 1;
            let s = surface.get_or_insert_with(|| surfaces.get(t.id, &mut hint));
            if s.as_ref().is_some_and(|s| surfaces.keeps(s, x, y)) {
                band.depth[i] = D::decode(key);
                band.ids[i] = t.id;
                n.written += 1;
            }
        });
    }
    n
}
