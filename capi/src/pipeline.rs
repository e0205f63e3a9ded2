//! The frame pipeline behind the C ABI: over this project's renderer on a scene
//! ([`stereotrace_pipeline_create_scene`]), or over an engine's own G-buffers and tracer
//! given as C callbacks ([`stereotrace_pipeline_create_callbacks`]). Either way the pipeline
//! owns its buffers and worker threads; the caller reads images out with
//! [`stereotrace_pipeline_output`].

use std::ffi::{CStr, c_char, c_void};
use std::time::Duration;

use stereotrace_kernels::frame::same_extent;
use stereotrace_kernels::reproject::Tolerances;
use stereotrace_kernels::{CameraModel, Extent, GBufferBuf, PlaneBuf, RgbBuf};
use stereotrace_runtime::camera::{Eye, StereoRig};
use stereotrace_runtime::pipeline::{
    Background, Blend, Filter, FrameStats, GBufferView, History, Layout, MAX_SPP, Mode, Order, Pipeline,
    PipelineConfig, PipelineError, budget_duration, check_spp,
};
use stereotrace_runtime::render::{Renderer, RendererSource};
use stereotrace_runtime::source::{FrameSource, PixelSelection, RasterPassStats, TraceRequest, TraceStats};

use crate::boundary::{Context, Exclusive, Failure, StStatus, guard};
use crate::context::{check_threads, thread_pool};
use crate::kernels::{StCamera, StLayout, StReprojectParams};
use crate::views::{
    Borrows, StPlaneF32, StPlaneMutF32, StPlaneMutU8, StPlaneU8, StPlaneU32, StRgb, StRgbMut, required,
};

/// The pipeline's modes (the paper's Section IV): the values of [`StPipelineConfig::mode`].
/// Each names which eye the trace callback is asked for: "both" means every pixel of each eye
/// (under a budget, the pixels without valid history first, then tiles while time remains).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StMode {
    /// Both eyes fully path traced. Traces both eyes.
    PathTraced = 0,
    /// The left eye reprojected from the right, traced where discarded. Traces the right
    /// eye, and the left eye's discarded pixels only.
    Stereo = 1,
    /// Each eye accumulates its own reprojected history. Traces both eyes.
    Temporal = 2,
    /// Stereo and temporal reprojection combined. Traces the right eye, and the left eye's
    /// pixels where stereo reprojection was discarded only.
    Spatiotemporal = 3,
    /// Each eye blends its own samples with the other's reprojection. Traces both eyes.
    StereoBlend = 4,
    /// The blend over accumulated histories. Traces both eyes.
    SpatiotemporalBlend = 5,
}

/// Order of stereo and temporal reprojection: the values of [`StPipelineConfig::order`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StOrder {
    /// The paper's: temporal accumulation first, then stereo reprojection of the history.
    Paper = 0,
    /// Stereo reprojection of this frame's samples first, then accumulation.
    StereoFirst = 1,
}

/// How far the EMA trusts a reprojected history: the values of
/// [`StPipelineConfig::history`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StHistory {
    /// The paper's: wherever reprojection keeps it (it sees geometry, not lighting).
    Paper = 0,
    /// Also shortened where the lighting changed, measured by temporal gradients (A-SVGF):
    /// each frame, one reprojected sample of the last frame per 3×3 stratum is re-shaded.
    /// A callback pipeline asks `trace` for them as for any pixels, but with the last
    /// frame's number and camera (and a mask of the chosen pixels): the engine renders
    /// them with that frame's random numbers under its current lights and geometry. A
    /// scene pipeline whose lights and geometry never change traces none.
    Gradient = 1,
    /// Clamped before the EMA into the range this frame's samples around the pixel allow
    /// (TAA's variance clipping over the 3×3 neighbourhood of new samples, γ = 2). Asks
    /// nothing more of the engine.
    Clamp = 2,
}

/// How the stereo blend weighs an eye's own image against the other eye's reprojection:
/// the values of [`StPipelineConfig::blend`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StBlend {
    /// The paper's: ½ each.
    Fixed = 0,
    /// By inverse variance, from each eye's history length: it changes only the paper-order
    /// `ST_MODE_SPATIOTEMPORAL_BLEND` (equal lengths give the fixed blend bit for bit).
    Variance = 1,
}

/// A spatial filter of each eye's shown image: the values of [`StPipelineConfig::filter`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StFilter {
    /// The paper's: none.
    None = 0,
    /// The edge-avoiding à-trous filter (SVGF's edge-stopping functions, five passes)
    /// guided by each eye's G-buffer depth and normals. A display filter:
    /// `stereotrace_pipeline_output` is filtered, the histories are not.
    Atrous = 1,
}

/// What reprojection does with background pixels (no surface: a sky): the values of
/// [`StPipelineConfig::background`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StBackground {
    /// The paper's: discarded, so every background pixel is traced every frame.
    Trace = 0,
    /// Reprojected by view direction as points at infinity, from background taps: a sky
    /// that stays in view keeps its history and costs no ray. Only for a background that
    /// does not change between frames.
    Reproject = 1,
}

/// Settings of a pipeline (see [`stereotrace_pipeline_config_default`]).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StPipelineConfig {
    /// A `StMode` value.
    pub mode: u32,
    /// A `StOrder` value.
    pub order: u32,
    /// A `StLayout` value: the G-buffer planes reprojection reads (and a callback source
    /// must fill).
    pub layout: u32,
    /// Samples per traced pixel, 1 ..= `STEREOTRACE_MAX_SPP` (passed to the trace callback).
    pub spp: u32,
    /// Frame width per eye, in pixels (1 ..= `STEREOTRACE_MAX_DIMENSION`).
    pub width: u32,
    /// Frame height per eye, in pixels (1 ..= `STEREOTRACE_MAX_DIMENSION`, at most
    /// `STEREOTRACE_MAX_PIXELS` with the width).
    pub height: u32,
    /// Worker threads (0: one per logical CPU; at most `STEREOTRACE_MAX_THREADS`).
    pub threads: u32,
    /// Time budget per stereo frame in milliseconds, 0 for none (trace everything); else
    /// finite, > 0 and at most `STEREOTRACE_MAX_BUDGET_MS`. It covers the whole render call,
    /// the callbacks' time included. G-buffers, reprojection, accumulation and the pixels
    /// with no reprojected data run whatever the budget; the rest is traced tile by tile
    /// (8 rows) while the planner predicts the frame still fits, so a frame may overrun by
    /// about one tile's misprediction, or by the work that always runs.
    pub budget_ms: f64,
    /// Seed of the path tracer's random numbers (scene pipelines; a callback source has its
    /// own).
    pub seed: u64,
    /// In, read during the create call only: reprojection tolerances and tap policy; null
    /// for the scene's own tolerances (scene pipelines) or the room-scale defaults of
    /// `stereotrace_reproject_params_default` (callback pipelines).
    pub reprojection: *const StReprojectParams,
    /// 1: each G-buffer given to `fill_gbuffers` has a `history_confidence` plane for the
    /// engine to fill (see [`StGBufferMut::history_confidence`]); 0: none (the plain EMA).
    pub history_confidence: u32,
    /// 1: each G-buffer has motion planes, which temporal reprojection follows (moving
    /// objects keep their history): a callback pipeline hands them to `fill_gbuffers` (see
    /// [`StGBufferMut::motion`]), a scene pipeline fills them from the scene's moving area
    /// lights; 0: none (every surface is taken as still).
    pub motion_vectors: u32,
    /// Callback pipelines: 0 (the default) calls `trace` once per eye (or budget tile) from
    /// one worker thread at a time; N ≥ 1 declares the engine's `trace` thread-safe and splits
    /// each call's rows into bands of N rows, called concurrently from the pipeline's worker
    /// threads (`config.threads` of them): the engine's own tracing then runs in parallel
    /// without a job system of its own. Bands of one call cover its rows exactly once; a
    /// band that fails refuses the frame like any failing call. Scene pipelines ignore it.
    pub trace_band_rows: u32,
    /// A `StHistory` value (the paper's: `ST_HISTORY_PAPER`).
    pub history: u32,
    /// A `StBlend` value (the paper's: `ST_BLEND_FIXED`).
    pub blend: u32,
    /// A `StFilter` value (the paper's: `ST_FILTER_NONE`).
    pub filter: u32,
    /// A `StBackground` value (the paper's: `ST_BACKGROUND_TRACE`).
    pub background: u32,
}

