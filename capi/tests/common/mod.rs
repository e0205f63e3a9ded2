//! An engine behind the C ABI's callbacks, written in Rust as a C engine would write it: an
//! analytic room (closed-form G-buffers) whose "path-traced" samples are its texture times
//! a deterministic noise, for tests of the callback pipeline.

// These call the C ABI on pointers made a few lines before each call, as a C caller would;
// what each call requires is its documentation in the header.
#![allow(clippy::undocumented_unsafe_blocks)]
#![allow(dead_code)]

use std::ffi::{CStr, c_void};
use std::sync::atomic::{AtomicU64, Ordering};

use glam::{DMat4, Vec3};
use stereotrace_capi::*;
use stereotrace_kernels::synth::AnalyticScene;
use stereotrace_kernels::{CameraModel, Extent};

/// The last error's text.
pub fn last_error() -> String {
    unsafe { CStr::from_ptr(stereotrace_last_error()) }.to_string_lossy().into_owned()
}

/// Asserts `status` and returns the message.
#[track_caller]
pub fn expect(status: StStatus, want: StStatus) -> String {
    let message = last_error();
    assert_eq!(status, want, "{message}");
    message
}

/// A camera at `x` metres along the room's width, looking down −z (the kernels' analytic
/// camera), in the C ABI's form. Sizes past the limits are kept as given (for tests of
/// their refusal); the matrix is then made for a clamped size.
pub fn camera(x: f64, width: u32, height: u32) -> StCamera {
    let extent = Extent::new((width as usize).clamp(1, 4096), (height as usize).clamp(1, 4096)).unwrap();
    let eye = Vec3::new(x as f32, 0.0, 0.0);
    let vp = stereotrace_kernels::camera::look_at_perspective(eye, eye - Vec3::Z, Vec3::Y, 60f32.to_radians(), extent);
    StCamera { view_proj: vp.as_dmat4().to_cols_array(), width, height }
}

/// The engine's state, passed to the callbacks as `user`.
pub struct RoomEngine {
    pub scene: AnalyticScene,
    /// Pixels traced per eye since made.
    pub traced: [AtomicU64; 2],
    /// Calls of each callback.
    pub gbuffer_calls: u64,
    pub trace_calls: AtomicU64,
    /// The history confidence written where the pipeline gives a plane for it.
    pub confidence: f32,
    /// The motion vector written to every pixel where the pipeline gives motion planes.
    pub motion: [f32; 3],
    /// A sub-pixel jitter the engine renders its G-buffers with without telling the
    /// pipeline (added to the one the pipeline states).
    pub hidden_jitter: [f32; 2],
    /// Whether traced samples carry the per-frame noise (±20 %) or are exact.
    pub noisy: bool,
    /// The engine's own job system, if it offers one.
    pub run_jobs: Option<RunJobs>,
    /// The light's strength now (1: as the room's textures; 0: switched off); the scene's
    /// state, so a re-shaded sample of the last frame sees today's.
    pub light: f32,
    /// The frame `fill_gbuffers` was last called for.
    pub frame: u32,
    /// Trace calls for another frame than the current one (temporal gradients' re-shading).
    pub reshades: AtomicU64,
}

impl RoomEngine {
    pub fn new() -> Box<Self> {
        Box::new(Self {
            scene: AnalyticScene::room(6.0),
            traced: [AtomicU64::new(0), AtomicU64::new(0)],
            gbuffer_calls: 0,
            trace_calls: AtomicU64::new(0),
            confidence: 1.0,
            motion: [0.0; 3],
            hidden_jitter: [0.0; 2],
            noisy: true,
            run_jobs: None,
            light: 1.0,
            frame: 0,
            reshades: AtomicU64::new(0),
        })
    }

    pub fn callbacks(self: &mut Box<Self>) -> StFrameSourceCallbacks {
        StFrameSourceCallbacks {
            user: (&mut **self as *mut RoomEngine).cast::<c_void>(),
            fill_gbuffers: Some(fill_gbuffers),
            trace: Some(trace),
            run_jobs: self.run_jobs,
        }
    }
}

/// The `run_jobs` callback's type.
pub type RunJobs = unsafe extern "C" fn(*mut c_void, u32, unsafe extern "C" fn(*mut c_void, u32), *mut c_void) -> i32;

/// An engine's job system: two threads of its own pull job indices from a shared counter
/// (`skip` jobs at the end are left out, to play a broken job system).
fn run_on_two_threads(count: u32, job: unsafe extern "C" fn(*mut c_void, u32), context: *mut c_void, skip: u32) -> i32 {
    let next = AtomicU64::new(0);
    let context = context as usize;
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i + u64::from(skip) >= u64::from(count) {
                        break;
                    }
                    unsafe { job(context as *mut c_void, i as u32) };
                }
            });
        }
    });
    0
}

/// [`run_on_two_threads`] running every job.
pub unsafe extern "C" fn two_thread_jobs(
    _: *mut c_void,
    count: u32,
    job: unsafe extern "C" fn(*mut c_void, u32),
    context: *mut c_void,
) -> i32 {
    run_on_two_threads(count, job, context, 0)
}

/// [`run_on_two_threads`] that forgets the last job.
pub unsafe extern "C" fn forgetful_jobs(
    _: *mut c_void,
    count: u32,
    job: unsafe extern "C" fn(*mut c_void, u32),
    context: *mut c_void,
) -> i32 {
    run_on_two_threads(count, job, context, 1)
}

pub fn model(c: &StCamera) -> CameraModel {
    let extent = Extent::new(c.width as usize, c.height as usize).unwrap();
    CameraModel::from_f64(DMat4::from_cols_array(&c.view_proj), extent).unwrap()
}

