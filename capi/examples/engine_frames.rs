//! What an engine gains from two parts of the C ABI, at 1280×720 stereo:
//! - `trace_band_rows`: milliseconds per path-traced frame with `trace` called once per eye on
//!   one worker against per band of rows on the pipeline's workers;
//! - `stereotrace_pipeline_output_view`: milliseconds to get both eyes' images, copied into
//!   the engine's planes (`stereotrace_pipeline_output`) against lent;
//! - `stereotrace_pipeline_render_frame_lent`: the pipeline's own milliseconds per temporal
//!   frame (the frame less the engine's tracing) when the engine copies its G-buffers into
//!   the pipeline's planes in `fill_gbuffers` against lending them in place.
//!
//! The engine is synthetic: each pixel's "path tracing" is a fixed amount of arithmetic
//! (`WORK` rounds of a hash per sample), so the frame's time is the engine's, as with a real
//! tracer, and the figures compare scheduling, not renderers.
//!
//! ```sh
//! cargo run --release -p stereotrace-capi --example engine_frames -- [FRAMES] [THREADS]
//! ```

// These call the C ABI on pointers made a few lines before each call, as a C caller would;
// what each call requires is its documentation in the header.
#![allow(clippy::undocumented_unsafe_blocks)]

use std::ffi::c_void;
use std::time::Instant;

use stereotrace_capi::*;

const W: u32 = 1280;
const H: u32 = 720;
const WORK: u32 = 64;

unsafe extern "C" fn fill_gbuffers(
    _: *mut c_void,
    _: u32,
    left: *const StGBufferMut,
    right: *const StGBufferMut,
) -> i32 {
    // A wall facing the cameras: what the pipeline needs to run; path-traced mode reads none
    // of it, but the planes must hold a surface or background.
    for g in [left, right] {
        let g = unsafe { &*g };
        for y in 0..g.depth.height as usize {
            for x in 0..g.depth.width as usize {
                let i = y * g.depth.stride as usize + x;
                unsafe {
                    *g.depth.data.add(i) = 5.0;
                    *g.normal_octahedral.data.add(i) = stereotrace_encode_normal(0.0, 0.0, 1.0);
                }
            }
        }
    }
    0
}

#[allow(clippy::too_many_arguments)]
unsafe extern "C" fn trace(
    _: *mut c_void,
    eye: u32,
    frame: u32,
    spp: u32,
    _: *const StCamera,
    mask: *const StPlaneU8,
    row_start: u32,
    row_end: u32,
    out: *const StRgbMut,
) -> i32 {
    let out = unsafe { &*out };
    let mask = unsafe { mask.as_ref() };
    for y in row_start as usize..row_end as usize {
        for x in 0..out.r.width as usize {
            if mask.is_some_and(|m| unsafe { *m.data.add(y * m.stride as usize + x) } == 0) {
                continue;
            }
            let mut h = (u64::from(eye) << 60) ^ (u64::from(frame) << 40) ^ (y * W as usize + x) as u64;
            let mut sum = 0.0f32;
            for _ in 0..spp * WORK {
                h ^= h >> 33;
                h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
                sum += (h >> 40) as f32;
            }
            let v = sum / (spp * WORK) as f32 / (1u64 << 24) as f32;
            let i = y * out.r.stride as usize + x;
            unsafe { *out.r.data.add(i) = v };
            unsafe { *out.g.data.add(i) = v };
            unsafe { *out.b.data.add(i) = v };
        }
    }
    0
}

/// The engine's own job system: two threads of its own (started per call, as a simple engine
/// might) pull band indices from a shared counter.
unsafe extern "C" fn engine_jobs(
    _: *mut c_void,
    count: u32,
    job: unsafe extern "C" fn(*mut c_void, u32),
    context: *mut c_void,
) -> i32 {
    let next = std::sync::atomic::AtomicU32::new(0);
    let context = context as usize;
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    if i >= count {
                        break;
                    }
                    unsafe { job(context as *mut c_void, i) };
                }
            });
        }
    });
    0
}

fn camera(x: f64) -> StCamera {
    let extent = stereotrace_kernels::Extent::new(W as usize, H as usize).unwrap();
    let eye = glam::Vec3::new(x as f32, 0.0, 0.0);
    let vp = stereotrace_kernels::camera::look_at_perspective(eye, eye - glam::Vec3::Z, glam::Vec3::Y, 1.0, extent);
    StCamera { view_proj: vp.as_dmat4().to_cols_array(), width: W, height: H }
}

