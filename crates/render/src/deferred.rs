//! Deferred shading: color every pixel from its triangle ID after visibility is settled.
//!
//! Rasterization writes only depth and IDs, so each pixel is shaded once however deep the
//! overdraw. Per pixel the triangle is found from its ID, and the world-space (perspective-
//! correct) barycentric weights of the pixel center come from the 2D homogeneous form of
//! Olano & Greer ("Triangle Scan Conversion using 2D Homogeneous Coordinates", 1997): with
//! the clip-space rows `h_i = (x_i, y_i, w_i)`, the weights of the point seen through NDC
//! `p = (x, y, 1)` are proportional to `(h_j × h_k) · p`. That equals interpolating `a/w`
//! and `1/w` linearly in screen space and dividing (Heckbert & Moreton 1991; Blinn 1992),
//! needs no clipped vertices, and works for triangles crossing the eye plane. Affine
//! (screen-space) weights, for comparison, are `β_i·w_i` renormalized.
//!
//! Triangles and instances are prepared once and cached per band of rows (direct-mapped
//! caches), so a triangle covering many pixels costs one setup.

use glam::{Mat4, Vec3, Vec3A};
use rayon::prelude::*;
use sightline_scene::{Camera, Instance, Material, Mesh, Scene};

use crate::shading::{InstanceShading, ShadeOptions, ShadingMode, TriangleShader};
use crate::Framebuffer;

/// Bands of rows per worker thread (see [`Shader::band_rows`]).
const BANDS_PER_THREAD: usize = 3;
const TRI_CACHE: usize = 4096;
const INST_CACHE: usize = 64;

/// Finds the instance drawing global triangle `g` (instances ordered by first triangle).
struct Lookup<'a> {
    instances: &'a [Instance],
    order: Option<Vec<u32>>,
}

impl<'a> Lookup<'a> {
    fn new(instances: &'a [Instance]) -> Self {
        let sorted = instances.windows(2).all(|w| w[0].first_triangle <= w[1].first_triangle);
        let order = (!sorted).then(|| {
            let mut o: Vec<u32> =
                (0..instances.len() as u32).filter(|&i| instances[i as usize].triangle_count > 0).collect();
            o.sort_by_key(|&i| instances[i as usize].first_triangle);
            o
        });
        Self { instances, order }
    }

    fn find(&self, g: u32) -> Option<u32> {
        let inst = |k: usize| match &self.order {
            Some(o) => o[k],
            None => k as u32,
        };
        let n = self.order.as_ref().map_or(self.instances.len(), |o| o.len());
        // Last position whose first triangle is ≤ g; step back over empty instances.
        let (mut lo, mut hi) = (0, n);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.instances[inst(mid) as usize].first_triangle <= g {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        let mut k = lo;
        while k > 0 {
            k -= 1;
            let i = inst(k);
            let it = &self.instances[i as usize];
            if g < it.first_triangle {
                return None;
            }
            if g - it.first_triangle < it.triangle_count {
                return Some(i);
            }
            if it.triangle_count > 0 {
                return None;
            }
        }
        None
    }
}

struct InstEntry<'a> {
    index: u32,
    clip: Mat4,
    shading: InstanceShading<'a>,
    mesh: &'a Mesh,
}

struct TriEntry<'a> {
    rows: [Vec3A; 3],
    w: [f32; 3],
    shader: TriangleShader<'a>,
}

/// Writes every color of `fb`: pixels with ID 0, IDs that no instance claims and every
/// pixel in mode `None` get `background`; the others are shaded. So the color plane needs no
/// clearing before a frame.
pub fn shade_pass(
    scene: &Scene,
    instances: &[Instance],
    camera: &Camera,
    fb: &mut Framebuffer,
    opts: &ShadeOptions,
    background: [u8; 4],
) {
    let shader = Shader::new(scene, instances, camera, opts, background, fb.width(), fb.height());
    let w = fb.width() as usize;
    let rows = shader.band_rows();
    let ids = &fb.ids;
    fb.color.par_chunks_mut(w * rows).enumerate().for_each(|(band, color)| {
        let mut b = shader.band();
        for (r, crow) in color.chunks_mut(w).enumerate() {
            let y = band * rows + r;
            b.shade_row(y, &ids[y * w..(y + 1) * w], crow);
        }
    });
}

