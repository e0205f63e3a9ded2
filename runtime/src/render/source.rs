//! This crate's renderer behind the pipeline's seam ([`crate::source::FrameSource`]): the
//! per-frame light table, the rasterised or traced G-buffer pass and the specialised or
//! general path tracer, as [`RendererOptions`] choose.

use std::borrow::Borrow;
use std::ops::Range;

use super::lights::FrameLights;
use super::raster::{RasterGBuffers, Visibility};
use super::renderer::{RenderError, Renderer};
use super::trace::PrimaryRays;
use crate::kernels::{CameraModel, Extent, GBufferBuf, RgbBuf};
use crate::scene::Effect;
use crate::source::{FrameSource, Layout, PipelineError, PixelSelection, RasterPassStats, TraceRequest, TraceStats};

/// How each frame's G-buffers are made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum GBufferPass {
    /// Both eyes rasterised as GPUs rasterise (vertices snapped to 1/256 px, integer edge
    /// functions, the top-left rule), then resolved on each triangle's plane: the traced
    /// pass's triangle except within 1/256 px of an edge or at a depth tie, and where the
    /// triangle is the same, its texel within rounding (depth 1e-4 relative, normals 1e-3,
    /// tested). `fixed`, its name before it became the default, is accepted.
    #[default]
    #[cfg_attr(feature = "clap", value(alias = "fixed"))]
    #[serde(alias = "fixed")]
    Raster,
    /// One primary ray per pixel through the BVH (the reference).
    Traced,
    /// Both eyes rasterised with the tracer's own triangle test wherever rounding could
    /// decide (`render::raster`'s exact rasteriser): the same triangles as `traced` except at
    /// exact depth ties, resolved as `raster` is, but slower than `raster` (kept for the
    /// comparison of visibility).
    Exact,
}

impl GBufferPass {
    /// The CLI's and the tables' name.
    pub fn name(self) -> &'static str {
        match self {
            GBufferPass::Raster => "raster",
            GBufferPass::Traced => "traced",
            GBufferPass::Exact => "exact",
        }
    }

    /// The pass's key in evaluation caches: the name each pass's results were stored under
    /// before the fixed-point pass became `raster` (then `fixed`; the exact pass was
    /// `raster`), so a cache filled earlier is never read as the other pass's.
    pub fn cache_key(self) -> &'static str {
        match self {
            GBufferPass::Raster => "fixed",
            GBufferPass::Traced => "traced",
            GBufferPass::Exact => "raster",
        }
    }

    /// The rasteriser that finds the visibility, `None` for the traced pass.
    pub fn visibility(self) -> Option<Visibility> {
        match self {
            GBufferPass::Raster => Some(Visibility::Fixed),
            GBufferPass::Traced => None,
            GBufferPass::Exact => Some(Visibility::Exact),
        }
    }
}

/// Where each pixel's first sample of a frame starts (the others are always jittered).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum FirstSample {
    /// At a uniformly jittered point of the pixel (the paper's estimator).
    #[default]
    Jittered,
    /// At the pixel centre, where the G-buffer pass already found the primary hit: with a
    /// rasterised pass the hit is read from its visibility buffer instead of traced (the
    /// same hit as tracing the centre ray except at depth ties); with the traced pass the
    /// centre ray is traced. At 1 spp no pixel is then antialiased within a frame.
    Centre,
}

impl FirstSample {
    /// The CLI's and the tables' name.
    pub fn name(self) -> &'static str {
        match self {
            FirstSample::Jittered => "jittered",
            FirstSample::Centre => "centre",
        }
    }
}

/// How [`RendererSource`] makes a frame: the choices that belong to the renderer, not to
/// the pipeline (whose images they do not change beyond the G-buffer pass's tolerance).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RendererOptions {
    /// How the G-buffers are made.
    pub gbuffer: GBufferPass,
    /// Use the general integrator instead of the one specialised for the scene's effects
    /// (the same images; a test of the specialisation).
    pub general_integrator: bool,
    /// Where each pixel's first sample of a frame starts.
    pub first_sample: FirstSample,
}

impl RendererOptions {
    /// The default integrator with G-buffers made by `gbuffer`.
    pub fn with_gbuffer(gbuffer: GBufferPass) -> Self {
        Self { gbuffer, ..Self::default() }
    }

    /// The default integrator with G-buffers made by `gbuffer` and first samples started as
    /// `first_sample` says.
    pub fn with_first_sample(gbuffer: GBufferPass, first_sample: FirstSample) -> Self {
        Self { first_sample, ..Self::with_gbuffer(gbuffer) }
    }
}

/// The renderer's failures as the pipeline reports them: a refused buffer stays a
/// [`PipelineError::Frame`] (an allocation failure is still `OutOfMemory`), anything else is
/// the source's error, kept whole.
impl From<RenderError> for PipelineError {
    fn from(e: RenderError) -> Self {
        match e {
            RenderError::Frame(frame) => PipelineError::Frame(frame),
            other => PipelineError::Source(Box::new(other)),
        }
    }
}

