//! The public entry points: batched draws equal one draw, counters add up, antialiasing,
//! wireframe, shading modes and the output writers.

use glam::{Vec3, Vec4};
use sightline_render::output;
use sightline_render::{
    draw_all, render_scene, Antialias, DrawItem, Framebuffer, RenderOptions, Renderer, ShadeOptions, ShadingMode,
    Wireframe,
};
use sightline_scene::{shapes, Angle, Camera, LookAt, Material, NodeDesc, Scene};

use crate::support::{self, one_node_scene};

fn small_city() -> (sightline_scene::builders::City, Camera) {
    let c = support::small_city();
    let cam = c.layout.street_path(10, 11)[2].camera(4.0 / 3.0).unwrap();
    (c, cam)
}

#[test]
fn batches_in_any_split_equal_one_draw_and_counters_add_up() {
    let (c, cam) = small_city();
    let inst = c.scene.instances();
    let items = draw_all(&inst);
    let opts = RenderOptions::ids_only();
    let mut r = Renderer::new();
    let mut one = Framebuffer::new(160, 120).unwrap();
    one.count_depth_tests(true);
    let st = r.render(&c.scene, &inst, &items, &cam, &mut one, &opts).unwrap();

    // Clusters of 100 triangles, in three batches, through `draw`.
    let clusters: Vec<DrawItem> = items
        .iter()
        .flat_map(|d| {
            (0..d.count.div_ceil(100)).map(move |k| DrawItem {
                instance: d.instance,
                first: k * 100,
                count: (d.count - k * 100).min(100),
            })
        })
        .collect();
    let mut many = Framebuffer::new(160, 120).unwrap();
    many.count_depth_tests(true);
    many.clear(opts.background);
    let mut sum = sightline_render::FrameStats::default();
    let third = clusters.len() / 3;
    for batch in [&clusters[..third], &clusters[third..2 * third], &clusters[2 * third..]] {
        let s = r.draw(&c.scene, &inst, batch, &cam, &mut many, &opts).unwrap();
        sum.add(&s);
    }
    assert_eq!(one.ids, many.ids);
    assert_eq!(one.depth, many.depth);
    assert_eq!(one.depth_tests, many.depth_tests);
    assert_eq!(sum.triangles_in, st.triangles_in);
    assert_eq!(sum.fragments_written, st.fragments_written);

    // Every submitted triangle is accounted for once.
    assert_eq!(
        st.triangles_in + st.clip_output - st.clipped,
        st.trivially_rejected + st.backface_culled + st.degenerate + st.too_small + st.rasterized
    );
    assert_eq!(st.triangles_in, inst.iter().map(|i| i.triangle_count as u64).sum::<u64>());
    assert!(st.clipped > 0, "the street camera clips the ground");
    assert_eq!(st.fragments_tested, one.depth_tests.as_ref().unwrap().iter().map(|&c| c as u64).sum::<u64>());
    assert_eq!(st.covered_pixels, one.ids.iter().filter(|&&i| i != 0).count() as u64);
    assert!(st.overdraw >= 1.0);
    // Back-face culling removes triangles and changes no visible ID on closed buildings.
    let mut off = Framebuffer::new(160, 120).unwrap();
    let so =
        r.render(&c.scene, &inst, &items, &cam, &mut off, &RenderOptions { backface_culling: false, ..opts }).unwrap();
    assert_eq!(so.backface_culled, 0);
    assert!(st.backface_culled > 0);
    let differ = off.ids.iter().zip(&one.ids).filter(|(a, b)| a != b).count();
    assert!(differ * 200 < off.ids.len(), "{differ} pixels differ with culling off");
}

fn quad_scene(material: Material) -> (Scene, Camera) {
    let mut s = Scene::new();
    let m = s.add_mesh(shapes::ground_quad("q", 4).unwrap());
    let mat = s.add_material(material);
    s.add_node(None, NodeDesc::new("q").mesh(m).material(mat)).unwrap();
    s.update_transforms();
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(0.0, 2.0, 0.01),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(60.0),
            near: 0.1,
            far: 10.0,
        },
        1.0,
    )
    .unwrap();
    (s, cam)
}

