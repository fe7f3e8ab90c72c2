//! A ray cast frame: bands of rows in parallel, 8 × 8 packets along each band, then per
//! pixel the outputs the rasterizer writes (ID, window depth, shaded color).
//!
//! Per packet: generate the 64 primary rays and their near–far intervals, trace them as a
//! packet (closest hit, frustum culling, back-face culling as configured), test the CSG
//! solids per lane, then resolve each hit: its ID, and the window depth `(z_ndc + 1) / 2` of
//! the world point `o + t·d` through `clip_from_world` (f64, all 64 lanes in one vectorized
//! loop; the hit's `t` is the same in every space, so no triangle is read again).
//!
//! Colors come one of two ways:
//! * *From the ID buffer* when nothing but the triangles colors a pixel (no shadow rays,
//!   no CSG solids): the frame is cast for IDs and depth only, then shaded by the
//!   rasterizer's deferred pass ([`crate::shade_pass`]), sky and background included. A
//!   pixel showing the same triangle as in a raster frame then gets the raster frame's
//!   color exactly: weights at the pixel center from 2D homogeneous coordinates (affine
//!   ones when [`crate::ShadeOptions::perspective_correct`] is off), and flat colors bit
//!   for bit as per hit. Its caches hold a whole frame's triangles, where the per-hit
//!   shaders below, 256 per band, were missed so often that flat shading took a street
//!   frame of the OBJ city 3.7–4.2 ms instead of 0.3–0.6 ms.
//! * *Per hit* otherwise: an optional any-hit shadow packet goes towards the light and the
//!   color comes from the shared [`crate::shading`] at the hit's exact barycentrics
//!   (perspective-correct whatever the option says; `TriangleShader`s cached per band, one
//!   per triangle and light state).
//!
//! Each band owns its rows of the framebuffer, so the image does not depend on the thread
//! count. The whole packet step is compiled once per instruction set (AVX-512, AVX2,
//! portable) and picked at run time ([`RaycastOptions::simd`]; the deferred pass picks its
//! own, with the same result at every level).

use std::time::Instant;

use glam::{DAffine3, DMat4, DVec3, DVec4, Vec3, Vec3A};
use sightline_scene::{Camera, Material, Scene};

use super::camera::CameraRays;
#[cfg(target_arch = "x86_64")]
use super::isa::{Avx2, Avx512};
use super::isa::{Isa, Portable};
use super::packet::{BeamPlanes, Hits, Rays, CHUNK, CHUNKS, LANES, NO_HIT, TILE};
use super::trace::{trace, Scratch};
use super::{RayCaster, RaycastOptions, RaycastStats, SimdLevel};
use crate::claim::{for_each_claimed, Claim};
use crate::csg::CsgScratch;
use crate::shading::{shade, InstanceShading, ShadeOptions, ShadingMode, TriangleShader};
use crate::{shade_pass, Framebuffer, Result};

/// Entries of the per-band triangle shader cache (direct mapped).
const CACHE: usize = 256;

/// Per-frame constants.
struct CastFrame<'a> {
    caster: &'a RayCaster,
    scene: &'a Scene,
    camera: &'a Camera,
    gen: CameraRays,
    /// The options the frame is cast with (shading off when the deferred pass shades it).
    opts: &'a RaycastOptions,
    dark: ShadeOptions,
    /// Per instance, what shading per hit needs (empty when no hit is shaded).
    shading: Vec<InstanceShading<'a>>,
    csg_materials: Vec<Material>,
    simd: SimdLevel,
    /// `clip_from_world` rows z and w (window depth of a world point).
    world_zw: [DVec4; 2],
    /// Per TLAS record: `world_from_blas` in f64 (empty when no hit is shaded).
    world_f64: Vec<DAffine3>,
    width: u32,
}

/// Per-band scratch and counters.
struct Band<'a> {
    scratch: Scratch,
    rays: Rays,
    hits: Hits,
    srays: Rays,
    shits: Hits,
    csg: CsgScratch,
    /// CSG object hit per lane (`u32::MAX`: none) and its normal.
    csg_hit: [(u32, Vec3); LANES],
    cache: Vec<Option<(u32, bool, TriangleShader<'a>)>>,
    shadow_rays: u64,
    hit_count: u64,
}

/// The output slices of one band (rows y0 .. y0 + TILE).
struct Out<'o> {
    color: &'o mut [[u8; 4]],
    depth: &'o mut [f32],
    ids: &'o mut [u32],
}

