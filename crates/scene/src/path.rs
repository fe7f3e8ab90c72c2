//! Camera paths: a list of look-at keys, serialized as plain JSON that other renderers can
//! replay (`[{"eye":[x,y,z],"target":[x,y,z],"up":[x,y,z],"fovy_deg":f,"near":f,"far":f}, …]`),
//! and the two paths through the city: a street walk at eye height and a flight above roofs.

use std::path::Path;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::builders::CityLayout;
use crate::rng::Rng;
use crate::{Aabb, Angle, Camera, Error, LookAt, Result};

/// Eye height of the street walk.
pub const EYE_HEIGHT: f32 = 1.7;

/// One camera of a path.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraKey {
    /// Eye position.
    pub eye: [f32; 3],
    /// Point looked at.
    pub target: [f32; 3],
    /// Approximate up direction.
    pub up: [f32; 3],
    /// Vertical field of view in degrees.
    pub fovy_deg: f32,
    /// Near plane distance.
    pub near: f32,
    /// Far plane distance.
    pub far: f32,
}

impl CameraKey {
    /// The key as a [`LookAt`].
    pub fn look_at(&self) -> LookAt {
        LookAt {
            eye: Vec3::from(self.eye),
            target: Vec3::from(self.target),
            up: Vec3::from(self.up),
            fovy: Angle::degrees(self.fovy_deg),
            near: self.near,
            far: self.far,
        }
    }

    /// The key of a [`LookAt`] (the field of view written in degrees).
    pub fn from_look_at(look: &LookAt) -> Self {
        Self {
            eye: look.eye.to_array(),
            target: look.target.to_array(),
            up: look.up.to_array(),
            fovy_deg: look.fovy.to_degrees(),
            near: look.near,
            far: look.far,
        }
    }

    /// The perspective camera of this key for a viewport of the given aspect (width / height).
    pub fn camera(&self, aspect: f32) -> Result<Camera> {
        Camera::perspective(&self.look_at(), aspect)
    }
}

/// The largest camera path file read (2 GiB; a million frames of pretty-printed keys take
/// about 300 MB).
pub const MAX_PATH_FILE_BYTES: u64 = 2 << 30;

/// Reads a camera path JSON file (a regular file of at most [`MAX_PATH_FILE_BYTES`]: a FIFO
/// or a device is refused, see [`crate::assets::read_regular_file`]).
pub fn read_path(path: &Path) -> Result<Vec<CameraKey>> {
    let bytes = crate::assets::read_regular_file(path, MAX_PATH_FILE_BYTES).map_err(|e| Error::load(path, e))?;
    parse_path(&bytes, path)
}

/// Parses camera path JSON from memory (what [`read_path`] does after reading the file);
/// `path` names the file in messages.
pub fn parse_path(bytes: &[u8], path: &Path) -> Result<Vec<CameraKey>> {
    let keys: Vec<CameraKey> =
        serde_json::from_slice(bytes).map_err(|e| Error::load(path, format!("not a camera path: {e}")))?;
    if keys.is_empty() {
        return Err(Error::load(path, "camera path has no frames"));
    }
    // Each key must place a camera (finite numbers, the eye apart from the target, up not
    // along the gaze): a bad key is named here rather than when a walk reaches it. Near and
    // far are checked with each frame's camera, since a program may replace them.
    for (k, key) in keys.iter().enumerate() {
        // The camera below checks the rest; near and far are set aside there.
        let finite = key.near.is_finite() && key.far.is_finite();
        let placed = CameraKey { near: 1.0, far: 2.0, ..*key };
        let why = if finite {
            placed.camera(1.0).err().map(|e| e.to_string())
        } else {
            Some("a number is not finite".into())
        };
        if let Some(why) = why {
            return Err(Error::load(path, format!("frame {k}: {why}")));
        }
    }
    Ok(keys)
}

/// Writes a camera path JSON file.
pub fn write_path(path: &Path, keys: &[CameraKey]) -> Result<()> {
    let text = serde_json::to_string_pretty(keys).map_err(|e| Error::load(path, e.to_string()))?;
    std::fs::write(path, text).map_err(|source| Error::Io { path: path.into(), source })
}

/// A polyline sampled by arc length.
struct Polyline(Vec<Vec3>);

impl Polyline {
    fn length(&self) -> f32 {
        self.0.windows(2).map(|w| w[0].distance(w[1])).sum()
    }
    /// The point at arc length `s`; outside `[0, length]` it continues along the first or
    /// last segment.
    fn at(&self, mut s: f32) -> Vec3 {
        for w in self.0.windows(2) {
            let l = w[0].distance(w[1]);
            if s <= l || l == 0.0 {
                return w[0].lerp(w[1], if l > 0.0 { s / l } else { 0.0 });
            }
            s -= l;
        }
        let n = self.0.len();
        let dir = (self.0[n - 1] - self.0[n - 2]).normalize_or_zero();
        self.0[n - 1] + dir * s
    }
}