/// Median milliseconds per frame over `frames` frames (after one warm-up frame), and the
/// median milliseconds to read both eyes' output after each, copied and lent.
fn median_frame_ms(band_rows: u32, threads: u32, frames: u32, own_jobs: bool) -> (f64, [f64; 2]) {
    let callbacks = StFrameSourceCallbacks {
        user: std::ptr::null_mut(),
        fill_gbuffers: Some(fill_gbuffers),
        trace: Some(trace),
        run_jobs: if own_jobs { Some(engine_jobs) } else { None },
    };
    let mut config = stereotrace_pipeline_config_default();
    (config.mode, config.threads, config.trace_band_rows) = (StMode::PathTraced as u32, threads, band_rows);
    let cameras = [camera(-0.0325), camera(0.0325)];
    let mut p = std::ptr::null_mut();
    let status = unsafe { stereotrace_pipeline_create_callbacks(&callbacks, &config, cameras.as_ptr(), &mut p) };
    assert_eq!(status, StStatus::Ok);
    let n = (W * H) as usize;
    let mut planes = vec![vec![0.0f32; n]; 3];
    let [r, g, b] = [0, 1, 2].map(|c| StPlaneMutF32 { data: planes[c].as_mut_ptr(), width: W, height: H, stride: W });
    let copy_into = StRgbMut { r, g, b };
    let (mut times, mut copies, mut views) = (Vec::new(), Vec::new(), Vec::new());
    let mut checksum = 0.0f32;
    for f in 0..=frames {
        let start = Instant::now();
        let status = unsafe { stereotrace_pipeline_render_frame_at(p, f, cameras.as_ptr(), std::ptr::null_mut()) };
        assert_eq!(status, StStatus::Ok);
        let rendered = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        for eye in 0..2 {
            assert_eq!(unsafe { stereotrace_pipeline_output(p, eye, &copy_into) }, StStatus::Ok);
            checksum += planes[1][n / 2];
        }
        let copied = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        for eye in 0..2 {
            let empty = StPlaneF32 { data: std::ptr::null(), width: 0, height: 0, stride: 0 };
            let mut view = StRgb { r: empty, g: empty, b: empty };
            assert_eq!(unsafe { stereotrace_pipeline_output_view(p, eye, &mut view) }, StStatus::Ok);
            checksum += unsafe { *view.g.data.add(n / 2) };
        }
        let lent = start.elapsed().as_secs_f64() * 1e3;
        if f > 0 {
            times.push(rendered);
            copies.push(copied);
            views.push(lent);
        }
    }
    assert!(checksum.is_finite());
    unsafe { stereotrace_pipeline_destroy(p) };
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    (median(times), [median(copies), median(views)])
}

/// An engine's own compact G-buffers (both eyes, this frame's and last frame's), at a padded
/// stride as a GPU readback might have: a floor plane receding from the camera.
struct EngineGBuffers {
    stride: u32,
    depth: [Vec<f32>; 2],
    normals: [Vec<u32>; 2],
}

impl EngineGBuffers {
    fn new() -> Self {
        let stride = W + 64;
        let len = (stride * H) as usize;
        let mut depth = vec![f32::INFINITY; len];
        for y in 0..H as usize {
            // Below the horizon a floor 1.6 m down: depth grows as the row nears the middle.
            let below = (y as f32 + 0.5 - H as f32 / 2.0) / (H as f32 / 2.0);
            let d = if below > 0.01 { (1.6 / below).min(1e3) } else { f32::INFINITY };
            depth[y * stride as usize..y * stride as usize + W as usize].fill(d);
        }
        let up = stereotrace_encode_normal(0.0, 1.0, 0.0);
        Self { stride, depth: [depth.clone(), depth], normals: [vec![up; len], vec![up; len]] }
    }

    fn lent(&self, eye: usize) -> StLentGBuffer {
        let null = StPlaneF32 { data: std::ptr::null(), width: 0, height: 0, stride: 0 };
        let f = |d: &Vec<f32>| StPlaneF32 { data: d.as_ptr(), width: W, height: H, stride: self.stride };
        StLentGBuffer {
            depth: f(&self.depth[eye]),
            position: [null; 3],
            normal: [null; 3],
            normal_octahedral: StPlaneU32 {
                data: self.normals[eye].as_ptr(),
                width: W,
                height: H,
                stride: self.stride,
            },
            history_confidence: null,
            motion: [null; 3],
        }
    }
}