/// A frame's shading, prepared once: [`Shader::band`] gives the state of one band of rows
/// (its caches), which shades rows one at a time. The renderer uses it to shade rows right
/// as it writes them out, while their IDs are in cache; [`shade_pass`] over a finished
/// framebuffer.
pub struct Shader<'a> {
    scene: &'a Scene,
    lookup: Lookup<'a>,
    camera: &'a Camera,
    opts: &'a ShadeOptions,
    background: [u8; 4],
    default: Material,
    width: usize,
    height: usize,
}

impl std::fmt::Debug for Shader<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Shader").field("mode", &self.opts.mode).field("size", &(self.width, self.height)).finish()
    }
}

impl<'a> Shader<'a> {
    /// Shading of a `width × height` frame of `instances` seen by `camera`.
    pub fn new(
        scene: &'a Scene,
        instances: &'a [Instance],
        camera: &'a Camera,
        opts: &'a ShadeOptions,
        background: [u8; 4],
        width: u32,
        height: u32,
    ) -> Self {
        Self {
            scene,
            lookup: Lookup::new(instances),
            camera,
            opts,
            background,
            default: Material::default(),
            width: width as usize,
            height: height as usize,
        }
    }

    /// Rows per parallel band: few and tall, because a triangle spanning several bands is
    /// prepared once in each (a measurable cost at street level, where triangles are large),
    /// yet more than one per thread to balance uneven bands.
    pub fn band_rows(&self) -> usize {
        self.height.div_ceil(rayon::current_num_threads().max(1) * BANDS_PER_THREAD).max(1)
    }

    /// Fresh state (caches) for one band of rows.
    pub fn band(&self) -> BandShader<'_> {
        BandShader {
            shader: self,
            insts: (0..INST_CACHE).map(|_| None).collect(),
            slots: vec![Slot { id: 0, color: self.background, full: NO_FULL }; TRI_CACHE],
            fulls: Vec::new(),
            hint: 0,
        }
    }
}

/// The shading state of one band of rows: direct-mapped caches of instances and triangles
/// (a small slot per triangle, since flat triangles need nothing but their color; full
/// interpolation data only for the others).
pub struct BandShader<'s> {
    shader: &'s Shader<'s>,
    insts: Vec<Option<InstEntry<'s>>>,
    slots: Vec<Slot>,
    fulls: Vec<TriEntry<'s>>,
    hint: u32,
}

impl std::fmt::Debug for BandShader<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BandShader").field("shader", self.shader).finish_non_exhaustive()
    }
}

