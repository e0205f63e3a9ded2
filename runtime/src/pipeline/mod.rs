//! The embeddable per-frame stereo pipeline.
//!
//! Built once for a renderer, a configuration and a frame size, then driven frame by frame
//! with a head pose (the scene's camera path, or poses a runtime tracks). It owns every
//! buffer and allocates nothing per frame; it runs on the caller's current rayon pool.
//!
//! # Modes (what each eye shows at frame t)
//! `PT_e` is eye e's `spp`-sample path-traced image, `R_{a→b}` backward reprojection from
//! view a into view b, `EMA` the temporal accumulation (history reset where its reprojection
//! was discarded).
//!
//! | mode | right eye | left eye |
//! |---|---|---|
//! | `path-traced` | `PT_R` | `PT_L` |
//! | `stereo` (paper IV-B) | `PT_R` | `R_{R→L}(PT_R)` where valid, `PT_L` where discarded |
//! | `temporal` | `EMA(R_{t−1→t}(hist_R), PT_R)` | same for L |
//! | `spatiotemporal`, paper order | `acc_R = EMA(…, PT_R)` | `R_{R→L}(acc_R)` where valid; where discarded `EMA(R_{t−1→t}(hist_L), PT_L)`; the shown image is the next history |
//! | `spatiotemporal`, stereo first | `acc_R` | `EMA(R_{t−1→t}(hist_L), stereo-mode left image)` |
//! | `stereo-blend` (IV-C) | `½PT_R + ½R_{L→R}(PT_L)` where valid, `PT_R` elsewhere | mirror image |
//! | `spatiotemporal-blend`, paper order | `½acc_R + ½R_{L→R}(acc_L)` | mirror image; each `acc` accumulates its own `PT` |
//! | `spatiotemporal-blend`, stereo first | `EMA(R_{t−1→t}(hist_R), stereo-blend right image)` | mirror image |
//!
//! Only the pixels an eye needs are traced: in `stereo` and both `spatiotemporal` modes the
//! left eye traces just the pixels whose stereo reprojection was discarded (2–6 % in the
//! paper), with exactly the random numbers a full render would use for them. Likewise in
//! the paper-order `spatiotemporal` mode the left eye's history is reprojected only where
//! its stereo reprojection was discarded: elsewhere the shown pixel is the stereo sample
//! and the history restarts from it, so the temporal reprojection there would be unused
//! (its reason is recorded as `Invalid` and not counted). With the paper's history rule or
//! the temporal gradients (any `History` but the clamp, which reads the whole stereo-mode
//! image as new samples) the restart costs nothing: the stereo reprojection writes its samples
//! straight into the left history (the kernel flushes them as the EMA's restart would), and
//! the left EMA runs only at the stereo-discarded pixels (its pixel mask). The result is the
//! bits of the EMA over the whole eye; a test holds the two schedules to each other.
//! Likewise every other EMA of an eye's own samples skips the pixels whose history it would
//! keep as reprojected (no new sample, a valid reprojection): under a budget, nearly all of
//! them. The reprojection has already written those pixels as the EMA would keep them.
//!
//! # Refused frames
//! A frame that fails anywhere (a source's G-buffers or samples, a camera, a kernel's check)
//! returns its error and leaves the pipeline exactly as before the call: outputs, histories,
//! G-buffers, reason planes, cameras and the budget planner (each eye keeps the committed
//! frame's buffers beside the frame in flight's: see `EyeState`). The same frame may then be
//! rendered again and gives what it would have given the first time.
//!
//! # Budget
//! With a per-frame time budget, G-buffers, reprojection and accumulation always run; path
//! tracing goes over row tiles in priority order: first every pixel that has no valid
//! reprojected data at all (disocclusions), then the remaining pixels the mode would trace,
//! tile by tile, until the budget is spent. Pixels that were not traced keep their
//! reprojected value (or stay holes where there is none). A tile starts only if the time so
//! far, the tile's predicted cost and the work that followed the loop in the previous frame
//! (the other eye, accumulation) fit the budget (`BudgetPlanner`, predictions from measured
//! times), so the overrun is the misprediction of about one tile; the frame statistics
//! report it. Work that always runs is never skipped: a budget below the G-buffers,
//! reprojection, accumulation and the urgent pixels is overrun by that much. Under a budget
//! the stereo-first schedules reproject (or blend) the whole `traced` image of an eye, whose
//! untraced pixels hold an older frame's samples: an approximation the budget buys.

use std::time::Instant;

use crate::camera::{CameraPose, Eye, StereoRig};
use crate::kernels::accumulate::{self, BlendParams, EmaInput, EmaParams, EmaState};
use crate::kernels::atrous::{self, AtrousGuide, AtrousParams, AtrousScratch, GuideNormals};
use crate::kernels::clamp::{self, ClampInput, ClampParams};
use crate::kernels::frame::{Plane, RgbPlanes};
use crate::kernels::gbuffer::{CompactGBuffer, GBuffer, SurfaceLayout};
use crate::kernels::gradient::{self, GradientInput, STRATUM};
use crate::kernels::reproject::{self, Reason, ReasonCounts, ReprojectInput, ReprojectOutput, ReprojectParams};
use crate::kernels::{CameraModel, Extent, FrameError, GBufferBuf, PlaneBuf, RgbBuf};
use crate::source::{FrameSource, PixelSelection, TraceRequest};

mod budget;
pub(crate) mod config;
mod gradients;
mod lent;
mod plan;
mod stats;
#[cfg(test)]
mod tests;

use budget::BudgetPlanner;
pub use config::{
    ATROUS_ITERATIONS, Background, Blend, CLAMP_GAMMA, Filter, History, MAX_BUDGET_MS, MAX_SPP, Mode, Order,
    PipelineConfig, budget_duration, check_spp, readable,
};
use gradients::GradientBuffers;
// The seam's types a pipeline user names, where the pipeline's own are.
pub use crate::source::{Layout, PipelineError};
pub use lent::GBufferView;
use lent::Lent;
use plan::Target;
pub use plan::{Source, Step, StereoSource, plan};
pub use stats::{FrameStats, StageTimes};

/// What one frame of one eye leaves behind: everything a caller reads after the frame (the
/// shown image, the reasons, the G-buffer) and everything the next frame reads (G-buffer,
/// history and its length). Each eye keeps two: the last committed frame's and the one in
/// flight (see [`EyeState`]).
struct FrameBuffers {
    gbuffer: GBufferBuf,
    /// This frame's path-traced samples (where traced).
    traced: RgbBuf,
    /// Stereo reprojection of the other eye / blend output / the stereo-mode left image.
    work: RgbBuf,
    /// Temporal history: reprojected from the previous frame's, then accumulated in place.
    history: RgbBuf,
    len: PlaneBuf,
    stereo_reason: PlaneBuf<u8>,
    temporal_reason: PlaneBuf<u8>,
    /// 1 where this frame path traced the pixel.
    traced_mask: PlaneBuf<u8>,
    /// The shown image filtered (with `Filter::Atrous`).
    filtered: Option<RgbBuf>,
}

