//! This crate's renderer driving the pipeline: [`Pipeline::new`] over a [`RendererSource`],
//! and the one frame driver, a [`Session`] walking the scene's camera path frame after frame.
//!
//! The pipeline (`crate::pipeline`) and the renderer (`crate::render`) meet only at the seam
//! (`crate::source`); this module, above both, is where they are put together.
//!
//! Every loop that renders a scene's frames (the `throughput` and `tradeoff` commands, the
//! evaluation, the frame benchmark) is this driver: what differs between them is only how the
//! head walks the path ([`CameraWalk`]) and what they record of each frame's [`FrameStats`].
//! The C ABI takes frame numbers from its caller and an engine with its own cameras drives
//! [`Pipeline::render_frame_at`]; neither needs a session.

use std::borrow::Borrow;

use crate::camera::{CameraPose, StereoRig};
use crate::kernels::Extent;
use crate::pipeline::{FrameStats, Pipeline, PipelineConfig, PipelineError};
use crate::render::{Renderer, RendererOptions, RendererSource};

/// The pipeline over this crate's renderer.
pub type RendererPipeline<'r> = Pipeline<RendererSource<&'r Renderer>>;

impl<R: Borrow<Renderer>> Pipeline<RendererSource<R>> {
    /// A pipeline over this crate's renderer (borrowed, owned or shared: see
    /// [`RendererSource`]), with every buffer allocated for frames of `extent`; `rig` turns
    /// the scene's head poses into eye cameras.
    ///
    /// Three spatiotemporal frames of the built-in Cornell box, the head walking the scene's
    /// camera path:
    ///
    /// ```
    /// use stereotrace_runtime::camera::{Eye, StereoRig};
    /// use stereotrace_runtime::kernels::Extent;
    /// use stereotrace_runtime::pipeline::{Mode, Pipeline, PipelineConfig};
    /// use stereotrace_runtime::render::Renderer;
    ///
    /// # fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// let renderer = Renderer::new(stereotrace_runtime::scene::resolve("cornell")?)?;
    /// let extent = Extent::new(64, 36)?;
    /// let tolerances = renderer.scene().tolerances.at_height(extent.height());
    /// let config = PipelineConfig::paper(Mode::Spatiotemporal, 1, tolerances);
    /// let mut pipeline = Pipeline::new(&renderer, config, StereoRig::default(), extent)?;
    /// for frame in 0..3 {
    ///     let head = renderer.scene().camera.pose_back_and_forth(frame);
    ///     let stats = pipeline.render_frame(frame, &head)?;
    ///     // The right eye is path traced; most of the left eye is reprojected from it.
    ///     assert!(stats.traced_pixels[0] < stats.traced_pixels[1] / 4);
    /// }
    /// let left = pipeline.output(Eye::Left);
    /// assert!(left.r().as_slice().iter().all(|v| v.is_finite()));
    /// # Ok(())
    /// # }
    /// ```
    pub fn new(renderer: R, config: PipelineConfig, rig: StereoRig, extent: Extent) -> Result<Self, PipelineError> {
        Self::with_options(renderer, RendererOptions::default(), config, rig, extent)
    }

    /// [`Pipeline::new`] with the renderer's own choices (how G-buffers are made, which
    /// integrator traces).
    pub fn with_options(
        renderer: R,
        options: RendererOptions,
        config: PipelineConfig,
        rig: StereoRig,
        extent: Extent,
    ) -> Result<Self, PipelineError> {
        config.validate().map_err(PipelineError::Config)?;
        let head = renderer.borrow().scene().camera.pose_at(0.0);
        Pipeline::with_rig(RendererSource::new(renderer, options, extent)?, config, rig, &head, extent)
    }
}

/// How the head moves along the scene's camera path, frame after frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraWalk {
    /// Frame `f` at the path's frame `f` (poses past its end stay at its last key): the frames
    /// the evaluation measures against references of the same frames.
    Path,
    /// Forward and back along the path (`0, 1, …, n−1, n−2, …, 1, 0, 1, …`), so any number of
    /// frames keeps moving: what a real-time runtime and the benchmarks render.
    BackAndForth,
}

/// Which frames a [`Session`] renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    /// Stereo frames ([`Pipeline::render_frame`]).
    Stereo,
    /// The mono baseline: the right eye alone, path traced ([`Pipeline::render_mono_frame`]).
    Mono,
}

/// A pipeline over the renderer `R` (borrowed, owned or shared), the frames it has rendered
/// and the walk that gives the next one's head pose. Allocates nothing per frame.
///
/// ```
/// use stereotrace_runtime::camera::StereoRig;
/// use stereotrace_runtime::kernels::Extent;
/// use stereotrace_runtime::pipeline::{Mode, Pipeline, PipelineConfig};
/// use stereotrace_runtime::session::{CameraWalk, Session};
/// use stereotrace_runtime::render::Renderer;
///
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let renderer = Renderer::new(stereotrace_runtime::scene::resolve("cornell")?)?;
/// let extent = Extent::new(32, 18)?;
/// let config = PipelineConfig::paper(Mode::Temporal, 1, renderer.scene().tolerances.at_height(18));
/// let mut session = Session::new(Pipeline::new(&renderer, config, StereoRig::default(), extent)?, CameraWalk::Path);
/// for _ in 0..3 {
///     let stats = session.next_frame()?;
///     println!("frame {}: {:?}", stats.frame, stats.times.total);
/// }
/// assert_eq!(session.frames_rendered(), 3);
/// # Ok(())
/// # }
/// ```
pub struct Session<R: Borrow<Renderer>> {
    pipeline: Pipeline<RendererSource<R>>,
    walk: CameraWalk,
    view: View,
    next: u32,
}

impl<R: Borrow<Renderer>> Session<R> {
    /// A session of stereo frames from frame 0.
    pub fn new(pipeline: Pipeline<RendererSource<R>>, walk: CameraWalk) -> Self {
        Self { pipeline, walk, view: View::Stereo, next: 0 }
    }

    /// The same session rendering `view`'s frames.
    pub fn with_view(mut self, view: View) -> Self {
        self.view = view;
        self
    }

    /// Renders the next frame: its index keys the random numbers and moving lights, the walk
    /// gives its head pose.
    pub fn next_frame(&mut self) -> Result<FrameStats, PipelineError> {
        let path = &self.pipeline.source().renderer().scene().camera;
        let head = match self.walk {
            CameraWalk::Path => path.pose(self.next),
            CameraWalk::BackAndForth => path.pose_back_and_forth(self.next),
        };
        self.next_frame_at(&head)
    }

    /// Renders the next frame with the head at `head` instead of the walk's pose: an
    /// interactive viewer's free camera. The frame index advances as with
    /// [`Session::next_frame`].
    pub fn next_frame_at(&mut self, head: &CameraPose) -> Result<FrameStats, PipelineError> {
        let frame = self.next;
        let stats = match self.view {
            View::Stereo => self.pipeline.render_frame(frame, head),
            View::Mono => self.pipeline.render_mono_frame(frame, head),
        }?;
        self.next += 1;
        Ok(stats)
    }

    /// The pipeline, to change between frames ([`Pipeline::reconfigure`], a reset).
    pub fn pipeline_mut(&mut self) -> &mut Pipeline<RendererSource<R>> {
        &mut self.pipeline
    }

    /// Frames rendered so far (the next frame's index).
    pub fn frames_rendered(&self) -> u32 {
        self.next
    }

    /// The pipeline: its images and reason maps of the last frame.
    pub fn pipeline(&self) -> &Pipeline<RendererSource<R>> {
        &self.pipeline
    }
}