impl Out<'_> {
    /// Writes a packet's IDs and depths (lane `ly · TILE + lx` at column `x0 + lx` of the
    /// band's row `ly`), every lane inside the image: the band needs no clearing first.
    #[inline(always)]
    fn write_rows(&mut self, w: usize, x0: u32, ids: &[u32; LANES], zs: &[f32; LANES]) {
        let (x0, tile) = (x0 as usize, TILE as usize);
        let n = tile.min(w.saturating_sub(x0));
        let rows = self.ids.len() / w.max(1);
        for ly in 0..tile.min(rows) {
            let at = ly * w + x0;
            let lanes = ly * tile..ly * tile + n;
            if let (Some(d), Some(s)) = (self.ids.get_mut(at..at + n), ids.get(lanes.clone())) {
                d.copy_from_slice(s);
            }
            if let (Some(d), Some(s)) = (self.depth.get_mut(at..at + n), zs.get(lanes)) {
                d.copy_from_slice(s);
            }
        }
    }
}

fn to_f64(m: &glam::Affine3A) -> DAffine3 {
    DAffine3::from_cols(
        m.matrix3.x_axis.as_dvec3(),
        m.matrix3.y_axis.as_dvec3(),
        m.matrix3.z_axis.as_dvec3(),
        m.translation.as_dvec3(),
    )
}

/// Renders a frame (see the module docs).
pub(crate) fn render(
    caster: &RayCaster,
    scene: &Scene,
    camera: &Camera,
    opts: &RaycastOptions,
    fb: &mut Framebuffer,
) -> Result<RaycastStats> {
    let t0 = Instant::now();
    camera.projection.validate()?;
    let (width, height) = (fb.width(), fb.height());
    // A replaced plane of another length would cut the bands short and leave stale pixels.
    fb.assert_planes();
    // Each band paints its own rows' background below (unless the deferred pass shades the
    // frame), while they are in cache (each packet writes its depth and IDs whole); only the
    // raster's depth-test counters are cleared here.
    if let Some(c) = &mut fb.depth_tests {
        c.fill(0);
    }
    // Shaded from the ID buffer after the cast, or per hit (see the module docs): the cast
    // itself runs with `cast_opts`, shading off in the first case.
    let deferred = opts.shading.mode != ShadingMode::None && !opts.shadows && caster.csg.is_empty();
    let ids_only = RaycastOptions { shading: ShadeOptions { mode: ShadingMode::None, ..opts.shading }, ..*opts };
    let cast_opts = if deferred { &ids_only } else { opts };
    let per_hit = cast_opts.shading.mode != ShadingMode::None;
    // With shading off every pixel keeps the clear color, as in the raster's shading pass.
    let sky = match (&cast_opts.shading.sky, cast_opts.shading.mode) {
        (Some(s), m) if m != ShadingMode::None => Some(s.rows(camera, height as usize)),
        _ => None,
    };
    let clip: DMat4 = camera.clip_from_world_f64();
    // What shading per hit reads (instances' shading, f64 transforms), made only for it.
    let world_f64: Vec<DAffine3> =
        if per_hit { caster.tlas.instances().iter().map(|r| to_f64(&r.world_from_blas)).collect() } else { Vec::new() };
    let frame = CastFrame {
        caster,
        scene,
        camera,
        gen: CameraRays::new(camera, width, height),
        opts: cast_opts,
        dark: ShadeOptions { diffuse: 0.0, ..opts.shading },
        shading: if per_hit {
            caster
                .instances
                .iter()
                .map(|i| InstanceShading::new(i.world_from_local, scene.instance_material(i)))
                .collect()
        } else {
            Vec::new()
        },
        csg_materials: caster
            .csg
            .iter()
            .map(|o| Material { name: o.name.clone(), base_color: o.color, ..Material::default() })
            .collect(),
        simd: opts.simd.resolve(),
        world_zw: [clip.row(2), clip.row(3)],
        world_f64,
        width,
    };
    let w = width as usize;
    let band_len = w * TILE as usize;
    let (tlas_depth, blas_depth) =
        (caster.tlas.bvh().depth(), caster.blases.iter().map(|b| b.bvh().depth()).max().unwrap_or(0));
    // Bands are claimed one at a time (see [`crate::claim`]: a street view's bands differ
    // in cost by orders of magnitude, sky against facades), each worker with its scratch.
    let bands = fb.color.chunks_mut(band_len).zip(fb.depth.chunks_mut(band_len)).zip(fb.ids.chunks_mut(band_len));
    let scratch = || Band {
        scratch: Scratch::new(tlas_depth, blas_depth),
        rays: Rays::new(),
        hits: Hits::new(),
        srays: Rays::new(),
        shits: Hits::new(),
        csg: CsgScratch::default(),
        csg_hit: [(u32::MAX, Vec3::ZERO); LANES],
        cache: if per_hit { vec![None; CACHE] } else { Vec::new() },
        shadow_rays: 0,
        hit_count: 0,
    };
    let workers = for_each_claimed(bands.enumerate(), Claim::InOrder, scratch, |band, (b, ((color, depth), ids))| {
        let mut out = Out { color, depth, ids };
        let y0 = b as u32 * TILE;
        // The background: the sky's row colors (as the raster's deferred shading paints
        // them) or the flat clear color; hit pixels are shaded over it (by the deferred
        // pass, which paints the background too, when it shades the frame).
        match &sky {
            Some(rows) => {
                for (r, row) in out.color.chunks_mut(w).enumerate() {
                    row.fill(rows.get(y0 as usize + r).copied().unwrap_or(opts.background));
                }
            }
            None if !deferred => out.color.fill(opts.background),
            None => {}
        }
        // Depth and IDs: each packet writes its whole square (see `Out::write_rows`).
        let mut x0 = 0;
        while x0 < width {
            frame.packet(band, x0, y0, &mut out);
            x0 += TILE;
        }
    });
    if deferred {
        shade_pass(scene, &caster.instances, camera, fb, &opts.shading, opts.background);
    }
    let shadow_rays = workers.iter().map(|b| b.shadow_rays).sum();
    let hit_count = workers.iter().map(|b| b.hit_count).sum();
    Ok(RaycastStats {
        primary_rays: width as u64 * height as u64,
        shadow_rays,
        hits: hit_count,
        ms_total: t0.elapsed().as_secs_f64() * 1e3,
    })
}

