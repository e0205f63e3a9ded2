//! The camera as the kernels see it: a validated view-projection matrix for one extent, and
//! the pose (an orthonormal frame and a field of view) it is usually built from.
//!
//! Convention: `clip = M · [X, 1]` with the clip `w` equal to the distance of `X` along the
//! camera's view axis (what `glam::Mat4::perspective_rh` / `_lh` times a view matrix gives).
//! Normalised device coordinates run from −1 (left, bottom) to +1 (right, top); pixel
//! `(i, j)` has its centre at `(i + 0.5, j + 0.5)` with `j` counting rows from the top.
//!
//! From the same matrix the model also derives the ray through every pixel centre scaled to
//! unit view depth, so a world position can be rebuilt from a depth value
//! (`X = centre + depth · ray(x, y)`); the compact G-buffer layout relies on that.

use glam::{DMat3, DMat4, DVec3, DVec4, Mat4, Vec3};

use crate::frame::{Extent, FrameError};

/// A validated perspective camera for one frame extent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraModel {
    /// Rows of the view-projection matrix (row `i` dotted with `[X, 1]` gives clip component `i`).
    pub rows: [[f32; 4]; 4],
    /// Camera centre in world space.
    pub centre: [f32; 3],
    /// Ray at pixel coordinate (0, 0) (the top-left image corner), at unit view depth.
    pub ray_origin_corner: [f32; 3],
    /// Change of the unit-depth ray per pixel to the right.
    pub ray_dx: [f32; 3],
    /// Change of the unit-depth ray per pixel down.
    pub ray_dy: [f32; 3],
    /// The frame extent the pixel mapping refers to.
    pub extent: Extent,
}

/// Refuses ([`FrameError::InvalidParameter`]) a sub-pixel jitter offset (in pixels) that is
/// not finite or exceeds one pixel on either axis: the one rule for every jitter the crate
/// takes ([`CameraModel::jittered`], `reproject::Jitter`).
pub fn check_jitter(jitter: [f32; 2]) -> Result<(), FrameError> {
    if jitter.iter().all(|j| j.abs() <= 1.0) {
        Ok(())
    } else {
        Err(FrameError::InvalidParameter("jitter offsets must be finite and within one pixel"))
    }
}

impl CameraModel {
    /// Validates `view_proj` for frames of `extent`.
    ///
    /// Refuses ([`FrameError::SingularCamera`]) matrices that are not finite or are singular,
    /// and matrices whose x, y and w rows do not define a pinhole (needed to rebuild positions
    /// from depth), such as orthographic projections.
    pub fn new(view_proj: Mat4, extent: Extent) -> Result<Self, FrameError> {
        Self::from_f64(view_proj.as_dmat4(), extent)
    }

    /// [`CameraModel::new`] from a double-precision matrix. The centre and the pixel rays are
    /// derived in f64 and rounded once, so a camera far from the origin keeps its exact
    /// position: an f32 view matrix stores `−R·eye` rounded, which 10⁵ units away moves the
    /// recovered centre by millimetres and shifts the image.
    pub fn from_f64(view_proj: DMat4, extent: Extent) -> Result<Self, FrameError> {
        let m = view_proj;
        if !m.is_finite() {
            return Err(FrameError::SingularCamera);
        }
        let det = m.determinant();
        if !det.is_finite() || det == 0.0 {
            return Err(FrameError::SingularCamera);
        }
        let row = |i: usize| m.row(i);
        let (r0, r1, r3) = (row(0), row(1), row(3));
        // Rows x, y and w restricted to xyz: A · X = (x_clip, y_clip, w) − translation.
        let a =
            DMat3::from_cols(DVec3::new(r0.x, r1.x, r3.x), DVec3::new(r0.y, r1.y, r3.y), DVec3::new(r0.z, r1.z, r3.z));
        let det_a = a.determinant();
        // Relative test: a pinhole's A is well conditioned; an orthographic one has a zero row.
        let scale = a.x_axis.length() * a.y_axis.length() * a.z_axis.length();
        if !det_a.is_finite() || det_a.abs() <= 1e-12 * scale || scale == 0.0 {
            return Err(FrameError::SingularCamera);
        }
        let b = a.inverse();
        let centre = b * DVec3::new(-r0.w, -r1.w, -r3.w);
        // ray(nx, ny) = B · (nx, ny, 1): linear in the pixel coordinate.
        let (w, h) = (extent.width() as f64, extent.height() as f64);
        let corner = b * DVec3::new(-1.0, 1.0, 1.0);
        let dx = b * DVec3::new(2.0 / w, 0.0, 0.0);
        let dy = b * DVec3::new(0.0, -2.0 / h, 0.0);
        let to_f32 = |v: DVec3| [v.x as f32, v.y as f32, v.z as f32];
        let all = [centre, corner, dx, dy];
        if all.iter().any(|v| !v.is_finite()) {
            return Err(FrameError::SingularCamera);
        }
        let rows = [0, 1, 2, 3].map(|i| row(i).as_vec4().to_array());
        if rows.iter().flatten().any(|v| !v.is_finite()) {
            return Err(FrameError::SingularCamera);
        }
        Ok(Self {
            rows,
            centre: to_f32(centre),
            ray_origin_corner: to_f32(corner),
            ray_dx: to_f32(dx),
            ray_dy: to_f32(dy),
            extent,
        })
    }