/// Spatiotemporal mode in the paper's order and with the paper's history, blend and (no)
/// filter, compact G-buffers, 1 spp, 1280×720, one thread per CPU, no budget, seed 1.
#[unsafe(no_mangle)]
pub extern "C" fn stereotrace_pipeline_config_default() -> StPipelineConfig {
    StPipelineConfig {
        mode: StMode::Spatiotemporal as u32,
        order: StOrder::Paper as u32,
        layout: StLayout::Compact as u32,
        spp: 1,
        width: 1280,
        height: 720,
        threads: 0,
        budget_ms: 0.0,
        seed: 1,
        reprojection: std::ptr::null(),
        history_confidence: 0,
        motion_vectors: 0,
        trace_band_rows: 0,
        history: StHistory::Paper as u32,
        blend: StBlend::Fixed as u32,
        filter: StFilter::None as u32,
        background: StBackground::Trace as u32,
    }
}

impl StPipelineConfig {
    fn extent(&self) -> Result<Extent, Failure> {
        Extent::new(self.width as usize, self.height as usize).about("config size")
    }

    /// The runtime's configuration, with `tolerances` unless the caller gave its own.
    ///
    /// # Safety
    /// `self.reprojection` null or valid.
    unsafe fn runtime(&self, tolerances: Tolerances) -> Result<PipelineConfig, Failure> {
        let mode = match self.mode {
            0 => Mode::PathTraced,
            1 => Mode::Stereo,
            2 => Mode::Temporal,
            3 => Mode::Spatiotemporal,
            4 => Mode::StereoBlend,
            5 => Mode::SpatiotemporalBlend,
            other => return Err(Failure::invalid(format!("config.mode {other} is not a StMode (0 ..= 5)"))),
        };
        // The pipeline's own rule, as the CLI's `--spp` applies it.
        check_spp(self.spp)
            .map_err(|e| Failure::invalid(format!("config.spp: {e} (STEREOTRACE_MAX_SPP ({MAX_SPP}) is the most)")))?;
        let mut c = PipelineConfig::paper(mode, self.spp, tolerances);
        c.order = match self.order {
            0 => Order::Paper,
            1 => Order::StereoFirst,
            other => return Err(Failure::invalid(format!("config.order {other} is not a StOrder (0 or 1)"))),
        };
        c.layout = StLayout::parse(self.layout, "config.layout")?;
        c.seed = self.seed;
        c.history_confidence = match self.history_confidence {
            0 => false,
            1 => true,
            other => return Err(Failure::invalid(format!("config.history_confidence must be 0 or 1, got {other}"))),
        };
        c.motion_vectors = match self.motion_vectors {
            0 => false,
            1 => true,
            other => return Err(Failure::invalid(format!("config.motion_vectors must be 0 or 1, got {other}"))),
        };
        c.history = match self.history {
            0 => History::Paper,
            1 => History::Gradient,
            2 => History::Clamp,
            other => return Err(Failure::invalid(format!("config.history {other} is not a StHistory (0 to 2)"))),
        };
        c.blend = match self.blend {
            0 => Blend::Fixed,
            1 => Blend::Variance,
            other => return Err(Failure::invalid(format!("config.blend {other} is not a StBlend (0 or 1)"))),
        };
        c.filter = match self.filter {
            0 => Filter::None,
            1 => Filter::Atrous,
            other => return Err(Failure::invalid(format!("config.filter {other} is not a StFilter (0 or 1)"))),
        };
        c.background = match self.background {
            0 => Background::Trace,
            1 => Background::Reproject,
            other => return Err(Failure::invalid(format!("config.background {other} is not a StBackground (0 or 1)"))),
        };
        // SAFETY: the caller's contract.
        if let Some(r) = unsafe { self.reprojection.as_ref() } {
            let r = r.kernel()?;
            (c.tolerances, c.policy) = (r.tolerances, r.policy);
        }
        // 0 means no budget; anything else is checked as the CLI checks `--budget-ms`.
        c.budget = match self.budget_ms {
            0.0 => None,
            ms => Some(budget_duration(ms).map_err(|e| Failure::invalid(format!("config.budget_ms: {e}")))?),
        };
        Ok(c)
    }

    fn check_threads(&self) -> Result<(), Failure> {
        check_threads(self.threads, "config.threads")
    }

    /// The worker threads, started after every buffer is allocated: nothing to stop if an
    /// allocation fails, and the buffers exist before the threads that fill them (what a
    /// race detector needs to see).
    fn pool(&self) -> Result<rayon::ThreadPool, Failure> {
        thread_pool(self.threads, "config.threads", "stereotrace-pipeline")
    }
}

/// A writable plane of `uint32_t`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StPlaneMutU32 {
    /// Pixel `(0, 0)`; pixel `(x, y)` is `data[y * stride + x]`.
    pub data: *mut u32,
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Elements from one row's start to the next (at least `width`).
    pub stride: u32,
}

/// One eye's G-buffer for a callback source to fill: planes owned by the pipeline, of the
/// pipeline's size (packed: stride = width), valid only during the `fill_gbuffers` call.
/// Every plane is an output the callback writes for every pixel; `camera` is an input. With
/// `ST_LAYOUT_COMPACT` the pipeline reads `depth` and `normal_octahedral` only; with
/// `ST_LAYOUT_FULL`, `depth`, `position` and `normal`. `material` is the source's own (kept,
/// not read by the pipeline). Depth is `+INFINITY` where the pixel sees no surface. Units
/// are the scene's (the reprojection tolerances are in the same units).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StGBufferMut {
    /// Out: view-axis depth of the surface at the pixel centre, > 0 (`+INFINITY`: none).
    pub depth: StPlaneMutF32,
    /// Out: world position x, y, z (full layout).
    pub position: [StPlaneMutF32; 3],
    /// Out: world shading normal x, y, z (full layout; need not be unit length).
    pub normal: [StPlaneMutF32; 3],
    /// Out: `stereotrace_encode_normal` of the shading normal (compact layout).
    pub normal_octahedral: StPlaneMutU32,
    /// Out: the source's own material id per pixel (not read by the pipeline).
    pub material: StPlaneMutU32,
    /// In: the camera this G-buffer is for, as given to `stereotrace_pipeline_render_frame_at`
    /// (left: `cameras[0]`, right: `cameras[1]`). A copy: writing it changes nothing.
    pub camera: StCamera,
    /// In: the sub-pixel jitter to render this G-buffer with, in pixels (x right, y down), as
    /// set by `stereotrace_pipeline_set_jitter` (0, 0 without): pixel (x, y) must show the
    /// surface `camera` sees at `(x + 0.5 + jitter[0], y + 0.5 + jitter[1])` (a TAA projection
    /// offset). The traced images stay on the unjittered grid.
    pub jitter: [f32; 2],
    /// Out, only with `config.history_confidence` (else `data` is null): how far each pixel's
    /// history can be trusted, in [0, 1] (1 when the engine writes nothing: it holds the value
    /// of the frame before last otherwise, so write every pixel or none). The EMA weighs the
    /// history by it: 1 is the plain EMA, 0 restarts the pixel from this frame's sample (a
    /// light that moved, a disocclusion the engine knows of). A value outside [0, 1] or NaN
    /// refuses the frame.
    pub history_confidence: StPlaneMutF32,
    /// Out, only with `config.motion_vectors` (else every `data` is null): the world-space
    /// motion x, y, z of each pixel's surface since the previous frame, in scene units (0 when
    /// the engine writes nothing: like `history_confidence`, the planes hold the frame before
    /// last's values otherwise, so write every pixel or none). The surface at a pixel was at
    /// `position − motion` then; temporal reprojection looks for it there. 0 is a still
    /// surface; a non-finite vector discards the pixel's history (`ST_REASON_INVALID`).
    pub motion: [StPlaneMutF32; 3],
}