/// The packet step compiled for one instruction set.
macro_rules! isa_packet {
    ($name:ident, $isa:ty, $features:literal) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $name<'a>(f: &CastFrame<'a>, band: &mut Band<'a>, x0: u32, y0: u32, out: &mut Out<'_>) {
            f.packet_impl::<$isa>(band, x0, y0, out)
        }
    };
}

isa_packet!(packet_avx512, Avx512, "avx512f,avx512bw,avx512dq,avx512vl,avx2,bmi1,bmi2,lzcnt,popcnt");
isa_packet!(packet_avx2, Avx2, "avx2,bmi1,bmi2,lzcnt,popcnt");

impl<'a> CastFrame<'a> {
    /// Casts, resolves and writes the packet at (x0, y0) on the resolved SIMD level.
    fn packet(&self, band: &mut Band<'a>, x0: u32, y0: u32, out: &mut Out<'_>) {
        match self.simd {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `SimdLevel::resolve` yields Avx512 only when the CPU has every feature
            // `packet_avx512` enables.
            SimdLevel::Avx512 => unsafe { packet_avx512(self, band, x0, y0, out) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above, for the AVX2 feature set.
            SimdLevel::Avx2 => unsafe { packet_avx2(self, band, x0, y0, out) },
            _ => self.packet_impl::<Portable>(band, x0, y0, out),
        }
    }

    /// Local-space hit point of lane (c, j) of a triangle hit, in f64, and the record.
    #[inline(always)]
    fn local_point(&self, hits: &Hits, c: usize, j: usize) -> Option<(usize, DVec3, f64, f64)> {
        let rec = hits.inst[c][j] as usize;
        let r = self.caster.tlas.instances().get(rec)?;
        let blas = self.caster.blases.get(r.blas as usize)?;
        let (v, _) = blas.triangle(hits.prim[c][j])?;
        let rdet = 1.0 / hits.det[c][j] as f64;
        let (b1, b2) = (hits.e1[c][j] as f64 * rdet, hits.e2[c][j] as f64 * rdet);
        let v0 = v[0].as_dvec3();
        let p = v0 + (v[1].as_dvec3() - v0) * b1 + (v[2].as_dvec3() - v0) * b2;
        Some((rec, p, b1, b2))
    }

    #[inline(always)]
    fn packet_impl<I: Isa>(&self, band: &mut Band<'a>, x0: u32, y0: u32, out: &mut Out<'_>) {
        let caster = self.caster;
        let Band { scratch, rays, hits, srays, shits, csg, csg_hit, .. } = band;
        let mask = self.gen.fill::<I>(x0, y0, rays, hits);
        let w = self.width as usize;
        if mask == 0 {
            out.write_rows(w, x0, &[0; LANES], &[1.0; LANES]);
            return;
        }
        let frustum = self.gen.frustum(x0, y0);
        trace::<I, false>(
            &caster.blases,
            &caster.tlas,
            rays,
            &frustum,
            self.opts.backface_culling,
            hits,
            mask,
            scratch,
        );
        // CSG solids, per lane, in front of the triangle hit.
        let has_csg = !caster.csg.is_empty();
        if has_csg {
            for (i, ch) in csg_hit.iter_mut().enumerate() {
                *ch = (u32::MAX, Vec3::ZERO);
                if mask >> i & 1 == 0 {
                    continue;
                }
                let (o, d) = (Vec3::from(rays.origin(i)), Vec3::from(rays.dir(i)));
                let (tmin, mut t) = hits.range(i);
                for (k, obj) in caster.csg.iter().enumerate() {
                    if let Some(h) = obj.intersect_with(o, d, tmin, t, csg) {
                        t = h.t;
                        *ch = (k as u32, h.normal);
                    }
                }
                hits.t[i / CHUNK][i % CHUNK] = t;
            }
        }
        // Which lanes hit, as a mask made per chunk in SIMD, and the ID of every lane (0 for
        // a miss). (Through an array of flags folded into the mask lane by lane, this took
        // about a tenth of a frame's work outside tracing.)
        let mut hit_mask = 0u64;
        let mut ids = [0u32; LANES];
        for c in 0..CHUNKS {
            // SAFETY: `I` is only instantiated for an instruction set the CPU has.
            hit_mask |= unsafe { I::ne16(&hits.inst[c], NO_HIT) } << (c * CHUNK);
            for j in 0..CHUNK {
                ids[c * CHUNK + j] = if hits.inst[c][j] != NO_HIT { hits.gid[c][j] } else { 0 };
            }
        }
        if has_csg {
            for (i, (id, ch)) in ids.iter_mut().zip(csg_hit.iter()).enumerate() {
                if ch.0 != u32::MAX {
                    *id = caster.csg_id(ch.0 as usize);
                    hit_mask |= 1 << i;
                }
            }
        }
        if hit_mask == 0 {
            out.write_rows(w, x0, &ids, &[1.0; LANES]);
            return;
        }
        // Window depth of every lane's world point `o + t·d` (f64; t is the same in every
        // space, instances map directions without normalizing), in one vectorizable loop;
        // a miss reads as the far plane.
        let [rz, rw] = self.world_zw;
        let (mut cz, mut cw) = ([0f64; LANES], [1f64; LANES]);
        for c in 0..CHUNKS {
            for j in 0..CHUNK {
                let t = hits.t[c][j] as f64;
                let p = [0, 1, 2].map(|a| rays.o[a][c][j] as f64 + rays.d[a][c][j] as f64 * t);
                cz[c * CHUNK + j] = rz.x * p[0] + rz.y * p[1] + rz.z * p[2] + rz.w;
                cw[c * CHUNK + j] = rw.x * p[0] + rw.y * p[1] + rw.z * p[2] + rw.w;
            }
        }
        let mut zs = [1f32; LANES];
        for i in 0..LANES {
            let z = (cz[i] / cw[i] + 1.0) * 0.5;
            // Clamped to [0, 1]; NaN (a degenerate w) reads as the far plane.
            let z = if z >= 0.0 {
                if z <= 1.0 {
                    z as f32
                } else {
                    1.0
                }
            } else if z < 0.0 {
                0.0
            } else {
                1.0
            };
            zs[i] = if hit_mask >> i & 1 != 0 { z } else { 1.0 };
        }
        out.write_rows(w, x0, &ids, &zs);
        band.hit_count += hit_mask.count_ones() as u64;
        if self.opts.shading.mode == ShadingMode::None {
            return;
        }
        // World point and normal of each hit (for shadows and CSG shading).
        let surface = |i: usize| -> Option<(DVec3, DVec3)> {
            let (c, j) = (i / CHUNK, i % CHUNK);
            if has_csg && csg_hit[i].0 != u32::MAX {
                let t = hits.t[c][j] as f64;
                let p = Vec3::from(rays.origin(i)).as_dvec3() + Vec3::from(rays.dir(i)).as_dvec3() * t;
                return Some((p, csg_hit[i].1.as_dvec3()));
            }
            let (rec, p, _, _) = self.local_point(hits, c, j)?;
            let m = self.world_f64.get(rec)?;
            let r = caster.tlas.instances().get(rec)?;
            let (v, _) = caster.blases.get(r.blas as usize)?.triangle(hits.prim[c][j])?;
            let wv = v.map(|q| m.transform_point3(q.as_dvec3()));
            Some((m.transform_point3(p), (wv[1] - wv[0]).cross(wv[2] - wv[0]).normalize_or_zero()))
        };
        // Shadows: lanes whose surface, turned to the viewer, faces the light.
        let light = self.opts.shading.light_dir.as_dvec3();
        let mut dark = 0u64;
        if self.opts.shadows && light.is_finite() && light != DVec3::ZERO {
            let mut smask = 0u64;
            let mut bits = hit_mask;
            while bits != 0 {
                let i = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                shits.open(i, f32::INFINITY, f32::NEG_INFINITY);
                let Some((p, n)) = surface(i) else { continue };
                let d = Vec3::from(rays.dir(i)).as_dvec3();
                let n = if n.dot(d) > 0.0 { -n } else { n };
                if n.dot(light) <= 0.0 {
                    continue;
                }
                let eps = 1e-4 * (1.0 + p.abs().max_element());
                srays.set(i, Vec3A::from((p + n * eps).as_vec3()), Vec3A::from(light.as_vec3()));
                shits.open(i, 0.0, f32::INFINITY);
                smask |= 1 << i;
            }
            srays.shared = None;
            band.shadow_rays += smask.count_ones() as u64;
            if smask != 0 {
                let lanes = (0..LANES).filter(|&i| smask >> i & 1 != 0).map(|i| srays.origin(i));
                let beam = BeamPlanes::parallel(Vec3A::from(light.as_vec3()), lanes, 1e-3);
                dark = trace::<I, true>(&caster.blases, &caster.tlas, srays, &beam, false, shits, smask, scratch);
                let mut open = smask & !dark;
                while open != 0 {
                    let i = open.trailing_zeros() as usize;
                    open &= open - 1;
                    let (o, d) = (Vec3::from(srays.origin(i)), Vec3::from(srays.dir(i)));
                    if caster.csg.iter().any(|obj| obj.intersect_with(o, d, 0.0, f32::INFINITY, csg).is_some()) {
                        dark |= 1 << i;
                    }
                }
            }
        }
        // Colors.
        let eye = self.camera.view.eye;
        let mut bits = hit_mask;
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let (c, j) = (i / CHUNK, i % CHUNK);
            let shadowed = dark >> i & 1 != 0;
            let opts = if shadowed { &self.dark } else { &self.opts.shading };
            let rgba = if has_csg && csg_hit[i].0 != u32::MAX {
                let (k, normal) = csg_hit[i];
                let d = Vec3::from(rays.dir(i));
                let dist = hits.t[c][j] * d.length();
                let Some(m) = self.csg_materials.get(k as usize) else { continue };
                shade(m, normal, None, -d.normalize_or_zero(), dist, opts)
            } else {
                let rec = hits.inst[c][j] as usize;
                let Some(sh) = self.shader(&mut band.cache, rec, hits.gid[c][j], shadowed, eye) else { continue };
                match sh.constant() {
                    Some(color) => color,
                    None => {
                        // The shader is the mesh's triangle: weights in mesh order.
                        let rdet = 1.0 / hits.det[c][j];
                        let (b1, b2) = (hits.e1[c][j] * rdet, hits.e2[c][j] * rdet);
                        let Some(blas) =
                            caster.tlas.instances().get(rec).and_then(|r| caster.blases.get(r.blas as usize))
                        else {
                            continue;
                        };
                        sh.shade(blas.mesh_weights(hits.prim[c][j], Vec3::new(1.0 - b1 - b2, b1, b2)), opts)
                    }
                }
            };
            let at = (i / TILE as usize) * w + x0 as usize + i % TILE as usize;
            if let Some(px) = out.color.get_mut(at) {
                *px = rgba;
            }
        }
    }

    /// The cached shader of the triangle with `id` under TLAS record `rec`.
    fn shader<'c>(
        &self,
        cache: &'c mut [Option<(u32, bool, TriangleShader<'a>)>],
        rec: usize,
        id: u32,
        shadowed: bool,
        eye: Vec3,
    ) -> Option<&'c TriangleShader<'a>> {
        let slot = ((id as usize).wrapping_mul(0x9E37_79B1) >> 8 ^ shadowed as usize) & (CACHE - 1);
        let entry = cache.get_mut(slot)?;
        if !matches!(entry, Some((k, s, _)) if *k == id && *s == shadowed) {
            let caster = self.caster;
            let r = caster.tlas.instances().get(rec)?;
            let inst = caster.instances.get(r.scene_index as usize)?;
            let mesh = self.scene.mesh(inst.mesh)?;
            let ish = self.shading.get(r.scene_index as usize)?;
            let tri = id.checked_sub(1 + inst.first_triangle)? as usize;
            let opts = if shadowed { &self.dark } else { &self.opts.shading };
            *entry = Some((id, shadowed, TriangleShader::new(ish, mesh, tri, eye, opts)));
        }
        entry.as_ref().map(|e| &e.2)
    }
}