#[test]
fn supersampling_smooths_edges() {
    // A vertical edge through pixel column 5 at x = 5.3: sample columns at 5.25 (2×2) and
    // at 5.125 (4×4) are covered, so that column gets 1/2 or 1/4 of the white.
    let x = 5.3 / 8.0 - 1.0;
    let tri = [Vec4::new(x, -10.0, 0.0, 1.0), Vec4::new(x, 10.0, 0.0, 1.0), Vec4::new(-10.0, 0.0, 0.0, 1.0)];
    for (aa, s, want) in [(Antialias::Ssaa2x2, 2, 128), (Antialias::Ssaa4x4, 4, 64)] {
        let mut ss = Framebuffer::new(16 * s, 8 * s).unwrap();
        ss.clear([0, 0, 0, 255]);
        Renderer::new().draw_clip_triangles(
            &[tri],
            1,
            &mut ss,
            &RenderOptions { backface_culling: false, ..Default::default() },
        );
        for (c, &id) in ss.color.iter_mut().zip(&ss.ids) {
            if id != 0 {
                *c = [255; 4];
            }
        }
        let mut fb = Framebuffer::new(16, 8).unwrap();
        sightline_render::aa::resolve(&ss, s, &mut fb);
        assert_eq!(fb.color[4][0], 255, "{aa:?}");
        assert_eq!(fb.color[5][0], want, "{aa:?}");
        assert_eq!(fb.color[6][0], 0, "{aa:?}");
    }
    // Through `render`: edge pixels of the quad get in-between colors only with SSAA.
    let (s, cam) = quad_scene(Material::color("w", [1.0, 1.0, 1.0]));
    let count = |aa| {
        let mut fb = Framebuffer::new(40, 40).unwrap();
        let o = RenderOptions {
            antialias: aa,
            background: [0, 0, 0, 255],
            shading: ShadeOptions::unlit(),
            ..Default::default()
        };
        render_scene(&s, &cam, &mut fb, &o).unwrap();
        fb.color.iter().filter(|c| c[0] > 0 && c[0] < 255).count()
    };
    assert_eq!(count(Antialias::Off), 0);
    assert!(count(Antialias::Ssaa4x4) > 20);
}

#[test]
fn wireframe_alone_and_as_overlay() {
    let (s, cam) = quad_scene(Material::color("w", [1.0, 1.0, 1.0]));
    let wire = [255, 0, 0, 255];
    let mut fb = Framebuffer::new(64, 64).unwrap();
    let o = RenderOptions { wireframe: Wireframe::Only, wire_color: wire, ..Default::default() };
    render_scene(&s, &cam, &mut fb, &o).unwrap();
    let red = fb.color.iter().filter(|&&c| c == wire).count();
    assert!(red > 100, "{red}");
    assert!(fb.ids.iter().all(|&i| i == 0));
    let o = RenderOptions { wireframe: Wireframe::Overlay, wire_color: wire, ..Default::default() };
    render_scene(&s, &cam, &mut fb, &o).unwrap();
    assert_eq!(fb.color.iter().filter(|&&c| c == wire).count(), red);
    assert!(fb.ids.iter().filter(|&&i| i != 0).count() > 400);
}

