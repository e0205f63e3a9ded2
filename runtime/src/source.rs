//! The seam between the frame pipeline and whatever makes G-buffers and samples: every type
//! an engine needs to stand behind it.
//!
//! [`crate::pipeline::Pipeline`] owns every buffer and runs reprojection, accumulation, the
//! budget planner and the schedule of a mode; it asks a [`FrameSource`] for two things
//! only: both eyes' G-buffers for this frame's cameras, and path-traced samples for a
//! chosen set of pixels. An engine implements the trait over its own rasteriser and tracer
//! (`runtime/examples/embed.rs`); this crate's renderer stands behind it as
//! `render::RendererSource`.
//!
//! Why the seam is here: everything above it is defined on buffers (the paper's
//! reprojection, EMA and blend, the budget), everything below it on a scene. A source never
//! sees the pipeline's history, and the pipeline never sees a scene, a BVH or a light. This
//! module imports the kernels and the camera alone: neither side's code.

use std::ops::Range;
use std::time::Duration;

use crate::camera::Eye;
use crate::kernels::raster::RasterStats;
use crate::kernels::{CameraModel, Extent, FrameError, GBufferBuf, PlaneBuf, RgbBuf};

/// What makes a frame's G-buffers and samples for [`crate::pipeline::Pipeline`].
///
/// Calls come in this order each frame: [`FrameSource::begin_frame`], then
/// [`FrameSource::fill_gbuffers`] once, then [`FrameSource::trace`] any number of times
/// (once per eye without a budget; per tile of rows under one). Nothing may allocate per
/// frame in a real-time source.
pub trait FrameSource {
    /// A new frame starts (scene time `frame`): update what moves with time (lights).
    fn begin_frame(&mut self, frame: u32);

    /// Fills both eyes' G-buffers (`[left, right]`) for the cameras already stored in
    /// their `camera` fields: per pixel, the surface the pixel-centre ray hits (depth
    /// `+inf` for none), in the planes `layout` reads (compact: depth, octahedral normal,
    /// material; full: every plane). Returns the rasterised pass's statistics if it has
    /// any.
    fn fill_gbuffers(
        &mut self,
        gbuffers: [&mut GBufferBuf; 2],
        layout: Layout,
    ) -> Result<Option<RasterPassStats>, PipelineError>;

    /// Path traces the pixels of `rows` that `selection` selects, for `camera` at
    /// `request` (eye, frame, spp, seed), into `out`; other pixels of `out` keep their
    /// values.
    fn trace(
        &self,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: Range<usize>,
        out: &mut RgbBuf,
    ) -> Result<TraceStats, PipelineError>;

    /// Whether lights or geometry may differ between frames in ways the G-buffers'
    /// reprojection cannot see (a light that moves or switches, an object whose shadow moves
    /// over a still floor). With `History::Gradient` the pipeline then measures temporal
    /// gradients, re-shading samples of the last frame through [`FrameSource::trace`] with
    /// the last frame's camera and frame index under this frame's scene; a source that says
    /// `false` is asked for none. True by default: an engine's scene may change.
    fn scene_changes(&self) -> bool {
        true
    }

    /// Frames will be of `extent` from now on ([`crate::pipeline::Pipeline::resize`]): resize
    /// whatever the source keeps per pixel, or fail and keep it as it was. Nothing to do by
    /// default.
    fn resize(&mut self, extent: Extent) -> Result<(), PipelineError> {
        let _ = extent;
        Ok(())
    }
}

/// Which G-buffer layout the reprojection kernels read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Layout {
    /// Depth + octahedral normals, positions rebuilt from depth (8 B/px).
    #[default]
    Compact,
    /// Depth, position and normal planes (28 B/px).
    Full,
}

/// The parameters of one path-tracing call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TraceRequest {
    /// Which eye (part of every random number).
    pub eye: Eye,
    /// The frame (scene time, and part of every random number).
    pub frame: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Seed of the random numbers (references and comparison frames use different seeds).
    pub seed: u64,
    /// Index of the first sample (so that n more samples can be added to m earlier ones with
    /// the same numbers as one (m + n)-sample render).
    pub first_sample: u32,
}

/// Which pixels a tracing call fills.
#[derive(Clone, Copy)]
pub enum PixelSelection<'a> {
    /// Every pixel.
    All,
    /// Only pixels whose mask byte is non-zero; the others keep their value.
    Mask(&'a PlaneBuf<u8>),
}

impl PixelSelection<'_> {
    /// Whether pixel `(x, y)` is to be filled (for a frame source's per-pixel loop).
    pub fn selects(&self, x: usize, y: usize) -> bool {
        match self {
            PixelSelection::All => true,
            PixelSelection::Mask(m) => m.view().get(x, y) != 0,
        }
    }
}

/// Counters of one render call.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraceStats {
    /// Rays traced (primary, secondary and shadow).
    pub rays: u64,
    /// Pixel samples taken.
    pub samples: u64,
    /// Samples whose estimate was not finite (replaced by 0).
    pub non_finite: u64,
}

impl std::ops::Add for TraceStats {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self { rays: self.rays + o.rays, samples: self.samples + o.samples, non_finite: self.non_finite + o.non_finite }
    }
}

impl std::iter::Sum for TraceStats {
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::default(), |a, b| a + b)
    }
}

/// What one rasterised G-buffer pass did: the kernel's statistics (with its step times) and
/// the resolve's time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RasterPassStats {
    /// The rasteriser's counters and step times.
    pub raster: RasterStats,
    /// Wall time of the resolve (visibility into G-buffer texels).
    pub resolve: Duration,
}

/// Why a pipeline could not be built or could not run a frame: raised by the pipeline or by
/// its source, which share this one error type.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error("invalid pipeline configuration: {0}")]
    /// The configuration was refused (the message says which field and why).
    Config(String),
    #[error(transparent)]
    /// A buffer, extent or camera was refused by a kernel.
    Frame(#[from] FrameError),
    /// The [`FrameSource`] failed: an engine's message (`PipelineError::Source("...".into())`)
    /// or the renderer's own error, kept whole for `source()` and downcasting.
    #[error("frame source: {0}")]
    Source(Box<dyn std::error::Error + Send + Sync>),
    /// G-buffers lent to [`crate::pipeline::Pipeline::render_frame_lent`] were refused (a plane missing
    /// or of the wrong size, or last frame's G-buffers not lent again).
    #[error("lent G-buffers: {0}")]
    Lent(String),
}