impl FrameBuffers {
    fn try_new(camera: CameraModel, config: &PipelineConfig) -> Result<Self, FrameError> {
        let e = camera.extent;
        let rgb = || RgbBuf::try_new(e, 0.0);
        let mut gbuffer = GBufferBuf::try_new(camera)?;
        if config.history_confidence {
            gbuffer.history_confidence = Some(PlaneBuf::try_new(e, 1.0)?);
        }
        if config.motion_vectors {
            let still = || PlaneBuf::try_new(e, 0.0);
            gbuffer.motion = Some([still()?, still()?, still()?]);
        }
        Ok(Self {
            gbuffer,
            traced: rgb()?,
            work: rgb()?,
            history: rgb()?,
            len: PlaneBuf::try_new(e, 0.0)?,
            stereo_reason: PlaneBuf::try_new(e, Reason::Invalid as u8)?,
            temporal_reason: PlaneBuf::try_new(e, Reason::Invalid as u8)?,
            traced_mask: PlaneBuf::try_new(e, 0)?,
            filtered: match config.filter {
                Filter::Atrous => Some(rgb()?),
                Filter::None => None,
            },
        })
    }
}

/// One eye's buffers.
///
/// **Transactional frames.** Between frames `cur` holds the last committed frame and `prev`
/// the one before (stale). A frame starts by swapping them: it writes `cur` and reads the
/// committed frame in `prev` (temporal reprojection's G-buffer, history and length). If the
/// frame succeeds, `cur` is the new committed frame; if anything fails (a source's callback,
/// a kernel's check), the two are swapped back and the cameras and planner restored, so the
/// output, the history and what the next frame reads are exactly as before the call. No
/// step reads a `cur` plane where this frame has not written it, except that under a budget
/// the pixels a stereo-first schedule leaves untraced keep an older frame's samples in
/// `traced` (module notes).
struct EyeState {
    camera: CameraModel,
    /// The committed frame's camera (unjittered) while a frame is in flight: temporal
    /// gradients re-shade its pixels.
    last_camera: CameraModel,
    cur: FrameBuffers,
    prev: FrameBuffers,
    /// The history-validity plane the EMA reads (a combination in some modes).
    ema_reason: PlaneBuf<u8>,
    /// Pixels to trace this frame, and (after tracing) where a new sample exists.
    wanted: PlaneBuf<u8>,
    has_new: PlaneBuf<u8>,
    /// Pixels with no valid reprojected data (traced first under a budget).
    urgent: PlaneBuf<u8>,
    /// Temporal gradients' buffers (with `History::Gradient` only).
    gradient: Option<GradientBuffers>,
    /// The other eye's history length reprojected into this eye (with `Blend::Variance`).
    stereo_len: Option<PlaneBuf>,
    /// The à-trous filter's working planes (with `Filter::Atrous`).
    atrous: Option<AtrousScratch>,
}

impl EyeState {
    /// Every buffer of one eye, or [`FrameError::OutOfMemory`] (nothing kept) if the
    /// allocator refuses one.
    fn try_new(camera: CameraModel, config: &PipelineConfig) -> Result<Self, FrameError> {
        let e = camera.extent;
        let gradient = match config.history {
            History::Gradient => Some(GradientBuffers::try_new(e)?),
            History::Paper | History::Clamp => None,
        };
        Ok(Self {
            camera,
            last_camera: camera,
            cur: FrameBuffers::try_new(camera, config)?,
            prev: FrameBuffers::try_new(camera, config)?,
            ema_reason: PlaneBuf::try_new(e, Reason::Invalid as u8)?,
            wanted: PlaneBuf::try_new(e, 0)?,
            has_new: PlaneBuf::try_new(e, 0)?,
            urgent: PlaneBuf::try_new(e, 0)?,
            gradient,
            stereo_len: match config.blend {
                Blend::Variance => Some(PlaneBuf::try_new(e, 0.0)?),
                Blend::Fixed => None,
            },
            atrous: match config.filter {
                Filter::Atrous => Some(AtrousScratch::try_new(e)?),
                Filter::None => None,
            },
        })
    }
}

/// What a refused frame restores besides the buffers: each eye's camera and the budget
/// planner's predictions. (The previous frame's cameras are its G-buffers'.)
struct Committed {
    cameras: [CameraModel; 2],
    last_cameras: [CameraModel; 2],
    last_frame: u32,
    planner: BudgetPlanner,
}

/// The per-frame pipeline over a [`FrameSource`]: any source with eye cameras per frame
/// ([`Pipeline::with_source`]), or with head poses through a stereo rig
/// ([`Pipeline::with_rig`]). This crate's renderer has its constructor in
/// `crate::session`.
pub struct Pipeline<S: FrameSource> {
    source: S,
    config: PipelineConfig,
    /// Turns a head pose into eye cameras for [`Pipeline::render_frame`]; a pipeline made
    /// with [`Pipeline::with_source`] has none and takes eye cameras.
    rig: Option<StereoRig>,
    extent: Extent,
    eyes: [EyeState; 2],
    frames_done: u32,
    planner: BudgetPlanner,
    /// The sub-pixel jitter of the next frames' G-buffers ([`Pipeline::set_jitter`]).
    jitter: [f32; 2],
    /// The frame index of the last committed frame (temporal gradients re-shade with its
    /// random numbers).
    last_frame: u32,
    /// Whether the committed frame's G-buffers were lent ([`Pipeline::render_frame_lent`]):
    /// then the pipeline's own planes do not hold them, and the next lent frame must lend
    /// them again as its previous frame's.
    gbuffers_lent: bool,
    /// Whether the last frame's shown images are the filtered ones (a stereo frame with a
    /// filter; a mono frame shows its traced image).
    filtered_shown: bool,
    /// Whether the paper-order left eye may restart its history in the stereo pass
    /// ([`Pipeline::fuses_left_restart`]). Always on; the unit tests turn it off to hold the
    /// fused schedule to the unfused one.
    fuse_left_restart: bool,
    /// Whether an EMA skips the pixels whose history is kept as reprojected
    /// ([`Pipeline::skips_kept_history`]). Always on; the unit tests turn it off.
    skip_kept_history: bool,
    /// Whether temporal gradients are measured only in the strata that can reach a pixel
    /// the EMA blends: a new sample on a reprojected history (`Pipeline::temporal_gradients`).
    /// Always on; the unit tests turn it off.
    gradients_where_needed: bool,
}

const L: usize = Eye::Left as usize;

/// The planes of an owned G-buffer as a view (all present, as the configuration allocated
/// them).
fn planes_of(g: &GBufferBuf) -> GBufferView<'_> {
    GBufferView {
        depth: g.depth.view(),
        normal_oct: Some(g.normal_oct.view()),
        position: Some(g.position.each_ref().map(|p| p.view())),
        normal: Some(g.normal.each_ref().map(|p| p.view())),
        history_confidence: g.history_confidence.as_ref().map(|c| c.view()),
        motion: g.motion.as_ref().map(|m| m.each_ref().map(|p| p.view())),
    }
}

/// The kernel's compact G-buffer of `planes` seen by `camera` (present: checked on entry).
fn compact<'a>(planes: &GBufferView<'a>, camera: CameraModel) -> Result<CompactGBuffer<'a>, FrameError> {
    let normals = planes.normal_oct.ok_or(FrameError::InvalidParameter("compact layout without normals"))?;
    CompactGBuffer::new(planes.depth, normals, camera)
}

/// The kernel's full G-buffer of `planes` (present: checked on entry).
fn full<'a>(planes: &GBufferView<'a>) -> Result<GBuffer<'a>, FrameError> {
    let missing = FrameError::InvalidParameter("full layout without positions or normals");
    GBuffer::new(planes.depth, planes.position.ok_or(missing.clone())?, planes.normal.ok_or(missing)?)
}

