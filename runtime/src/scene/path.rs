//! Smooth keyframed paths: the moving observer's camera path and moving lights' transforms.
//!
//! Keys carry a (fractional) frame number and are interpolated with a cubic Hermite spline
//! whose tangents are Catmull-Rom finite differences over the key times (non-uniform
//! Catmull-Rom), so the path passes through every key, is C¹ (no velocity jumps, hence no
//! jumps between frames) and needs no extra control points. Before the first key and after
//! the last the path holds still.
//!
//! A camera path evaluates to a [`CameraPose`]: an orthonormal frame (the eye, a unit forward
//! vector, up and right) plus the vertical field of view. The stereo rig offsets both eyes
//! along `right`; it does not need anything else from the scene.

use glam::{Affine3A, Quat, Vec3};

pub use crate::camera::CameraPose;
use serde::{Deserialize, Serialize};

/// Default number of frames of a scene's camera path (the paper renders 60).
pub const DEFAULT_FRAMES: u32 = 60;

/// The most frames a camera path may have (every pose is computed when asked for all of them,
/// so a count of billions would allocate hundreds of gigabytes).
pub const MAX_FRAMES: u32 = 100_000;

/// The narrowest vertical field of view accepted, in degrees: narrower views make a camera
/// whose pixels are smaller than f32 resolves at scene scale.
pub const MIN_VFOV_DEG: f32 = 1e-3;

/// Evaluates the Catmull-Rom/Hermite spline through `(times[i], values[i])` at `t`.
/// `times` must be strictly increasing; an empty slice gives zero, one key a constant.
pub fn spline<const N: usize>(times: &[f32], values: &[[f32; N]], t: f32) -> [f32; N] {
    let n = times.len().min(values.len());
    spline_by(&times[..n], |&k| k, |i| values[i], t)
}

/// [`spline`] over keys read through accessors (`time(&key)`, `value(index)`), so paths
/// evaluate their keys in place: the real-time runtime asks for a pose every frame and must
/// not allocate.
fn spline_by<K, const N: usize>(
    keys: &[K],
    time: impl Fn(&K) -> f32,
    value: impl Fn(usize) -> [f32; N],
    t: f32,
) -> [f32; N] {
    let n = keys.len();
    if n == 0 {
        return [0.0; N];
    }
    let at = |i: usize| time(&keys[i]);
    if n == 1 || !(t > at(0)) {
        return value(0);
    }
    if t >= at(n - 1) {
        return value(n - 1);
    }
    let i = keys.partition_point(|k| time(k) <= t).saturating_sub(1).min(n - 2);
    let (t0, t1) = (at(i), at(i + 1));
    let h = t1 - t0;
    let s = (t - t0) / h;
    let tangent = |k: usize| -> [f32; N] {
        let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
        let dt = at(b) - at(a);
        let (va, vb) = (value(a), value(b));
        let mut m = [0.0; N];
        for (c, mc) in m.iter_mut().enumerate() {
            *mc = (vb[c] - va[c]) / dt;
        }
        m
    };
    let (m0, m1) = (tangent(i), tangent(i + 1));
    let (v0, v1) = (value(i), value(i + 1));
    let (s2, s3) = (s * s, s * s * s);
    let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
    let h10 = s3 - 2.0 * s2 + s;
    let h01 = -2.0 * s3 + 3.0 * s2;
    let h11 = s3 - s2;
    let mut out = [0.0; N];
    for (c, o) in out.iter_mut().enumerate() {
        *o = h00 * v0[c] + h10 * h * m0[c] + h01 * v1[c] + h11 * h * m1[c];
    }
    out
}

fn check_times(times: impl Iterator<Item = f32>) -> Result<(), String> {
    let mut prev = f32::NEG_INFINITY;
    let mut any = false;
    for t in times {
        any = true;
        if !t.is_finite() {
            return Err(format!("key frame {t} is not finite"));
        }
        if t <= prev {
            return Err(format!("key frames must increase strictly ({prev} then {t})"));
        }
        prev = t;
    }
    if any { Ok(()) } else { Err("a path needs at least one key".into()) }
}

/// One camera keyframe.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraKey {
    /// Frame number this key is reached at (may be fractional).
    pub frame: f32,
    /// Eye position (scene units).
    pub eye: [f32; 3],
    /// Point looked at.
    pub target: [f32; 3],
    /// Up hint (re-orthonormalised against the view direction; need not be unit).
    #[serde(default = "default_up")]
    pub up: [f32; 3],
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// A smooth camera path over a fixed number of frames.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPath {
    /// Keys, strictly increasing in `frame`.
    pub keys: Vec<CameraKey>,
    /// Number of frames rendered (frames `0..frames`).
    pub frames: u32,
    /// Vertical field of view in degrees, for every frame.
    pub vfov_deg: f32,
}

