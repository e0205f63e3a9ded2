//! One frame of the scene's camera path as the renderer sees it: the frame's lights (moving
//! lights and objects placed) and both eyes' cameras through a stereo rig. The one place
//! that setup is written; the CLI's `render`, the evaluation's references and curves, the
//! benches and the tests all start a frame here.

use crate::camera::{Eye, StereoRig};
use crate::kernels::{CameraModel, Extent, GBufferBuf, RgbBuf};
use crate::source::{PixelSelection, TraceRequest, TraceStats};

use super::lights::FrameLights;
use super::renderer::{RenderError, Renderer};

/// The lights and the eyes' cameras of one frame.
pub struct FrameView {
    /// Frame on the scene's camera path.
    pub frame: u32,
    /// The left and the right eye's cameras (index by `Eye as usize`); their extent is the
    /// images'.
    pub cameras: [CameraModel; 2],
    /// The scene's lights at that frame.
    pub lights: FrameLights,
}

impl FrameView {
    /// Frame `frame` of `renderer`'s scene seen through `rig` at `extent`. Refuses a frame
    /// whose pose gives no valid camera, naming the frame.
    pub fn new(renderer: &Renderer, rig: &StereoRig, extent: Extent, frame: u32) -> Result<Self, RenderError> {
        let cameras = eye_cameras(renderer, rig, extent, frame)?;
        Ok(Self { frame, cameras, lights: renderer.frame_lights(frame) })
    }

    /// Moves the view to `frame`, updating the lights in place (no allocation).
    pub fn set_frame(&mut self, renderer: &Renderer, rig: &StereoRig, frame: u32) -> Result<(), RenderError> {
        self.cameras = eye_cameras(renderer, rig, self.extent(), frame)?;
        self.lights.update(renderer.scene(), frame);
        self.frame = frame;
        Ok(())
    }

    /// The images' extent.
    pub fn extent(&self) -> Extent {
        self.cameras[0].extent
    }

    /// `eye`'s camera.
    pub fn camera(&self, eye: Eye) -> &CameraModel {
        &self.cameras[eye as usize]
    }

    /// The request for `spp` samples of `eye` in this frame, samples
    /// `first_sample..first_sample + spp` of the stream `seed`.
    pub fn request(&self, eye: Eye, spp: u32, seed: u64, first_sample: u32) -> TraceRequest {
        TraceRequest { eye, frame: self.frame, spp, seed, first_sample }
    }

    /// Path traces every pixel of `request.eye` into `out` ([`Renderer::trace`]). Refuses a
    /// request for another frame.
    pub fn trace(
        &self,
        renderer: &Renderer,
        request: &TraceRequest,
        out: &mut RgbBuf,
        general: bool,
    ) -> Result<TraceStats, RenderError> {
        if request.frame != self.frame {
            return Err(RenderError::Invalid(format!(
                "a request for frame {} traced in the view of frame {}",
                request.frame, self.frame
            )));
        }
        renderer.trace(&self.lights, self.camera(request.eye), request, PixelSelection::All, out, general)
    }

    /// [`FrameView::trace`] into a new image.
    pub fn render(
        &self,
        renderer: &Renderer,
        request: &TraceRequest,
        general: bool,
    ) -> Result<(RgbBuf, TraceStats), RenderError> {
        let mut image = RgbBuf::new(self.extent(), 0.0);
        let stats = self.trace(renderer, request, &mut image, general)?;
        Ok((image, stats))
    }

    /// `eye`'s traced G-buffer ([`Renderer::render_gbuffer`]).
    pub fn gbuffer(&self, renderer: &Renderer, eye: Eye) -> GBufferBuf {
        let mut g = GBufferBuf::new(*self.camera(eye));
        renderer.render_gbuffer(&self.lights, &mut g);
        g
    }
}

fn eye_cameras(
    renderer: &Renderer,
    rig: &StereoRig,
    extent: Extent,
    frame: u32,
) -> Result<[CameraModel; 2], RenderError> {
    let head = renderer.scene().camera.pose_at(frame as f32);
    let camera =
        |eye| rig.eye_camera(&head, eye, extent).map_err(|e| RenderError::Invalid(format!("frame {frame}: {e}")));
    Ok([camera(Eye::Left)?, camera(Eye::Right)?])
}