/// An engine's renderer as the pipeline's frame source.
///
/// **Threads.** The callbacks run on one of the pipeline's worker threads (not the thread
/// that called `stereotrace_pipeline_render_frame_at`, which waits), one at a time, only
/// during that call: first `fill_gbuffers` once, then `trace` once per eye without a budget
/// or once per tile of rows under one (and, with `ST_HISTORY_GRADIENT`, once per eye for
/// the gradient samples). With `config.trace_band_rows` ≥ 1 each of those
/// `trace` calls becomes one call per band of rows, concurrent on the pipeline's workers (the
/// engine declares `trace` thread-safe). `user` must be usable from that thread, and anything
/// the callbacks share with the engine's other threads needs the engine's own
/// synchronisation. From a callback, any call on the same pipeline returns `ST_STATUS_BUSY`
/// (and changes nothing); calls on other pipelines and contexts are allowed.
///
/// **Failure.** A callback that returns non-zero refuses the frame: the render call returns
/// `ST_STATUS_CALLBACK_FAILED` with the value in the message, and the pipeline's output,
/// history and statistics stay exactly as they were before the call (transactional frames).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StFrameSourceCallbacks {
    /// Passed to both callbacks as is; owned by the engine, which keeps it alive while the
    /// pipeline lives.
    pub user: *mut c_void,
    /// Fills both eyes' G-buffers for frame `frame` (see [`StGBufferMut`]: every pixel of
    /// every plane the layout reads); returns 0 on success, anything else to refuse the frame.
    pub fill_gbuffers: Option<
        unsafe extern "C" fn(
            user: *mut c_void,
            frame: u32,
            left: *const StGBufferMut,
            right: *const StGBufferMut,
        ) -> i32,
    >,
    /// Path traces `spp` samples per pixel of eye `eye` (0 left, 1 right) at frame `frame`,
    /// seen by `camera` (that eye's camera as given to the render call), and writes each
    /// selected pixel's estimate, the **mean** of its samples (linear RGB radiance), into
    /// `out`. `out` and `mask` are whole-frame planes of the pipeline's size, owned by the
    /// pipeline and valid during the call only, indexed by absolute row: the selected pixels
    /// are those of rows `row_start .. row_end` (end exclusive) where `mask` is non-zero (a
    /// null `mask`: every pixel of those rows). Other pixels of `out` must be left as they
    /// are. Returns 0 on success, anything else to refuse the frame.
    ///
    /// With `ST_HISTORY_GRADIENT` there are also calls for the temporal gradients' samples:
    /// `frame` and `camera` are then the **previous** frame's (its random numbers, its
    /// view), under the scene as it is now (today's lights and geometry), and `mask` selects
    /// one pixel per 3×3 stratum.
    #[allow(clippy::type_complexity)]
    pub trace: Option<
        unsafe extern "C" fn(
            user: *mut c_void,
            eye: u32,
            frame: u32,
            spp: u32,
            camera: *const StCamera,
            mask: *const StPlaneU8,
            row_start: u32,
            row_end: u32,
            out: *const StRgbMut,
        ) -> i32,
    >,
    /// Optional: the engine's own job system, used with `config.trace_band_rows` ≥ 1 instead
    /// of the pipeline's workers (null: the workers). Each `trace` call's bands are handed
    /// over as `count` jobs: the engine must call `job(context, i)` exactly once for every `i`
    /// in `0 .. count`, on any of its threads and in any order, and return after the last has
    /// returned: 0, or anything else to refuse the frame. A job runs `trace` for its band and
    /// records a failure itself; a job skipped or run twice refuses the frame. `context` is
    /// the pipeline's, valid only until `run_jobs` returns.
    #[allow(clippy::type_complexity)]
    pub run_jobs: Option<
        unsafe extern "C" fn(
            user: *mut c_void,
            count: u32,
            job: unsafe extern "C" fn(context: *mut c_void, index: u32),
            context: *mut c_void,
        ) -> i32,
    >,
}

/// The bands of one `trace` call handed to an engine's `run_jobs` (its `context`).
struct BandJobs<'a> {
    call: &'a TraceCall<'a>,
    rows: std::ops::Range<usize>,
    band: usize,
    /// How many times each job ran (an engine that skips or repeats one refuses the frame).
    runs: &'a [std::sync::atomic::AtomicU8],
    failure: std::sync::Mutex<Option<PipelineError>>,
}

impl BandJobs<'_> {
    fn fail(&self, error: PipelineError) {
        let mut first = self.failure.lock().unwrap_or_else(|e| e.into_inner());
        first.get_or_insert(error);
    }
}

/// One band's job, as the engine's job system calls it: runs `trace` on the band and records
/// a failure (or an index out of range) for the pipeline to report. Never unwinds into C.
unsafe extern "C" fn run_band_job(context: *mut c_void, index: u32) {
    // SAFETY: `context` is the `BandJobs` passed to `run_jobs`, alive until it returns.
    let jobs = unsafe { &*context.cast::<BandJobs<'_>>() };
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let Some(runs) = jobs.runs.get(index as usize) else {
            return Err(PipelineError::Source(
                format!("run_jobs called job {index} of {} jobs; the frame was refused", jobs.runs.len()).into(),
            ));
        };
        runs.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let start = jobs.rows.start + index as usize * jobs.band;
        jobs.call.rows(start..(start + jobs.band).min(jobs.rows.end))
    }));
    match outcome {
        Ok(Ok(())) => {}
        Ok(Err(e)) => jobs.fail(e),
        Err(_) => jobs.fail(PipelineError::Source("a trace job panicked; the frame was refused".into())),
    }
}

/// [`StFrameSourceCallbacks`] as a [`FrameSource`] (both callbacks checked non-null when the
/// pipeline was created).
struct CallbackSource {
    callbacks: StFrameSourceCallbacks,
    frame: u32,
    /// This frame's cameras as the caller gave them (f64, not the kernels' f32 rows).
    cameras: [StCamera; 2],
    /// Rows per concurrent `trace` call (0: one call, on one thread).
    band_rows: u32,
    /// How many times each band's job ran, for an engine's `run_jobs` (grown once, reused).
    job_runs: std::sync::Mutex<Vec<std::sync::atomic::AtomicU8>>,
}

