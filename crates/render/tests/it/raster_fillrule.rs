//! Fill rule and watertightness: shared edges cover every pixel exactly once, and centers
//! exactly on an edge go where llvmpipe puts them (left and bottom edges inclusive).

use glam::{Vec2, Vec4};
use sightline_render::{Framebuffer, RenderOptions, Renderer};
use sightline_scene::rng::Rng;

fn opts() -> RenderOptions {
    RenderOptions { backface_culling: false, ..RenderOptions::ids_only() }
}

fn counted(w: u32, h: u32) -> Framebuffer {
    let mut fb = Framebuffer::new(w, h).unwrap();
    fb.count_depth_tests(true);
    fb
}

fn clip(p: Vec2) -> Vec4 {
    Vec4::new(p.x, p.y, 0.0, 1.0)
}

/// An (n+1)² lattice over [−1.2, 1.2]² in NDC with shared random jitter, two triangles per
/// cell with a random diagonal and random winding.
fn jittered_grid(n: usize, seed: u64, snap_to_centers: bool, w: u32, h: u32) -> Vec<[Vec4; 3]> {
    let mut rng = Rng::new(seed);
    let step = 2.4 / n as f32;
    let mut pts = vec![Vec2::ZERO; (n + 1) * (n + 1)];
    for j in 0..=n {
        for i in 0..=n {
            let mut p = Vec2::new(-1.2 + i as f32 * step, -1.2 + j as f32 * step);
            p += Vec2::new(rng.range(-0.3, 0.3), rng.range(-0.3, 0.3)) * step;
            if snap_to_centers {
                // Put vertices on pixel centers so many edges pass exactly through centers.
                let px = ((p.x + 1.0) * 0.5 * w as f32).floor() + 0.5;
                let py = ((p.y + 1.0) * 0.5 * h as f32).floor() + 0.5;
                p = Vec2::new(px / w as f32 * 2.0 - 1.0, py / h as f32 * 2.0 - 1.0);
            }
            pts[j * (n + 1) + i] = p;
        }
    }
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = pts[j * (n + 1) + i];
            let b = pts[j * (n + 1) + i + 1];
            let c = pts[(j + 1) * (n + 1) + i + 1];
            let d = pts[(j + 1) * (n + 1) + i];
            let (t1, t2) = if rng.below(2) == 0 { ([a, b, c], [a, c, d]) } else { ([a, b, d], [b, c, d]) };
            for mut t in [t1, t2] {
                if rng.below(2) == 0 {
                    t.swap(1, 2);
                }
                tris.push(t.map(clip));
            }
        }
    }
    tris
}

#[test]
fn jittered_quad_grid_covers_every_pixel_exactly_once() {
    for (seed, snap) in [(1, false), (2, true), (3, false), (4, true)] {
        let (w, h) = (96, 64);
        let tris = jittered_grid(12, seed, snap, w, h);
        let mut fb = counted(w, h);
        let st = Renderer::new().draw_clip_triangles(&tris, 1, &mut fb, &opts());
        let counts = fb.depth_tests.as_ref().unwrap();
        let bad: Vec<_> = counts
            .iter()
            .enumerate()
            .filter(|(_, &c)| c != 1)
            .map(|(i, &c)| (i as u32 % w, i as u32 / w, c))
            .take(5)
            .collect();
        assert!(bad.is_empty(), "seed {seed}: pixels not covered once: {bad:?}");
        assert_eq!(st.fragments_tested, (w * h) as u64);
    }
}

#[test]
fn fan_of_64_triangles_covers_every_pixel_exactly_once() {
    let (w, h) = (80, 60);
    let mut rng = Rng::new(7);
    // Center on a pixel center (ties on many spokes) or jittered.
    for center in [Vec2::new(0.5 / 40.0, 0.5 / 30.0), Vec2::new(0.0123, -0.0456)] {
        let rim: Vec<Vec2> = (0..64)
            .map(|k| {
                let a = std::f32::consts::TAU * (k as f32 + rng.range(-0.3, 0.3)) / 64.0;
                Vec2::new(a.cos(), a.sin()) * 3.0
            })
            .collect();
        let tris: Vec<[Vec4; 3]> = (0..64).map(|k| [center, rim[k], rim[(k + 1) % 64]].map(clip)).collect();
        let mut fb = counted(w, h);
        Renderer::new().draw_clip_triangles(&tris, 1, &mut fb, &opts());
        let counts = fb.depth_tests.as_ref().unwrap();
        assert!(counts.iter().all(|&c| c == 1), "{center}: {:?}", {
            let mut v: Vec<_> = counts.to_vec();
            v.sort();
            v.dedup();
            v
        });
        // Every spoke got some pixels.
        let mut seen = [false; 65];
        for &id in &fb.ids {
            seen[id as usize] = true;
        }
        assert!(seen[1..].iter().filter(|&&s| s).count() > 32);
    }
}

/// Ties resolved as llvmpipe resolves them, through the public API: pairs of triangles sharing
/// an edge through pixel centers, given in GL window coordinates (y up) on an 8×8 target.
#[test]
fn llvmpipe_probe_ties() {
    let to_ndc = |(x, y): (f32, f32)| Vec4::new(x / 4.0 - 1.0, y / 4.0 - 1.0, 0.0, 1.0);
    let run = |pts: [(f32, f32); 6]| {
        let p = pts.map(to_ndc);
        let mut fb = Framebuffer::new(8, 8).unwrap();
        Renderer::new().draw_clip_triangles(&[[p[0], p[1], p[2]], [p[3], p[4], p[5]]], 1, &mut fb, &opts());
        fb
    };
    // Horizontal edge at GL y = 4.5: GL row 4 = image row 3; the triangle visually above
    // (tri 2) owns the centers.
    let fb = run([(0.0, 4.5), (4.0, 0.0), (8.0, 4.5), (0.0, 4.5), (8.0, 4.5), (4.0, 9.0)]);
    assert_eq!(&fb.ids[3 * 8 + 2..3 * 8 + 6], &[2, 2, 2, 2]);
    assert_eq!(fb.ids[4 * 8 + 4], 1);
    // Vertical edge at x = 4.5: the triangle on the right (tri 2) owns column 4.
    let fb = run([(4.5, 0.0), (4.5, 8.0), (0.0, 4.0), (4.5, 8.0), (4.5, 0.0), (9.0, 4.0)]);
    for row in 2..6 {
        assert_eq!(fb.ids[row * 8 + 4], 2, "row {row}");
        assert_eq!(fb.ids[row * 8 + 3], 1, "row {row}");
    }
    // Winding does not matter: the same with both triangles reversed.
    let fb2 = run([(4.5, 8.0), (4.5, 0.0), (0.0, 4.0), (4.5, 0.0), (4.5, 8.0), (9.0, 4.0)]);
    assert_eq!(fb.ids, fb2.ids);
}