    /// This camera with a sub-pixel jitter (TAA-style): pixel (x, y) of the jittered camera
    /// sees what (x + jitter.x, y + jitter.y) of this one sees, so every point projects
    /// `jitter` pixels up-left of where it did. A clip-space shear of the projection, in f64;
    /// the centre is this camera's (jitter does not move the eye). `[0, 0]` is this camera,
    /// bit for bit. Refuses ([`FrameError::InvalidParameter`]) an offset that is not finite or
    /// exceeds one pixel.
    pub fn jittered(&self, jitter: [f32; 2]) -> Result<Self, FrameError> {
        check_jitter(jitter)?;
        if jitter == [0.0; 2] {
            return Ok(*self);
        }
        let (hw, hh) = self.half_extent();
        let m = self.view_proj().as_dmat4().transpose();
        let (r0, r1, r3) = (m.x_axis, m.y_axis, m.w_axis);
        // s_x = (x/w)·hw + hw moves by −j.x where x gains −(j.x/hw)·w; s_y = −(y/w)·hh + hh
        // moves by −j.y where y gains +(j.y/hh)·w.
        let x = r0 - r3 * (f64::from(jitter[0]) / f64::from(hw));
        let y = r1 + r3 * (f64::from(jitter[1]) / f64::from(hh));
        let rows = DMat4::from_cols(x, y, m.z_axis, r3).transpose();
        Ok(Self { centre: self.centre, ..Self::from_f64(rows, self.extent)? })
    }

    /// The view-projection matrix.
    pub fn view_proj(&self) -> Mat4 {
        Mat4::from_cols_array_2d(&self.rows).transpose()
    }

    /// Clip coordinates of a world point, evaluated in the fixed order every kernel uses.
    #[inline(always)]
    pub fn clip(&self, p: [f32; 3]) -> [f32; 4] {
        let r = &self.rows;
        let dot = |i: usize| r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2] + r[i][3];
        [dot(0), dot(1), dot(2), dot(3)]
    }

    /// Continuous pixel coordinate of a world point (centres at `i + 0.5`) and its view
    /// depth; `None` behind the camera or for non-finite input.
    pub fn project(&self, p: [f32; 3]) -> Option<([f32; 2], f32)> {
        let [cx, cy, _, cw] = self.clip(p);
        if !(cw > 0.0) {
            return None;
        }
        let (hw, hh) = self.half_extent();
        let inv_w = 1.0 / cw;
        let s = [(cx * inv_w) * hw + hw, (-(cy * inv_w)) * hh + hh];
        (s[0].is_finite() && s[1].is_finite()).then_some((s, cw))
    }

    /// Half the width and height as f32 (the viewport scale).
    #[inline(always)]
    pub fn half_extent(&self) -> (f32, f32) {
        (self.extent.width() as f32 * 0.5, self.extent.height() as f32 * 0.5)
    }

    /// The unit-view-depth ray through continuous pixel coordinate `(px, py)`.
    #[inline(always)]
    pub fn ray(&self, px: f32, py: f32) -> [f32; 3] {
        let (o, dx, dy) = (self.ray_origin_corner, self.ray_dx, self.ray_dy);
        [0, 1, 2].map(|i| o[i] + px * dx[i] + py * dy[i])
    }

    /// World position of pixel `(x, y)`'s centre at view depth `depth`.
    #[inline(always)]
    pub fn unproject_pixel(&self, x: usize, y: usize, depth: f32) -> [f32; 3] {
        let r = self.ray(x as f32 + 0.5, y as f32 + 0.5);
        [0, 1, 2].map(|i| self.centre[i] + depth * r[i])
    }
}

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
    /// [`CameraModel::from_f64`]): the view's rows are this pose's
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

    /// An eye of a parallel stereo rig `separation` wide on this head pose: the left one for
    /// `side` −1, the right one for +1 (moved by `side · separation / 2` along `right`).
    pub fn stereo_eye(&self, side: f32, separation: f32) -> Self {
        self.offset_right(side * 0.5 * separation)
    }
}

