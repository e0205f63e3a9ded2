//! Camera poses and the stereo rig: parallel (sensor-shift) cameras offset along the head's
//! right vector.
//!
//! Both eyes share orientation and projection and sit at `±separation / 2` along the head
//! pose's right vector (no toe-in). A separation of 0 gives a mono pair. Each eye's camera
//! is a validated [`CameraModel`] for the frame extent; the renderer's primary rays come
//! from that same model (`centre + t · ray(px, py)` with rays of unit view depth), so the
//! G-buffer depth *is* the hit distance `t` and the compact G-buffer's rebuilt positions
//! equal the stored ones bit for bit.

use std::fmt;

use glam::{DMat4, DVec4, Mat4, Vec3};

use crate::kernels::{CameraModel, Extent, FrameError};

/// The camera of one frame: an orthonormal frame and the vertical field of view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraPose {
    /// Eye position (centre of the stereo rig).
    pub eye: Vec3,
    /// Unit view direction.
    pub forward: Vec3,
    /// Unit up, orthogonal to `forward`.
    pub up: Vec3,
    /// Unit right, `forward x up`.
    pub right: Vec3,
    /// Vertical field of view in degrees.
    pub vfov_deg: f32,
}

impl CameraPose {
    /// Right-handed view matrix (camera looks down −Z in view space).
    pub fn view(&self) -> Mat4 {
        glam::camera::rh::view::look_to_mat4(self.eye, self.forward, self.up)
    }

    /// Right-handed OpenGL-style perspective × view (clip `w` = view depth), in f64 (see
    /// `stereotrace_kernels::CameraModel::from_f64`): the view's rows are this pose's
    /// `right`, `up` and `−forward` with the translation `−R·eye` formed in f64.
    pub fn view_proj(&self, aspect: f32, near: f32, far: f32) -> DMat4 {
        let (r, u, f, e) = (self.right.as_dvec3(), self.up.as_dvec3(), self.forward.as_dvec3(), self.eye.as_dvec3());
        let view = DMat4::from_cols(
            DVec4::new(r.x, u.x, -f.x, 0.0),
            DVec4::new(r.y, u.y, -f.y, 0.0),
            DVec4::new(r.z, u.z, -f.z, 0.0),
            DVec4::new(-r.dot(e), -u.dot(e), f.dot(e), 1.0),
        );
        let focal = 1.0 / (0.5 * f64::from(self.vfov_deg).to_radians()).tan();
        let (near, far) = (f64::from(near), f64::from(far));
        let proj = DMat4::from_cols(
            DVec4::new(focal / f64::from(aspect), 0.0, 0.0, 0.0),
            DVec4::new(0.0, focal, 0.0, 0.0),
            DVec4::new(0.0, 0.0, (far + near) / (near - far), -1.0),
            DVec4::new(0.0, 0.0, 2.0 * far * near / (near - far), 0.0),
        );
        proj * view
    }

    /// The same pose moved by `offset` along `right` (a stereo eye: ±half the separation).
    pub fn offset_right(&self, offset: f32) -> Self {
        Self { eye: self.eye + self.right * offset, ..*self }
    }
}

/// Default distance between the eyes (metres), the average human interpupillary distance.
pub const DEFAULT_EYE_SEPARATION: f32 = 0.065;

/// Near and far planes of the projection. Only the x, y and w rows matter to the kernels,
/// so these only need to bracket nothing in particular; they are kept wide.
pub const NEAR: f32 = 0.01;
/// The far plane (see [`NEAR`]).
pub const FAR: f32 = 10_000.0;

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
        head.offset_right(eye.sign() * 0.5 * self.separation)
    }

    /// The camera of `eye` for `head` at `extent`.
    pub fn eye_camera(&self, head: &CameraPose, eye: Eye, extent: Extent) -> Result<CameraModel, FrameError> {
        camera_for(&self.eye_pose(head, eye), extent)
    }
}

/// The kernel camera of a pose at an extent.
pub fn camera_for(pose: &CameraPose, extent: Extent) -> Result<CameraModel, FrameError> {
    let aspect = extent.width() as f32 / extent.height() as f32;
    CameraModel::from_f64(pose.view_proj(aspect, NEAR, FAR), extent)
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