/// The arguments every band of one `trace` call shares, across the pool's threads.
struct TraceCall<'a> {
    callbacks: &'a StFrameSourceCallbacks,
    eye: u32,
    request: &'a TraceRequest,
    camera: &'a StCamera,
    mask: *const StPlaneU8,
    out: &'a StRgbMut,
}

// SAFETY: the engine declared `trace` thread-safe (`trace_band_rows` ≥ 1); the planes behind
// `mask` and `out` outlive the call, and concurrent bands write disjoint rows of `out`.
unsafe impl Sync for TraceCall<'_> {}

impl TraceCall<'_> {
    /// Calls `trace` for `rows`; `Err` names the refusal.
    fn rows(&self, rows: std::ops::Range<usize>) -> Result<(), PipelineError> {
        let trace = self.callbacks.trace.ok_or(PipelineError::Source("no trace callback".into()))?;
        // SAFETY: as in `fill_gbuffers`.
        let code = unsafe {
            trace(
                self.callbacks.user,
                self.eye,
                self.request.frame,
                self.request.spp,
                self.camera,
                self.mask,
                rows.start as u32,
                rows.end as u32,
                self.out,
            )
        };
        if code != 0 {
            return Err(PipelineError::Source(
                format!(
                    "trace callback returned {code} (eye {}, frame {}, rows {}..{}); the frame was refused",
                    self.eye, self.request.frame, rows.start, rows.end
                )
                .into(),
            ));
        }
        Ok(())
    }
}

// SAFETY: `user` and the callbacks are only used while a render call runs, one call at a
// time, and the header states that they are called from a worker thread.
unsafe impl Send for CallbackSource {}

/// The `run_jobs` callback's type.
type RunJobs = unsafe extern "C" fn(
    user: *mut c_void,
    count: u32,
    job: unsafe extern "C" fn(context: *mut c_void, index: u32),
    context: *mut c_void,
) -> i32;

impl CallbackSource {
    /// Hands the `bands` bands of one trace call to the engine's job system and checks that
    /// every job ran exactly once. Allocates nothing but the run counters (one byte a band,
    /// kept between frames).
    fn run_engine_jobs(
        &self,
        run_jobs: RunJobs,
        call: &TraceCall<'_>,
        rows: std::ops::Range<usize>,
        band: usize,
        bands: usize,
    ) -> Result<(), PipelineError> {
        use std::sync::atomic::{AtomicU8, Ordering};
        let mut runs = self.job_runs.lock().unwrap_or_else(|e| e.into_inner());
        if runs.len() < bands {
            runs.resize_with(bands, || AtomicU8::new(0));
        }
        for r in runs.iter() {
            r.store(0, Ordering::Relaxed);
        }
        let jobs = BandJobs { call, rows, band, runs: &runs[..bands], failure: std::sync::Mutex::new(None) };
        let context = (&jobs as *const BandJobs<'_>).cast_mut().cast::<c_void>();
        // SAFETY: the engine's contract (the header's): `job` is called with `context` only
        // until `run_jobs` returns.
        let code = unsafe { run_jobs(self.callbacks.user, bands as u32, run_band_job, context) };
        if let Some(e) = jobs.failure.into_inner().unwrap_or_else(|e| e.into_inner()) {
            return Err(e);
        }
        if code != 0 {
            return Err(PipelineError::Source(format!("run_jobs returned {code}; the frame was refused").into()));
        }
        if let Some(i) = runs[..bands].iter().position(|r| r.load(Ordering::Relaxed) != 1) {
            return Err(PipelineError::Source(format!(
                "run_jobs returned with job {i} of {bands} run {} times (each must run once); the frame was refused",
                runs[i].load(Ordering::Relaxed)
            ).into()));
        }
        Ok(())
    }
}

fn packed<T: Copy + Send + Sync>(buf: &mut PlaneBuf<T>) -> (*mut T, u32, u32) {
    let e = buf.extent();
    (buf.as_mut_slice().as_mut_ptr(), e.width() as u32, e.height() as u32)
}

/// A plane the pipeline does not have (null `data`).
const NO_PLANE: StPlaneMutF32 = StPlaneMutF32 { data: std::ptr::null_mut(), width: 0, height: 0, stride: 0 };

fn f32_plane(buf: &mut PlaneBuf) -> StPlaneMutF32 {
    let (data, width, height) = packed(buf);
    StPlaneMutF32 { data, width, height, stride: width }
}

fn u32_plane(buf: &mut PlaneBuf<u32>) -> StPlaneMutU32 {
    let (data, width, height) = packed(buf);
    StPlaneMutU32 { data, width, height, stride: width }
}

impl FrameSource for CallbackSource {
    fn begin_frame(&mut self, frame: u32) {
        self.frame = frame;
    }

    fn fill_gbuffers(
        &mut self,
        gbuffers: [&mut GBufferBuf; 2],
        _layout: Layout,
    ) -> Result<Option<RasterPassStats>, PipelineError> {
        let [left, right] = gbuffers;
        let view = |g: &mut GBufferBuf, camera: StCamera| StGBufferMut {
            depth: f32_plane(&mut g.depth),
            position: g.position.each_mut().map(f32_plane),
            normal: g.normal.each_mut().map(f32_plane),
            normal_octahedral: u32_plane(&mut g.normal_oct),
            material: u32_plane(&mut g.material),
            camera,
            jitter: g.jitter,
            history_confidence: g.history_confidence.as_mut().map_or(NO_PLANE, f32_plane),
            motion: g.motion.as_mut().map_or([NO_PLANE; 3], |m| m.each_mut().map(f32_plane)),
        };
        let (l, r) = (view(left, self.cameras[0]), view(right, self.cameras[1]));
        let fill_gbuffers =
            self.callbacks.fill_gbuffers.ok_or(PipelineError::Source("no fill_gbuffers callback".into()))?;
        // SAFETY: the views cover the pipeline's own buffers, alive and unaliased for the
        // call; the callback's contract is the header's.
        let code = unsafe { fill_gbuffers(self.callbacks.user, self.frame, &l, &r) };
        if code != 0 {
            return Err(PipelineError::Source(
                format!("fill_gbuffers callback returned {code} (frame {}); the frame was refused", self.frame).into(),
            ));
        }
        Ok(None)
    }