impl CameraPath {
    /// A path through `keys` (sorted by frame here).
    pub fn new(mut keys: Vec<CameraKey>, frames: u32, vfov_deg: f32) -> Result<Self, String> {
        keys.sort_by(|a, b| a.frame.total_cmp(&b.frame));
        let path = Self { keys, frames, vfov_deg };
        path.validate()?;
        Ok(path)
    }

    /// A still camera.
    pub fn fixed(eye: Vec3, target: Vec3, up: Vec3, frames: u32, vfov_deg: f32) -> Self {
        let key = CameraKey { frame: 0.0, eye: eye.into(), target: target.into(), up: up.into() };
        Self { keys: vec![key], frames, vfov_deg }
    }

    /// Checks keys (finite, increasing, eye ≠ target, up not parallel to the view), the
    /// frame count and the field of view.
    pub fn validate(&self) -> Result<(), String> {
        check_times(self.keys.iter().map(|k| k.frame))?;
        if self.frames == 0 || self.frames > MAX_FRAMES {
            return Err(format!("a camera path has 1..={MAX_FRAMES} frames, not {}", self.frames));
        }
        if !(self.vfov_deg >= MIN_VFOV_DEG && self.vfov_deg < 179.0) {
            return Err(format!("vertical field of view {} deg is outside [{MIN_VFOV_DEG}, 179)", self.vfov_deg));
        }
        for k in &self.keys {
            let (e, t, u) = (Vec3::from(k.eye), Vec3::from(k.target), Vec3::from(k.up));
            if !(e.is_finite() && t.is_finite() && u.is_finite()) {
                return Err(format!("camera key at frame {} is not finite", k.frame));
            }
            let f = (t - e).try_normalize().ok_or(format!("camera key at frame {}: eye == target", k.frame))?;
            if f.cross(u).length() < 1e-3 {
                return Err(format!("camera key at frame {}: up is parallel to the view direction", k.frame));
            }
        }
        Ok(())
    }

    /// The pose at (possibly fractional) frame `frame`.
    pub fn pose_at(&self, frame: f32) -> CameraPose {
        let keys = &self.keys;
        let time = |k: &CameraKey| k.frame;
        let eye = Vec3::from(spline_by(keys, time, |i| keys[i].eye, frame));
        let target = Vec3::from(spline_by(keys, time, |i| keys[i].target, frame));
        let up_hint = Vec3::from(spline_by(keys, time, |i| keys[i].up, frame));
        let forward = (target - eye).try_normalize().unwrap_or(Vec3::NEG_Z);
        let right = forward.cross(up_hint).try_normalize().unwrap_or_else(|| forward.any_orthonormal_vector());
        let up = right.cross(forward);
        CameraPose { eye, forward, up, right, vfov_deg: self.vfov_deg }
    }

    /// The pose of frame `frame` (`0..frames`).
    pub fn pose(&self, frame: u32) -> CameraPose {
        self.pose_at(frame as f32)
    }

    /// The pose of the `i`-th frame of a walk forward and back along the path (frames
    /// `0, 1, …, n−1, n−2, …, 1, 0, 1, …`), so any number of frames stays on it and the
    /// camera keeps moving: what the real-time driver and the C ABI render.
    pub fn pose_back_and_forth(&self, i: u32) -> CameraPose {
        let n = self.frames.max(2);
        let period = 2 * (n - 1);
        let k = i % period;
        self.pose(if k < n { k } else { period - k })
    }

    /// Every frame's pose.
    pub fn poses(&self) -> Vec<CameraPose> {
        (0..self.frames).map(|f| self.pose(f)).collect()
    }

    /// Total eye travel over the frames (sum of per-frame steps).
    pub fn travel(&self) -> f32 {
        let p = self.poses();
        p.windows(2).map(|w| (w[1].eye - w[0].eye).length()).sum()
    }
}

/// One key of a rigid transform path (moving lights).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TransformKey {
    /// Frame number (may be fractional).
    pub frame: f32,
    /// Translation (scene units).
    pub translation: [f32; 3],
    /// Rotation about +Y in degrees (applied before the translation).
    #[serde(default)]
    pub yaw_deg: f32,
}

/// A smooth rigid-transform path: Catmull-Rom translation, Catmull-Rom yaw.
#[derive(Clone, Debug, PartialEq)]
pub struct TransformPath {
    /// Keys, strictly increasing in `frame`.
    pub keys: Vec<TransformKey>,
}

impl TransformPath {
    /// A path through `keys` (sorted here).
    pub fn new(mut keys: Vec<TransformKey>) -> Result<Self, String> {
        keys.sort_by(|a, b| a.frame.total_cmp(&b.frame));
        let p = Self { keys };
        p.validate()?;
        Ok(p)
    }

    /// Keys finite and increasing.
    pub fn validate(&self) -> Result<(), String> {
        check_times(self.keys.iter().map(|k| k.frame))?;
        for k in &self.keys {
            if !(Vec3::from(k.translation).is_finite() && k.yaw_deg.is_finite()) {
                return Err(format!("transform key at frame {} is not finite", k.frame));
            }
        }
        Ok(())
    }