impl BandShader<'_> {
    /// Colors row `y` from its IDs.
    pub fn shade_row(&mut self, y: usize, ids: &[u32], colors: &mut [[u8; 4]]) {
        let sh = self.shader;
        let (opts, background, w) = (sh.opts, sh.background, ids.len().min(colors.len()));
        if opts.mode == ShadingMode::None {
            colors.fill(background);
            return;
        }
        let (sx, sy) = (2.0 / sh.width as f32, 2.0 / sh.height as f32);
        let ndc_y = 1.0 - (y as f32 + 0.5) * sy;
        // Runs of one ID along the row: one cache lookup and one fill per run.
        let mut x = 0;
        while x < w {
            let id = ids[x];
            let end = ids[x + 1..w].iter().position(|&v| v != id).map_or(w, |n| x + 1 + n);
            if id == 0 {
                colors[x..end].fill(background);
                x = end;
                continue;
            }
            let slot = (id as usize).wrapping_mul(0x9E37_79B1) >> 20 & (TRI_CACHE - 1);
            if self.slots[slot].id != id {
                self.slots[slot] = match prepare(id, sh, &mut self.insts, &mut self.hint) {
                    None => Slot { id, color: background, full: NO_FULL },
                    Some(Prepared::Constant(k)) => Slot { id, color: k, full: NO_FULL },
                    Some(Prepared::Full(e)) => {
                        // Reuse the entry this slot pointed at, else append.
                        let old = self.slots[slot].full;
                        let at = if (old as usize) < self.fulls.len() {
                            self.fulls[old as usize] = e;
                            old
                        } else {
                            self.fulls.push(e);
                            self.fulls.len() as u32 - 1
                        };
                        Slot { id, color: [0; 4], full: at }
                    }
                };
            }
            let sl = &self.slots[slot];
            let Some(entry) = self.fulls.get(sl.full as usize) else {
                colors[x..end].fill(sl.color);
                x = end;
                continue;
            };
            for (px, c) in colors[x..end].iter_mut().enumerate() {
                let p = Vec3A::new(((x + px) as f32 + 0.5) * sx - 1.0, ndc_y, 1.0);
                let mut b = Vec3::new(entry.rows[0].dot(p), entry.rows[1].dot(p), entry.rows[2].dot(p));
                if !opts.perspective_correct {
                    b *= Vec3::from(entry.w);
                }
                let s = b.x + b.y + b.z;
                let b = if s != 0.0 { b / s } else { Vec3::splat(1.0 / 3.0) };
                *c = entry.shader.shade(b, opts);
            }
            x = end;
        }
    }
}

const NO_FULL: u32 = u32::MAX;

/// A triangle cache slot: the ID it holds, its color when constant, else its full entry.
#[derive(Clone, Copy)]
struct Slot {
    id: u32,
    color: [u8; 4],
    full: u32,
}

#[allow(clippy::large_enum_variant)] // a short-lived return value; boxing would allocate
enum Prepared<'a> {
    Constant([u8; 4]),
    Full(TriEntry<'a>),
}

fn prepare<'a>(id: u32, sh: &'a Shader, insts: &mut [Option<InstEntry<'a>>], hint: &mut u32) -> Option<Prepared<'a>> {
    let (lookup, scene, camera, opts) = (&sh.lookup, sh.scene, sh.camera, sh.opts);
    let (eye, default) = (camera.view.eye, &sh.default);
    let g = id - 1;
    // Neighboring pixels mostly show the same instance: try the last one before searching.
    let index = match lookup.instances.get(*hint as usize) {
        Some(i) if g >= i.first_triangle && g - i.first_triangle < i.triangle_count => *hint,
        _ => {
            let i = lookup.find(g)?;
            *hint = i;
            i
        }
    };
    let inst = &lookup.instances[index as usize];
    let slot = index as usize & (INST_CACHE - 1);
    if !matches!(&insts[slot], Some(e) if e.index == index) {
        let mesh = scene.mesh(inst.mesh)?;
        let material = inst.material.and_then(|m| scene.material(m)).unwrap_or(default);
        insts[slot] = Some(InstEntry {
            index,
            clip: camera.clip_from_local(&inst.world_from_local),
            shading: InstanceShading::new(inst.world_from_local, material),
            mesh,
        });
    }
    let e = insts[slot].as_ref()?;
    let t = (g - inst.first_triangle) as usize;
    if t >= e.mesh.triangle_count() {
        return None;
    }
    if let Some(k) = crate::shading::flat_color(&e.shading, e.mesh, t, eye, opts) {
        // No interpolation needed: skip the clip-space rows.
        return Some(Prepared::Constant(k));
    }
    let shader = TriangleShader::new(&e.shading, e.mesh, t, eye, opts);
    let h = e
        .mesh
        .triangle(t)
        .map(|i| e.clip * e.mesh.positions()[i as usize].extend(1.0))
        .map(|c| Vec3A::new(c.x, c.y, c.w));
    Some(Prepared::Full(TriEntry {
        rows: [h[1].cross(h[2]), h[2].cross(h[0]), h[0].cross(h[1])],
        w: [h[0].z, h[1].z, h[2].z],
        shader,
    }))
}