    fn trace(
        &self,
        _camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
    ) -> Result<TraceStats, PipelineError> {
        let e = out.extent();
        let (w, h) = (e.width() as u32, e.height() as u32);
        let mask = match selection {
            PixelSelection::All => None,
            PixelSelection::Mask(m) => Some(StPlaneU8 { data: m.as_slice().as_ptr(), width: w, height: h, stride: w }),
        };
        let [r, g, b] =
            out.slices_mut().map(|s| StPlaneMutF32 { data: s.as_mut_ptr(), width: w, height: h, stride: w });
        let out = StRgbMut { r, g, b };
        let eye = request.eye as usize;
        let call = TraceCall {
            callbacks: &self.callbacks,
            eye: eye as u32,
            request,
            camera: &self.cameras[eye],
            mask: mask.as_ref().map_or(std::ptr::null(), |m| m as *const StPlaneU8),
            out: &out,
        };
        match self.band_rows as usize {
            0 => call.rows(rows)?,
            band => {
                let bands = rows.len().div_ceil(band);
                match self.callbacks.run_jobs {
                    None => {
                        use rayon::prelude::*;
                        (0..bands).into_par_iter().try_for_each(|b| {
                            let start = rows.start + b * band;
                            call.rows(start..(start + band).min(rows.end))
                        })?;
                    }
                    Some(run_jobs) => self.run_engine_jobs(run_jobs, &call, rows, band, bands)?,
                }
            }
        }
        Ok(TraceStats::default())
    }
}

enum Inner {
    Scene(Box<Pipeline<RendererSource<Box<Renderer>>>>),
    Callbacks(Box<Pipeline<CallbackSource>>),
}

/// A frame pipeline (opaque to C). One call at a time: a call on a pipeline that is in a
/// call already (from that call's callbacks, or from another thread) is refused with
/// `ST_STATUS_BUSY`.
pub struct StPipeline {
    state: Exclusive<PipelineState>,
}

/// What a pipeline's calls share, behind its [`Exclusive`] guard.
struct PipelineState {
    pool: rayon::ThreadPool,
    inner: Inner,
    /// Frames rendered (refused frames not counted): the output exists from the first.
    frames_rendered: u64,
}

impl StPipeline {
    fn new(pool: rayon::ThreadPool, inner: Inner) -> Self {
        Self { state: Exclusive::new("pipeline", PipelineState { pool, inner, frames_rendered: 0 }) }
    }
}

/// What one frame did.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct StFrameStats {
    /// The whole frame.
    pub total_ms: f64,
    /// Both eyes' G-buffers (the source's `fill_gbuffers`).
    pub gbuffer_ms: f64,
    /// Stereo and temporal reprojection.
    pub reprojection_ms: f64,
    /// Path tracing (the source's `trace`).
    pub tracing_ms: f64,
    /// EMA and blends.
    pub accumulation_ms: f64,
    /// Pixels path traced per eye (left, right).
    pub traced_pixels: [u64; 2],
    /// 1 when there was no budget or the frame kept it, 0 when it went over.
    pub budget_met: u32,
    /// Temporal gradients (`ST_HISTORY_GRADIENT`) outside their traced samples: choosing
    /// them, and turning them into history confidence (their tracing is in `tracing_ms`).
    pub gradients_ms: f64,
    /// The spatial filter of both eyes' shown images (`ST_FILTER_ATROUS`).
    pub filter_ms: f64,
    /// Gradient samples re-shaded per eye (left, right), not counted in `traced_pixels`.
    pub gradient_samples: [u64; 2],
    /// 3×3 strata per eye whose gradient shortened the history (the lighting changed).
    pub gradient_changed: [u64; 2],
    /// Colour values each eye's filter clamped to its range (NaN, ±∞, above 10¹⁸).
    pub filter_out_of_range: [u64; 2],
    /// Pixels per eye whose history the neighbourhood clamp moved (`ST_HISTORY_CLAMP`).
    pub history_clamped: [u64; 2],
}

impl From<&FrameStats> for StFrameStats {
    fn from(s: &FrameStats) -> Self {
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        let t = &s.times;
        Self {
            total_ms: ms(t.total),
            gbuffer_ms: ms(t.gbuffer),
            reprojection_ms: ms(t.reprojection),
            tracing_ms: ms(t.tracing),
            accumulation_ms: ms(t.accumulation),
            traced_pixels: s.traced_pixels,
            budget_met: u32::from(s.budget_met),
            gradients_ms: ms(t.gradients),
            filter_ms: ms(t.filter),
            gradient_samples: s.gradient_samples,
            gradient_changed: s.gradient_changed,
            filter_out_of_range: s.filter_out_of_range,
            history_clamped: s.history_clamped,
        }
    }
}

/// The status of a refused frame or creation: a callback's failure and an allocation
/// failure have their own, so an engine can tell them from a bad argument.
fn pipeline_error(e: PipelineError) -> Failure {
    match e {
        PipelineError::Source(message) => Failure::new(StStatus::CallbackFailed, message.to_string()),
        PipelineError::Frame(frame) => frame.into(),
        other => Failure::invalid(other.to_string()),
    }
}

/// Creates a pipeline over this project's renderer on `scene`: a built-in scene name
/// ("cornell", "atrium", ...), a TOML manifest or a scene folder (UTF-8 path). Reprojection
/// tolerances are `config.reprojection`, or when null the scene's, scaled to the frame
/// height. Its G-buffers are rasterised in fixed point as GPUs rasterise (the CLI's default
/// `--gbuffer raster`). The per-pixel buffers are allocated here (`ST_STATUS_OUT_OF_MEMORY`
/// if that fails, with nothing kept); the rasteriser's binning buffers grow with the first
/// frames, by the scene's triangles, with a quarter of headroom each time they grow.
/// Destroy it with [`stereotrace_pipeline_destroy`].
///
/// # Safety
/// `scene` must be null or a NUL-terminated string; `config` null or valid; `out` null or
/// writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_create_scene(
    scene: *const c_char,
    config: *const StPipelineConfig,
    out: *mut *mut StPipeline,
) -> StStatus {
    // SAFETY: `scene`, `config` and `out` are this function's arguments, valid as its
    // `# Safety` section states, and checked for null before they are read.
    guard(|| unsafe {
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        if scene.is_null() {
            return Err(Failure::null("scene"));
        }
        let config = required(config, "config")?;
        let spec = CStr::from_ptr(scene).to_str().map_err(|_| Failure::invalid("scene is not UTF-8"))?;
        let extent = config.extent()?;
        config.check_threads()?;
        let scene = stereotrace_runtime::scene::resolve(spec).map_err(|e| Failure::invalid(e.to_string()))?;
        let renderer = Renderer::new(scene).map_err(|e| Failure::invalid(e.to_string()))?;
        let runtime = config.runtime(renderer.scene().tolerances.at_height(extent.height()))?;
        let pipeline =
            Pipeline::new(Box::new(renderer), runtime, StereoRig::default(), extent).map_err(pipeline_error)?;
        let pool = config.pool()?;
        out.write(Box::into_raw(Box::new(StPipeline::new(pool, Inner::Scene(Box::new(pipeline))))));
        Ok(())
    })
}

/// Creates a pipeline over an engine's own G-buffers and tracer (`callbacks`, both
/// required), for frames of `config`'s size; `cameras` points to the two eye cameras
/// (left, right) of the first frame. Reprojection uses `config.reprojection`, or when null
/// the room-scale defaults of `stereotrace_reproject_params_default` (in metres). Frames are
/// rendered with [`stereotrace_pipeline_render_frame_at`]. Every buffer is allocated here
/// (none per frame): `ST_STATUS_OUT_OF_MEMORY` if that fails, with nothing kept.
///
/// # Safety
/// As [`stereotrace_pipeline_create_scene`]; `cameras` null or two valid cameras; the
/// callbacks keep the contract of [`StFrameSourceCallbacks`] for the pipeline's life.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_create_callbacks(
    callbacks: *const StFrameSourceCallbacks,
    config: *const StPipelineConfig,
    cameras: *const StCamera,
    out: *mut *mut StPipeline,
) -> StStatus {
    // SAFETY: `callbacks`, `config`, `cameras` and `out` are this function's arguments,
    // valid as its `# Safety` section states, and checked for null before they are read.
    guard(|| unsafe {
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        let callbacks = *required(callbacks, "callbacks")?;
        if callbacks.fill_gbuffers.is_none() {
            return Err(Failure::null("callbacks.fill_gbuffers"));
        }
        if callbacks.trace.is_none() {
            return Err(Failure::null("callbacks.trace"));
        }
        let config = required(config, "config")?;
        let extent = config.extent()?;
        let (given, models) = eye_cameras(cameras, extent)?;
        config.check_threads()?;
        let runtime = config.runtime(Tolerances::default())?;
        let band_rows = config.trace_band_rows;
        let job_runs = std::sync::Mutex::new(Vec::new());
        let source = CallbackSource { callbacks, frame: 0, cameras: given, band_rows, job_runs };
        let pipeline = Pipeline::with_source(source, runtime, models).map_err(pipeline_error)?;
        let pool = config.pool()?;
        out.write(Box::into_raw(Box::new(StPipeline::new(pool, Inner::Callbacks(Box::new(pipeline))))));
        Ok(())
    })
}