/// What a reprojection carries besides the two G-buffers: the kernel's input but for the
/// layout-specific views.
struct Carried<'a> {
    colour: RgbPlanes<'a>,
    extra: Option<Plane<'a>>,
    pixel_mask: Option<Plane<'a, u8>>,
    motion: Option<[Plane<'a>; 3]>,
    jitter: Option<reproject::Jitter>,
    /// Background pixels reprojected by direction ([`Background::Reproject`]).
    background: bool,
}

/// One reprojection from `source` (planes, and the camera that rendered them) into `target`
/// in `layout`: the one place the layout picks the kernel's G-buffer type (stereo and
/// temporal reprojection both come here).
fn reproject_in(
    layout: Layout,
    (target, target_camera): (&GBufferView<'_>, CameraModel),
    (source, source_camera): (&GBufferView<'_>, &CameraModel),
    carried: Carried<'_>,
    out: ReprojectOutput<'_>,
    params: &ReprojectParams,
) -> Result<ReasonCounts, PipelineError> {
    fn run<L: SurfaceLayout>(
        (target, target_camera): (&L, &CameraModel),
        source: &L,
        source_camera: &CameraModel,
        c: Carried<'_>,
        out: ReprojectOutput<'_>,
        params: &ReprojectParams,
    ) -> Result<ReasonCounts, FrameError> {
        let Carried { colour, extra, pixel_mask, motion, jitter, background } = c;
        let background = background.then_some(target_camera);
        let input =
            ReprojectInput { target, source, source_camera, colour, extra, pixel_mask, motion, jitter, background };
        reproject::reproject(&input, out, params)
    }
    Ok(match layout {
        Layout::Compact => {
            let (t, s) = (compact(target, target_camera)?, compact(source, *source_camera)?);
            run((&t, &target_camera), &s, source_camera, carried, out, params)?
        }
        Layout::Full => run((&full(target)?, &target_camera), &full(source)?, source_camera, carried, out, params)?,
    })
}

/// The jitter of a reprojection from `source`'s G-buffer into `target`'s, if either has one.
fn jitter_between(target: &GBufferBuf, source: &GBufferBuf) -> Option<reproject::Jitter> {
    let jittered = target.jitter != [0.0; 2] || source.jitter != [0.0; 2];
    jittered.then_some(reproject::Jitter { target: target.jitter, source: source.jitter })
}

/// The buffer of a frame's that `eye` shows in `mode` (before any filter).
fn shown_image(buffers: &FrameBuffers, mode: Mode, eye: Eye, order: Order) -> &RgbBuf {
    match (mode, eye, order) {
        (Mode::PathTraced, ..) | (Mode::Stereo, Eye::Right, _) => &buffers.traced,
        (Mode::Stereo, Eye::Left, _) | (Mode::StereoBlend, ..) => &buffers.work,
        (Mode::SpatiotemporalBlend, _, Order::Paper) => &buffers.work,
        (Mode::Temporal | Mode::Spatiotemporal | Mode::SpatiotemporalBlend, ..) => &buffers.history,
    }
}

fn is_reprojected(code: u8) -> bool {
    code == Reason::Reprojected as u8
}

impl<S: FrameSource> Pipeline<S> {
    /// A pipeline over any [`FrameSource`], with every buffer allocated for frames of the
    /// cameras' extent (`cameras` = `[left, right]`, used only until the first frame gives
    /// its own). Frames are rendered with [`Pipeline::render_frame_at`]. A complete engine
    /// source is `examples/embed.rs`; `runtime/tests/frame_source.rs` checks one against the
    /// kernels called directly.
    pub fn with_source(source: S, config: PipelineConfig, cameras: [CameraModel; 2]) -> Result<Self, PipelineError> {
        config.validate().map_err(PipelineError::Config)?;
        let extent = cameras[0].extent;
        crate::kernels::frame::same_extent("right eye camera", extent, cameras[1].extent)?;
        let [left, right] = cameras;
        Ok(Self {
            source,
            config,
            rig: None,
            extent,
            eyes: [EyeState::try_new(left, &config)?, EyeState::try_new(right, &config)?],
            frames_done: 0,
            last_frame: 0,
            planner: BudgetPlanner::default(),
            jitter: [0.0; 2],
            gbuffers_lent: false,
            filtered_shown: false,
            fuse_left_restart: true,
            skip_kept_history: true,
            gradients_where_needed: true,
        })
    }

    /// A pipeline over `source` driven by head poses: `rig` turns each frame's head pose
    /// into eye cameras of `extent` ([`Pipeline::render_frame`]); `head` gives the cameras
    /// the buffers are allocated for until the first frame.
    pub fn with_rig(
        source: S,
        config: PipelineConfig,
        rig: StereoRig,
        head: &CameraPose,
        extent: Extent,
    ) -> Result<Self, PipelineError> {
        config.validate().map_err(PipelineError::Config)?;
        let cameras = [rig.eye_camera(head, Eye::Left, extent)?, rig.eye_camera(head, Eye::Right, extent)?];
        let mut pipeline = Self::with_source(source, config, cameras)?;
        pipeline.rig = Some(rig);
        Ok(pipeline)
    }

    /// The frame source.
    pub fn source(&self) -> &S {
        &self.source
    }

    /// The frame source, to change between frames (an engine's source updating its scene).
    pub fn source_mut(&mut self) -> &mut S {
        &mut self.source
    }

    /// The configuration the pipeline was built with.
    pub fn config(&self) -> &PipelineConfig {
        &self.config
    }

    /// The frame size of both eyes.
    pub fn extent(&self) -> Extent {
        self.extent
    }

    /// Resizes the pipeline to frames of `extent` without rebuilding it: every buffer is
    /// allocated anew (fallibly: on an error nothing changes), the source resizes its own
    /// ([`FrameSource::resize`]), and the history is forgotten ([`Pipeline::reset`]). Frames
    /// after it take cameras of the new extent; the output of the last frame is gone.
    pub fn resize(&mut self, extent: Extent) -> Result<(), PipelineError> {
        let camera = |c: &CameraModel| {
            let view_proj = glam::Mat4::from_cols_array_2d(&c.rows).transpose();
            CameraModel::new(view_proj, extent)
        };
        let eyes = [
            EyeState::try_new(camera(&self.eyes[0].camera)?, &self.config)?,
            EyeState::try_new(camera(&self.eyes[1].camera)?, &self.config)?,
        ];
        self.source.resize(extent)?;
        (self.eyes, self.extent) = (eyes, extent);
        self.reset();
        Ok(())
    }

    /// Renders the next frames' G-buffers with a sub-pixel camera jitter (TAA-style; for
    /// example a Halton sequence, changed every frame), in pixels (x right, y down), within
    /// one pixel: G-buffer pixel (x, y) then shows the surface at (x + 0.5 + jitter.x,
    /// y + 0.5 + jitter.y) of the unjittered camera (each G-buffer's `camera` is the jittered
    /// one, `CameraModel::jittered`). The traced images and the output stay on the unjittered
    /// grid, and reprojection reads the colour where each pixel's unjittered centre lands
    /// (`ReprojectInput::jitter`), so the history converges to the unjittered image. Both
    /// eyes share the jitter (the rasterised pass needs a parallel pair). `[0, 0]` (the
    /// default) is no jitter, bit for bit.
    pub fn set_jitter(&mut self, jitter: [f32; 2]) -> Result<(), PipelineError> {
        crate::kernels::camera::check_jitter(jitter)?;
        self.jitter = jitter;
        Ok(())
    }

    /// Changes the configuration between frames (an interactive viewer switching the mode or
    /// the budget). A change of the budget alone keeps everything, history included. Any other
    /// change allocates every buffer for the new configuration (fallibly: on an error nothing
    /// changes) and forgets the history ([`Pipeline::reset`]).
    pub fn reconfigure(&mut self, config: PipelineConfig) -> Result<(), PipelineError> {
        config.validate().map_err(PipelineError::Config)?;
        let budget_only = PipelineConfig { budget: self.config.budget, ..config } == self.config;
        if budget_only {
            self.config = config;
            return Ok(());
        }
        let eyes = [EyeState::try_new(self.eyes[0].camera, &config)?, EyeState::try_new(self.eyes[1].camera, &config)?];
        (self.eyes, self.config) = (eyes, config);
        self.planner = BudgetPlanner::default();
        self.reset();
        Ok(())
    }

    /// Forgets the history (the next frame starts fresh, as the first one did).
    pub fn reset(&mut self) {
        self.frames_done = 0;
    }

    /// The image `eye` shows for the last frame (filtered, with a [`Filter`]).
    pub fn output(&self, eye: Eye) -> &RgbBuf {
        let s = &self.eyes[eye as usize];
        match &s.cur.filtered {
            Some(filtered) if self.filtered_shown => filtered,
            _ => self.unfiltered_output(eye),
        }
    }

    /// The image `eye` shows for the last frame before any [`Filter`]: what reprojection and
    /// accumulation made (the same as [`Pipeline::output`] without a filter).
    pub fn unfiltered_output(&self, eye: Eye) -> &RgbBuf {
        shown_image(&self.eyes[eye as usize].cur, self.config.mode, eye, self.config.order)
    }

    /// The G-buffer of `eye` for the last frame. With the rasterised pass and the compact
    /// layout only its depth, octahedral-normal and material planes are written (what the
    /// reprojection reads); the position and normal planes stay NaN.
    pub fn gbuffer(&self, eye: Eye) -> &GBufferBuf {
        &self.eyes[eye as usize].cur.gbuffer
    }

    /// The stereo reprojection reason codes of `eye` for the last frame (all `Invalid` in
    /// modes without stereo reprojection into that eye).
    pub fn stereo_reasons(&self, eye: Eye) -> &PlaneBuf<u8> {
        &self.eyes[eye as usize].cur.stereo_reason
    }

    /// The temporal reprojection reason codes of `eye` for the last frame. In the paper-order
    /// spatiotemporal mode the left eye's history is reprojected only where its stereo
    /// reprojection failed; its other pixels read `Invalid` (see the module notes).
    pub fn temporal_reasons(&self, eye: Eye) -> &PlaneBuf<u8> {
        &self.eyes[eye as usize].cur.temporal_reason
    }

    /// 1 where `eye`'s pixel was path traced in the last frame, 0 elsewhere (reprojected,
    /// accumulated, or left for a later frame under a budget).
    pub fn traced_mask(&self, eye: Eye) -> &PlaneBuf<u8> {
        &self.eyes[eye as usize].cur.traced_mask
    }

    /// The temporal history of `eye` after the last frame: what the next frame reprojects
    /// (the shown image in the temporal and spatiotemporal modes; behind the blend in the
    /// paper-order spatiotemporal blend; unused, and all zeros, in modes without history).
    pub fn history(&self, eye: Eye) -> &RgbBuf {
        &self.eyes[eye as usize].cur.history
    }

    /// Frames rendered since the pipeline was made or [`Pipeline::reset`] (refused frames
    /// are not counted): the next frame has history when this is non-zero.
    pub fn frames_since_reset(&self) -> u32 {
        self.frames_done
    }

    /// Renders frame `frame` (the index keys the random numbers and places moving lights)
    /// seen from `head`.
    pub fn render_frame(&mut self, frame: u32, head: &CameraPose) -> Result<FrameStats, PipelineError> {
        let cameras = self.eye_cameras(head, Eye::BOTH)?;
        self.render_frame_at(frame, cameras)
    }

    /// The cameras of `eyes` for a head pose, through the pipeline's stereo rig.
    fn eye_cameras<const N: usize>(
        &self,
        head: &CameraPose,
        eyes: [Eye; N],
    ) -> Result<[CameraModel; N], PipelineError> {
        let rig = self.rig.as_ref().ok_or_else(|| {
            PipelineError::Config("this pipeline has no stereo rig: give eye cameras to render_frame_at".into())
        })?;
        let mut cameras = [None; N];
        for (c, eye) in cameras.iter_mut().zip(eyes) {
            *c = Some(rig.eye_camera(head, eye, self.extent)?);
        }
        Ok(cameras.map(|c| c.expect("every eye's camera was made")))
    }

    /// [`Pipeline::render_frame`] with the eye cameras given (`[left, right]`, of the
    /// pipeline's extent) instead of a head pose: what an engine with its own cameras calls.
    pub fn render_frame_at(&mut self, frame: u32, cameras: [CameraModel; 2]) -> Result<FrameStats, PipelineError> {
        self.render_with(frame, cameras, None)
    }

    /// [`Pipeline::render_frame_at`] with both eyes' G-buffers lent by the caller instead of
    /// filled by the source (zero-copy input; see [`GBufferView`] for which planes the
    /// configuration reads): the source's `fill_gbuffers` is not called, and the kernels read
    /// the caller's planes directly, at their strides. `current` are this frame's
    /// G-buffers, rendered for `cameras` jittered by [`Pipeline::set_jitter`]'s jitter, as a
    /// source's would be. `previous` are the G-buffers of the last frame this pipeline
    /// committed, unchanged since: temporal reprojection reads them. They may be `None` when
    /// there is no history (the first frame, after [`Pipeline::reset`] or a resize) or when
    /// the last frame's G-buffers were the pipeline's own (filled by the source); otherwise
    /// the call is refused. The views are read during the call only. After a lent frame,
    /// [`Pipeline::gbuffer`] does not hold that frame's planes (only its camera and jitter).
    pub fn render_frame_lent(
        &mut self,
        frame: u32,
        cameras: [CameraModel; 2],
        current: [GBufferView<'_>; 2],
        previous: Option<[GBufferView<'_>; 2]>,
    ) -> Result<FrameStats, PipelineError> {
        for (eye, view) in Eye::BOTH.into_iter().zip(&current) {
            view.check(&format!("{eye} G-buffer"), self.extent, &self.config)?;
        }
        for (eye, view) in Eye::BOTH.into_iter().zip(previous.iter().flatten()) {
            view.check(&format!("previous {eye} G-buffer"), self.extent, &self.config)?;
        }
        if self.frames_done > 0 && self.gbuffers_lent && previous.is_none() {
            return Err(PipelineError::Lent(
                "the last frame's G-buffers were lent, so the pipeline does not hold them: lend them again as \
                 `previous` (or reset the history)"
                    .into(),
            ));
        }
        self.render_with(frame, cameras, Some(Lent { current, previous }))
    }

    /// A frame, transactional: G-buffers from the source or `lent`.
    fn render_with(
        &mut self,
        frame: u32,
        cameras: [CameraModel; 2],
        lent: Option<Lent<'_>>,
    ) -> Result<FrameStats, PipelineError> {
        for camera in &cameras {
            crate::kernels::frame::same_extent("eye camera", self.extent, camera.extent)?;
        }
        let gbuffer_cameras = [cameras[0].jittered(self.jitter)?, cameras[1].jittered(self.jitter)?];
        let committed = self.begin_frame(cameras, gbuffer_cameras);
        match self.run_frame(frame, lent.as_ref()) {
            Ok(stats) => {
                self.frames_done += 1;
                self.last_frame = frame;
                self.gbuffers_lent = lent.is_some();
                self.filtered_shown = self.config.filter != Filter::None;
                Ok(stats)
            }
            Err(e) => {
                self.roll_back(committed);
                Err(e)
            }
        }
    }

    /// Starts a frame seen by `cameras` (the G-buffers' by `gbuffer_cameras`, the same but for
    /// jitter): the committed frame's buffers become the previous frame's (see
    /// [`EyeState`]). Returns what [`Pipeline::roll_back`] restores.
    fn begin_frame(&mut self, cameras: [CameraModel; 2], gbuffer_cameras: [CameraModel; 2]) -> Committed {
        let committed = Committed {
            cameras: self.eyes.each_ref().map(|s| s.camera),
            last_cameras: self.eyes.each_ref().map(|s| s.last_camera),
            last_frame: self.last_frame,
            planner: self.planner,
        };
        for ((s, camera), gbuffer_camera) in self.eyes.iter_mut().zip(cameras).zip(gbuffer_cameras) {
            std::mem::swap(&mut s.cur, &mut s.prev);
            s.last_camera = s.camera;
            s.camera = camera;
            (s.cur.gbuffer.camera, s.cur.gbuffer.jitter) = (gbuffer_camera, self.jitter);
        }
        committed
    }

    /// Undoes [`Pipeline::begin_frame`] after a refused frame: the committed buffers,
    /// cameras and planner are back, as if the call had never been made.
    fn roll_back(&mut self, committed: Committed) {
        for ((s, camera), last_camera) in self.eyes.iter_mut().zip(committed.cameras).zip(committed.last_cameras) {
            std::mem::swap(&mut s.cur, &mut s.prev);
            (s.camera, s.last_camera) = (camera, last_camera);
        }
        (self.planner, self.last_frame) = (committed.planner, committed.last_frame);
    }

    /// The body of [`Pipeline::render_frame_at`], between [`Pipeline::begin_frame`] and the
    /// commit or roll-back: writes only the in-flight buffers.
    fn run_frame(&mut self, frame: u32, lent: Option<&Lent<'_>>) -> Result<FrameStats, PipelineError> {
        let start = Instant::now();
        let mut stats = FrameStats { frame, budget: self.config.budget, ..FrameStats::default() };
        let has_history = self.frames_done > 0;
        self.planner.start_frame();

        // G-buffers of both eyes (last frame's are the temporal source).
        let t0 = Instant::now();
        self.source.begin_frame(frame);
        if lent.is_none() {
            let [left, right] = &mut self.eyes;
            stats.raster =
                self.source.fill_gbuffers([&mut left.cur.gbuffer, &mut right.cur.gbuffer], self.config.layout)?;
        }
        stats.times.gbuffer = t0.elapsed();

        let mode = self.config.mode;
        // Temporal reprojection of each eye's history.
        if mode.temporal() {
            let t = Instant::now();
            for eye in Eye::BOTH {
                if !(eye == Eye::Left && self.left_history_on_demand()) {
                    stats.temporal_reasons[eye as usize] = self.reproject_history(eye, has_history, false, lent)?;
                }
            }
            stats.times.reprojection += t.elapsed();
        }

        for &step in plan(mode, self.config.order) {
            match step {
                Step::Trace(eye) => self.trace_all(eye, &mut stats, start)?,
                Step::StereoFillLeft(source) => self.stereo_fill_left(source, &mut stats, start, lent)?,
                Step::StereoBlend(eye, source) => self.stereo_blend(eye, source, &mut stats, lent)?,
                // Fused, the EMA reads the temporal reasons at the stereo-discarded pixels only.
                Step::CombineLeftValidity if self.fuses_left_restart() => {}
                Step::CombineLeftValidity => {
                    // Stereo-valid pixels show the reprojected right-eye accumulation as is;
                    // the rest accumulate their own path-traced samples with the left history.
                    let s = &mut self.eyes[L];
                    for ((ema, &stereo), &temporal) in s
                        .ema_reason
                        .as_mut_slice()
                        .iter_mut()
                        .zip(s.cur.stereo_reason.as_slice())
                        .zip(s.cur.temporal_reason.as_slice())
                    {
                        *ema = if is_reprojected(stereo) { Reason::Invalid as u8 } else { temporal };
                    }
                }
                Step::Accumulate(eye, source) => self.accumulate(eye, source, &mut stats, lent)?,
            }
        }
        if self.config.filter == Filter::Atrous {
            let t = Instant::now();
            for eye in Eye::BOTH {
                self.filter(eye, &mut stats, lent)?;
            }
            stats.times.filter = t.elapsed();
        }
        stats.times.total = start.elapsed();
        self.planner.end_frame(stats.times.total);
        stats.budget_met = self.config.budget.is_none_or(|b| stats.times.total <= b);
        Ok(stats)
    }

    /// A mono frame, the baseline a stereo frame is compared with: the right eye alone path
    /// traced at the configured spp (primary rays included, so no G-buffer), nothing
    /// reprojected or accumulated. Under the configured budget it follows the rule every
    /// frame follows: pixels without any other data are traced whatever the budget, and a
    /// mono frame has no other data, so it traces every pixel and its statistics report
    /// whether it kept the budget. Writes the right eye's `traced` image, which
    /// [`Pipeline::render_frame`] rewrites; call [`Pipeline::reset`] before going back to
    /// stereo frames on the same pipeline.
    pub fn render_mono_frame(&mut self, frame: u32, head: &CameraPose) -> Result<FrameStats, PipelineError> {
        let [camera] = self.eye_cameras(head, [Eye::Right])?;
        self.render_mono_frame_at(frame, camera)
    }

    /// [`Pipeline::render_mono_frame`] with the right eye's camera given.
    pub fn render_mono_frame_at(&mut self, frame: u32, camera: CameraModel) -> Result<FrameStats, PipelineError> {
        crate::kernels::frame::same_extent("eye camera", self.extent, camera.extent)?;
        let start = Instant::now();
        let mut stats = FrameStats { frame, budget: self.config.budget, ..FrameStats::default() };
        self.source.begin_frame(frame);
        let config = self.config;
        let request = TraceRequest { eye: Eye::Right, frame, spp: config.spp, seed: config.seed, first_sample: 0 };
        let s = &mut self.eyes[Eye::Right as usize];
        // Traced into the spare image, swapped in only if the source succeeds.
        let rows = 0..self.extent.height();
        stats.trace = self.source.trace(&camera, &request, PixelSelection::All, rows, &mut s.prev.traced)?;
        std::mem::swap(&mut s.cur.traced, &mut s.prev.traced);
        stats.traced_pixels[Eye::Right as usize] = self.extent.pixels() as u64;
        stats.times.tracing = start.elapsed();
        if self.config.budget.is_some() {
            // Every pixel was urgent: the budget could cut none of it.
            stats.times.urgent_tracing = stats.times.tracing;
        }
        stats.times.total = start.elapsed();
        stats.budget_met = self.config.budget.is_none_or(|b| stats.times.total <= b);
        self.filtered_shown = false;
        Ok(stats)
    }

    /// Whether the left eye's temporal reprojection runs only where its stereo reprojection
    /// was discarded (see the module notes).
    fn left_history_on_demand(&self) -> bool {
        self.config.mode == Mode::Spatiotemporal && self.config.order == Order::Paper
    }

    /// Whether the left eye's stereo samples go straight into its history, and its EMA
    /// runs only where stereo reprojection was discarded (see the module notes). Not with
    /// the clamp, which reads the whole stereo-mode image as new samples. The temporal
    /// gradients read only the last frame's traced pixels of it, which the trace writes
    /// either way, and their confidence only where the EMA blends.
    fn fuses_left_restart(&self) -> bool {
        self.fuse_left_restart && self.left_history_on_demand() && self.config.history != History::Clamp
    }

    /// Whether the EMA of `source` is the left eye's fused one: it visits only the
    /// stereo-discarded pixels, and reads [`ema_validity`]'s temporal reasons there.
    fn ema_is_fused(&self, source: Source) -> bool {
        source == Source::WorkCombined && self.fuses_left_restart()
    }

    /// Whether an EMA of the eye's own samples (`source` [`Source::Traced`] or
    /// [`Source::Work`]) runs only where it changes something: at the pixels with a new
    /// sample or without a reprojected history. Elsewhere it would keep the history as the
    /// reprojection wrote it (clamped to the finite range and flushed, so the EMA's `finish`
    /// gives the same bits) and the length as reprojected: under a budget, nearly every
    /// pixel. Not with the clamp, which rewrites reprojected histories first (the temporal
    /// gradients' confidence changes only pixels with a new sample).
    fn skips_kept_history(&self, source: Source) -> bool {
        self.skip_kept_history
            && self.config.history != History::Clamp
            && matches!(source, Source::Traced | Source::Work)
    }

    fn reproject_params(&self) -> ReprojectParams {
        ReprojectParams { tolerances: self.config.tolerances, policy: self.config.policy, band_rows: 16 }
    }

    /// Reprojects `eye`'s previous history into this frame (`history`, `len`,
    /// `temporal_reason`); on the first frame every pixel is marked invalid. With
    /// `only_wanted`, only the pixels `wanted` marks are reprojected (the kernel's pixel mask;
    /// [`Pipeline::stereo_fill_left`] marks the stereo-discarded ones); the others are marked
    /// invalid, keep stale history (the EMA restarts them from the stereo sample) and are not
    /// counted.
    fn reproject_history(
        &mut self,
        eye: Eye,
        has_history: bool,
        only_wanted: bool,
        lent: Option<&Lent<'_>>,
    ) -> Result<ReasonCounts, PipelineError> {
        let params = self.reproject_params();
        let ramp = self.config.tracks_history_length();
        let layout = self.config.layout;
        let background = self.config.background == Background::Reproject;
        let s = &mut self.eyes[eye as usize];
        if !has_history {
            s.cur.temporal_reason.as_mut_slice().fill(Reason::Invalid as u8);
            return Ok(ReasonCounts::default());
        }
        let pixel_mask = only_wanted.then(|| s.wanted.view());
        // This frame's planes and the last committed frame's: lent or the pipeline's own.
        let target = lent.map_or_else(|| planes_of(&s.cur.gbuffer), |l| l.current[eye as usize]);
        let source = match lent.and_then(|l| l.previous) {
            Some(previous) => previous[eye as usize],
            None => planes_of(&s.prev.gbuffer),
        };
        let (history, len, reason) = (&mut s.cur.history, &mut s.cur.len, &mut s.cur.temporal_reason);
        let out = ReprojectOutput {
            colour: history.view_mut(),
            extra: ramp.then(|| len.view_mut()),
            reason: reason.view_mut(),
            weight: None,
        };
        let colour = s.prev.history.view();
        let extra = ramp.then(|| s.prev.len.view());
        let g = &s.cur.gbuffer;
        // The surfaces' own motion since the last frame, where the source gives it.
        let motion = target.motion;
        let (prev_camera, jitter) = (s.prev.gbuffer.camera, jitter_between(g, &s.prev.gbuffer));
        let carried = Carried { colour, extra, pixel_mask, motion, jitter, background };
        reproject_in(layout, (&target, g.camera), (&source, &prev_camera), carried, out, &params)
    }

    /// Stereo reprojection of the other eye's `source` image into `eye`'s `work` buffer (`for_blend`:
    /// with the other eye's history length too, where the variance-guided blend needs it).
    fn stereo_into(
        &mut self,
        eye: Eye,
        source: StereoSource,
        for_blend: bool,
        lent: Option<&Lent<'_>>,
    ) -> Result<ReasonCounts, PipelineError> {
        let params = self.reproject_params();
        let layout = self.config.layout;
        let background = self.config.background == Background::Reproject;
        // The fused restart: the stereo samples are the left eye's new history.
        let into_history = eye == Eye::Left && !for_blend && self.fuses_left_restart();
        let (target, other) = match eye {
            Eye::Left => {
                let [l, r] = &mut self.eyes;
                (l, &*r)
            }
            Eye::Right => {
                let [l, r] = &mut self.eyes;
                (r, &*l)
            }
        };
        let colour = match source {
            StereoSource::Traced => other.cur.traced.view(),
            StereoSource::History => other.cur.history.view(),
        };
        // The variance-guided blend of histories weighs by their lengths: the other eye's
        // comes along with its image.
        let (extra, extra_out) = match (&mut target.stereo_len, source) {
            (Some(len), StereoSource::History) if for_blend => (Some(other.cur.len.view()), Some(len.view_mut())),
            _ => (None, None),
        };
        let (target_planes, source_planes) = match lent {
            Some(l) => (l.current[eye as usize], l.current[1 - eye as usize]),
            None => (planes_of(&target.cur.gbuffer), planes_of(&other.cur.gbuffer)),
        };
        let out = ReprojectOutput {
            colour: if into_history { target.cur.history.view_mut() } else { target.cur.work.view_mut() },
            extra: extra_out,
            reason: target.cur.stereo_reason.view_mut(),
            weight: None,
        };
        let jitter = jitter_between(&target.cur.gbuffer, &other.cur.gbuffer);
        let carried = Carried { colour, extra, pixel_mask: None, motion: None, jitter, background };
        let target_view = (&target_planes, target.cur.gbuffer.camera);
        reproject_in(layout, target_view, (&source_planes, &other.cur.gbuffer.camera), carried, out, &params)
    }

    /// The stereo-mode left image in `work`: the right eye's `source` reprojected where
    /// valid, path traced where discarded.
    fn stereo_fill_left(
        &mut self,
        source: StereoSource,
        stats: &mut FrameStats,
        start: Instant,
        lent: Option<&Lent<'_>>,
    ) -> Result<(), PipelineError> {
        let t = Instant::now();
        let stereo = self.stereo_into(Eye::Left, source, false, lent)?;
        stats.stereo_reasons[L] = stereo;
        let fused = self.fuses_left_restart();
        let track_len = self.config.tracks_history_length();
        // Wanted (traced, and the left history reprojected): where stereo was discarded.
        let s = &mut self.eyes[L];
        for (wanted, &stereo) in s.wanted.as_mut_slice().iter_mut().zip(s.cur.stereo_reason.as_slice()) {
            *wanted = u8::from(!is_reprojected(stereo));
        }
        if fused {
            // The rest of the EMA's restart at the stereo-valid pixels: a history of one
            // sample, and the restart counted as the EMA counts it.
            if track_len {
                for (len, &stereo) in s.cur.len.as_mut_slice().iter_mut().zip(s.cur.stereo_reason.as_slice()) {
                    *len = if is_reprojected(stereo) { 1.0 } else { *len };
                }
            }
            stats.accumulation[L].resets += stereo.get(Reason::Reprojected);
        }
        if self.left_history_on_demand() && self.config.mode.temporal() {
            stats.temporal_reasons[L] = self.reproject_history(Eye::Left, self.frames_done > 0, true, lent)?;
        }
        stats.times.reprojection += t.elapsed();
        let s = &mut self.eyes[L];
        let temporal_valid = self.config.mode.temporal() && self.frames_done > 0;
        for ((urgent, &stereo), &temporal) in
            s.urgent.as_mut_slice().iter_mut().zip(s.cur.stereo_reason.as_slice()).zip(s.cur.temporal_reason.as_slice())
        {
            // Urgent: neither a stereo sample nor a temporal history to fall back on.
            *urgent = u8::from(!(is_reprojected(stereo) || (temporal_valid && is_reprojected(temporal))));
        }
        self.trace_wanted(Eye::Left, Target::Work, stats, start)?;
        if !fused {
            // Where nothing was traced, the stereo sample (if valid) is the new sample.
            let s = &mut self.eyes[L];
            for (has, &stereo) in s.has_new.as_mut_slice().iter_mut().zip(s.cur.stereo_reason.as_slice()) {
                *has |= u8::from(is_reprojected(stereo));
            }
        }
        Ok(())
    }

    /// `eye`'s `work` = blend of its own image and the other eye's reprojection.
    fn stereo_blend(
        &mut self,
        eye: Eye,
        source: StereoSource,
        stats: &mut FrameStats,
        lent: Option<&Lent<'_>>,
    ) -> Result<(), PipelineError> {
        let t = Instant::now();
        stats.stereo_reasons[eye as usize] = self.stereo_into(eye, source, true, lent)?;
        stats.times.reprojection += t.elapsed();
        let t = Instant::now();
        let params = BlendParams { own_weight: self.config.blend_own_weight, band_rows: 16 };
        let s = &mut self.eyes[eye as usize];
        let own = match source {
            StereoSource::Traced => s.cur.traced.view(),
            StereoSource::History => s.cur.history.view(),
        };
        let reason = s.cur.stereo_reason.view();
        let blend = match (&s.stereo_len, source) {
            (Some(other_len), StereoSource::History) => {
                let lengths = accumulate::BlendLengths {
                    own: s.cur.len.view(),
                    other: other_len.view(),
                    alpha: self.config.alpha,
                };
                accumulate::blend_by_variance(&own, s.cur.work.view_mut(), &reason, &lengths, params.band_rows)?
            }
            _ => accumulate::blend(&own, s.cur.work.view_mut(), &reason, &params)?,
        };
        let acc = &mut stats.accumulation[eye as usize];
        acc.non_finite += blend.non_finite;
        acc.holes += blend.holes;
        stats.times.accumulation += t.elapsed();
        Ok(())
    }

    /// Path traces every pixel of `eye` (those without valid history first under a budget).
    fn trace_all(&mut self, eye: Eye, stats: &mut FrameStats, start: Instant) -> Result<(), PipelineError> {
        let temporal_valid = self.config.mode.temporal() && self.frames_done > 0;
        let s = &mut self.eyes[eye as usize];
        s.wanted.as_mut_slice().fill(1);
        for (urgent, &temporal) in s.urgent.as_mut_slice().iter_mut().zip(s.cur.temporal_reason.as_slice()) {
            *urgent = u8::from(!(temporal_valid && is_reprojected(temporal)));
        }
        self.trace_wanted(eye, Target::Traced, stats, start)
    }

    /// Traces the `wanted` pixels of `eye` into `target`: all of them without a budget;
    /// with one, the `urgent` ones first, then the rest tile by tile while time remains.
    /// Leaves `has_new` = what was traced.
    fn trace_wanted(
        &mut self,
        eye: Eye,
        target: Target,
        stats: &mut FrameStats,
        start: Instant,
    ) -> Result<(), PipelineError> {
        let t = Instant::now();
        let config = self.config;
        let s = &mut self.eyes[eye as usize];
        let request = TraceRequest { eye, frame: stats.frame, spp: config.spp, seed: config.seed, first_sample: 0 };
        let out = match target {
            Target::Traced => &mut s.cur.traced,
            Target::Work => &mut s.cur.work,
        };
        let height = self.extent.height();
        match config.budget {
            None => {
                let trace = self.source.trace(&s.camera, &request, PixelSelection::Mask(&s.wanted), 0..height, out)?;
                stats.trace = stats.trace + trace;
                s.has_new.as_mut_slice().copy_from_slice(s.wanted.as_slice());
                let wanted_count = count_set(s.wanted.as_slice());
                stats.wanted_pixels[eye as usize] += wanted_count;
                stats.traced_pixels[eye as usize] += wanted_count;
            }
            Some(budget) => {
                // Urgent pixels first (whole frame, from `has_new`), then the others (the
                // rest of `wanted`, in `urgent`, reused) tile by tile.
                let (wanted_count, urgent_count) =
                    split_urgent(s.wanted.as_slice(), s.urgent.as_mut_slice(), s.has_new.as_mut_slice());
                stats.wanted_pixels[eye as usize] += wanted_count;
                let urgent_start = Instant::now();
                let trace = self.source.trace(&s.camera, &request, PixelSelection::Mask(&s.has_new), 0..height, out)?;
                stats.times.urgent_tracing += urgent_start.elapsed();
                stats.trace = stats.trace + trace;
                stats.traced_pixels[eye as usize] += urgent_count;
                let tile = config.tile_rows;
                let mut y0 = 0;
                while y0 < height && self.planner.fits(eye, start.elapsed(), tile, budget) {
                    let rows = y0..(y0 + tile).min(height);
                    let tile_start = Instant::now();
                    let trace =
                        self.source.trace(&s.camera, &request, PixelSelection::Mask(&s.urgent), rows.clone(), out)?;
                    stats.trace = stats.trace + trace;
                    let w = self.extent.width();
                    let span = rows.start * w..rows.end * w;
                    let rest = &s.urgent.as_slice()[span.clone()];
                    stats.traced_pixels[eye as usize] += count_set(rest);
                    for (has, &u) in s.has_new.as_mut_slice()[span].iter_mut().zip(rest) {
                        *has |= u;
                    }
                    self.planner.tile_done(eye, rows.len(), tile_start.elapsed());
                    y0 = rows.end;
                }
                self.planner.loop_done(start.elapsed());
            }
        }
        // What was traced, before a stereo fill adds its reprojected pixels to `has_new`.
        s.cur.traced_mask.as_mut_slice().copy_from_slice(s.has_new.as_slice());
        stats.times.tracing += t.elapsed();
        Ok(())
    }

    /// The à-trous filter of `eye`'s shown image into its `filtered` buffer, guided by this
    /// frame's G-buffer (lent or the pipeline's own).
    fn filter(&mut self, eye: Eye, stats: &mut FrameStats, lent: Option<&Lent<'_>>) -> Result<(), PipelineError> {
        let (mode, order, layout) = (self.config.mode, self.config.order, self.config.layout);
        let s = &mut self.eyes[eye as usize];
        let (Some(mut filtered), Some(scratch)) = (s.cur.filtered.take(), s.atrous.as_mut()) else {
            return Ok(());
        };
        let planes = lent.map_or_else(|| planes_of(&s.cur.gbuffer), |l| l.current[eye as usize]);
        let normals = match (layout, planes.normal_oct, planes.normal) {
            (Layout::Compact, Some(oct), _) => GuideNormals::Octahedral(oct),
            (_, _, Some(n)) => GuideNormals::Planes(n),
            (_, Some(oct), None) => GuideNormals::Octahedral(oct),
            (_, None, None) => return Err(FrameError::InvalidParameter("a G-buffer without normals").into()),
        };
        let guide = AtrousGuide { depth: planes.depth, normals };
        let params = AtrousParams { iterations: ATROUS_ITERATIONS, ..AtrousParams::default() };
        let input = shown_image(&s.cur, mode, eye, order).view();
        let result = atrous::atrous(&input, &guide, &params, scratch, filtered.view_mut());
        // Put the buffer back whatever happened (a refused frame rolls back to it).
        s.cur.filtered = Some(filtered);
        stats.filter_out_of_range[eye as usize] = result?.out_of_range;
        Ok(())
    }

    /// EMA of `eye`'s reprojected history with this frame's `source` samples.
    fn accumulate(
        &mut self,
        eye: Eye,
        source: Source,
        stats: &mut FrameStats,
        lent: Option<&Lent<'_>>,
    ) -> Result<(), PipelineError> {
        let gradients = self.temporal_gradients(eye, source, stats, lent)?;
        let t = Instant::now();
        let params = EmaParams { alpha: self.config.alpha, ramp: self.config.ramp, band_rows: 16 };
        let track_len = self.config.tracks_history_length();
        let fused = self.ema_is_fused(source);
        let skip_kept = self.skips_kept_history(source);
        let s = &mut self.eyes[eye as usize];
        let new = match source {
            Source::Traced => s.cur.traced.view(),
            Source::Work | Source::WorkCombined => s.cur.work.view(),
        };
        let reason = ema_validity(&s.ema_reason, &s.cur.temporal_reason, source, fused).view();
        let pixel_mask = if fused {
            Some(s.wanted.view())
        } else if skip_kept && kept_history_mask(&mut s.urgent, &s.has_new, &reason) {
            // `urgent` is free once the eye is traced.
            Some(s.urgent.view())
        } else {
            None
        };
        // The gradients' confidence (the engine's already multiplied in), or the engine's.
        let confidence = match (gradients, &s.gradient) {
            (true, Some(g)) => Some(g.confidence.view()),
            _ => Self::engine_confidence(&s.cur.gbuffer, eye, lent),
        };
        if self.config.history == History::Clamp {
            let input = ClampInput { new, has_new: Some(s.has_new.view()), reason };
            let params = ClampParams { gamma: CLAMP_GAMMA, ..ClampParams::default() };
            let clamp = clamp::clamp_history(&input, s.cur.history.view_mut(), &params)?;
            stats.history_clamped[eye as usize] += clamp.clamped;
        }
        let input = EmaInput { new, reason, has_new: Some(s.has_new.view()), confidence, pixel_mask };
        let state = EmaState { accum: s.cur.history.view_mut(), history_len: track_len.then(|| s.cur.len.view_mut()) };
        let acc = accumulate::ema(&input, state, &params)?;
        let total = &mut stats.accumulation[eye as usize];
        total.non_finite += acc.non_finite;
        total.holes += acc.holes;
        total.resets += acc.resets;
        stats.times.accumulation += t.elapsed();
        Ok(())
    }
}

/// The validity plane an EMA of `source` reads (`ema_reason` and `temporal_reason` are the
/// eye's): the temporal reasons, except for the paper order's left eye (`WorkCombined`),
/// whose plane [`Step::CombineLeftValidity`] combined. With the left eye's restart `fused`
/// into the stereo pass, that EMA visits only the stereo-discarded pixels, where the
/// combination is the temporal reason. The EMA and the gradients' choice of strata both
/// take it from here, so they read the same plane.
fn ema_validity<'p>(
    ema_reason: &'p PlaneBuf<u8>,
    temporal_reason: &'p PlaneBuf<u8>,
    source: Source,
    fused: bool,
) -> &'p PlaneBuf<u8> {
    match source {
        Source::WorkCombined if !fused => ema_reason,
        Source::Traced | Source::Work | Source::WorkCombined => temporal_reason,
    }
}

/// Writes into `mask` the pixels an EMA must visit: those with a new sample (`has_new`) or
/// without a reprojected history (`reason`). Returns whether any pixel may be skipped (a
/// frame that traced every pixel runs the unmasked EMA).
fn kept_history_mask(mask: &mut PlaneBuf<u8>, has_new: &PlaneBuf<u8>, reason: &Plane<'_, u8>) -> bool {
    use rayon::prelude::*;
    let reprojected = Reason::Reprojected as u8;
    let width = reason.width();
    // Rows in parallel: a pass over three bytes a pixel, in the frame's serial part otherwise.
    let visited: usize = (mask.as_mut_slice().par_chunks_exact_mut(width), has_new.as_slice().par_chunks_exact(width))
        .into_par_iter()
        .enumerate()
        .with_min_len(16)
        .map(|(y, (row, has_new))| {
            let mut row_visited = 0u32;
            for ((m, &h), &r) in row.iter_mut().zip(has_new).zip(reason.row(y)) {
                *m = h | u8::from(r != reprojected);
                row_visited += u32::from(*m != 0);
            }
            row_visited as usize
        })
        .sum();
    visited < mask.as_slice().len()
}

/// How many bytes of `mask` are set (counted in blocks of `u32`, which vectorise).
fn count_set(mask: &[u8]) -> u64 {
    mask.chunks(1 << 16).map(|block| u64::from(block.iter().map(|&m| u32::from(m != 0)).sum::<u32>())).sum()
}

/// One pass over an eye's 0/1 masks before tracing under a budget: `has_new` = the wanted
/// urgent pixels (traced first, whatever the budget), `urgent` = the rest of `wanted` (traced
/// tile by tile while time remains). Returns how many pixels are wanted, and how many of them
/// urgent.
fn split_urgent(wanted: &[u8], urgent: &mut [u8], has_new: &mut [u8]) -> (u64, u64) {
    const BLOCK: usize = 1 << 16;
    let (mut wanted_count, mut urgent_count) = (0, 0);
    for ((w, u), h) in wanted.chunks(BLOCK).zip(urgent.chunks_mut(BLOCK)).zip(has_new.chunks_mut(BLOCK)) {
        let (mut block_wanted, mut block_urgent) = (0u32, 0u32);
        for ((&w, u), h) in w.iter().zip(u.iter_mut()).zip(h.iter_mut()) {
            let first = w & *u;
            (*h, *u) = (first, w & !first & 1);
            block_wanted += u32::from(w != 0);
            block_urgent += u32::from(first != 0);
        }
        wanted_count += u64::from(block_wanted);
        urgent_count += u64::from(block_urgent);
    }
    (wanted_count, urgent_count)
}