/// This crate's renderer as a [`FrameSource`]: the per-frame light table, the rasterised or
/// traced G-buffer pass the configuration names, and the specialised or general path
/// tracer. `R` is how the renderer is held: borrowed (`&Renderer`, what
/// [`crate::pipeline::Pipeline::new`] is usually given) or owned/shared (`Renderer`,
/// `Arc<Renderer>`: a pipeline that must outlive its caller's stack, as behind the C ABI).
pub struct RendererSource<R: Borrow<Renderer>> {
    renderer: R,
    lights: FrameLights,
    /// The rasterised G-buffer pass's buffers (with [`GBufferPass::Raster`] or `Exact`).
    raster: Option<RasterGBuffers>,
    /// The cameras of the rasterised pass's visibility buffers, while they show this frame
    /// (cleared when a frame begins): a trace with one of them reads its centre hits there.
    visible_cameras: Option<[CameraModel; 2]>,
    options: RendererOptions,
}

impl<R: Borrow<Renderer>> RendererSource<R> {
    /// The renderer with `options`, for frames of `extent`; fails only if the per-pixel
    /// buffers cannot be allocated ([`crate::kernels::FrameError::OutOfMemory`]).
    pub fn new(renderer: R, options: RendererOptions, extent: Extent) -> Result<Self, PipelineError> {
        let raster = match options.gbuffer.visibility() {
            Some(visibility) => {
                let mut raster = RasterGBuffers::try_new(extent)?;
                raster.visibility_by = visibility;
                Some(raster)
            }
            None => None,
        };
        Ok(Self { lights: renderer.borrow().frame_lights(0), renderer, raster, visible_cameras: None, options })
    }

    /// How this source makes G-buffers and samples.
    pub fn options(&self) -> RendererOptions {
        self.options
    }

    /// The renderer behind this source.
    pub fn renderer(&self) -> &Renderer {
        self.renderer.borrow()
    }
}

impl<R: Borrow<Renderer>> FrameSource for RendererSource<R> {
    fn begin_frame(&mut self, frame: u32) {
        self.visible_cameras = None;
        self.lights.update(self.renderer.borrow().scene(), frame);
    }

    fn scene_changes(&self) -> bool {
        let effects = self.renderer.borrow().scene().effects;
        effects.has(Effect::MovingLights) || effects.has(Effect::MovingObjects)
    }

    fn resize(&mut self, extent: Extent) -> Result<(), PipelineError> {
        self.visible_cameras = None;
        if let Some(raster) = &mut self.raster {
            let mut resized = RasterGBuffers::try_new(extent)?;
            (resized.planes, resized.visibility_by, resized.body) = (raster.planes, raster.visibility_by, raster.body);
            *raster = resized;
        }
        Ok(())
    }

    fn fill_gbuffers(
        &mut self,
        gbuffers: [&mut GBufferBuf; 2],
        layout: Layout,
    ) -> Result<Option<RasterPassStats>, PipelineError> {
        let renderer = self.renderer.borrow();
        let [left, right] = gbuffers;
        let stats = match &mut self.raster {
            Some(raster) => {
                // The compact layout reads depth, normal and material: the resolve writes
                // those alone (the traced pass writes every plane whatever the layout).
                raster.planes = layout;
                self.visible_cameras = None;
                let stats = renderer.render_gbuffers_raster(&self.lights, [&mut *left, &mut *right], raster)?;
                self.visible_cameras = Some([left.camera, right.camera]);
                Some(stats)
            }
            None => {
                renderer.render_gbuffer(&self.lights, left);
                renderer.render_gbuffer(&self.lights, right);
                None
            }
        };
        // The rasteriser's visibility names each pixel's moving triangle.
        let seen = self.raster.as_ref().map(|r| r.visibility().each_ref().map(|v| v.prim.as_slice()));
        renderer.write_motion(&self.lights, left, seen.map(|s| s[0]));
        renderer.write_motion(&self.lights, right, seen.map(|s| s[1]));
        Ok(stats)
    }

    fn trace(
        &self,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: Range<usize>,
        out: &mut RgbBuf,
    ) -> Result<TraceStats, PipelineError> {
        let general = self.options.general_integrator;
        let primary = match (self.options.first_sample, &self.raster, &self.visible_cameras) {
            (FirstSample::Jittered, ..) => PrimaryRays::Jittered,
            // The visibility of this frame seen by this very camera: its hits are the centre
            // rays'. Anything else (a mono frame, the last frame's camera) traces them.
            (FirstSample::Centre, Some(raster), Some(cameras)) => match cameras.iter().position(|c| c == camera) {
                Some(eye) => PrimaryRays::CentreVisible(&raster.visibility()[eye]),
                None => PrimaryRays::Centre,
            },
            (FirstSample::Centre, ..) => PrimaryRays::Centre,
        };
        Ok(self.renderer.borrow().trace_rows_from(
            &self.lights,
            camera,
            request,
            selection,
            rows,
            out,
            general,
            primary,
        )?)
    }
}