/// Two eye cameras from C, checked against the pipeline's extent.
///
/// # Safety
/// `cameras` null or pointing to two cameras.
unsafe fn eye_cameras(cameras: *const StCamera, extent: Extent) -> Result<([StCamera; 2], [CameraModel; 2]), Failure> {
    if cameras.is_null() {
        return Err(Failure::null("cameras"));
    }
    // SAFETY: the caller's contract: two cameras.
    let given = unsafe { [*cameras, *cameras.add(1)] };
    let model = |c: &StCamera, what: &str| -> Result<CameraModel, Failure> {
        let m = c.model(what)?;
        same_extent("camera size", extent, m.extent).about(what)?;
        Ok(m)
    };
    Ok((given, [model(&given[0], "cameras[0]")?, model(&given[1], "cameras[1]")?]))
}

/// Renders frame `frame` of a scene pipeline, the head walking the scene's camera path
/// forward and back (so any frame number is on it). `stats` may be null.
///
/// # Safety
/// `pipeline` null or a live pipeline not in use by another thread; `stats` null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_render_frame(
    pipeline: *mut StPipeline,
    frame: u32,
    stats: *mut StFrameStats,
) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`); the pipeline's state is taken
    // through its busy guard, so no other call uses it meanwhile.
    guard(|| unsafe {
        let p = pipeline.as_ref().ok_or_else(|| Failure::null("pipeline"))?;
        let mut state = p.state.enter("stereotrace_pipeline_render_frame")?;
        let PipelineState { pool, inner, frames_rendered } = &mut *state;
        let Inner::Scene(inner) = inner else {
            return Err(Failure::invalid(
                "this pipeline has no scene (made with callbacks): use stereotrace_pipeline_render_frame_at",
            ));
        };
        let head = inner.source().renderer().scene().camera.pose_back_and_forth(frame);
        let s = pool.install(|| inner.render_frame(frame, &head)).map_err(pipeline_error)?;
        *frames_rendered += 1;
        if let Some(out) = stats.as_mut() {
            *out = (&s).into();
        }
        Ok(())
    })
}

/// Renders frame `frame` with the two eye cameras `cameras` (left, right; the pipeline's
/// size). For a callback pipeline the callbacks run during this call. `stats` may be null.
///
/// - **Frame numbers** key the samples only (the callbacks' `frame`; a scene's random numbers
///   and moving lights). They may repeat, go backwards or reach `UINT32_MAX`: the history
///   follows the order of the calls, not the numbers.
/// - **Cameras** are taken as given: eye 0's output is always `cameras[0]`'s view. Swapped
///   eyes, eyes far apart or both eyes at one camera are computed as such (stereo
///   reprojection is valid where the two views see the same surface; elsewhere the eye that
///   reprojects is traced).
/// - **Refused frames change nothing.** Whatever refuses the frame (a camera, a callback, a
///   kernel's check), the output, the histories and what the next frame reprojects stay as
///   they were, and `stats` is not written.
///
/// # Safety
/// As [`stereotrace_pipeline_render_frame`]; `cameras` null or two valid cameras.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_render_frame_at(
    pipeline: *mut StPipeline,
    frame: u32,
    cameras: *const StCamera,
    stats: *mut StFrameStats,
) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`); the pipeline's state is taken
    // through its busy guard, so no other call uses it meanwhile.
    guard(|| unsafe {
        let p = pipeline.as_ref().ok_or_else(|| Failure::null("pipeline"))?;
        let mut state = p.state.enter("stereotrace_pipeline_render_frame_at")?;
        let PipelineState { pool, inner, frames_rendered } = &mut *state;
        let s = match inner {
            Inner::Scene(inner) => {
                let (_, models) = eye_cameras(cameras, inner.extent())?;
                pool.install(|| inner.render_frame_at(frame, models))
            }
            Inner::Callbacks(inner) => {
                let (given, models) = eye_cameras(cameras, inner.extent())?;
                inner.source_mut().cameras = given;
                pool.install(|| inner.render_frame_at(frame, models))
            }
        }
        .map_err(pipeline_error)?;
        *frames_rendered += 1;
        if let Some(out) = stats.as_mut() {
            *out = (&s).into();
        }
        Ok(())
    })
}

/// One eye's G-buffer lent by the engine for one frame (zero-copy input to
/// [`stereotrace_pipeline_render_frame_lent`]): read-only views of the engine's own planes,
/// any stride, each of the pipeline's size. Which planes must be given follows the pipeline's
/// configuration, and a plane the configuration does not read must be left null (`data`):
/// `depth` always; `normal_octahedral` with `ST_LAYOUT_COMPACT`; `position` and `normal` with
/// `ST_LAYOUT_FULL`; `history_confidence` exactly when `config.history_confidence`; `motion`
/// exactly when `config.motion_vectors`. Values mean what the same planes of
/// [`StGBufferMut`] mean. The cameras and jitter are the render call's. The pipeline's
/// worker threads read the planes during the render call only; the engine must not write
/// them meanwhile and keeps ownership.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StLentGBuffer {
    /// View-axis depth at the pixel centre, > 0 (`+INFINITY`: no surface).
    pub depth: StPlaneF32,
    /// `ST_LAYOUT_FULL`: world position x, y, z (else null).
    pub position: [StPlaneF32; 3],
    /// `ST_LAYOUT_FULL`: world shading normal x, y, z (else null).
    pub normal: [StPlaneF32; 3],
    /// `ST_LAYOUT_COMPACT`: `stereotrace_encode_normal` of the shading normal (else null).
    pub normal_octahedral: StPlaneU32,
    /// With `config.history_confidence`: history confidence in [0, 1] (else null).
    pub history_confidence: StPlaneF32,
    /// With `config.motion_vectors`: world-space motion x, y, z since the previous frame
    /// (else null).
    pub motion: [StPlaneF32; 3],
}

