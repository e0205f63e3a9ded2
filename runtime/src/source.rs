//! The seam between the frame pipeline and whatever makes G-buffers and samples.
//!
//! [`crate::pipeline::Pipeline`] owns every buffer and runs reprojection, accumulation, the
//! budget planner and the schedule of a mode; it asks a [`FrameSource`] for two things
//! only: both eyes' G-buffers for this frame's cameras, and path-traced samples for a
//! chosen set of pixels. [`RendererSource`] is this crate's renderer behind the seam
//! (rasterised or traced G-buffers, the paper's path tracer); an engine implements the
//! trait over its own rasteriser and tracer and gets the same pipeline.
//!
//! Why the seam is here: everything above it is defined on buffers (the paper's
//! reprojection, EMA and blend, the budget), everything below it on a scene. A source never
//! sees the pipeline's history, and the pipeline never sees a scene, a BVH or a light.

use std::borrow::Borrow;
use std::ops::Range;

use crate::kernels::{CameraModel, Extent, RgbBuf};
// From the configuration module only: the pipeline proper sits above this seam.
use crate::pipeline::config::{GBufferPass, Layout, PipelineConfig, PipelineError};
use crate::render::lights::FrameLights;
use crate::render::raster::{GBufferPlanes, RasterGBuffers, RasterPassStats, Visibility};
use crate::render::{GBufferBuf, PixelSelection, Renderer, TraceRequest, TraceStats};

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

    /// Frames will be of `extent` from now on ([`crate::pipeline::Pipeline::resize`]): resize
    /// whatever the source keeps per pixel, or fail and keep it as it was. Nothing to do by
    /// default.
    fn resize(&mut self, extent: Extent) -> Result<(), PipelineError> {
        let _ = extent;
        Ok(())
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
    /// The rasterised G-buffer pass's buffers (with [`GBufferPass::Raster`]).
    raster: Option<RasterGBuffers>,
    general_integrator: bool,
}

impl<R: Borrow<Renderer>> RendererSource<R> {
    /// The renderer configured as `config` asks, for frames of `extent`; fails only if the
    /// per-pixel buffers cannot be allocated ([`crate::kernels::FrameError::OutOfMemory`]).
    pub fn new(renderer: R, config: &PipelineConfig, extent: Extent) -> Result<Self, PipelineError> {
        let raster = match config.gbuffer {
            GBufferPass::Raster | GBufferPass::Fixed => {
                let mut raster = RasterGBuffers::try_new(extent)?;
                if config.layout == Layout::Compact {
                    raster.planes = GBufferPlanes::Compact;
                }
                if config.gbuffer == GBufferPass::Fixed {
                    raster.visibility_by = Visibility::Fixed;
                }
                Some(raster)
            }
            GBufferPass::Traced => None,
        };
        Ok(Self {
            lights: renderer.borrow().frame_lights(0),
            renderer,
            raster,
            general_integrator: config.general_integrator,
        })
    }

    /// The renderer behind this source.
    pub fn renderer(&self) -> &Renderer {
        self.renderer.borrow()
    }
}

impl<R: Borrow<Renderer>> FrameSource for RendererSource<R> {
    fn begin_frame(&mut self, frame: u32) {
        self.lights.update(self.renderer.borrow().scene(), frame);
    }

    fn resize(&mut self, extent: Extent) -> Result<(), PipelineError> {
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
        _layout: Layout,
    ) -> Result<Option<RasterPassStats>, PipelineError> {
        // The layout was fixed at construction (the raster pass's planes).
        let renderer = self.renderer.borrow();
        let [left, right] = gbuffers;
        let stats = match &mut self.raster {
            Some(raster) => Some(renderer.render_gbuffers_raster(&self.lights, [&mut *left, &mut *right], raster)?),
            None => {
                renderer.render_gbuffer(&self.lights, left);
                renderer.render_gbuffer(&self.lights, right);
                None
            }
        };
        renderer.write_motion(&self.lights, left);
        renderer.write_motion(&self.lights, right);
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
        let general = self.general_integrator;
        Ok(self.renderer.borrow().trace_rows(&self.lights, camera, request, selection, rows, out, general)?)
    }
}