/// `fill_gbuffers` of an engine with G-buffers of its own: row copies into the pipeline's.
unsafe extern "C" fn copy_gbuffers(
    user: *mut c_void,
    _: u32,
    left: *const StGBufferMut,
    right: *const StGBufferMut,
) -> i32 {
    let engine = unsafe { &*(user as *const EngineGBuffers) };
    for (eye, g) in [left, right].into_iter().enumerate() {
        let g = unsafe { &*g };
        for y in 0..H as usize {
            let from = y * engine.stride as usize..y * engine.stride as usize + W as usize;
            let (to_depth, to_normals) = (y * g.depth.stride as usize, y * g.normal_octahedral.stride as usize);
            unsafe {
                std::slice::from_raw_parts_mut(g.depth.data.add(to_depth), W as usize)
                    .copy_from_slice(&engine.depth[eye][from.clone()]);
                std::slice::from_raw_parts_mut(g.normal_octahedral.data.add(to_normals), W as usize)
                    .copy_from_slice(&engine.normals[eye][from]);
            }
        }
    }
    0
}

/// Median of the pipeline's own milliseconds per temporal frame (total less tracing) and of
/// the G-buffer step's, with the engine's G-buffers copied in or lent.
fn gbuffers_in_ms(threads: u32, frames: u32, lend: bool) -> (f64, f64) {
    // Two frames' G-buffers, as an engine double-buffers them; the walls do not move, so
    // both hold the same picture and each frame lends one as this frame's, one as last's.
    let engine = [EngineGBuffers::new(), EngineGBuffers::new()];
    let callbacks = StFrameSourceCallbacks {
        user: &engine[0] as *const EngineGBuffers as *mut c_void,
        fill_gbuffers: Some(copy_gbuffers),
        trace: Some(trace),
        run_jobs: None,
    };
    let mut config = stereotrace_pipeline_config_default();
    (config.mode, config.threads, config.trace_band_rows) = (StMode::Temporal as u32, threads, 16);
    let cameras = [camera(-0.0325), camera(0.0325)];
    let mut p = std::ptr::null_mut();
    let status = unsafe { stereotrace_pipeline_create_callbacks(&callbacks, &config, cameras.as_ptr(), &mut p) };
    assert_eq!(status, StStatus::Ok);
    let (mut own, mut gbuffer) = (Vec::new(), Vec::new());
    for f in 0..=frames {
        let mut stats = unsafe { std::mem::zeroed::<StFrameStats>() };
        let status = if lend {
            let (now, then) = (&engine[f as usize % 2], &engine[(f as usize + 1) % 2]);
            let current = [now.lent(0), now.lent(1)];
            let previous = [then.lent(0), then.lent(1)];
            let previous = if f == 0 { std::ptr::null() } else { previous.as_ptr() };
            unsafe {
                stereotrace_pipeline_render_frame_lent(p, f, cameras.as_ptr(), current.as_ptr(), previous, &mut stats)
            }
        } else {
            unsafe { stereotrace_pipeline_render_frame_at(p, f, cameras.as_ptr(), &mut stats) }
        };
        assert_eq!(status, StStatus::Ok);
        if f > 0 {
            own.push(stats.total_ms - stats.tracing_ms);
            gbuffer.push(stats.gbuffer_ms);
        }
    }
    unsafe { stereotrace_pipeline_destroy(p) };
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    (median(own), median(gbuffer))
}

fn main() {
    let mut args = std::env::args().skip(1);
    let frames: u32 = args.next().map_or(9, |a| a.parse().expect("FRAMES"));
    let threads: u32 = args.next().map_or(2, |a| a.parse().expect("THREADS"));
    println!("1280x720 path-traced stereo frame, synthetic engine, {threads} pipeline threads, median of {frames}");
    let (one_call, [copied, lent]) = median_frame_ms(0, threads, frames, false);
    println!("| trace calls | ms per frame | speed-up |");
    println!("|---|--:|--:|");
    println!("| one per eye (trace_band_rows = 0) | {one_call:.1} | 1.00 |");
    for band in [8, 32, 128] {
        let (ms, _) = median_frame_ms(band, threads, frames, false);
        println!("| per band of {band} rows, pipeline workers | {ms:.1} | {:.2} |", one_call / ms);
    }
    for band in [8, 32] {
        let (ms, _) = median_frame_ms(band, threads, frames, true);
        println!("| per band of {band} rows, engine's job system (2 threads) | {ms:.1} | {:.2} |", one_call / ms);
    }
    println!("\nboth eyes' output: copied {copied:.3} ms, lent {lent:.4} ms");
    let (own_copied, gbuffer_copied) = gbuffers_in_ms(threads, frames, false);
    let (own_lent, gbuffer_lent) = gbuffers_in_ms(threads, frames, true);
    println!("\ntemporal frame, the pipeline's own ms (frame less tracing) / G-buffer step ms:");
    println!("G-buffers copied in by fill_gbuffers: {own_copied:.2} / {gbuffer_copied:.2}");
    println!("G-buffers lent (render_frame_lent):  {own_lent:.2} / {gbuffer_lent:.3}");
}