fn sample(line: &Polyline, frames: usize, lookahead: f32, key: impl Fn(Vec3, Vec3) -> CameraKey) -> Vec<CameraKey> {
    let len = line.length();
    let frames = frames.max(1);
    (0..frames)
        .map(|i| {
            let s = if frames == 1 { 0.0 } else { len * i as f32 / (frames - 1) as f32 };
            key(line.at(s), line.at(s + lookahead))
        })
        .collect()
}

impl CityLayout {
    /// A walk along the street center lines at eye height, looking horizontally ahead;
    /// it turns at intersections and stays off the outermost streets where it can.
    pub fn street_path(&self, frames: usize, seed: u64) -> Vec<CameraKey> {
        let b = self.blocks as i32;
        let (lo, hi) = if b >= 4 { (1, b - 1) } else { (0, b) };
        let mut rng = Rng::new(seed);
        let mut at = [(b / 2).clamp(lo, hi), lo];
        let mut dir = [0i32, 1];
        let mut pts = vec![at];
        let mut walked = 0;
        while walked < 10.max(b) {
            // Go 1–3 blocks straight if possible, then turn left or right.
            let want = 1 + rng.below(3) as i32;
            let mut steps = 0;
            while steps < want {
                let next = [at[0] + dir[0], at[1] + dir[1]];
                if next[0] < lo || next[0] > hi || next[1] < lo || next[1] > hi {
                    break;
                }
                at = next;
                steps += 1;
            }
            walked += steps.max(1);
            pts.push(at);
            let left = [-dir[1], dir[0]];
            let right = [dir[1], -dir[0]];
            let ok = |d: [i32; 2]| {
                let n = [at[0] + d[0], at[1] + d[1]];
                n[0] >= lo && n[0] <= hi && n[1] >= lo && n[1] <= hi
            };
            dir = match (ok(left), ok(right)) {
                (true, true) => {
                    if rng.below(2) == 0 {
                        left
                    } else {
                        right
                    }
                }
                (true, false) => left,
                (false, true) => right,
                _ => [-dir[0], -dir[1]],
            };
        }
        pts.dedup();
        let to_world = |p: [i32; 2]| Vec3::new(self.street(p[0] as u32), EYE_HEIGHT, self.street(p[1] as u32));
        let mut line = Polyline(pts.into_iter().map(to_world).collect());
        if line.0.len() < 2 {
            let p = line.0[0];
            line.0.push(p + Vec3::Z * 52.0);
        }
        let far = (self.bounds().extent().length() * 1.5).max(100.0);
        // Lerp can turn 1.7 into 1.6999999: pin the height so the gaze is exactly horizontal.
        sample(&line, frames, 20.0, |eye, target| CameraKey {
            eye: [eye.x, EYE_HEIGHT, eye.z],
            target: [target.x, EYE_HEIGHT, target.z],
            up: [0.0, 1.0, 0.0],
            fovy_deg: 60.0,
            near: 0.1,
            far,
        })
    }

    /// A flight above the roofs: a circle around the city center at 1.5× the tallest
    /// building plus 20 units, looking ahead and down.
    pub fn aerial_path(&self, frames: usize) -> Vec<CameraKey> {
        aerial(&self.bounds(), self.max_height * 1.5 + 20.0, frames)
    }
}

fn aerial(bounds: &Aabb, height: f32, frames: usize) -> Vec<CameraKey> {
    let c = bounds.center();
    let r = bounds.extent().x.max(bounds.extent().z) * 0.3;
    let n = 96;
    let line = Polyline(
        (0..=n)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / n as f32;
                Vec3::new(c.x + r * a.cos(), bounds.min.y + height, c.z + r * a.sin())
            })
            .collect(),
    );
    let far = (bounds.extent().length() * 2.0).max(100.0);
    sample(&line, frames, r * 0.8, |eye, ahead| CameraKey {
        eye: eye.into(),
        target: [ahead.x, bounds.min.y, ahead.z],
        up: [0.0, 1.0, 0.0],
        fovy_deg: 60.0,
        near: 1.0,
        far,
    })
}

