//! A ray cast frame: bands of rows in parallel, 8 × 8 packets along each band, then per
//! pixel the outputs the rasterizer writes (ID, window depth, shaded color).
//!
//! Per packet: generate the 64 primary rays and their near–far intervals, trace them as a
//! packet (closest hit, frustum culling, back-face culling as configured), test the CSG
//! solids per lane, optionally trace an any-hit shadow packet towards the light, then
//! resolve each hit: the world point from the exact barycentrics in f64, its window depth
//! `(z_ndc + 1) / 2` through `clip_from_world` (f64), and the color from the shared
//! [`crate::shading`] (`TriangleShader`s are cached per band, one per triangle and light
//! state). Each band owns its rows of the framebuffer, so the image does not depend on the
//! thread count.

use std::time::Instant;

use glam::{DAffine3, DMat4, DVec3, DVec4, Vec3, Vec3A};
use rayon::prelude::*;
use sightline_scene::{Camera, Material};

use super::blas::Blas;
use super::camera::CameraRays;
use super::packet::{Beam, Hits, Rays, CHUNK, LANES, NO_HIT, TILE};
use super::tlas::Tlas;
use super::trace::{trace, Scratch};
use super::{RayCaster, RaycastOptions, RaycastStats, SimdLevel};
use crate::csg::CsgScratch;
use crate::shading::{shade, InstanceShading, ShadeOptions, ShadingMode, TriangleShader};
use crate::{triangle_id, Framebuffer, Result};

/// Entries of the per-band triangle shader cache (direct mapped).
const CACHE: usize = 256;

/// Traces with the kernels compiled for one instruction set.
macro_rules! isa_trace {
    ($name:ident, $features:literal) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        #[allow(clippy::too_many_arguments)]
        fn $name<const ANY: bool>(
            blases: &[Blas],
            tlas: &Tlas,
            rays: &Rays,
            beam: Option<&Beam>,
            backface: bool,
            hits: &mut Hits,
            mask: u64,
            s: &mut Scratch,
        ) -> u64 {
            trace::<ANY>(blases, tlas, rays, beam, backface, hits, mask, s)
        }
    };
}

isa_trace!(trace_avx512, "avx512f,avx512bw,avx512dq,avx512vl,avx2,bmi1,bmi2,lzcnt,popcnt");
isa_trace!(trace_avx2, "avx2,bmi1,bmi2,lzcnt,popcnt");

