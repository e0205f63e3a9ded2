//! What an engine's own tracing gains from `trace_band_rows`: milliseconds per 1280×720
//! path-traced stereo frame through the C ABI, with `trace` called once per eye on one worker
//! against per band of rows on the pipeline's workers.
//!
//! The engine is synthetic: each pixel's "path tracing" is a fixed amount of arithmetic
//! (`WORK` rounds of a hash per sample), so the frame's time is the engine's, as with a real
//! tracer, and the figures compare scheduling, not renderers.
//!
//! ```sh
//! cargo run --release -p stereotrace-capi --example trace_bands -- [FRAMES] [THREADS]
//! ```

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

fn camera(x: f64) -> StCamera {
    let extent = stereotrace_kernels::Extent::new(W as usize, H as usize).unwrap();
    let eye = glam::Vec3::new(x as f32, 0.0, 0.0);
    let vp = stereotrace_kernels::camera::look_at_perspective(eye, eye - glam::Vec3::Z, glam::Vec3::Y, 1.0, extent);
    StCamera { view_proj: vp.as_dmat4().to_cols_array(), width: W, height: H }
}

/// Median milliseconds per frame over `frames` frames (after one warm-up frame).
fn median_frame_ms(band_rows: u32, threads: u32, frames: u32) -> f64 {
    let callbacks =
        StFrameSourceCallbacks { user: std::ptr::null_mut(), fill_gbuffers: Some(fill_gbuffers), trace: Some(trace) };
    let mut config = stereotrace_pipeline_config_default();
    (config.mode, config.threads, config.trace_band_rows) = (StMode::PathTraced as u32, threads, band_rows);
    let cameras = [camera(-0.0325), camera(0.0325)];
    let mut p = std::ptr::null_mut();
    let status = unsafe { stereotrace_pipeline_create_callbacks(&callbacks, &config, cameras.as_ptr(), &mut p) };
    assert_eq!(status, StStatus::Ok);
    let mut times = Vec::new();
    for f in 0..=frames {
        let start = Instant::now();
        let status = unsafe { stereotrace_pipeline_render_frame_at(p, f, cameras.as_ptr(), std::ptr::null_mut()) };
        assert_eq!(status, StStatus::Ok);
        if f > 0 {
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    unsafe { stereotrace_pipeline_destroy(p) };
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let frames: u32 = args.next().map_or(9, |a| a.parse().expect("FRAMES"));
    let threads: u32 = args.next().map_or(2, |a| a.parse().expect("THREADS"));
    println!("1280x720 path-traced stereo frame, synthetic engine, {threads} pipeline threads, median of {frames}");
    let one_call = median_frame_ms(0, threads, frames);
    println!("| trace calls | ms per frame | speed-up |");
    println!("|---|--:|--:|");
    println!("| one per eye (trace_band_rows = 0) | {one_call:.1} | 1.00 |");
    for band in [8, 32, 128] {
        let ms = median_frame_ms(band, threads, frames);
        println!("| per band of {band} rows | {ms:.1} | {:.2} |", one_call / ms);
    }
}
