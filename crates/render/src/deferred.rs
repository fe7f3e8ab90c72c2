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

/// Rows per parallel band for plain fills.
const BAND_ROWS: usize = 16;
/// Bands per worker thread when shading: few and tall, because a triangle spanning several
/// bands is prepared once in each (a measurable cost at street level, where triangles
/// are large), yet more than one per thread to balance uneven bands.
const BANDS_PER_THREAD: usize = 3;
const TRI_CACHE: usize = 4096;
const INST_CACHE: usize = 64;

/// Finds the instance drawing global triangle `g` (instances ordered by first triangle).
pub(crate) struct Lookup<'a> {
    pub(crate) instances: &'a [Instance],
    order: Option<Vec<u32>>,
}

impl<'a> Lookup<'a> {
    pub(crate) fn new(instances: &'a [Instance]) -> Self {
        let sorted = instances.windows(2).all(|w| w[0].first_triangle <= w[1].first_triangle);
        let order = (!sorted).then(|| {
            let mut o: Vec<u32> =
                (0..instances.len() as u32).filter(|&i| instances[i as usize].triangle_count > 0).collect();
            o.sort_by_key(|&i| instances[i as usize].first_triangle);
            o
        });
        Self { instances, order }
    }

    /// The instance drawing global triangle `g`, trying `hint` (the last answer) first:
    /// neighboring pixels mostly show the same instance.
    #[inline]
    pub(crate) fn find_hinted(&self, g: u32, hint: &mut u32) -> Option<u32> {
        match self.instances.get(*hint as usize) {
            Some(i) if g >= i.first_triangle && g - i.first_triangle < i.triangle_count => Some(*hint),
            _ => {
                let i = self.find(g)?;
                *hint = i;
                Some(i)
            }
        }
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

/// A triangle ready for shading at any pixel: its 2D homogeneous rows and its shader.
pub(crate) struct TriEntry<'a> {
    rows: [Vec3A; 3],
    w: [f32; 3],
    pub(crate) shader: TriangleShader<'a>,
}

impl<'a> TriEntry<'a> {
    /// Triangle `t` of `mesh`, drawn under `clip` (`clip_from_local`) with `shader`.
    pub(crate) fn new(clip: &Mat4, mesh: &Mesh, t: usize, shader: TriangleShader<'a>) -> Self {
        let h = mesh
            .triangle(t)
            .map(|i| *clip * mesh.positions()[i as usize].extend(1.0))
            .map(|c| Vec3A::new(c.x, c.y, c.w));
        TriEntry { rows: [h[1].cross(h[2]), h[2].cross(h[0]), h[0].cross(h[1])], w: [h[0].z, h[1].z, h[2].z], shader }
    }