impl StLentGBuffer {
    /// The kernel views of the planes given (null `data`: not given), checked for pointer,
    /// extent and stride; which of them the configuration needs is the pipeline's check.
    ///
    /// # Safety
    /// Every non-null plane as the header requires of an input plane, for the call's length.
    unsafe fn views<'a>(&self) -> Result<GBufferView<'a>, Failure> {
        let mut b = Borrows::new();
        let f32s = |p: &StPlaneF32, what, b: &mut Borrows| -> Result<Option<_>, Failure> {
            // SAFETY: the caller's contract for a non-null plane.
            if p.data.is_null() { Ok(None) } else { unsafe { p.view(what, b).map(Some) } }
        };
        let three = |p: &[StPlaneF32; 3],
                     what: [&'static str; 3],
                     b: &mut Borrows|
         -> Result<Option<[_; 3]>, Failure> {
            match (f32s(&p[0], what[0], b)?, f32s(&p[1], what[1], b)?, f32s(&p[2], what[2], b)?) {
                (Some(x), Some(y), Some(z)) => Ok(Some([x, y, z])),
                (None, None, None) => Ok(None),
                _ => Err(Failure::invalid(format!("{}: give all three planes or none", &what[0][..what[0].len() - 2]))),
            }
        };
        let depth = f32s(&self.depth, "depth", &mut b)?.ok_or_else(|| Failure::null("depth.data"))?;
        let normal_oct = if self.normal_octahedral.data.is_null() {
            None
        } else {
            // SAFETY: the caller's contract for a non-null plane.
            Some(unsafe { self.normal_octahedral.view("normal_octahedral", &mut b)? })
        };
        Ok(GBufferView {
            depth,
            normal_oct,
            position: three(&self.position, ["position.x", "position.y", "position.z"], &mut b)?,
            normal: three(&self.normal, ["normal.x", "normal.y", "normal.z"], &mut b)?,
            history_confidence: f32s(&self.history_confidence, "history_confidence", &mut b)?,
            motion: three(&self.motion, ["motion.x", "motion.y", "motion.z"], &mut b)?,
        })
    }
}

/// Two lent G-buffers (left, right) from C.
///
/// # Safety
/// `gbuffers` null or pointing to two `StLentGBuffer`s whose planes keep the header's
/// contract.
unsafe fn lent_pair<'a>(gbuffers: *const StLentGBuffer, what: &str) -> Result<[GBufferView<'a>; 2], Failure> {
    if gbuffers.is_null() {
        return Err(Failure::null(what));
    }
    // SAFETY: the caller's contract: two G-buffers, whose planes are valid.
    unsafe {
        let (left, right) = (&*gbuffers, &*gbuffers.add(1));
        let left = left.views().map_err(|e| Failure::new(e.status, format!("{what}[0].{}", e.message)))?;
        let right = right.views().map_err(|e| Failure::new(e.status, format!("{what}[1].{}", e.message)))?;
        Ok([left, right])
    }
}

/// [`stereotrace_pipeline_render_frame_at`] with both eyes' G-buffers lent by the engine
/// instead of filled by `fill_gbuffers` (zero-copy input; a scene pipeline also takes them
/// instead of rendering its own): the kernels read the engine's planes in place during this
/// call, and the callback `fill_gbuffers` is not called. `gbuffers` points to two
/// [`StLentGBuffer`]s (left, right) rendered for `cameras` (jittered as set by
/// `stereotrace_pipeline_set_jitter`).
///
/// `previous` points to the two G-buffers of the last frame this pipeline committed,
/// unchanged since, which temporal reprojection reads: the engine keeps its last frame's
/// G-buffers alive (double-buffering, as TAA does). It may be null on the first frame, after
/// `stereotrace_pipeline_reset` or a resize, or when the last frame's G-buffers were filled
/// by `fill_gbuffers` (the pipeline then holds them); otherwise the call is refused
/// (`ST_STATUS_INVALID_ARGUMENT`). Nothing is kept after the call. Refused frames change
/// nothing, as for `stereotrace_pipeline_render_frame_at`.
///
/// # Safety
/// As [`stereotrace_pipeline_render_frame_at`]; `gbuffers` null or two valid lent
/// G-buffers, `previous` null or two valid lent G-buffers, their planes readable and not
/// written during the call.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_render_frame_lent(
    pipeline: *mut StPipeline,
    frame: u32,
    cameras: *const StCamera,
    gbuffers: *const StLentGBuffer,
    previous: *const StLentGBuffer,
    stats: *mut StFrameStats,
) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`); the pipeline's state is taken
    // through its busy guard, so no other call uses it meanwhile.
    // The lent planes are checked by `StLentGBuffer::views`.
    guard(|| unsafe {
        let p = pipeline.as_ref().ok_or_else(|| Failure::null("pipeline"))?;
        let mut state = p.state.enter("stereotrace_pipeline_render_frame_lent")?;
        let PipelineState { pool, inner, frames_rendered } = &mut *state;
        let current = lent_pair(gbuffers, "gbuffers")?;
        let previous = if previous.is_null() { None } else { Some(lent_pair(previous, "previous")?) };
        let s = match inner {
            Inner::Scene(inner) => {
                let (_, models) = eye_cameras(cameras, inner.extent())?;
                pool.install(|| inner.render_frame_lent(frame, models, current, previous))
            }
            Inner::Callbacks(inner) => {
                let (given, models) = eye_cameras(cameras, inner.extent())?;
                inner.source_mut().cameras = given;
                pool.install(|| inner.render_frame_lent(frame, models, current, previous))
            }
        }
        .map_err(pipeline_error)?;
        *frames_rendered += 1;
        if let Some(out) = stats.as_mut() {
            *out = (&s).into();
        }
        Ok(())
    })
}

/// Renders the next frames' G-buffers with a sub-pixel camera jitter of (`x`, `y`) pixels
/// (x right, y down; each within [−1, 1]), as TAA does, for example a Halton sequence changed
/// every frame: a callback pipeline's `fill_gbuffers` gets it in `StGBufferMut.jitter`, a
/// scene pipeline jitters its own G-buffer cameras. The traced images and the output stay on
/// the unjittered pixel grid, and reprojection reads the colour where each pixel's
/// unjittered centre lands, so the history converges to the unjittered image. Both eyes
/// share it; (0, 0), the default, is no jitter. A non-finite or larger offset is
/// `ST_STATUS_INVALID_ARGUMENT` and changes nothing.
///
/// # Safety
/// `pipeline` null or a live pipeline.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_set_jitter(pipeline: *mut StPipeline, x: f32, y: f32) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`); the pipeline's state is taken
    // through its busy guard, so no other call uses it meanwhile.
    guard(|| unsafe {
        let p = pipeline.as_ref().ok_or_else(|| Failure::null("pipeline"))?;
        let mut state = p.state.enter("stereotrace_pipeline_set_jitter")?;
        match &mut state.inner {
            Inner::Scene(inner) => inner.set_jitter([x, y]),
            Inner::Callbacks(inner) => inner.set_jitter([x, y]),
        }
        .map_err(pipeline_error)
    })
}

/// Forgets the history: the next frame starts as the first did (no temporal reprojection,
/// every pixel reset to its new sample), as after a camera cut. The output of the last frame
/// stays readable.
///
/// # Safety
/// `pipeline` null or a live pipeline.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_reset(pipeline: *mut StPipeline) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`); the pipeline's state is taken
    // through its busy guard, so no other call uses it meanwhile.
    guard(|| unsafe {
        let p = pipeline.as_ref().ok_or_else(|| Failure::null("pipeline"))?;
        let mut state = p.state.enter("stereotrace_pipeline_reset")?;
        match &mut state.inner {
            Inner::Scene(inner) => inner.reset(),
            Inner::Callbacks(inner) => inner.reset(),
        }
        Ok(())
    })
}