#[test]
fn shading_modes_differ_where_they_should() {
    // A box with per-face normals, seen from a corner: flat, Gouraud and per-pixel agree
    // on flat faces; all are lit (not background) and the default material is grey.
    let s = one_node_scene("c", shapes::cube("c").unwrap());
    let cam = Camera::perspective(
        &LookAt {
            eye: Vec3::new(1.5, 1.2, 2.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fovy: Angle::degrees(50.0),
            near: 0.1,
            far: 10.0,
        },
        1.0,
    )
    .unwrap();
    let img = |mode| {
        let mut fb = Framebuffer::new(48, 48).unwrap();
        let mut o = RenderOptions::default();
        o.shading.mode = mode;
        render_scene(&s, &cam, &mut fb, &o).unwrap();
        fb
    };
    let flat = img(ShadingMode::Flat);
    let covered: Vec<usize> = (0..flat.len()).filter(|&i| flat.ids[i] != 0).collect();
    assert!(covered.len() > 300);
    for mode in [ShadingMode::Gouraud, ShadingMode::PerPixel] {
        let f = img(mode);
        for &i in &covered {
            for k in 0..3 {
                assert!((f.color[i][k] as i32 - flat.color[i][k] as i32).abs() <= 1, "{mode:?}");
            }
        }
    }
    // Three faces with three different intensities.
    let mut shades: Vec<u8> = covered.iter().map(|&i| flat.color[i][0]).collect();
    shades.sort();
    shades.dedup();
    assert!(shades.len() >= 3, "{shades:?}");
    let none = img(ShadingMode::None);
    assert!(none.color.iter().all(|&c| c == RenderOptions::default().background));
}

#[test]
fn output_writers() {
    let (c, cam) = small_city();
    let mut fb = Framebuffer::new(64, 48).unwrap();
    fb.count_depth_tests(true);
    render_scene(&c.scene, &cam, &mut fb, &RenderOptions::default()).unwrap();
    let dir = std::env::temp_dir().join(format!("sightline-raster-api-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    output::write_color_png(&fb, &dir.join("color.png")).unwrap();
    output::write_depth_png(&fb, &dir.join("depth.png")).unwrap();
    output::write_id_png(&fb, &dir.join("ids.png")).unwrap();
    output::write_heatmap_png(&fb, &dir.join("heat.png")).unwrap();
    output::write_ids_npy(&fb, &dir.join("ids.npy")).unwrap();
    output::write_depth_npy(&fb, &dir.join("depth.npy")).unwrap();
    for f in ["color", "depth", "ids", "heat"] {
        let img = image::open(dir.join(format!("{f}.png"))).unwrap();
        assert_eq!((img.width(), img.height()), (64, 48));
    }
    let npy = std::fs::read(dir.join("ids.npy")).unwrap();
    let hl = u16::from_le_bytes([npy[8], npy[9]]) as usize;
    assert!(std::str::from_utf8(&npy[10..10 + hl]).unwrap().contains("'shape': (48, 64)"));
    let ids: Vec<u32> = npy[10 + hl..].chunks_exact(4).map(|b| u32::from_le_bytes(b.try_into().unwrap())).collect();
    assert_eq!(ids, fb.ids);
    // A framebuffer without counters cannot make a heat map.
    let plain = Framebuffer::new(4, 4).unwrap();
    assert!(output::write_heatmap_png(&plain, &dir.join("x.png")).is_err());
    assert!(output::write_color_png(&fb, &dir.join("no/such/dir/c.png")).is_err());
    std::fs::remove_dir_all(&dir).ok();
}

/// The plain renderer overwrites every plane too, with and without supersampling.
#[test]
fn render_needs_no_clear() {
    let (c, cam) = small_city();
    let inst = c.scene.instances();
    let items = draw_all(&inst);
    for antialias in [Antialias::Off, Antialias::Ssaa2x2] {
        let opts = RenderOptions { antialias, ..Default::default() };
        let mut r = Renderer::new();
        let mut clean = Framebuffer::new(160, 120).unwrap();
        let mut dirty = Framebuffer::new(160, 120).unwrap();
        dirty.color.fill([9, 9, 9, 9]);
        dirty.depth.fill(0.0);
        dirty.ids.fill(5);
        r.render(&c.scene, &inst, &items, &cam, &mut clean, &opts).unwrap();
        r.render(&c.scene, &inst, &items, &cam, &mut dirty, &opts).unwrap();
        assert!(clean.ids.contains(&0), "the view shows some background");
        assert_eq!((&clean.ids, &clean.depth, &clean.color), (&dirty.ids, &dirty.depth, &dirty.color), "{antialias:?}");
    }
}