    /// The world-space barycentric weights of the point seen through NDC `p = (x, y, 1)`
    /// (affine screen-space weights when `perspective_correct` is off).
    #[inline(always)]
    pub(crate) fn weights(&self, p: Vec3A, perspective_correct: bool) -> Vec3 {
        let mut b = Vec3::new(self.rows[0].dot(p), self.rows[1].dot(p), self.rows[2].dot(p));
        if !perspective_correct {
            b *= Vec3::from(self.w);
        }
        let s = b.x + b.y + b.z;
        if s != 0.0 {
            b / s
        } else {
            Vec3::splat(1.0 / 3.0)
        }
    }
}

/// NDC of the center of pixel column `x` (`sx` = 2 / width).
#[inline(always)]
pub(crate) fn ndc_x(x: usize, sx: f32) -> f32 {
    (x as f32 + 0.5) * sx - 1.0
}

/// NDC of the center of pixel row `y` (`sy` = 2 / height; row 0 is the top).
#[inline(always)]
pub(crate) fn ndc_y(y: usize, sy: f32) -> f32 {
    1.0 - (y as f32 + 0.5) * sy
}

/// Writes every color of `fb`: pixels with ID 0 get the sky's color for their row when
/// `opts` has a sky ([`crate::sky`]), else `background`, as do IDs that no instance claims
/// and every pixel in mode `None`; the others are shaded. So the color plane needs no
/// clearing before a frame.
pub fn shade_pass(
    scene: &Scene,
    instances: &[Instance],
    camera: &Camera,
    fb: &mut Framebuffer,
    opts: &ShadeOptions,
    background: [u8; 4],
) {
    if opts.mode == ShadingMode::None {
        let chunk = fb.width() as usize * BAND_ROWS;
        fb.color.par_chunks_mut(chunk).for_each(|c| c.fill(background));
        return;
    }
    let lookup = Lookup::new(instances);
    let default = Material::default();
    let (w, h) = (fb.width() as usize, fb.height() as usize);
    let eye = camera.view.eye;
    let (sx, sy) = (2.0 / w as f32, 2.0 / h as f32);
    let ids = &fb.ids;
    let sky = opts.sky.map(|s| s.rows(camera, h));
    let band_rows = h.div_ceil(rayon::current_num_threads().max(1) * BANDS_PER_THREAD).max(1);
    fb.color.par_chunks_mut(w * band_rows).enumerate().for_each(|(band, color)| {
        let mut insts: Vec<Option<InstEntry>> = (0..INST_CACHE).map(|_| None).collect();
        // Direct-mapped triangle cache: a small slot per entry (flat triangles need nothing
        // but their color), full interpolation data only for the others.
        let mut slots = vec![Slot { id: 0, color: background, full: NO_FULL }; TRI_CACHE];
        let mut fulls: Vec<TriEntry> = Vec::new();
        let mut hint = 0u32;
        let y0 = band * band_rows;
        for (r, crow) in color.chunks_mut(w).enumerate() {
            let y = y0 + r;
            if y >= h {
                break;
            }
            let row_y = ndc_y(y, sy);
            let irow = &ids[y * w..(y + 1) * w];
            // Runs of one ID along the row: one cache lookup and one fill per run.
            let mut x = 0;
            while x < w {
                let id = irow[x];
                let end = run_end(irow, x + 1, id);
                if id == 0 {
                    crow[x..end].fill(sky.as_ref().map_or(background, |s| s[y]));
                    x = end;
                    continue;
                }
                let slot = (id as usize).wrapping_mul(0x9E37_79B1) >> 20 & (TRI_CACHE - 1);
                if slots[slot].id != id {
                    slots[slot] = match prepare(id, &lookup, &mut insts, scene, camera, eye, &default, opts, &mut hint)
                    {
                        None => Slot { id, color: background, full: NO_FULL },
                        Some(Prepared::Constant(k)) => Slot { id, color: k, full: NO_FULL },
                        Some(Prepared::Full(e)) => {
                            // Reuse the entry this slot pointed at, else append.
                            let old = slots[slot].full;
                            let at = if (old as usize) < fulls.len() {
                                fulls[old as usize] = e;
                                old
                            } else {
                                fulls.push(e);
                                fulls.len() as u32 - 1
                            };
                            Slot { id, color: [0; 4], full: at }
                        }
                    };
                }
                let sl = &slots[slot];
                let Some(entry) = fulls.get(sl.full as usize) else {
                    crow[x..end].fill(sl.color);
                    x = end;
                    continue;
                };
                for (px, c) in crow[x..end].iter_mut().enumerate() {
                    let p = Vec3A::new(ndc_x(x + px, sx), row_y, 1.0);
                    *c = entry.shader.shade(entry.weights(p, opts.perspective_correct), opts);
                }
                x = end;
            }
        }
    });
}

const NO_FULL: u32 = u32::MAX;

/// The end of the run of `id` in `row` that continues at `from`: the first position at or
/// after `from` holding another ID, or the row's length. Eight IDs per step while the run
/// lasts (the OR of XORs has no branch per lane, so it vectorizes), then one at a time: on
/// big triangles the scan for the run's end was most of the shading pass.
#[inline(always)]
fn run_end(row: &[u32], from: usize, id: u32) -> usize {
    let mut x = from;
    while let Some(c) = row.get(x..x + 8) {
        if c.iter().fold(0, |a, &v| a | (v ^ id)) != 0 {
            break;
        }
        x += 8;
    }
    while x < row.len() && row[x] == id {
        x += 1;
    }
    x
}

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

#[allow(clippy::too_many_arguments)]
fn prepare<'a>(
    id: u32,
    lookup: &Lookup,
    insts: &mut [Option<InstEntry<'a>>],
    scene: &'a Scene,
    camera: &Camera,
    eye: Vec3,
    default: &'a Material,
    opts: &ShadeOptions,
    hint: &mut u32,
) -> Option<Prepared<'a>> {
    let g = id - 1;
    let index = lookup.find_hinted(g, hint)?;
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
    Some(Prepared::Full(TriEntry::new(&e.clip, e.mesh, t, shader)))
}

#[cfg(test)]
mod tests {
    use super::run_end;

    /// The eight-at-a-time scan ends every run where a plain scan does, at every run length
    /// and start, at the row's end too.
    #[test]
    fn run_end_equals_a_plain_scan() {
        let mut rng = sightline_scene::rng::Rng::new(5);
        for _ in 0..200 {
            let n = (rng.range(1.0, 70.0)) as usize;
            // Long runs of few IDs, so runs of every length occur.
            let mut row = Vec::with_capacity(n);
            while row.len() < n {
                let (id, len) = (rng.range(0.0, 3.0) as u32, rng.range(1.0, 20.0) as usize);
                row.extend(std::iter::repeat_n(id, len.min(n - row.len())));
            }
            for from in 0..=n {
                let id = row.get(from).copied().unwrap_or(1);
                let plain = row[from..].iter().position(|&v| v != id).map_or(n, |k| from + k);
                assert_eq!(run_end(&row, from, id), plain, "row {row:?} from {from}");
            }
        }
    }
}