/// Near and far planes of the projection. Only the x, y and w rows matter to the kernels,
/// so these only need to bracket nothing in particular; they are kept wide.
pub const NEAR: f32 = 0.01;
/// The far plane (see [`NEAR`]).
pub const FAR: f32 = 10_000.0;

impl CameraModel {
    /// The camera of `pose` for frames of `extent` (the projection's aspect is the extent's).
    pub fn from_pose(pose: &CameraPose, extent: Extent) -> Result<Self, FrameError> {
        let aspect = extent.width() as f32 / extent.height() as f32;
        Self::from_f64(pose.view_proj(aspect, NEAR, FAR), extent)
    }

    /// The left and right eyes' cameras of a parallel stereo rig `separation` wide on `head`
    /// ([`CameraPose::stereo_eye`]).
    pub fn stereo_pair(head: &CameraPose, separation: f32, extent: Extent) -> Result<[Self; 2], FrameError> {
        Ok([
            Self::from_pose(&head.stereo_eye(-1.0, separation), extent)?,
            Self::from_pose(&head.stereo_eye(1.0, separation), extent)?,
        ])
    }
}

/// A right-handed OpenGL-style perspective view-projection looking from `eye` towards
/// `target` (clip `w` = view depth), for tests, fuzzing and callers without a camera type of
/// their own.
pub fn look_at_perspective(eye: glam::Vec3, target: glam::Vec3, up: glam::Vec3, vfov_rad: f32, extent: Extent) -> Mat4 {
    let aspect = extent.width() as f32 / extent.height() as f32;
    glam::camera::rh::proj::opengl::perspective(vfov_rad, aspect, 0.01, 1000.0)
        * glam::camera::rh::view::look_at_mat4(eye, target, up)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn camera() -> CameraModel {
        let e = Extent::new(64, 48).unwrap();
        CameraModel::new(look_at_perspective(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.0, 0.5, -4.0), Vec3::Y, 1.0, e), e)
            .unwrap()
    }

    #[test]
    fn unproject_then_project_round_trips() {
        let cam = camera();
        for &(x, y, d) in &[(0usize, 0usize, 1.0f32), (63, 47, 7.5), (17, 30, 0.3), (40, 2, 120.0)] {
            let p = cam.unproject_pixel(x, y, d);
            let (s, w) = cam.project(p).unwrap();
            assert!((s[0] - (x as f32 + 0.5)).abs() < 2e-3, "{s:?}");
            assert!((s[1] - (y as f32 + 0.5)).abs() < 2e-3, "{s:?}");
            assert!((w - d).abs() <= 1e-4 * d, "{w} vs {d}");
        }
    }

    #[test]
    fn centre_projects_to_w_zero() {
        let cam = camera();
        let c = cam.clip(cam.centre);
        assert!(c[3].abs() < 1e-4, "{c:?}");
        assert!((Vec3::from(cam.centre) - Vec3::new(1.0, 2.0, 3.0)).length() < 1e-5);
    }

    #[test]
    fn singular_and_non_finite_cameras_are_refused() {
        let e = Extent::new(8, 8).unwrap();
        assert_eq!(CameraModel::new(Mat4::ZERO, e), Err(FrameError::SingularCamera));
        let mut nan = Mat4::IDENTITY;
        nan.x_axis.x = f32::NAN;
        assert_eq!(CameraModel::new(nan, e), Err(FrameError::SingularCamera));
        // Orthographic: invertible, but its w row has no xyz part, so no pinhole.
        let ortho = glam::camera::rh::proj::opengl::orthographic(-1.0, 1.0, -1.0, 1.0, 0.1, 10.0);
        assert_eq!(CameraModel::new(ortho, e), Err(FrameError::SingularCamera));
    }
}
