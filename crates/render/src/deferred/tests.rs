//! Deferred shading checked against itself: the gathered rows against the run-by-run rows,
//! the instance lookup, and the end of a run.

use super::*;
use crate::{RenderOptions, Renderer, Sky};
use sightline_scene::builders::{city, CityParams};

/// The gathered rows (eight pixels a step, and sixteen where the CPU has AVX-512) give
/// the colors of the run-by-run rows, bit for bit:
/// flat triangles (the gathers' fast path), interpolated ones (entries the gathers
/// miss), the sky, and a cache with many triangles sharing slots (a small city seen
/// along a street, at two sizes so rows end mid-group); the gathered rows' uncached
/// triangles are asked for ahead on every row, and some are, flat and interpolated.
#[test]
fn gathered_rows_equal_run_by_run_rows() {
    if SimdLevel::Auto.resolve() < SimdLevel::Avx2 {
        return; // only the run-by-run rows exist here
    }
    // Run by run, eight and (where the CPU has it) sixteen pixels at a time.
    let best = SimdLevel::Auto.resolve();
    let levels = [SimdLevel::Portable, SimdLevel::Avx2, best];
    let c = city(&CityParams::for_triangles(30_000)).unwrap();
    let instances = c.scene.instances();
    let items = crate::draw_all(&instances);
    let mut renderer = Renderer::new();
    // Triangles asked for ahead, flat (face records) and interpolated (indices, corners).
    let mut asked = [0; 2];
    for (w, h) in [(320, 180), (203, 97)] {
        let mut fb = Framebuffer::new(w, h).unwrap();
        for key in c.layout.street_path(3, 5) {
            let cam = key.camera(w as f32 / h as f32).unwrap();
            renderer.render(&c.scene, &instances, &items, &cam, &mut fb, &RenderOptions::ids_only()).unwrap();
            assert!(fb.ids.contains(&0) && fb.ids.iter().any(|&i| i != 0));
            for mode in [ShadingMode::Flat, ShadingMode::Gouraud, ShadingMode::PerPixel] {
                for sky in [None, Some(Sky::default())] {
                    let opts = ShadeOptions { mode, sky, ..Default::default() };
                    let size = (w as usize, h as usize);
                    let frames = levels.map(|simd| ShadeFrame {
                        simd,
                        ..ShadeFrame::new(&c.scene, &instances, &cam, size, &opts, [9, 8, 7, 255])
                    });
                    let mut colors = levels.map(|_| vec![[0u8; 4]; w as usize]);
                    let mut shaders = levels.map(|_| Shader::default());
                    for y in 0..h as usize {
                        let ids = &fb.ids[y * w as usize..(y + 1) * w as usize];
                        for (k, frame) in frames.iter().enumerate() {
                            // Asking for the row's triangles ahead changes no color.
                            if k > 0 {
                                asked[usize::from(mode != ShadingMode::Flat)] +=
                                    frame.start_loads(&mut shaders[k], ids);
                            }
                            frame.row(&mut shaders[k], ids, y, &mut colors[k]);
                        }
                        for (k, c) in colors.iter().enumerate().skip(1) {
                            let l = levels[k];
                            assert_eq!(&colors[0], c, "{l:?}: {mode:?}, sky {}, row {y}", sky.is_some());
                        }
                    }
                }
            }
        }
    }
    assert!(asked.iter().all(|&a| a > 0), "no row had an uncached triangle to ask for: {asked:?}");
}

/// The lookup finds every triangle's instance, and none for IDs no instance holds,
/// whether the list is in first-triangle order (searched directly) or shuffled (found
/// through the sorted index made on the first failed search), with empty instances
/// and gaps between ranges: a small city's list (searched by halving) and lists long
/// enough for the search to guess positions, of even sizes (where the first guess is the
/// answer) and of sizes spread over five orders of magnitude.
#[test]
fn lookup_finds_each_triangles_instance_in_any_order() {
    let c = city(&CityParams::for_triangles(5_000)).unwrap();
    let small = c.scene.instances();
    let mut rng = sightline_scene::rng::Rng::new(3);
    // `n` copies of an instance with the sizes `size(k)`, every third starting 7 after the
    // last one's end.
    let list = |n: usize, size: &mut dyn FnMut(usize) -> u32| {
        let mut first = 0;
        (0..n)
            .map(|k| {
                first += if k % 3 == 0 { 7 } else { 0 };
                let inst = Instance { first_triangle: first, triangle_count: size(k), ..small[0] };
                first += inst.triangle_count;
                inst
            })
            .collect::<Vec<_>>()
    };
    let lists = [
        list(small.len(), &mut |k| if k % 5 == 0 { 0 } else { small[k].triangle_count }),
        list(20_000, &mut |_| 12),
        list(5_000, &mut |k| if k % 5 == 0 { 0 } else { 10f32.powf(rng.range(0.0, 5.0)) as u32 }),
    ];
    for list in &lists {
        let end = list.last().map_or(0, |i| i.first_triangle + i.triangle_count) + 10;
        let mut shuffled = list.clone();
        for k in (1..shuffled.len()).rev() {
            shuffled.swap(k, rng.range(0.0, k as f32 + 1.0) as usize % (k + 1));
        }
        for instances in [list, &shuffled] {
            let lookup = Lookup::new(instances);
            let mut hint = 0;
            // In order (the hint or a neighbor of it holds the next), then at random.
            let ordered = (0..end).step_by((end as usize / 4_000).max(1));
            let random: Vec<u32> = (0..4_000).map(|_| rng.range(0.0, end as f32) as u32 % end).collect();
            for g in ordered.chain(random) {
                let owner =
                    instances.iter().position(|i| g >= i.first_triangle && g - i.first_triangle < i.triangle_count);
                assert_eq!(lookup.find_hinted(g, &mut hint), owner.map(|k| k as u32), "triangle {g}");
            }
        }
    }
    // Searches in the evenly sized list (no hint): the guesses find an instance in a few
    // probes where halving 20,000 positions takes about 15.
    let lookup = Lookup::new(&lists[1]);
    for _ in 0..1_000 {
        let k = rng.range(0.0, lists[1].len() as f32) as usize % lists[1].len();
        let g = lists[1][k].first_triangle + rng.range(0.0, 12.0) as u32 % 12;
        assert_eq!(lookup.find(g), Some(k as u32), "triangle {g}");
    }
    let probes = lookup.probes.load(std::sync::atomic::Ordering::Relaxed);
    assert!(probes <= 4 * 1_000, "{probes} probes for 1,000 searches");
    // Every triangle in order, then in reverse: the next instance is always a neighbor of
    // the last answer on the triangle's side, found without a search.
    let lookup = Lookup::new(&lists[1]);
    let mut hint = 0;
    let all: Vec<u32> = lists[1].iter().flat_map(|i| i.first_triangle..i.first_triangle + i.triangle_count).collect();
    for &g in all.iter().chain(all.iter().rev()) {
        assert!(lookup.find_hinted(g, &mut hint).is_some(), "triangle {g}");
    }
    assert_eq!(lookup.probes.load(std::sync::atomic::Ordering::Relaxed), 0, "searches made");
}

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
