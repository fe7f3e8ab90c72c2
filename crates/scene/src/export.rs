//! OBJ export of the flattened, world-space scene, so other renderers can draw exactly the
//! same triangles in the same order.
//!
//! The file has a single object (no `o`, `g`, `usemtl` or `mtllib` lines): for each instance
//! of [`Scene::instances`] (depth-first node order, which defines triangle IDs) it writes the
//! instance's mesh vertices transformed by `world_from_local` as `v x y z` lines, then its
//! triangles as `f a b c` lines (1-based, absolute indices), in mesh triangle order. So
//! triangle `k` of the file is flattened triangle `k` of the scene, and
//! [`load_obj`](crate::obj_loader::load_obj) reads it back as one mesh in the same order.
//!
//! Coordinates are written with Rust's shortest round-trip formatting of `f32`, so parsing
//! them back gives the same bits.

use std::io::Write;
use std::path::Path;

use glam::{Affine3A, Vec3};

use crate::{Error, Result, Scene};

/// Writes the flattened world-space scene as one OBJ object to `w`.
///
/// World transforms are taken from the last [`Scene::update_transforms`]; if the scene has
/// un-propagated edits, the instances, their transforms and their order are worked out from
/// the tree as it is now instead, so the output is always current. Fails with `InvalidData` when a world position is NaN or
/// infinite (a transform overflowed), since such a file could not be read back.
pub fn write_obj(scene: &Scene, w: &mut impl Write) -> std::io::Result<()> {
    // With un-propagated edits, the scene as it is now (not as of the last update).
    let stale = scene.needs_update();
    let instances = if stale { scene.instances_now() } else { scene.instances() };
    let triangles: u64 = instances.iter().map(|i| i.triangle_count as u64).sum();
    writeln!(w, "# sightline scene export: {} instances, {triangles} triangles, world space", instances.len())?;
    let mut line = String::with_capacity(1 << 16);
    let mut base: u64 = 1;
    for inst in &instances {
        let Some(mesh) = scene.mesh(inst.mesh) else {
            continue;
        };
        let world: Affine3A = inst.world_from_local;
        for &p in mesh.positions() {
            let q: Vec3 = world.transform_point3(p);
            if !q.is_finite() {
                let name = scene.node(inst.node).map_or("?", |n| n.name());
                return Err(std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    format!("node '{name}': world position {q} is not finite"),
                ));
            }
            line.push_str("v ");
            push_f32(&mut line, q.x);
            line.push(' ');
            push_f32(&mut line, q.y);
            line.push(' ');
            push_f32(&mut line, q.z);
            line.push('\n');
            flush_if_full(&mut line, w)?;
        }
        for t in mesh.indices().chunks_exact(3) {
            line.push('f');
            for &i in t {
                line.push(' ');
                push_u64(&mut line, base + i as u64);
            }
            line.push('\n');
            flush_if_full(&mut line, w)?;
        }
        base += mesh.positions().len() as u64;
    }
    w.write_all(line.as_bytes())?;
    w.flush()
}

/// Writes the flattened world-space scene to an OBJ file (see [`write_obj`]).
pub fn export_obj(scene: &Scene, path: &Path) -> Result<()> {
    let io = |source| Error::Io { path: path.to_path_buf(), source };
    let file = std::fs::File::create(path).map_err(io)?;
    let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
    write_obj(scene, &mut w).map_err(io)?;
    w.into_inner().map_err(|e| io(e.into_error()))?;
    Ok(())
}

#[inline]
fn flush_if_full(line: &mut String, w: &mut impl Write) -> std::io::Result<()> {
    if line.len() > (1 << 16) - 128 {
        w.write_all(line.as_bytes())?;
        line.clear();
    }
    Ok(())
}

/// Appends the shortest decimal that parses back to exactly `x` (Rust's `Display` for f32).
#[inline]
fn push_f32(s: &mut String, x: f32) {
    use std::fmt::Write as _;
    if x == x.trunc() && x.abs() < 1.0e7 {
        // Integral values (common: grids, cubes) skip the float formatter.
        if x == 0.0 && x.is_sign_negative() {
            s.push('-');
        }
        push_i64(s, x as i64);
    } else {
        let _ = write!(s, "{x}");
    }
}

#[inline]
fn push_i64(s: &mut String, v: i64) {
    if v < 0 {
        s.push('-');
    }
    push_u64(s, v.unsigned_abs());
}

#[inline]
fn push_u64(s: &mut String, mut v: u64) {
    let mut buf = [0u8; 20];
    let mut i = buf.len();
    loop {
        i -= 1;
        buf[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    for &b in &buf[i..] {
        s.push(b as char);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float_text_round_trips() {
        for x in [
            0.0f32,
            -0.0,
            1.0,
            -3.0,
            0.1,
            1.0e-30,
            -7.25e12,
            f32::MAX,
            f32::MIN_POSITIVE,
            9_999_999.0,
            16_777_217.0,
            123.456,
        ] {
            let mut s = String::new();
            push_f32(&mut s, x);
            let back: f32 = s.parse().unwrap();
            assert_eq!(back.to_bits(), x.to_bits(), "{x} -> {s}");
        }
        let mut s = String::new();
        push_u64(&mut s, 0);
        push_i64(&mut s, -120);
        assert_eq!(s, "0-120");
    }
}