unsafe extern "C" fn fill_gbuffers(
    user: *mut c_void,
    frame: u32,
    left: *const StGBufferMut,
    right: *const StGBufferMut,
) -> i32 {
    let engine = unsafe { &mut *user.cast::<RoomEngine>() };
    engine.gbuffer_calls += 1;
    engine.frame = frame;
    for g in [left, right] {
        let g = unsafe { &*g };
        let jitter = [g.jitter[0] + engine.hidden_jitter[0], g.jitter[1] + engine.hidden_jitter[1]];
        let frame = engine.scene.render(&model(&g.camera).jittered(jitter).unwrap(), [0.0; 3]);
        let s = &frame.surfaces;
        let (w, h) = (g.depth.width as usize, g.depth.height as usize);
        for y in 0..h {
            for x in 0..w {
                let i = y * g.depth.stride as usize + x;
                let j = y * w + x;
                unsafe {
                    *g.depth.data.add(i) = s.depth.as_slice()[j];
                    for c in 0..3 {
                        *g.position[c].data.add(i) = s.position[c].as_slice()[j];
                        *g.normal[c].data.add(i) = s.normal[c].as_slice()[j];
                    }
                    *g.normal_octahedral.data.add(i) = s.normal_oct.as_slice()[j];
                    *g.material.data.add(i) = 0;
                    if !g.history_confidence.data.is_null() {
                        *g.history_confidence.data.add(y * g.history_confidence.stride as usize + x) =
                            engine.confidence;
                    }
                    for (plane, value) in g.motion.iter().zip(engine.motion) {
                        if !plane.data.is_null() {
                            *plane.data.add(y * plane.stride as usize + x) = value;
                        }
                    }
                }
            }
        }
    }
    0
}

#[allow(clippy::too_many_arguments)]
unsafe extern "C" fn trace(
    user: *mut c_void,
    eye: u32,
    frame: u32,
    spp: u32,
    camera: *const StCamera,
    mask: *const StPlaneU8,
    row_start: u32,
    row_end: u32,
    out: *const StRgbMut,
) -> i32 {
    // Shared, not exclusive: with `trace_band_rows` bands run concurrently.
    let engine = unsafe { &*user.cast::<RoomEngine>() };
    engine.trace_calls.fetch_add(1, Ordering::Relaxed);
    if frame != engine.frame {
        engine.reshades.fetch_add(1, Ordering::Relaxed);
    }
    let _ = spp;
    let rendered = engine.scene.render(&model(unsafe { &*camera }), [0.0; 3]);
    let out = unsafe { &*out };
    let w = out.r.width as usize;
    for y in row_start as usize..row_end as usize {
        for x in 0..w {
            let selected =
                unsafe { mask.as_ref() }.is_none_or(|m| unsafe { *m.data.add(y * m.stride as usize + x) } != 0);
            if !selected {
                continue;
            }
            let mut h = u64::from(eye) << 56 ^ u64::from(frame) << 32 ^ (y * w + x) as u64;
            h = (h ^ (h >> 33)).wrapping_mul(0xff51_afd7_ed55_8ccd);
            let noise = if engine.noisy { 0.8 + 0.4 * ((h >> 40) as f32 / (1u64 << 24) as f32) } else { 1.0 };
            let c = rendered.colour.get(x, y);
            for (p, v) in [out.r, out.g, out.b].iter().zip(c) {
                unsafe { *p.data.add(y * p.stride as usize + x) = v * noise * engine.light };
            }
            engine.traced[eye as usize].fetch_add(1, Ordering::Relaxed);
        }
    }
    0
}

/// A callback pipeline over `engine` in `mode` for frames of `width`×`height`, with
/// tolerances for this coarse view of the room.
pub fn room_pipeline(engine: &mut Box<RoomEngine>, mode: StMode, width: u32, height: u32) -> *mut StPipeline {
    room_pipeline_with(engine, mode, width, height, |_| ())
}

/// [`room_pipeline`] with `edit` applied to the configuration.
pub fn room_pipeline_with(
    engine: &mut Box<RoomEngine>,
    mode: StMode,
    width: u32,
    height: u32,
    edit: impl Fn(&mut StPipelineConfig),
) -> *mut StPipeline {
    let callbacks = engine.callbacks();
    let mut config = stereotrace_pipeline_config_default();
    (config.mode, config.width, config.height, config.threads) = (mode as u32, width, height, 1);
    edit(&mut config);
    let mut tolerances = stereotrace_reproject_params_default();
    tolerances.position_tolerance = 0.5;
    config.reprojection = &tolerances;
    let cameras = [camera(-0.03, width, height), camera(0.03, width, height)];
    let mut p = std::ptr::null_mut();
    expect(
        unsafe { stereotrace_pipeline_create_callbacks(&callbacks, &config, cameras.as_ptr(), &mut p) },
        StStatus::Ok,
    );
    p
}

/// Both eyes' output images, as bits, `[left, right]` (R, G and B planes after each other).
pub fn outputs(p: *const StPipeline, width: u32, height: u32) -> [Vec<u32>; 2] {
    [0, 1].map(|eye| {
        let n = (width * height) as usize;
        let mut planes = vec![vec![f32::NAN; n]; 3];
        let [r, g, b] = [0, 1, 2].map(|c| StPlaneMutF32 { data: planes[c].as_mut_ptr(), width, height, stride: width });
        let out = StRgbMut { r, g, b };
        expect(unsafe { stereotrace_pipeline_output(p, eye, &out) }, StStatus::Ok);
        planes.concat().into_iter().map(f32::to_bits).collect()
    })
}
