//! The stereo rig: parallel (sensor-shift) cameras offset along the head pose's
//! right vector.
//!
//! Both eyes share orientation and projection and sit at `±separation / 2` along the head
//! pose's right vector (no toe-in). A separation of 0 gives a mono pair. Each eye's camera
//! is a validated [`CameraModel`] for the frame extent; the renderer's primary rays come
//! from that same model (`centre + t · ray(px, py)` with rays of unit view depth), so the
//! G-buffer depth *is* the hit distance `t` and the compact G-buffer's rebuilt positions
//! equal the stored ones bit for bit.

use std::fmt;

pub use crate::kernels::camera::{CameraPose, FAR, NEAR};
use crate::kernels::{CameraModel, Extent, FrameError};

/// Default distance between the eyes (metres), the average human interpupillary distance.
pub const DEFAULT_EYE_SEPARATION: f32 = 0.065;

/// Which eye.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Eye {
    /// The left eye (index 0): filled by stereo reprojection in the stereo modes.
    Left = 0,
    /// The right eye (index 1): always path traced.
    Right = 1,
}

impl Eye {
    /// Both eyes in index order.
    pub const BOTH: [Eye; 2] = [Eye::Left, Eye::Right];

    /// The other eye.
    pub fn other(self) -> Eye {
        match self {
            Eye::Left => Eye::Right,
            Eye::Right => Eye::Left,
        }
    }

    /// `-1` for the left eye, `+1` for the right (the sign of the offset along `right`).
    pub fn sign(self) -> f32 {
        match self {
            Eye::Left => -1.0,
            Eye::Right => 1.0,
        }
    }

    /// A lower-case name for tables and file names.
    pub fn name(self) -> &'static str {
        match self {
            Eye::Left => "left",
            Eye::Right => "right",
        }
    }
}

impl fmt::Display for Eye {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A parallel stereo rig.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoRig {
    /// Distance between the eyes in scene units (metres).
    pub separation: f32,
}

impl Default for StereoRig {
    fn default() -> Self {
        Self { separation: DEFAULT_EYE_SEPARATION }
    }
}

/// The widest eye separation a rig accepts, in metres (10 km: wider eyes stand outside any
/// scene here, and at 10⁶ m and beyond f32 eye positions no longer resolve the scene).
pub const MAX_EYE_SEPARATION: f32 = 1e4;

impl StereoRig {
    /// A rig with the given separation; refuses negative, non-finite and larger than
    /// [`MAX_EYE_SEPARATION`] values.
    pub fn new(separation: f32) -> Result<Self, String> {
        if !(0.0..=MAX_EYE_SEPARATION).contains(&separation) {
            return Err(format!("eye separation must be in 0..={MAX_EYE_SEPARATION} m, got {separation}"));
        }
        Ok(Self { separation })
    }

    /// The pose of `eye` for the head pose `head`.
    pub fn eye_pose(&self, head: &CameraPose, eye: Eye) -> CameraPose {
        head.stereo_eye(eye.sign(), self.separation)
    }

    /// The camera of `eye` for `head` at `extent`.
    pub fn eye_camera(&self, head: &CameraPose, eye: Eye, extent: Extent) -> Result<CameraModel, FrameError> {
        CameraModel::from_pose(&self.eye_pose(head, eye), extent)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn head() -> CameraPose {
        CameraPose { eye: Vec3::new(1.0, 1.6, 2.0), forward: -Vec3::Z, up: Vec3::Y, right: Vec3::X, vfov_deg: 60.0 }
    }

    #[test]
    fn eyes_are_offset_along_right_by_half_the_separation() {
        let rig = StereoRig::default();
        let l = rig.eye_pose(&head(), Eye::Left);
        let r = rig.eye_pose(&head(), Eye::Right);
        assert!(((r.eye - l.eye) - Vec3::X * DEFAULT_EYE_SEPARATION).length() < 1e-6);
        assert_eq!(l.forward, r.forward);
        let mono = StereoRig::new(0.0).unwrap();
        assert_eq!(mono.eye_pose(&head(), Eye::Left).eye, mono.eye_pose(&head(), Eye::Right).eye);
        assert!(StereoRig::new(-1.0).is_err());
        assert!(StereoRig::new(f32::NAN).is_err());
    }

    #[test]
    fn camera_centre_is_the_eye() {
        let e = Extent::new(64, 36).unwrap();
        let cam = StereoRig::default().eye_camera(&head(), Eye::Right, e).unwrap();
        assert!((Vec3::from(cam.centre) - (head().eye + Vec3::X * 0.0325)).length() < 1e-4);
    }
}
