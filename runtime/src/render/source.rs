//! This crate's renderer behind the pipeline's seam ([`crate::source::FrameSource`]): the
//! per-frame light table, the rasterised or traced G-buffer pass and the specialised or
//! general path tracer, as [`RendererOptions`] choose.

use std::borrow::Borrow;
use std::ops::Range;

use super::lights::FrameLights;
use super::raster::{RasterGBuffers, Visibility};
use super::renderer::{RenderError, Renderer};
use crate::kernels::{CameraModel, Extent, GBufferBuf, RgbBuf};
use crate::scene::Effect;
use crate::source::{FrameSource, Layout, PipelineError, PixelSelection, RasterPassStats, TraceRequest, TraceStats};

/// How each frame's G-buffers are made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum GBufferPass {
    /// Both eyes rasterised in one pass over the triangles, then resolved with the tracer's
    /// own triangle test (`render::raster`): the same texels as `traced` except at exact depth
    /// ties, at a fraction of the cost.
    #[default]
    Raster,
    /// One primary ray per pixel through the BVH (the reference).
    Traced,
    /// Both eyes rasterised as GPUs rasterise (vertices snapped to 1/256 px, integer edge
    /// functions, the top-left rule), then resolved like `raster`: the traced pass's triangle
    /// except within 1/256 px of an edge or at a depth tie, and where the triangle is the
    /// same, the same texel.
    Fixed,
}

impl GBufferPass {
    /// The CLI's and the tables' name.
    pub fn name(self) -> &'static str {
        match self {
            GBufferPass::Raster => "raster",
            GBufferPass::Traced => "traced",
            GBufferPass::Fixed => "fixed",
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
}

impl RendererOptions {
    /// The default integrator with G-buffers made by `gbuffer`.
    pub fn with_gbuffer(gbuffer: GBufferPass) -> Self {
        Self { gbuffer, ..Self::default() }
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
    /// The rasterised G-buffer pass's buffers (with [`GBufferPass::Raster`] or `Fixed`).
    raster: Option<RasterGBuffers>,
    options: RendererOptions,
}

impl<R: Borrow<Renderer>> RendererSource<R> {
    /// The renderer with `options`, for frames of `extent`; fails only if the per-pixel
    /// buffers cannot be allocated ([`crate::kernels::FrameError::OutOfMemory`]).
    pub fn new(renderer: R, options: RendererOptions, extent: Extent) -> Result<Self, PipelineError> {
        let raster = match options.gbuffer {
            GBufferPass::Raster | GBufferPass::Fixed => {
                let mut raster = RasterGBuffers::try_new(extent)?;
                if options.gbuffer == GBufferPass::Fixed {
                    raster.visibility_by = Visibility::Fixed;
                }
                Some(raster)
            }
            GBufferPass::Traced => None,
        };
        Ok(Self { lights: renderer.borrow().frame_lights(0), renderer, raster, options })
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
        self.lights.update(self.renderer.borrow().scene(), frame);
    }

    fn scene_changes(&self) -> bool {
        let effects = self.renderer.borrow().scene().effects;
        effects.has(Effect::MovingLights) || effects.has(Effect::MovingObjects)
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
        layout: Layout,
    ) -> Result<Option<RasterPassStats>, PipelineError> {
        let renderer = self.renderer.borrow();
        let [left, right] = gbuffers;
        let stats = match &mut self.raster {
            Some(raster) => {
                // The compact layout reads depth, normal and material: the resolve writes
                // those alone (the traced pass writes every plane whatever the layout).
                raster.planes = layout;
                Some(renderer.render_gbuffers_raster(&self.lights, [&mut *left, &mut *right], raster)?)
            }
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
        let general = self.options.general_integrator;
        Ok(self.renderer.borrow().trace_rows(&self.lights, camera, request, selection, rows, out, general)?)
    }
}