/// Resizes the pipeline to frames of `width`×`height` (the limits of
/// [`StPipelineConfig::width`]) without recreating it: its buffers are allocated anew
/// (`ST_STATUS_OUT_OF_MEMORY` if that fails, and then the pipeline is as it was), the history
/// is forgotten, and the output is unavailable until the next frame. Frames after it take
/// cameras of the new size.
///
/// # Safety
/// `pipeline` null or a live pipeline.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_resize(pipeline: *mut StPipeline, width: u32, height: u32) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`); the pipeline's state is taken
    // through its busy guard, so no other call uses it meanwhile.
    guard(|| unsafe {
        let p = pipeline.as_ref().ok_or_else(|| Failure::null("pipeline"))?;
        let mut state = p.state.enter("stereotrace_pipeline_resize")?;
        let extent = Extent::new(width as usize, height as usize).about("size")?;
        match &mut state.inner {
            Inner::Scene(inner) => inner.resize(extent),
            Inner::Callbacks(inner) => inner.resize(extent),
        }
        .map_err(pipeline_error)?;
        state.frames_rendered = 0;
        Ok(())
    })
}

/// Copies eye `eye`'s (0 left, 1 right) per-pixel record of the last successful frame into
/// the caller's byte plane `out` (the pipeline's size, any stride): `what` 0 is the stereo
/// reprojection's `StReason` codes (all `ST_REASON_INVALID` in modes without stereo
/// reprojection into that eye), 1 the temporal reprojection's, and 2 the traced mask (1 where
/// the pixel was path traced this frame, 0 elsewhere).
///
/// # Safety
/// `pipeline` null or a live pipeline; `out` null or valid, its plane writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_pixels(
    pipeline: *const StPipeline,
    eye: u32,
    what: u32,
    out: *const StPlaneMutU8,
) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`); the pipeline's state is taken
    // through its busy guard, so no other call uses it meanwhile.
    guard(|| unsafe {
        let p = pipeline.as_ref().ok_or_else(|| Failure::null("pipeline"))?;
        let state = p.state.enter("stereotrace_pipeline_pixels")?;
        if state.frames_rendered == 0 {
            return Err(Failure::invalid("no frame has been rendered yet (since the pipeline was made or resized)"));
        }
        let eye = match eye {
            0 => Eye::Left,
            1 => Eye::Right,
            other => return Err(Failure::invalid(format!("eye {other} is not 0 (left) or 1 (right)"))),
        };
        let plane = match &state.inner {
            Inner::Scene(inner) => pixel_record(inner, eye, what),
            Inner::Callbacks(inner) => pixel_record(inner, eye, what),
        }?;
        let mut b = Borrows::new();
        let mut out = required(out, "out")?.view("out", &mut b)?;
        same_extent("out", plane.extent(), out.extent()).about("out")?;
        for y in 0..plane.extent().height() {
            out.row_mut(y).copy_from_slice(plane.view().row(y));
        }
        Ok(())
    })
}

/// The plane [`stereotrace_pipeline_pixels`] reads for `what`.
fn pixel_record<S: FrameSource>(pipeline: &Pipeline<S>, eye: Eye, what: u32) -> Result<&PlaneBuf<u8>, Failure> {
    match what {
        0 => Ok(pipeline.stereo_reasons(eye)),
        1 => Ok(pipeline.temporal_reasons(eye)),
        2 => Ok(pipeline.traced_mask(eye)),
        other => Err(Failure::invalid(format!("what {other} is not 0 (stereo reasons), 1 (temporal) or 2 (traced)"))),
    }
}

/// The image eye `eye` (0 left, 1 right) shows after the last successful frame, or the
/// refusal: no frame yet, or no such eye.
fn committed_output(state: &PipelineState, eye: u32) -> Result<&RgbBuf, Failure> {
    if state.frames_rendered == 0 {
        return Err(Failure::invalid(
            "no frame has been rendered yet: the output exists after the first successful render call",
        ));
    }
    let eye = match eye {
        0 => Eye::Left,
        1 => Eye::Right,
        other => return Err(Failure::invalid(format!("eye {other} is not 0 (left) or 1 (right)"))),
    };
    Ok(match &state.inner {
        Inner::Scene(inner) => inner.output(eye),
        Inner::Callbacks(inner) => inner.output(eye),
    })
}

/// Lends the image eye `eye` (0 left, 1 right) shows after the last successful frame without
/// copying it: writes to `view` three read-only planes of the pipeline's own memory (packed:
/// stride = width). They stay valid and unchanged until the next call that renders, resets,
/// resizes or destroys this pipeline (a render reuses the memory for a later frame); read them
/// before that, or copy with `stereotrace_pipeline_output`. Refused before the first
/// successful frame; `view` is left as it was on any refusal.
///
/// # Safety
/// `pipeline` null or a live pipeline; `view` null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_output_view(
    pipeline: *const StPipeline,
    eye: u32,
    view: *mut StRgb,
) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`); the pipeline's state is taken
    // through its busy guard, so no other call uses it meanwhile.
    guard(|| unsafe {
        let p = pipeline.as_ref().ok_or_else(|| Failure::null("pipeline"))?;
        let state = p.state.enter("stereotrace_pipeline_output_view")?;
        let view = view.as_mut().ok_or_else(|| Failure::null("view"))?;
        let image = committed_output(&state, eye)?;
        let e = image.extent();
        let (w, h) = (e.width() as u32, e.height() as u32);
        let [r, g, b] =
            image.planes().map(|p| StPlaneF32 { data: p.as_slice().as_ptr(), width: w, height: h, stride: w });
        *view = StRgb { r, g, b };
        Ok(())
    })
}

/// Copies the image eye `eye` (0 left, 1 right) shows after the last successful frame into
/// the caller's planes `out` (the pipeline's size, any stride). Refused before the first
/// successful frame (there is no image yet).
///
/// # Safety
/// `pipeline` null or a live pipeline; `out` null or valid, its planes writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_output(
    pipeline: *const StPipeline,
    eye: u32,
    out: *const StRgbMut,
) -> StStatus {
    // SAFETY: the entry-point contract (`boundary.rs`); the pipeline's state is taken
    // through its busy guard, so no other call uses it meanwhile.
    guard(|| unsafe {
        let p = pipeline.as_ref().ok_or_else(|| Failure::null("pipeline"))?;
        let state = p.state.enter("stereotrace_pipeline_output")?;
        let image = committed_output(&state, eye)?;
        let mut b = Borrows::new();
        let out = required(out, "out")?.view(["out.r", "out.g", "out.b"], &mut b)?;
        same_extent("out", image.extent(), out.extent()).about("out")?;
        for (mut dst, src) in out.into_channels().into_iter().zip(image.planes()) {
            for y in 0..image.extent().height() {
                dst.row_mut(y).copy_from_slice(src.view().row(y));
            }
        }
        Ok(())
    })
}

/// Destroys a pipeline (null is ignored: OK). A pipeline in a call (from that call's
/// callbacks, or on another thread) is not destroyed: `ST_STATUS_BUSY`.
///
/// # Safety
/// `pipeline` null or from a `stereotrace_pipeline_create_*` call, not yet destroyed; no call
/// may start on it once this one has returned OK.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn stereotrace_pipeline_destroy(pipeline: *mut StPipeline) -> StStatus {
    guard(|| {
        // SAFETY: null, or a live pipeline (the caller's contract).
        let Some(p) = (unsafe { pipeline.as_ref() }) else { return Ok(()) };
        p.state.idle("stereotrace_pipeline_destroy")?;
        // SAFETY: the caller's contract: made by `Box::into_raw` in a create function, and no
        // call holds it (checked above).
        drop(unsafe { Box::from_raw(pipeline) });
        Ok(())
    })
}