/// Paths for a scene that is not a built-in city, from its bounds: `street` comes in from
/// half the box's diagonal in front of it and crosses it at 5% of its height looking
/// horizontally (so the first frames see the whole scene, even a flat one); `aerial` circles
/// above it.
pub fn generic_path(bounds: &Aabb, street: bool, frames: usize) -> Result<Vec<CameraKey>> {
    placeable(bounds)?;
    let e = bounds.extent().max(Vec3::splat(1e-3));
    if !street {
        return Ok(aerial(bounds, e.y * 1.5 + e.length() * 0.2, frames));
    }
    let y = bounds.min.y + e.y * 0.05;
    let c = bounds.center();
    let start = bounds.min.z - (e.z * 0.1).max(e.length() * 0.5);
    let line = Polyline(vec![Vec3::new(c.x, y, start), Vec3::new(c.x, y, bounds.max.z)]);
    let far = e.length() * 2.0;
    Ok(sample(&line, frames, e.z * 0.1, |eye, target| looking_ahead(eye, target, far)))
}

/// One turn around any scene: the eye circles its center at the three-quarter view's height
/// (28° above the horizon) and at the distance where its bounding sphere fits a 60° view,
/// looking at the center, starting front-right.
pub fn orbit_path(bounds: &Aabb, frames: usize) -> Result<Vec<CameraKey>> {
    placeable(bounds)?;
    let c = bounds.center();
    let r = (bounds.extent().length() * 0.5).max(1e-3);
    let dist = r / 30f32.to_radians().sin() * 1.05;
    let elevation = 28f32.to_radians();
    let frames = frames.max(1);
    Ok((0..frames)
        .map(|i| {
            let azimuth = std::f32::consts::FRAC_PI_4 + std::f32::consts::TAU * i as f32 / frames as f32;
            let dir = Vec3::new(azimuth.sin() * elevation.cos(), elevation.sin(), azimuth.cos() * elevation.cos());
            CameraKey {
                eye: (c + dir * dist).into(),
                target: c.into(),
                up: [0.0, 1.0, 0.0],
                fovy_deg: 60.0,
                near: ((dist - r) * 0.9).max(dist * 1e-3),
                far: (dist + r) * 1.5,
            }
        })
        .collect())
}

/// A flight through any scene: in from outside its front-left corner, over its center at a
/// third of its height, and out past the back-right corner, looking ahead.
pub fn fly_path(bounds: &Aabb, frames: usize) -> Result<Vec<CameraKey>> {
    placeable(bounds)?;
    let (lo, e, c) = (bounds.min, bounds.extent().max(Vec3::splat(1e-3)), bounds.center());
    let y = lo.y + e.y / 3.0;
    let reach = e.length() * 0.5;
    let line = Polyline(vec![
        Vec3::new(lo.x - reach * 0.5, y + e.y * 0.5, bounds.max.z + reach),
        Vec3::new(c.x, y, c.z),
        Vec3::new(bounds.max.x + reach * 0.5, y + e.y * 0.5, lo.z - reach),
    ]);
    let far = e.length() * 3.0;
    Ok(sample(&line, frames, e.length() * 0.05, |eye, target| looking_ahead(eye, target, far)))
}

/// A key of a path through a scene of any size: 60° view, +y up, near plane a 10^-5 of the
/// far one (at least 10^-3).
fn looking_ahead(eye: Vec3, target: Vec3, far: f32) -> CameraKey {
    CameraKey {
        eye: eye.into(),
        target: target.into(),
        up: [0.0, 1.0, 0.0],
        fovy_deg: 60.0,
        near: (far * 1e-5).max(1e-3),
        far,
    }
}

