//! Depth complexity heat maps, plain z-buffer beside HZB: one street frame of the
//! 10^6-triangle city, every depth test counted per pixel, brute force on the left, occlusion
//! culling on the right, on one color scale. Writes `depth_complexity.png` (and the two
//! halves) into the directory given,
//! and `z_pyramid.png`: Greene's z-pyramid over the HZB frame's depth buffer, levels 1–8,
//! each texel the farthest depth of the pixels below it (near dark, far light, nothing
//! drawn white): what occlusion tests compare a box's nearest depth against.
//!
//! `cargo run --release --example depth_complexity [-- OUT_DIR [FRAME]]`

#![forbid(unsafe_code)]

use std::path::PathBuf;

use sightline::render::cull::DepthPyramid;
use sightline::render::output::heat_color;
use sightline::render::{Framebuffer, Method, RenderOptions, World};
use sightline::scene::builders::{city, CityParams};

fn main() {
    let out = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "out".into()));
    let frame: usize = std::env::args().nth(2).and_then(|a| a.parse().ok()).unwrap_or(40);
    std::fs::create_dir_all(&out).expect("output directory");
    let c = city(&CityParams::for_triangles(1_000_000)).expect("city");
    let key = c.layout.street_path(120, 11)[frame.min(119)];
    let (w, h) = (1280u32, 720u32);
    let cam = key.camera(w as f32 / h as f32).expect("camera");
    let mut world = World::new(c.scene);
    let opts = RenderOptions::ids_only();
    let mut counts = Vec::new();
    let mut depth = Vec::new();
    for method in [Method::Brute, Method::Hzb] {
        let mut fb = Framebuffer::new(w, h).expect("framebuffer");
        fb.count_depth_tests(true);
        let frame = world.render(&cam, method, &mut fb, &opts).expect("frame");
        let (cs, fs) = (frame.cull.expect("a culled frame"), frame.raster.expect("a rasterized frame"));
        let tests = fb.depth_tests.take().expect("counting was on");
        let total: u64 = tests.iter().map(|&t| t as u64).sum();
        println!(
            "{:<6} triangles drawn {:>8}, depth tests {:>9} ({:.2} per pixel), max {} at one pixel",
            method.name(),
            cs.triangles_drawn,
            fs.fragments_tested,
            total as f64 / (w * h) as f64,
            tests.iter().max().unwrap_or(&0)
        );
        counts.push(tests);
        depth = fb.depth.into();
    }
    // One scale for both: the brute-force maximum.
    let max = counts.iter().flat_map(|c| c.iter()).copied().max().unwrap_or(1).max(1) as f32;
    let gap = 16;
    let mut both = image::RgbaImage::from_pixel(2 * w + gap, h, image::Rgba([255, 255, 255, 255]));
    for (k, c) in counts.iter().enumerate() {
        let mut one = image::RgbaImage::new(w, h);
        for (i, &n) in c.iter().enumerate() {
            let px = image::Rgba(heat_color((n as f32 / max).sqrt()));
            let (x, y) = (i as u32 % w, i as u32 / w);
            one.put_pixel(x, y, px);
            both.put_pixel(x + k as u32 * (w + gap), y, px);
        }
        one.save(out.join(if k == 0 { "depth_complexity_zbuffer.png" } else { "depth_complexity_hzb.png" }))
            .expect("png");
    }
    both.save(out.join("depth_complexity.png")).expect("png");
    println!(
        "wrote {} (left: plain z-buffer, right: HZB; color = sqrt(tests / {max}))",
        out.join("depth_complexity.png").display()
    );
    write_pyramid(&depth, w, h, &out.join("z_pyramid.png"));
}

/// Levels 1–8 of the z-pyramid over `depth` in a 4 × 2 grid, each level scaled (nearest
/// texel) to half the frame's size; gray stretched over the depths drawn, as in depth PNGs.
fn write_pyramid(depth: &[f32], w: u32, h: u32, path: &std::path::Path) {
    let mut pyramid = DepthPyramid::new(w, h);
    pyramid.build(depth);
    let drawn = || depth.iter().copied().filter(|d| *d < 1.0);
    let lo = drawn().fold(f32::INFINITY, f32::min);
    let span = (drawn().fold(f32::NEG_INFINITY, f32::max) - lo).max(f32::MIN_POSITIVE);
    let gray = |d: f32| if d < 1.0 { ((d - lo) / span * 254.0).clamp(0.0, 254.0) as u8 } else { 255 };
    let (cw, ch, gap) = (w / 2, h / 2, 8);
    let mut img = image::RgbaImage::from_pixel(4 * cw + 3 * gap, 2 * ch + gap, image::Rgba([255, 255, 255, 255]));
    for k in 1..=8 {
        let Some(level) = pyramid.level(k) else { break };
        let (lw, lh) = (level.width, level.height);
        let (ox, oy) = (((k - 1) % 4) as u32 * (cw + gap), ((k - 1) / 4) as u32 * (ch + gap));
        for y in 0..ch {
            for x in 0..cw {
                let (tx, ty) = ((x * lw / cw).min(lw - 1), (y * lh / ch).min(lh - 1));
                let g = gray(level.at(tx, ty));
                img.put_pixel(ox + x, oy + y, image::Rgba([g, g, g, 255]));
            }
        }
    }
    img.save(path).expect("png");
    println!("wrote {} (z-pyramid levels 1-8, left to right, top to bottom)", path.display());
}