    /// Translation and yaw (degrees) at `frame`.
    pub fn at(&self, frame: f32) -> (Vec3, f32) {
        let keys = &self.keys;
        let time = |k: &TransformKey| k.frame;
        let translation = spline_by(keys, time, |i| keys[i].translation, frame);
        let yaw = spline_by(keys, time, |i| [keys[i].yaw_deg], frame);
        (Vec3::from(translation), yaw[0])
    }

    /// The local-to-world transform at `frame`.
    pub fn transform(&self, frame: f32) -> Affine3A {
        let (t, yaw) = self.at(frame);
        Affine3A::from_rotation_translation(Quat::from_rotation_y(yaw.to_radians()), t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spline_passes_through_keys_and_is_smooth() {
        let times = [0.0, 10.0, 25.0, 59.0];
        let vals = [[0.0f32], [1.0], [1.5], [3.0]];
        for (t, v) in times.iter().zip(vals) {
            assert!((spline(&times, &vals, *t)[0] - v[0]).abs() < 1e-5);
        }
        // Velocity has no jumps: second differences are small everywhere.
        let f = |t: f32| spline(&times, &vals, t)[0];
        let mut worst = 0.0f32;
        for k in 1..590 {
            let t = k as f32 * 0.1;
            worst = worst.max((f(t + 0.1) - 2.0 * f(t) + f(t - 0.1)).abs());
        }
        assert!(worst < 1e-3, "{worst}");
        assert_eq!(spline(&times, &vals, -5.0), [0.0]);
        assert_eq!(spline(&times, &vals, 100.0), [3.0]);
        assert_eq!(spline(&times, &vals, f32::NAN), [0.0]);
        assert_eq!(spline::<1>(&[], &[], 1.0), [0.0]);
    }

    #[test]
    fn poses_are_orthonormal() {
        let keys = vec![
            CameraKey { frame: 0.0, eye: [0.0, 1.6, 0.0], target: [0.0, 1.5, -5.0], up: [0.0, 1.0, 0.0] },
            CameraKey { frame: 59.0, eye: [0.5, 1.6, -0.3], target: [1.0, 1.5, -5.0], up: [0.0, 1.0, 0.0] },
        ];
        let p = CameraPath::new(keys, 60, 60.0).unwrap();
        for pose in p.poses() {
            assert!((pose.forward.length() - 1.0).abs() < 1e-5);
            assert!(pose.forward.dot(pose.up).abs() < 1e-5 && pose.forward.dot(pose.right).abs() < 1e-5);
            assert!(pose.right.cross(pose.up).dot(-pose.forward) > 0.999, "right-handed");
            assert!(pose.up.y > 0.9, "no roll");
        }
        assert!((p.travel() - Vec3::new(0.5, 0.0, -0.3).length()).abs() < 0.05);
        // The eye projects to the view-space origin.
        let v = p.pose(0).view();
        assert!(v.transform_point3(Vec3::new(0.0, 1.6, 0.0)).length() < 1e-5);
    }

    #[test]
    fn bad_paths_are_refused() {
        let k = CameraKey { frame: 0.0, eye: [0.0; 3], target: [0.0; 3], up: [0.0, 1.0, 0.0] };
        assert!(CameraPath::new(vec![k], 60, 60.0).is_err(), "eye == target");
        let k2 = CameraKey { target: [0.0, 5.0, 0.0], ..k };
        assert!(CameraPath::new(vec![k2], 60, 60.0).is_err(), "up parallel");
        let k3 = CameraKey { target: [0.0, 0.0, -1.0], ..k };
        assert!(CameraPath::new(vec![k3, k3], 60, 60.0).is_err(), "duplicate frames");
        assert!(CameraPath::new(vec![], 60, 60.0).is_err());
        assert!(CameraPath::new(vec![k3], 0, 60.0).is_err());
        assert!(CameraPath::new(vec![k3], 60, f32::NAN).is_err());
        let nan = CameraKey { eye: [f32::NAN, 0.0, 0.0], ..k3 };
        assert!(CameraPath::new(vec![nan], 60, 60.0).is_err());
    }

    #[test]
    fn transform_path_rotates_then_translates() {
        let p = TransformPath::new(vec![
            TransformKey { frame: 0.0, translation: [0.0, 2.0, 0.0], yaw_deg: 0.0 },
            TransformKey { frame: 10.0, translation: [4.0, 2.0, 0.0], yaw_deg: 90.0 },
        ])
        .unwrap();
        let m = p.transform(10.0);
        let x = m.transform_point3(Vec3::X);
        assert!((x - Vec3::new(4.0, 2.0, -1.0)).length() < 1e-5, "{x}");
        assert!(TransformPath::new(vec![]).is_err());
    }
}
