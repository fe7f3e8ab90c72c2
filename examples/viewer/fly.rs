//! The camera controller: first-person flying, and walking at eye height.
//!
//! The camera is kept as an eye and a target point, not as angles, so that the start camera
//! (given with `--eye/--target`, or a street-walk frame) is reproduced exactly, bit for bit,
//! until the first input. Looking turns the target about the eye: the gaze direction is
//! taken apart into yaw (about +y) and pitch, changed, and put back at the same distance;
//! pitch stays within ±86° so the gaze never lines up with the up vector. Moving shifts eye
//! and target together, by speed × elapsed time along the gaze (level in walk mode), its
//! right-hand side, and +y.

use glam::Vec3;

use crate::engine::Pose;

/// Held keys that move the camera.
#[derive(Debug, Default, Clone, Copy)]
pub struct Held {
    pub forward: bool,
    pub back: bool,
    pub left: bool,
    pub right: bool,
    pub down: bool,
    pub up: bool,
    pub turn_left: bool,
    pub turn_right: bool,
    pub turn_up: bool,
    pub turn_down: bool,
    pub fast: bool,
    pub slow: bool,
}

impl Held {
    /// True while some held key changes the camera.
    pub fn any(&self) -> bool {
        self.forward
            || self.back
            || self.left
            || self.right
            || self.down
            || self.up
            || self.turn_left
            || self.turn_right
            || self.turn_up
            || self.turn_down
    }
}

/// The flying (or walking) camera.
#[derive(Debug, Clone)]
pub struct Fly {
    pub pose: Pose,
    /// Where `R` goes back to.
    pub start: Pose,
    pub held: Held,
    /// Walk mode: the eye stays `eye_height` above `ground`.
    pub walk: bool,
    pub ground: f32,
    pub eye_height: f32,
    /// Scene units per second.
    pub speed: f32,
    /// Radians per pixel of mouse motion.
    pub mouse_turn: f32,
}

const MAX_PITCH: f32 = 1.5;
/// Radians per second when turning with the arrow keys.
const KEY_TURN: f32 = 1.6;

impl Fly {
    pub fn new(start: Pose, ground: f32, eye_height: f32, speed: f32) -> Self {
        Fly { pose: start, start, held: Held::default(), walk: false, ground, eye_height, speed, mouse_turn: 0.003 }
    }

    /// Back to the start camera.
    pub fn reset(&mut self) {
        self.pose = self.start;
        self.walk = false;
    }

    /// Turns the gaze by `yaw` radians (to the right) and `pitch` radians (up).
    pub fn turn(&mut self, yaw: f32, pitch: f32) {
        let d = self.pose.target - self.pose.eye;
        let len = d.length();
        if len.is_nan() || len <= 0.0 {
            return;
        }
        let y0 = d.x.atan2(-d.z);
        let p0 = (d.y / len).clamp(-1.0, 1.0).asin();
        let (y, p) = (y0 + yaw, (p0 + pitch).clamp(-MAX_PITCH, MAX_PITCH));
        let dir = Vec3::new(p.cos() * y.sin(), p.sin(), -p.cos() * y.cos());
        self.pose.target = self.pose.eye + dir * len;
    }

    /// Mouse motion of (dx, dy) pixels.
    pub fn look(&mut self, dx: f64, dy: f64) {
        self.turn(dx as f32 * self.mouse_turn, -dy as f32 * self.mouse_turn);
    }

    /// Walk mode on or off; on puts the eye at eye height and levels the gaze.
    pub fn toggle_walk(&mut self) {
        self.walk = !self.walk;
        if self.walk {
            let y = self.ground + self.eye_height;
            self.pose.eye.y = y;
            self.pose.target.y = y;
            if (self.pose.target - self.pose.eye).length() == 0.0 {
                self.pose.target = self.pose.eye - Vec3::Z;
            }
        }
    }

    /// Applies the held keys over `dt` seconds; true when the camera changed.
    pub fn update(&mut self, dt: f32) -> bool {
        if !self.held.any() {
            return false;
        }
        let h = self.held;
        let axis = |neg: bool, pos: bool| (pos as i32 - neg as i32) as f32;
        let turn = KEY_TURN * dt;
        if h.turn_left || h.turn_right || h.turn_up || h.turn_down {
            self.turn(axis(h.turn_left, h.turn_right) * turn, axis(h.turn_down, h.turn_up) * turn);
        }
        let mut speed = self.speed;
        if h.fast {
            speed *= 5.0;
        }
        if h.slow {
            speed *= 0.2;
        }
        let gaze = (self.pose.target - self.pose.eye).normalize_or_zero();
        let mut forward = gaze;
        if self.walk {
            forward = Vec3::new(gaze.x, 0.0, gaze.z).normalize_or_zero();
        }
        let right = forward.cross(Vec3::Y).normalize_or_zero();
        let mut step = forward * axis(h.back, h.forward) + right * axis(h.left, h.right);
        if !self.walk {
            step += Vec3::Y * axis(h.down, h.up);
        }
        let delta = step.normalize_or_zero() * speed * dt;
        self.pose.eye += delta;
        self.pose.target += delta;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose() -> Pose {
        Pose { eye: Vec3::new(0.0, 2.0, 0.0), target: Vec3::new(0.0, 2.0, -10.0), fov_deg: 60.0, near: 0.1, far: 100.0 }
    }

    #[test]
    fn moving_keeps_the_gaze_and_walking_stays_level() {
        let mut f = Fly::new(pose(), 0.0, 1.7, 10.0);
        assert!(!f.update(0.5), "no key held, no change");
        f.held.forward = true;
        assert!(f.update(0.5));
        assert!((f.pose.eye - Vec3::new(0.0, 2.0, -5.0)).length() < 1e-5, "{:?}", f.pose.eye);
        assert!((f.pose.target - f.pose.eye - Vec3::new(0.0, 0.0, -10.0)).length() < 1e-4);
        f.turn(0.0, 0.5); // look up, then walk: the eye keeps its height
        f.toggle_walk();
        assert_eq!(f.pose.eye.y, 1.7);
        f.update(1.0);
        assert!((f.pose.eye.y - 1.7).abs() < 1e-6);
        f.turn(std::f32::consts::FRAC_PI_2, 0.0); // turn right: now looking along +x
        let d = (f.pose.target - f.pose.eye).normalize();
        assert!((d - Vec3::X).length() < 1e-4, "{d:?}");
        f.turn(0.0, 10.0);
        let d = (f.pose.target - f.pose.eye).normalize();
        assert!(d.y < MAX_PITCH.sin() + 1e-4 && d.y > 0.99, "pitch is clamped: {d:?}");
        f.reset();
        assert_eq!(f.pose, pose());
    }
}