/// Scene bounds a camera can be placed around: not empty, finite, and small enough for the
/// path's arithmetic in f32.
fn placeable(bounds: &Aabb) -> Result<()> {
    let (lo, hi) = (bounds.min, bounds.max);
    let (finite, nan) = (lo.is_finite() && hi.is_finite(), lo.is_nan() || hi.is_nan());
    if !finite && !nan && !bounds.is_empty() {
        return Err(Error::InvalidParams(format!(
            "scene bounds are not finite (min {lo}, max {hi}): a coordinate or transform overflowed f32"
        )));
    }
    if !bounds.is_finite() {
        return Err(Error::InvalidParams("cannot make a camera path for an empty scene".into()));
    }
    // The camera is placed from the extent and its length: both must stay finite with room
    // for the path's arithmetic.
    if !(bounds.extent().length() < 1e30 && bounds.center().is_finite()) {
        return Err(Error::InvalidParams(format!(
            "scene bounds (min {lo}, max {hi}) are too large to place a camera in f32; scale the scene down"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The orbit keeps the whole bounding sphere inside a 60° cone around its line of sight
    /// on every frame and goes once around; the flight passes over the center.
    #[test]
    fn orbit_sees_the_whole_scene_and_fly_crosses_it() {
        let b = Aabb::new(Vec3::new(-3.0, 0.0, -1.0), Vec3::new(5.0, 2.0, 9.0));
        let (c, r) = (b.center(), b.extent().length() * 0.5);
        let keys = orbit_path(&b, 16).unwrap();
        assert_eq!(keys.len(), 16);
        for k in &keys {
            let eye = Vec3::from(k.eye);
            let d = (eye - c).length();
            assert!((r / d).asin() <= 30f32.to_radians(), "the sphere fits the view");
            assert!(k.near < d - r && k.far > d + r, "near and far enclose the scene");
            assert_eq!(Vec3::from(k.target), c);
        }
        let first = Vec3::from(keys[0].eye) - c;
        let half = Vec3::from(keys[8].eye) - c;
        assert!((first.x + half.x).abs() < 1e-3 && (first.z + half.z).abs() < 1e-3, "half a turn apart");
        let fly = fly_path(&b, 21).unwrap();
        let mid = Vec3::from(fly[10].eye);
        assert!((mid.x - c.x).abs() < 1.0 && (mid.z - c.z).abs() < 1.0, "over the center half way: {mid}");
        assert!(orbit_path(&Aabb::EMPTY, 4).is_err() && fly_path(&Aabb::EMPTY, 4).is_err());
    }

    /// A key that places no camera is refused when the path is read, naming the file and
    /// the frame; near and far, which a program may replace, are left to each frame.
    #[test]
    fn a_bad_key_is_named_by_its_frame() {
        let key = |target_z: f32, near: &str| {
            format!(r#"{{"eye":[0,1,5],"target":[0,1,{target_z}],"up":[0,1,0],"fovy_deg":60,"near":{near},"far":100}}"#)
        };
        let read = |keys: &[String]| parse_path(format!("[{}]", keys.join(",")).as_bytes(), Path::new("p.json"));
        assert_eq!(read(&[key(0.0, "0.1"), key(0.0, "0")]).unwrap().len(), 2, "near = 0 is left to the frame");
        let e = read(&[key(0.0, "0.1"), key(0.0, "0.1"), key(5.0, "0.1")]).unwrap_err().to_string();
        assert!(e.contains("p.json") && e.contains("frame 2"), "the eye on the target: {e}");
        let e = read(&[key(0.0, "1e39")]).unwrap_err().to_string();
        assert!(e.contains("frame 0") && e.contains("not finite"), "{e}");
    }

    #[test]
    fn huge_or_overflowed_bounds_are_named_as_the_cause() {
        let huge = Aabb::new(Vec3::splat(-3e38), Vec3::splat(3e38));
        let e = generic_path(&huge, true, 4).unwrap_err().to_string();
        assert!(e.contains("too large"), "{e}");
        let overflowed = Aabb::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(f32::INFINITY, 1.0, 1.0));
        let e = generic_path(&overflowed, true, 4).unwrap_err().to_string();
        assert!(e.contains("not finite"), "{e}");
        let e = generic_path(&Aabb::EMPTY, true, 4).unwrap_err().to_string();
        assert!(e.contains("empty scene"), "{e}");
    }
    use crate::builders::{city, CityParams};

    /// A scene's generic street walk starts outside it and sees it, even a flat one.
    #[test]
    fn generic_street_walk_starts_in_front_of_the_scene() {
        let flat = Aabb::new(Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 0.0));
        let keys = generic_path(&flat, true, 10).unwrap();
        let first = Vec3::from(keys[0].eye);
        assert!(first.z < -1.0, "{first}");
        assert!(Vec3::from(keys[0].target).z > first.z, "looks towards the scene");
    }

    #[test]
    fn street_walk_stays_on_streets_and_looks_horizontally() {
        let c = city(&CityParams::for_triangles(100_000)).unwrap();
        let keys = c.layout.street_path(200, 7);
        assert_eq!(keys.len(), 200);
        let buildings: Vec<Aabb> = c.scene.instances().iter().map(|i| i.world_aabb).filter(|b| b.max.y > 0.0).collect();
        for k in &keys {
            let eye = Vec3::from(k.eye);
            assert_eq!(k.eye[1], EYE_HEIGHT);
            assert_eq!(k.target[1], EYE_HEIGHT, "street cameras look exactly horizontally");
            assert!(buildings.iter().all(|b| !b.contains_point(eye)), "eye {eye} inside a building");
            k.camera(16.0 / 9.0).unwrap();
        }
    }

    #[test]
    fn json_round_trip() {
        let c = city(&CityParams::for_triangles(10_000)).unwrap();
        let keys = c.layout.aerial_path(5);
        let dir = std::env::temp_dir().join(format!("sightline-path-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("aerial.json");
        write_path(&f, &keys).unwrap();
        assert_eq!(read_path(&f).unwrap(), keys);
        std::fs::write(&f, "[{\"eye\": 1}]").unwrap();
        let e = read_path(&f).unwrap_err().to_string();
        assert!(e.contains("aerial.json") && e.contains("camera path"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