/// [`trace`] on the resolved SIMD level.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(crate) fn trace_on<const ANY: bool>(
    simd: SimdLevel,
    blases: &[Blas],
    tlas: &Tlas,
    rays: &Rays,
    beam: Option<&Beam>,
    backface: bool,
    hits: &mut Hits,
    mask: u64,
    s: &mut Scratch,
) -> u64 {
    match simd {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `SimdLevel::resolve` only yields Avx512 when the CPU has every feature
        // the function enables.
        SimdLevel::Avx512 => unsafe { trace_avx512::<ANY>(blases, tlas, rays, beam, backface, hits, mask, s) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above, for the AVX2 feature set.
        SimdLevel::Avx2 => unsafe { trace_avx2::<ANY>(blases, tlas, rays, beam, backface, hits, mask, s) },
        _ => trace::<ANY>(blases, tlas, rays, beam, backface, hits, mask, s),
    }
}

/// What a pixel's ray found.
#[derive(Debug, Clone, Copy)]
enum Found {
    Nothing,
    Triangle {
        /// TLAS instance record.
        rec: u32,
        /// Leaf-order slot in its BLAS.
        slot: u32,
        b1: f64,
        b2: f64,
    },
    Csg {
        object: u32,
        normal: Vec3,
    },
}

/// A resolved hit: where, which surface normal (world, unit), which ID.
#[derive(Debug, Clone, Copy)]
struct Surface {
    p: DVec3,
    normal: DVec3,
    id: u32,
}

/// Per-frame constants.
struct Frame<'a, 's> {
    caster: &'a RayCaster<'s>,
    camera: &'a Camera,
    gen: CameraRays,
    clip: DMat4,
    opts: &'a RaycastOptions,
    dark: ShadeOptions,
    shading: Vec<InstanceShading<'a>>,
    csg_materials: Vec<Material>,
    simd: SimdLevel,
    world_f64: Vec<DAffine3>,
    width: u32,
    height: u32,
}

/// Per-band scratch and counters.
struct Band<'a> {
    scratch: Scratch,
    rays: Rays,
    hits: Hits,
    srays: Rays,
    shits: Hits,
    csg: CsgScratch,
    cache: Vec<Option<(u32, bool, TriangleShader<'a>)>>,
    shadow_rays: u64,
    hit_count: u64,
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
    caster: &RayCaster<'_>,
    camera: &Camera,
    opts: &RaycastOptions,
    fb: &mut Framebuffer,
) -> Result<RaycastStats> {
    let t0 = Instant::now();
    camera.projection.validate()?;
    let (width, height) = (fb.width(), fb.height());
    fb.clear(opts.background);
    let default = Material::default();
    let scene = caster.scene;
    let shading = caster
        .instances
        .iter()
        .map(|i| {
            let m = i.material.and_then(|m| scene.material(m)).unwrap_or(&default);
            InstanceShading::new(i.world_from_local, m)
        })
        .collect();
    let frame = Frame {
        caster,
        camera,
        gen: CameraRays::new(camera, width, height),
        clip: camera.clip_from_world_f64(),
        opts,
        dark: ShadeOptions { diffuse: 0.0, ..opts.shading },
        shading,
        csg_materials: caster
            .csg
            .iter()
            .map(|o| Material { name: o.name.clone(), base_color: o.color, base_color_texture: None })
            .collect(),
        simd: opts.simd.resolve(),
        world_f64: caster.tlas.instances.iter().map(|r| to_f64(&r.world_from_blas)).collect(),
        width,
        height,
    };
    let w = width as usize;
    let band_len = w * TILE as usize;
    let (tlas_depth, blas_depth) =
        (caster.tlas.bvh.depth, caster.blases.iter().map(|b| b.bvh.depth).max().unwrap_or(0));
    let (shadow_rays, hit_count) = fb
        .color
        .par_chunks_mut(band_len)
        .zip(fb.depth.par_chunks_mut(band_len))
        .zip(fb.ids.par_chunks_mut(band_len))
        .enumerate()
        .map_init(
            || Band {
                scratch: Scratch::new(tlas_depth, blas_depth),
                rays: Rays::new(),
                hits: Hits::new(),
                srays: Rays::new(),
                shits: Hits::new(),
                csg: CsgScratch::default(),
                cache: vec![None; CACHE],
                shadow_rays: 0,
                hit_count: 0,
            },
            |band, (b, ((color, depth), ids))| {
                band.shadow_rays = 0;
                band.hit_count = 0;
                let y0 = b as u32 * TILE;
                let mut x0 = 0;
                while x0 < width {
                    frame.packet(band, x0, y0, color, depth, ids);
                    x0 += TILE;
                }
                (band.shadow_rays, band.hit_count)
            },
        )
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    Ok(RaycastStats {
        primary_rays: width as u64 * height as u64,
        shadow_rays,
        hits: hit_count,
        ms_total: t0.elapsed().as_secs_f64() * 1e3,
    })
}

impl<'a> Frame<'a, '_> {
    /// Casts, resolves and writes the packet at (x0, y0); the band slices start at row y0.
    fn packet(&self, band: &mut Band<'a>, x0: u32, y0: u32, color: &mut [[u8; 4]], depth: &mut [f32], ids: &mut [u32]) {
        let caster = self.caster;
        let Band { scratch, rays, hits, srays, shits, csg, .. } = band;
        // Primary rays.
        let mut mask = 0u64;
        for ly in 0..TILE {
            for lx in 0..TILE {
                let i = (ly * TILE + lx) as usize;
                let (px, py) = (x0 + lx, y0 + ly);
                hits.open(i, f32::INFINITY, f32::NEG_INFINITY);
                if px >= self.width || py >= self.height {
                    continue;
                }
                let (o, d) = self.gen.ray(px, py);
                rays.set(i, o, d);
                if let Some((a, b)) = self.gen.interval(o, d) {
                    hits.open(i, a, b);
                    mask |= 1 << i;
                }
            }
        }
        if mask == 0 {
            return;
        }
        rays.shared = self.gen.perspective.then_some(self.gen.eye32);
        let beam = self.gen.beam(x0, y0, x0 + TILE, y0 + TILE, self.camera);
        trace_on::<false>(
            self.simd,
            &caster.blases,
            &caster.tlas,
            rays,
            Some(&beam),
            self.opts.backface_culling,
            hits,
            mask,
            scratch,
        );
        // Per lane: what was found.
        let mut found = [Found::Nothing; LANES];
        for (i, f) in found.iter_mut().enumerate() {
            if mask >> i & 1 == 0 {
                continue;
            }
            let (c, j) = (i / CHUNK, i % CHUNK);
            if hits.inst[c][j] != NO_HIT {
                let det = hits.det[c][j] as f64;
                *f = Found::Triangle {
                    rec: hits.inst[c][j],
                    slot: hits.prim[c][j],
                    b1: hits.e1[c][j] as f64 / det,
                    b2: hits.e2[c][j] as f64 / det,
                };
            }
            if !caster.csg.is_empty() {
                let (o, d) = (Vec3::from(rays.origin(i)), Vec3::from(rays.dir(i)));
                let (tmin, mut t) = hits.range(i);
                for (k, obj) in caster.csg.iter().enumerate() {
                    if let Some(h) = obj.intersect_with(o, d, tmin, t, csg) {
                        t = h.t;
                        *f = Found::Csg { object: k as u32, normal: h.normal };
                    }
                }
                hits.t[c][j] = t;
            }
        }
        // Surfaces, depth and IDs.
        let mut surf: [Option<Surface>; LANES] = [None; LANES];
        for i in 0..LANES {
            let s = match found[i] {
                Found::Nothing => continue,
                Found::Triangle { rec, slot, b1, b2 } => self.triangle_surface(rec, slot, b1, b2),
                Found::Csg { object, normal } => {
                    let (c, j) = (i / CHUNK, i % CHUNK);
                    let t = hits.t[c][j] as f64;
                    let o = Vec3::from(rays.origin(i)).as_dvec3();
                    let d = Vec3::from(rays.dir(i)).as_dvec3();
                    Some(Surface { p: o + d * t, normal: normal.as_dvec3(), id: caster.csg_id(object as usize) })
                }
            };
            let Some(s) = s else { continue };
            let (lx, ly) = (i as u32 % TILE, i as u32 / TILE);
            let at = ly as usize * self.width as usize + (x0 + lx) as usize;
            let clip = self.clip * DVec4::new(s.p.x, s.p.y, s.p.z, 1.0);
            let z = (clip.z / clip.w + 1.0) * 0.5;
            if let (Some(dp), Some(id)) = (depth.get_mut(at), ids.get_mut(at)) {
                *dp = if z.is_finite() { z.clamp(0.0, 1.0) as f32 } else { 1.0 };
                *id = s.id;
            }
            surf[i] = Some(s);
            band.hit_count += 1;
        }
        if self.opts.shading.mode == ShadingMode::None {
            return;
        }
        // Shadows: lanes whose surface (turned to the viewer) faces the light.
        let light = self.opts.shading.light_dir.as_dvec3();
        let mut smask = 0u64;
        if self.opts.shadows && light.is_finite() && light != DVec3::ZERO {
            for (i, s) in surf.iter().enumerate() {
                let Some(s) = *s else { continue };
                let d = Vec3::from(rays.dir(i)).as_dvec3();
                let n = if s.normal.dot(d) > 0.0 { -s.normal } else { s.normal };
                shits.open(i, f32::INFINITY, f32::NEG_INFINITY);
                if n.dot(light) <= 0.0 {
                    continue;
                }
                let eps = 1e-4 * (1.0 + s.p.abs().max_element());
                let o = s.p + n * eps;
                srays.set(i, Vec3A::from(o.as_vec3()), Vec3A::from(light.as_vec3()));
                shits.open(i, 0.0, f32::INFINITY);
                smask |= 1 << i;
            }
            srays.shared = None;
            band.shadow_rays += smask.count_ones() as u64;
        }
        let mut dark = 0u64;
        if smask != 0 {
            dark = trace_on::<true>(self.simd, &caster.blases, &caster.tlas, srays, None, false, shits, smask, scratch);
            for i in 0..LANES {
                if (smask & !dark) >> i & 1 == 0 {
                    continue;
                }
                let (o, d) = (Vec3::from(srays.origin(i)), Vec3::from(srays.dir(i)));
                if caster.csg.iter().any(|obj| obj.intersect_with(o, d, 0.0, f32::INFINITY, csg).is_some()) {
                    dark |= 1 << i;
                }
            }
        }
        // Colors.
        let eye = self.camera.view.eye;
        for i in 0..LANES {
            let Some(s) = surf[i] else { continue };
            let shadowed = dark >> i & 1 != 0;
            let opts = if shadowed { &self.dark } else { &self.opts.shading };
            let rgba = match found[i] {
                Found::Triangle { rec, b1, b2, .. } => {
                    let Some(shader) = self.shader(&mut band.cache, rec, s.id, shadowed, eye) else {
                        continue;
                    };
                    shader.shade(Vec3::new((1.0 - b1 - b2) as f32, b1 as f32, b2 as f32), opts)
                }
                Found::Csg { object, normal } => {
                    let d = Vec3::from(rays.dir(i));
                    let dist = (s.p - Vec3::from(rays.origin(i)).as_dvec3()).length() as f32;
                    let Some(m) = self.csg_materials.get(object as usize) else {
                        continue;
                    };
                    shade(m, normal, None, -d.normalize_or_zero(), dist, opts)
                }
                Found::Nothing => continue,
            };
            let (lx, ly) = (i as u32 % TILE, i as u32 / TILE);
            let at = ly as usize * self.width as usize + (x0 + lx) as usize;
            if let Some(c) = color.get_mut(at) {
                *c = rgba;
            }
        }
    }

    /// World point, face normal and ID of a triangle hit.
    fn triangle_surface(&self, rec: u32, slot: u32, b1: f64, b2: f64) -> Option<Surface> {
        let caster = self.caster;
        let r = caster.tlas.instances.get(rec as usize)?;
        let blas = caster.blases.get(r.blas as usize)?;
        let v = blas.tris.get(slot as usize)?;
        let tri = *blas.bvh.order.get(slot as usize)?;
        let inst = caster.instances.get(r.scene_index as usize)?;
        let m = self.world_f64.get(rec as usize)?;
        let w = v.map(|p| m.transform_point3(Vec3::from(p).as_dvec3()));
        let p = w[0] * (1.0 - b1 - b2) + w[1] * b1 + w[2] * b2;
        Some(Surface {
            p,
            normal: (w[1] - w[0]).cross(w[2] - w[0]).normalize_or_zero(),
            id: triangle_id(inst.first_triangle, tri),
        })
    }

    /// The cached shader of the triangle with `id` under instance record `rec`.
    fn shader(
        &self,
        cache: &mut [Option<(u32, bool, TriangleShader<'a>)>],
        rec: u32,
        id: u32,
        shadowed: bool,
        eye: Vec3,
    ) -> Option<TriangleShader<'a>> {
        let slot = ((id as usize).wrapping_mul(0x9E37_79B1) >> 8 ^ shadowed as usize) & (CACHE - 1);
        if let Some((k, s, sh)) = &cache[slot] {
            if *k == id && *s == shadowed {
                return Some(*sh);
            }
        }
        let caster = self.caster;
        let r = caster.tlas.instances.get(rec as usize)?;
        let inst = caster.instances.get(r.scene_index as usize)?;
        let mesh = caster.scene.mesh(inst.mesh)?;
        let ish = self.shading.get(r.scene_index as usize)?;
        let tri = id.checked_sub(1 + inst.first_triangle)? as usize;
        let opts = if shadowed { &self.dark } else { &self.opts.shading };
        let sh = TriangleShader::new(ish, mesh, tri, eye, opts);
        cache[slot] = Some((id, shadowed, sh));
        Some(sh)
    }
}
