//! `sightline csg`: the built-in CSG demo, ray cast to a PNG.
//!
//! The solid is [`classic_demo`] (a cube intersected with a sphere, minus three cylinders
//! along the axes, evaluated by ray casting as in Roth 1982, "Ray Casting for Modeling
//! Solids"), standing on a ground plane, lit by the default directional light with hard
//! shadows and seen from above and aside.

use std::path::Path;

use anyhow::Result;
use glam::{Affine3A, Vec3};
use sightline::render::csg::{classic_demo, CsgObject};
use sightline::render::{output, Framebuffer, RayCaster, RaycastOptions};
use sightline::scene::{shapes, Angle, Camera, Material, NodeDesc, Projection, Scene, Transform, View};

/// Renders [`classic_demo`] (colored, standing on a ground plane, with hard shadows, seen
/// from above and aside) into a new framebuffer of the given size.
pub fn render_classic_demo(width: u32, height: u32) -> Result<Framebuffer> {
    let mut scene = Scene::new();
    let ground = scene.add_mesh(shapes::ground_quad("ground", 1)?);
    let gray = scene.add_material(Material::color("ground", [0.55, 0.57, 0.6]));
    let place = Transform::from_translation(Vec3::new(0.0, -1.0, 0.0)).with_scale(Vec3::new(12.0, 1.0, 12.0));
    scene.add_node(None, NodeDesc::new("ground").transform(place).mesh(ground).material(gray))?;
    scene.update_transforms();
    let object = CsgObject::new("classic", &classic_demo(), Affine3A::from_rotation_y(0.35), [0.85, 0.45, 0.25, 1.0])?;
    let caster = RayCaster::build(&scene)?.with_csg(vec![object]);
    let view = View::look_at(Vec3::new(3.2, 2.6, 4.0), Vec3::new(0.0, -0.2, 0.0), Vec3::Y)?;
    let aspect = width as f32 / height.max(1) as f32;
    let camera = Camera::new(view, Projection::perspective(Angle::radians(0.75), aspect, 0.1, 100.0)?)?;
    let mut fb = Framebuffer::new(width, height)?;
    let opts = RaycastOptions { shadows: true, background: [40, 44, 52, 255], ..RaycastOptions::default() };
    caster.render(&scene, &camera, &mut fb, &opts)?;
    Ok(fb)
}

/// Renders [`classic_demo`] to a PNG file (what `sightline csg` writes).
pub fn write_classic_demo_png(path: &Path, width: u32, height: u32) -> Result<()> {
    let fb = render_classic_demo(width, height)?;
    output::write_color_png(&fb, path)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csg_classic_demo_renders() {
        let fb = render_classic_demo(64, 48).unwrap();
        let hits = fb.ids.iter().filter(|&&i| i != 0).count();
        assert!(hits > 300, "{hits}");
        // The three holes: the view straight through the middle is not all material... and the
        // image has several shades (lit, shadowed, cut faces).
        let mut shades: Vec<[u8; 4]> = fb.color.to_vec();
        shades.sort();
        shades.dedup();
        assert!(shades.len() > 20);
        let dir = std::env::temp_dir().join(format!("sightline-csg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let png = dir.join("csg.png");
        write_classic_demo_png(&png, 64, 48).unwrap();
        assert!(std::fs::metadata(&png).unwrap().len() > 100);
        std::fs::remove_dir_all(&dir).ok();
    }
}
