//! What the C ABI refuses and what it documents instead, each case pinned:
//!
//! - kernels refuse inputs they cannot compute honestly: SSIM below its 11×11 window (every
//!   size, both variants), reason codes outside the defined set (every code, every kernel
//!   that reads them), history lengths that are not counts; refused calls write nothing;
//! - a pipeline's output before its first frame is refused;
//! - cases the header documents as accepted (frame numbers in any order, swapped eyes, eyes
//!   far apart, both eyes at one camera) do what it says;
//! - the settings beyond the paper reach the pipeline: temporal gradients see an engine's
//!   light switched off, the variance blend weighs differently once histories differ, and
//!   the filter's output is the à-trous kernel applied to the unfiltered output.

// These call the C ABI on pointers made a few lines before each call, as a C caller would;
// what each call requires is its documentation in the header.
#![allow(clippy::undocumented_unsafe_blocks)]

mod common;

use common::{RoomEngine, camera, expect, model, outputs, room_pipeline, room_pipeline_with};
use stereotrace_capi::*;

fn context() -> *mut StContext {
    let mut ctx = std::ptr::null_mut();
    expect(unsafe { stereotrace_context_create(1, &mut ctx) }, StStatus::Ok);
    ctx
}

/// Three planes of `w`×`h` floats.
struct Image {
    w: u32,
    h: u32,
    planes: [Vec<f32>; 3],
}

impl Image {
    fn new(w: u32, h: u32, f: impl Fn(usize) -> f32) -> Self {
        let n = (w * h) as usize;
        Self { w, h, planes: [0, 1, 2].map(|c| (0..n).map(|i| f(i * 3 + c)).collect()) }
    }

    fn view(&self) -> StRgb {
        let [r, g, b] = [0, 1, 2].map(|c| StPlaneF32 {
            data: self.planes[c].as_ptr(),
            width: self.w,
            height: self.h,
            stride: self.w,
        });
        StRgb { r, g, b }
    }

    fn view_mut(&mut self) -> StRgbMut {
        let (w, h) = (self.w, self.h);
        let [r, g, b] =
            self.planes.each_mut().map(|p| StPlaneMutF32 { data: p.as_mut_ptr(), width: w, height: h, stride: w });
        StRgbMut { r, g, b }
    }
}

#[test]
fn ssim_refuses_every_size_below_its_window_in_both_variants() {
    let ctx = context();
    let mut refused = 0;
    for w in 1..=STEREOTRACE_SSIM_MIN_SIDE {
        for h in 1..=STEREOTRACE_SSIM_MIN_SIDE {
            let (a, b) = (Image::new(w, h, |i| (i % 7) as f32 * 0.1), Image::new(w, h, |i| (i % 5) as f32 * 0.1));
            for variant in [StSsimVariant::Volume, StSsimVariant::PerChannel] {
                let mut result = StSsimResult { ssim: -7.0, ..StSsimResult::default() };
                let status = unsafe { stereotrace_ssim(ctx, &a.view(), &b.view(), variant as u32, &mut result) };
                if w < STEREOTRACE_SSIM_MIN_SIDE || h < STEREOTRACE_SSIM_MIN_SIDE {
                    let message = expect(status, StStatus::InvalidArgument);
                    assert!(message.contains(&format!("{w}x{h} is smaller than the 11x11 window")), "{message}");
                    assert_eq!(result.ssim, -7.0, "{w}x{h}: a refused call wrote its result");
                    refused += 1;
                } else {
                    expect(status, StStatus::Ok);
                    assert!(result.ssim < 1.0 && result.voxels == 11 * 11 * 3, "{result:?}");
                }
            }
        }
    }
    assert_eq!(refused, 2 * 120, "every size from 1x1 to 11x10 in both variants");
    unsafe { stereotrace_context_destroy(ctx) };
}

#[test]
fn every_kernel_that_reads_reasons_refuses_every_undefined_code() {
    let (w, h) = (13u32, 7u32);
    let ctx = context();
    let new = Image::new(w, h, |i| 0.25 + (i % 11) as f32 * 0.05);
    let n = (w * h) as usize;
    for code in ST_REASON_COUNT as u32..=255 {
        // Valid codes everywhere but one pixel, placed differently for each code.
        let bad = (code as usize * 37) % n;
        let reasons: Vec<u8> =
            (0..n).map(|i| if i == bad { code as u8 } else { (i % ST_REASON_COUNT) as u8 }).collect();
        let reason = StPlaneU8 { data: reasons.as_ptr(), width: w, height: h, stride: w };
        let want = format!("reason plane holds {code} at pixel ({}, {})", bad % w as usize, bad / w as usize);

        let mut accum = Image::new(w, h, |i| i as f32);
        let before = accum.planes.clone();
        let mut stats = StAccumulateStats { resets: 77, ..Default::default() };
        let (new_c, accum_c) = (new.view(), accum.view_mut());
        let status = unsafe {
            stereotrace_ema(
                ctx,
                &new_c,
                &reason,
                std::ptr::null(),
                std::ptr::null(),
                &accum_c,
                std::ptr::null(),
                std::ptr::null(),
                &mut stats,
            )
        };
        let message = expect(status, StStatus::InvalidArgument);
        assert!(message.contains(&want) && message.contains("0 ..= 5"), "EMA, code {code}: {message}");
        assert!(accum.planes == before && stats.resets == 77, "EMA, code {code}: a refused call wrote");

        let reprojected = accum.view_mut();
        let status = unsafe { stereotrace_blend(ctx, &new_c, &reprojected, &reason, 0.5, 4, &mut stats) };
        let message = expect(status, StStatus::InvalidArgument);
        assert!(message.contains(&want), "blend, code {code}: {message}");
        assert!(accum.planes == before, "blend, code {code}: a refused call wrote");
    }
    unsafe { stereotrace_context_destroy(ctx) };
}

#[test]
fn the_ema_refuses_history_lengths_that_are_not_counts() {
    let (w, h) = (9u32, 4u32);
    let ctx = context();
    let new = Image::new(w, h, |_| 1.0);
    let reasons = vec![0u8; (w * h) as usize];
    let reason = StPlaneU8 { data: reasons.as_ptr(), width: w, height: h, stride: w };
    let params = StEmaParams { ramp: 1, ..stereotrace_ema_params_default() };
    for bad in [-5.0, -0.5, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let mut len = vec![3.0f32; (w * h) as usize];
        len[22] = bad;
        let len_c = StPlaneMutF32 { data: len.as_mut_ptr(), width: w, height: h, stride: w };
        let mut accum = Image::new(w, h, |_| 0.5);
        let accum_c = accum.view_mut();
        let status = unsafe {
            stereotrace_ema(
                ctx,
                &new.view(),
                &reason,
                std::ptr::null(),
                std::ptr::null(),
                &accum_c,
                &len_c,
                &params,
                std::ptr::null_mut(),
            )
        };
        let message = expect(status, StStatus::InvalidArgument);
        assert!(message.contains("history length plane holds") && message.contains("(4, 2)"), "{bad}: {message}");
        assert!(accum.planes.iter().all(|p| p.iter().all(|&v| v == 0.5)), "{bad}: a refused call wrote");
    }
    // Zero and large finite counts are counts.
    let mut len = vec![0.0f32; (w * h) as usize];
    len[1] = 1e30;
    let len_c = StPlaneMutF32 { data: len.as_mut_ptr(), width: w, height: h, stride: w };
    let mut accum = Image::new(w, h, |_| 0.5);
    let accum_c = accum.view_mut();
    let status = unsafe {
        stereotrace_ema(
            ctx,
            &new.view(),
            &reason,
            std::ptr::null(),
            std::ptr::null(),
            &accum_c,
            &len_c,
            &params,
            std::ptr::null_mut(),
        )
    };
    expect(status, StStatus::Ok);
    unsafe { stereotrace_context_destroy(ctx) };
}

const W: u32 = 40;
const H: u32 = 24;

#[test]
fn the_output_before_any_frame_is_refused_and_exists_after_the_first() {
    let mut engine = RoomEngine::new();
    let p = room_pipeline(&mut engine, StMode::Stereo, W, H);
    let mut image = Image::new(W, H, |_| -1.0);
    let out = image.view_mut();
    let message = expect(unsafe { stereotrace_pipeline_output(p, 0, &out) }, StStatus::InvalidArgument);
    assert!(message.contains("no frame has been rendered yet"), "{message}");
    assert!(image.planes.iter().all(|p| p.iter().all(|&v| v == -1.0)), "a refused output wrote");
    let cameras = [camera(-0.03, W, H), camera(0.03, W, H)];
    let null = std::ptr::null_mut();
    expect(unsafe { stereotrace_pipeline_render_frame_at(p, 0, cameras.as_ptr(), null) }, StStatus::Ok);
    expect(unsafe { stereotrace_pipeline_output(p, 0, &out) }, StStatus::Ok);
    expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
}

/// Documented: frame numbers may go backwards, repeat and reach `UINT32_MAX`; the history
/// follows the order of the calls, and a frame number keys only the samples (the engine's,
/// or the scene's random numbers and time).
#[test]
fn frame_numbers_in_any_order_are_accepted_and_key_only_the_samples() {
    let mut config = stereotrace_pipeline_config_default();
    (config.mode, config.width, config.height, config.threads) = (StMode::PathTraced as u32, 32, 18, 1);
    let mut p = std::ptr::null_mut();
    expect(unsafe { stereotrace_pipeline_create_scene(c"cornell".as_ptr(), &config, &mut p) }, StStatus::Ok);
    let mut seen = Vec::new();
    for frame in [5, 3, 3, u32::MAX, 3] {
        expect(unsafe { stereotrace_pipeline_render_frame(p, frame, std::ptr::null_mut()) }, StStatus::Ok);
        seen.push(outputs(p, 32, 18));
    }
    assert_eq!(seen[1], seen[2], "a repeated frame number gives the same path-traced samples");
    assert_eq!(seen[1], seen[4], "frame 3 after UINT32_MAX is frame 3");
    assert_ne!(seen[0], seen[1], "another frame number gives other samples");
    expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);

    // With history (temporal), repeating a frame number accumulates: history follows calls.
    let mut engine = RoomEngine::new();
    let p = room_pipeline(&mut engine, StMode::Temporal, W, H);
    let cameras = [camera(-0.03, W, H), camera(0.03, W, H)];
    let mut images = Vec::new();
    for frame in [7, 7, 2] {
        let status = unsafe { stereotrace_pipeline_render_frame_at(p, frame, cameras.as_ptr(), std::ptr::null_mut()) };
        expect(status, StStatus::Ok);
        images.push(outputs(p, W, H));
    }
    assert_eq!(images[0], images[1], "the same samples averaged with themselves");
    assert_ne!(images[1], images[2]);
    expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
}

/// Documented: the pipeline assumes nothing about where the eyes are. Eye 0's output is
/// always the first camera's view; swapped eyes, eyes a kilometre apart and both eyes at one
/// camera give the images of the cameras as given, with stereo reprojection valid wherever
/// the two views show the same surface.
#[test]
fn eye_placement_is_the_callers_swapped_far_apart_or_coincident() {
    let run = |cameras: [StCamera; 2]| {
        let mut engine = RoomEngine::new();
        let p = room_pipeline(&mut engine, StMode::Stereo, W, H);
        let mut stats = StFrameStats::default();
        let status = unsafe { stereotrace_pipeline_render_frame_at(p, 0, cameras.as_ptr(), &mut stats) };
        expect(status, StStatus::Ok);
        let images = outputs(p, W, H);
        expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
        (stats.traced_pixels, images)
    };
    let all = u64::from(W * H);
    let (normal, normal_images) = run([camera(-0.03, W, H), camera(0.03, W, H)]);
    assert!(normal[0] < all / 4 && normal[1] == all, "{normal:?}");

    // Swapped: the right camera is eye 0 now; its (right) eye 1 is fully traced.
    let (swapped, swapped_images) = run([camera(0.03, W, H), camera(-0.03, W, H)]);
    assert!(swapped[0] < all / 4 && swapped[1] == all, "{swapped:?}");
    assert_ne!(swapped_images[1], normal_images[1], "eye 1 shows the camera it was given");

    // A kilometre apart: nothing reprojects, eye 0 is traced in full.
    let (far, _) = run([camera(-500.0, W, H), camera(500.0, W, H)]);
    assert_eq!(far, [all, all]);

    // One camera for both: every pixel reprojects, eye 0 traces nothing, and shows eye 1's
    // samples.
    let (same, same_images) = run([camera(0.03, W, H), camera(0.03, W, H)]);
    assert_eq!(same, [0, all]);
    assert_eq!(same_images[0], same_images[1]);
}

/// Renders frames `0..frames` of the room with the camera moving 3 cm a frame; returns each
/// frame's outputs.
fn frames(p: *mut StPipeline, range: std::ops::Range<u32>) -> Vec<[Vec<u32>; 2]> {
    range
        .map(|f| {
            let x = 0.03 * f as f64;
            let cameras = [camera(x - 0.03, W, H), camera(x + 0.03, W, H)];
            let status = unsafe { stereotrace_pipeline_render_frame_at(p, f, cameras.as_ptr(), std::ptr::null_mut()) };
            expect(status, StStatus::Ok);
            outputs(p, W, H)
        })
        .collect()
}

/// The engine's per-pixel history confidence: 1 is the plain EMA bit for bit, 0 makes every
/// frame its own samples (what path tracing alone shows), and a value outside [0, 1] refuses
/// the frame without touching the output.
#[test]
fn an_engines_history_confidence_weighs_the_history() {
    let run = |mode: StMode, confidence: Option<f32>| {
        let mut engine = RoomEngine::new();
        engine.confidence = confidence.unwrap_or(1.0);
        let p = room_pipeline_with(&mut engine, mode, W, H, |c| c.history_confidence = u32::from(confidence.is_some()));
        let out = frames(p, 0..4);
        expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
        out
    };
    let plain = run(StMode::Temporal, None);
    assert_eq!(run(StMode::Temporal, Some(1.0)), plain, "confidence 1 is the plain EMA");
    let traced = run(StMode::PathTraced, None);
    assert_eq!(run(StMode::Temporal, Some(0.0)), traced, "confidence 0 shows each frame's own samples");
    assert_ne!(plain, traced);
    let half = run(StMode::Temporal, Some(0.5));
    assert!(half != plain && half != traced);

    let mut engine = RoomEngine::new();
    let p = room_pipeline_with(&mut engine, StMode::Temporal, W, H, |c| c.history_confidence = 1);
    let before = frames(p, 0..2).pop().unwrap();
    engine.confidence = 1.5;
    let cameras = [camera(0.03, W, H), camera(0.09, W, H)];
    let status = unsafe { stereotrace_pipeline_render_frame_at(p, 2, cameras.as_ptr(), std::ptr::null_mut()) };
    let message = expect(status, StStatus::InvalidArgument);
    assert!(message.contains("history confidence plane holds 1.5"), "{message}");
    assert_eq!(outputs(p, W, H), before, "a refused frame left the output as it was");
    expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
}

/// An engine's motion vectors: zero is the pipeline without them, bit for bit; a non-finite
/// vector discards every pixel's history (each frame shows its own samples); a flag that is
/// not 0 or 1 is refused.
#[test]
fn an_engines_motion_vectors_reach_temporal_reprojection() {
    let run = |mode: StMode, motion: Option<[f32; 3]>| {
        let mut engine = RoomEngine::new();
        engine.motion = motion.unwrap_or([0.0; 3]);
        let p = room_pipeline_with(&mut engine, mode, W, H, |c| c.motion_vectors = u32::from(motion.is_some()));
        let out = frames(p, 0..4);
        expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
        out
    };
    let still = run(StMode::Temporal, None);
    assert_eq!(run(StMode::Temporal, Some([0.0; 3])), still, "zero motion is no motion");
    let traced = run(StMode::PathTraced, None);
    assert_eq!(run(StMode::Temporal, Some([0.0, f32::NAN, 0.0])), traced, "no pixel keeps a history");
    assert_ne!(run(StMode::Temporal, Some([0.3, 0.0, 0.0])), still, "a moved surface is looked for elsewhere");

    let mut engine = RoomEngine::new();
    let callbacks = engine.callbacks();
    let mut config = stereotrace_pipeline_config_default();
    (config.width, config.height, config.motion_vectors) = (W, H, 2);
    let cameras = [camera(-0.03, W, H), camera(0.03, W, H)];
    let mut p = std::ptr::null_mut();
    let status = unsafe { stereotrace_pipeline_create_callbacks(&callbacks, &config, cameras.as_ptr(), &mut p) };
    let message = expect(status, StStatus::InvalidArgument);
    assert!(message.contains("config.motion_vectors must be 0 or 1"), "{message}");
    assert!(p.is_null());
}

/// Jitter: a camera moving sideways whose G-buffers are jittered along a Halton sequence, the
/// samples exact and on the unjittered grid. With the jitter stated
/// (`stereotrace_pipeline_set_jitter`) the temporal output is as close to the unjittered image
/// (the path-traced mode's) as without any jitter, the history's only error being its
/// bilinear resampling; the same jitter hidden from the pipeline leaves it off by up to the
/// jitter. Offsets past a pixel are refused.
#[test]
fn stated_jitter_keeps_the_history_on_the_unjittered_grid() {
    let halton = |mut i: u32, base: u32| {
        let (mut f, mut r) = (1.0f32, 0.0f32);
        while i > 0 {
            f /= base as f32;
            r += f * (i % base) as f32;
            i /= base;
        }
        r
    };
    const FRAMES: u32 = 8;
    let cameras_at = |f: u32| {
        let x = 0.01 * f as f64;
        [camera(x - 0.03, W, H), camera(x + 0.03, W, H)]
    };
    #[derive(Clone, Copy, PartialEq)]
    enum Jitter {
        None,
        Stated,
        Hidden,
    }
    let run = |mode: StMode, jitter_use: Jitter| {
        let mut engine = RoomEngine::new();
        engine.noisy = false;
        // World positions from the engine (the full layout) are where jitter shows most.
        let p = room_pipeline_with(&mut engine, mode, W, H, |c| c.layout = StLayout::Full as u32);
        for f in 0..FRAMES {
            let jitter = [halton(f + 1, 2) - 0.5, halton(f + 1, 3) - 0.5];
            match jitter_use {
                Jitter::None => {}
                Jitter::Stated => {
                    expect(unsafe { stereotrace_pipeline_set_jitter(p, jitter[0], jitter[1]) }, StStatus::Ok);
                }
                Jitter::Hidden => engine.hidden_jitter = jitter,
            }
            let cameras = cameras_at(f);
            let status = unsafe { stereotrace_pipeline_render_frame_at(p, f, cameras.as_ptr(), std::ptr::null_mut()) };
            expect(status, StStatus::Ok);
        }
        let out = outputs(p, W, H);
        expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
        out
    };
    let reference = run(StMode::PathTraced, Jitter::None);
    // Away from depth edges: there a sub-pixel shift changes which surface a pixel shows, and
    // its history is discarded or blended as at any silhouette.
    let last = cameras_at(FRAMES - 1);
    let smooth: [Vec<bool>; 2] = [0, 1].map(|eye| {
        let depth = RoomEngine::new().scene.render(&model(&last[eye]), [0.0; 3]).surfaces.depth;
        let (w, h) = (W as usize, H as usize);
        let d = |x: usize, y: usize| depth.as_slice()[y * w + x];
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                x > 1 && y > 1 && x + 2 < w && y + 2 < h && {
                    let around = (y - 2..=y + 2).flat_map(|v| (x - 2..=x + 2).map(move |u| (u, v)));
                    around.map(|(u, v)| d(u, v)).all(|n| n.is_finite() && (n - d(x, y)).abs() < 0.02 * d(x, y))
                }
            })
            .collect()
    });
    let mean_error = |out: &[Vec<u32>; 2]| {
        let (mut sum, mut n) = (0.0f64, 0u32);
        for eye in 0..2 {
            for (i, (a, b)) in out[eye].iter().zip(&reference[eye]).enumerate() {
                if smooth[eye][i % (W * H) as usize] {
                    sum += f64::from((f32::from_bits(*a) - f32::from_bits(*b)).abs());
                    n += 1;
                }
            }
        }
        assert!(n > 1000, "{n} smooth samples");
        sum / f64::from(n)
    };
    let none = mean_error(&run(StMode::Temporal, Jitter::None));
    let stated = mean_error(&run(StMode::Temporal, Jitter::Stated));
    let hidden = mean_error(&run(StMode::Temporal, Jitter::Hidden));
    eprintln!("mean error on smooth pixels: no jitter {none:.2e}, stated {stated:.2e}, hidden {hidden:.2e}");
    assert!(stated <= 1.25 * none + 1e-5, "stated jitter: {stated} against {none} without jitter");
    assert!(hidden >= 2.0 * stated, "hidden jitter: {hidden} against stated {stated}");

    let mut engine = RoomEngine::new();
    let p = room_pipeline(&mut engine, StMode::Temporal, W, H);
    let message = expect(unsafe { stereotrace_pipeline_set_jitter(p, 1.5, 0.0) }, StStatus::InvalidArgument);
    assert!(message.contains("within one pixel"), "{message}");
    expect(unsafe { stereotrace_pipeline_set_jitter(p, f32::NAN, 0.0) }, StStatus::InvalidArgument);
    expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
}

/// A thread-safe engine's `trace` called per band of rows (`trace_band_rows`), on the
/// pipeline's workers or on the engine's own job system (`run_jobs`): the same images bit for
/// bit as one call per eye, with and without a budget, and one call per band. A job system
/// that forgets a job refuses the frame, which changes nothing.
#[test]
fn trace_bands_give_the_images_of_one_call_per_eye() {
    use std::sync::atomic::Ordering;
    let run = |mode: StMode, band_rows: u32, budget_ms: f64, jobs: Option<common::RunJobs>| {
        let mut engine = RoomEngine::new();
        engine.run_jobs = jobs;
        let p = room_pipeline_with(&mut engine, mode, W, H, |c| {
            (c.trace_band_rows, c.threads, c.budget_ms) = (band_rows, 2, budget_ms);
        });
        let out = frames(p, 0..3);
        expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
        (out, engine.trace_calls.load(Ordering::Relaxed))
    };
    for mode in [StMode::PathTraced, StMode::Spatiotemporal] {
        let (one_call, calls) = run(mode, 0, 0.0, None);
        for jobs in [None, Some(common::two_thread_jobs as common::RunJobs)] {
            let (banded, band_calls) = run(mode, 3, 0.0, jobs);
            assert!(banded == one_call, "{mode:?}, engine jobs {}", jobs.is_some());
            if mode == StMode::PathTraced {
                assert_eq!((calls, band_calls), (3 * 2, 3 * 2 * u64::from(H.div_ceil(3))));
            }
            assert!(run(mode, 3, 1e6, jobs).0 == one_call, "{mode:?} under a budget, engine jobs {}", jobs.is_some());
        }
    }

    let mut engine = RoomEngine::new();
    engine.run_jobs = Some(common::forgetful_jobs);
    let p = room_pipeline_with(&mut engine, StMode::PathTraced, W, H, |c| c.trace_band_rows = 4);
    let cameras = [camera(-0.03, W, H), camera(0.03, W, H)];
    let status = unsafe { stereotrace_pipeline_render_frame_at(p, 0, cameras.as_ptr(), std::ptr::null_mut()) };
    let message = expect(status, StStatus::CallbackFailed);
    assert!(message.contains("run 0 times (each must run once)"), "{message}");
    expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
}

/// The output lent without a copy (`stereotrace_pipeline_output_view`) is the copied output,
/// bit for bit, after every frame; refused before the first frame and for a null view.
#[test]
fn the_lent_output_is_the_copied_output() {
    let mut engine = RoomEngine::new();
    let p = room_pipeline(&mut engine, StMode::Spatiotemporal, W, H);
    let empty = StPlaneF32 { data: std::ptr::null(), width: 0, height: 0, stride: 0 };
    let mut view = StRgb { r: empty, g: empty, b: empty };
    let message = expect(unsafe { stereotrace_pipeline_output_view(p, 0, &mut view) }, StStatus::InvalidArgument);
    assert!(message.contains("no frame has been rendered yet"), "{message}");
    assert!(view.r.data.is_null(), "a refused call wrote the view");
    for frame in 0..3 {
        let copied = frames(p, frame..frame + 1).pop().unwrap();
        for eye in 0..2 {
            expect(unsafe { stereotrace_pipeline_output_view(p, eye, &mut view) }, StStatus::Ok);
            let lent: Vec<u32> = [view.r, view.g, view.b]
                .iter()
                .flat_map(|plane| {
                    assert_eq!((plane.width, plane.height, plane.stride), (W, H, W));
                    unsafe { std::slice::from_raw_parts(plane.data, (W * H) as usize) }.iter().map(|v| v.to_bits())
                })
                .collect();
            assert!(lent == copied[eye as usize], "eye {eye}, frame {frame}: the lent output differs");
        }
    }
    expect(unsafe { stereotrace_pipeline_output_view(p, 2, &mut view) }, StStatus::InvalidArgument);
    expect(unsafe { stereotrace_pipeline_output_view(p, 0, std::ptr::null_mut()) }, StStatus::NullPointer);
    expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
}

/// `stereotrace_pipeline_reset` forgets the history: the next frame is what a new pipeline's
/// first frame would be.
#[test]
fn a_reset_pipeline_starts_over() {
    let mut engine = RoomEngine::new();
    let p = room_pipeline(&mut engine, StMode::Spatiotemporal, W, H);
    let accumulated = frames(p, 0..3).pop().unwrap();
    expect(unsafe { stereotrace_pipeline_reset(p) }, StStatus::Ok);
    assert_eq!(outputs(p, W, H), accumulated, "the last output stays readable");
    let after_reset = frames(p, 3..4).pop().unwrap();
    let mut fresh_engine = RoomEngine::new();
    let fresh = room_pipeline(&mut fresh_engine, StMode::Spatiotemporal, W, H);
    assert_eq!(frames(fresh, 3..4).pop().unwrap(), after_reset);
    expect(unsafe { stereotrace_pipeline_destroy(fresh) }, StStatus::Ok);
    expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
    expect(unsafe { stereotrace_pipeline_reset(std::ptr::null_mut()) }, StStatus::NullPointer);
}

/// The per-pixel record of a frame: the traced mask counts what the statistics count, and in
/// stereo mode the left eye is traced exactly where its stereo reprojection was discarded.
#[test]
fn per_pixel_reasons_and_the_traced_mask_can_be_read() {
    let mut engine = RoomEngine::new();
    let p = room_pipeline(&mut engine, StMode::Stereo, W, H);
    let mut plane = vec![0xAAu8; (W * H) as usize];
    let out = StPlaneMutU8 { data: plane.as_mut_ptr(), width: W, height: H, stride: W };
    let message = expect(unsafe { stereotrace_pipeline_pixels(p, 0, 2, &out) }, StStatus::InvalidArgument);
    assert!(message.contains("no frame has been rendered yet"), "{message}");
    let cameras = [camera(-0.03, W, H), camera(0.03, W, H)];
    let mut stats = StFrameStats::default();
    expect(unsafe { stereotrace_pipeline_render_frame_at(p, 0, cameras.as_ptr(), &mut stats) }, StStatus::Ok);
    let read = |eye: u32, what: u32| {
        expect(unsafe { stereotrace_pipeline_pixels(p, eye, what, &out) }, StStatus::Ok);
        plane.clone()
    };
    let (left_traced, right_traced) = (read(0, 2), read(1, 2));
    let count = |m: &[u8]| m.iter().filter(|&&v| v == 1).count() as u64;
    assert_eq!([count(&left_traced), count(&right_traced)], stats.traced_pixels);
    assert!(left_traced.iter().chain(&right_traced).all(|&v| v <= 1));
    let left_stereo = read(0, 0);
    for (i, (&t, &r)) in left_traced.iter().zip(&left_stereo).enumerate() {
        assert_eq!(t == 1, r != StReason::Reprojected as u8, "pixel {i}: traced {t}, stereo reason {r}");
    }
    assert!(read(0, 1).iter().all(|&r| r == StReason::Invalid as u8), "stereo mode reprojects no history");
    let message = expect(unsafe { stereotrace_pipeline_pixels(p, 0, 3, &out) }, StStatus::InvalidArgument);
    assert!(message.contains("what 3"), "{message}");
    expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
}

/// `stereotrace_pipeline_resize`: frames of the new size follow, equal to a new pipeline's of
/// that size; cameras of the old size are refused, and the output waits for a frame.
#[test]
fn a_pipeline_resizes_without_being_rebuilt() {
    let (w2, h2) = (33u32, 17u32);
    let mut engine = RoomEngine::new();
    let p = room_pipeline(&mut engine, StMode::Spatiotemporal, W, H);
    frames(p, 0..2);
    expect(unsafe { stereotrace_pipeline_resize(p, w2, h2) }, StStatus::Ok);
    let mut image = vec![vec![0.0f32; (w2 * h2) as usize]; 3];
    let [r, g, b] = [0, 1, 2].map(|c| StPlaneMutF32 { data: image[c].as_mut_ptr(), width: w2, height: h2, stride: w2 });
    let out = StRgbMut { r, g, b };
    expect(unsafe { stereotrace_pipeline_output(p, 0, &out) }, StStatus::InvalidArgument);
    let old = [camera(0.0, W, H), camera(0.06, W, H)];
    expect(
        unsafe { stereotrace_pipeline_render_frame_at(p, 2, old.as_ptr(), std::ptr::null_mut()) },
        StStatus::InvalidArgument,
    );
    let new = [camera(0.0, w2, h2), camera(0.06, w2, h2)];
    expect(unsafe { stereotrace_pipeline_render_frame_at(p, 2, new.as_ptr(), std::ptr::null_mut()) }, StStatus::Ok);
    let resized = outputs(p, w2, h2);

    let mut fresh_engine = RoomEngine::new();
    let fresh = room_pipeline(&mut fresh_engine, StMode::Spatiotemporal, w2, h2);
    expect(unsafe { stereotrace_pipeline_render_frame_at(fresh, 2, new.as_ptr(), std::ptr::null_mut()) }, StStatus::Ok);
    assert_eq!(outputs(fresh, w2, h2), resized);
    for (w, h) in [(0, 5), (STEREOTRACE_MAX_DIMENSION + 1, 5)] {
        expect(unsafe { stereotrace_pipeline_resize(p, w, h) }, StStatus::InvalidArgument);
    }
    expect(unsafe { stereotrace_pipeline_destroy(fresh) }, StStatus::Ok);
    expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
}

/// Renders frame `f` with both eyes still at their first place; returns the frame's
/// statistics.
fn still_frame(p: *mut StPipeline, f: u32) -> StFrameStats {
    let cameras = [camera(-0.03, W, H), camera(0.03, W, H)];
    let mut stats = StFrameStats::default();
    expect(unsafe { stereotrace_pipeline_render_frame_at(p, f, cameras.as_ptr(), &mut stats) }, StStatus::Ok);
    stats
}

/// The paper's settings are the defaults, and a history, blend or filter value that names
/// nothing is refused at creation.
#[test]
fn the_history_blend_and_filter_settings_default_to_the_papers_and_refuse_unknown_values() {
    let config = stereotrace_pipeline_config_default();
    assert_eq!(
        (config.history, config.blend, config.filter, config.background),
        (StHistory::Paper as u32, StBlend::Fixed as u32, StFilter::None as u32, StBackground::Trace as u32)
    );
    assert_eq!(stereotrace_version(), 500, "0.5: StPipelineConfig.background");
    let mut engine = RoomEngine::new();
    let callbacks = engine.callbacks();
    let cameras = [camera(-0.03, W, H), camera(0.03, W, H)];
    type Edit = fn(&mut StPipelineConfig);
    let edits: [(Edit, &str); 4] = [
        (|c| c.history = 3, "config.history 3 is not a StHistory (0 to 2)"),
        (|c| c.blend = 7, "config.blend 7 is not a StBlend (0 or 1)"),
        (|c| c.filter = u32::MAX, "config.filter 4294967295 is not a StFilter (0 or 1)"),
        (|c| c.background = 2, "config.background 2 is not a StBackground (0 or 1)"),
    ];
    for (edit, want) in edits {
        let mut config = stereotrace_pipeline_config_default();
        (config.width, config.height, config.threads) = (W, H, 1);
        edit(&mut config);
        let mut p = std::ptr::null_mut();
        let status = unsafe { stereotrace_pipeline_create_callbacks(&callbacks, &config, cameras.as_ptr(), &mut p) };
        let message = expect(status, StStatus::InvalidArgument);
        assert!(message.contains(want), "{message}");
        assert!(p.is_null());
        let status = unsafe { stereotrace_pipeline_create_scene(c"cornell".as_ptr(), &config, &mut p) };
        assert!(expect(status, StStatus::InvalidArgument).contains(want));
    }
}

/// `ST_HISTORY_GRADIENT` over an engine: the trace callback is asked to re-shade samples of
/// the last frame (its number, under today's light), and when the engine switches its light
/// off the next frame shows its own (black) samples where the paper's history still shows
/// 80 % of the old light. While nothing changes, the images are the paper's bit for bit.
#[test]
fn an_engines_light_switched_off_is_seen_by_temporal_gradients() {
    let pipeline = |history: StHistory, engine: &mut Box<RoomEngine>| {
        room_pipeline_with(engine, StMode::Temporal, W, H, |c| c.history = history as u32)
    };
    let (mut gradient_engine, mut paper_engine) = (RoomEngine::new(), RoomEngine::new());
    let gradient = pipeline(StHistory::Gradient, &mut gradient_engine);
    let paper = pipeline(StHistory::Paper, &mut paper_engine);
    const OFF_AT: u32 = 4;
    for f in 0..OFF_AT {
        let stats = still_frame(gradient, f);
        still_frame(paper, f);
        assert_eq!(outputs(gradient, W, H), outputs(paper, W, H), "frame {f}: nothing changed yet");
        if f > 0 {
            let strata = u64::from((W / 3) * (H / 3));
            assert!(stats.gradient_samples.iter().all(|&n| n >= strata * 9 / 10), "{:?}", stats.gradient_samples);
            assert_eq!(stats.gradient_changed, [0, 0]);
        }
    }
    assert!(gradient_engine.reshades.load(std::sync::atomic::Ordering::Relaxed) > 0);
    assert_eq!(paper_engine.reshades.load(std::sync::atomic::Ordering::Relaxed), 0);

    (gradient_engine.light, paper_engine.light) = (0.0, 0.0);
    let stats = still_frame(gradient, OFF_AT);
    still_frame(paper, OFF_AT);
    assert!(stats.gradient_changed.iter().all(|&n| n > 0), "{:?}", stats.gradient_changed);
    let (shown, lagging) = (outputs(gradient, W, H), outputs(paper, W, H));
    for eye in 0..2 {
        let dark = shown[eye].iter().filter(|&&v| v == 0f32.to_bits()).count();
        assert_eq!(dark, shown[eye].len(), "eye {eye}: every pixel shows this frame's black sample");
        assert!(lagging[eye].iter().all(|&v| f32::from_bits(v) > 0.0), "eye {eye}: the paper's history lags");
    }
    for p in [gradient, paper] {
        expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
    }
}

/// `ST_HISTORY_CLAMP` over an engine: the first frame has no history and is the paper's bit
/// for bit; when the engine switches its light off, every box is [0, 0], so the next frame is
/// black where the paper's history still shows the old light, and the statistics count the
/// moved pixels.
#[test]
fn an_engines_light_switched_off_is_followed_by_the_neighbourhood_clamp() {
    let pipeline = |history: StHistory, engine: &mut Box<RoomEngine>| {
        room_pipeline_with(engine, StMode::Temporal, W, H, |c| c.history = history as u32)
    };
    let (mut clamp_engine, mut paper_engine) = (RoomEngine::new(), RoomEngine::new());
    let clamp = pipeline(StHistory::Clamp, &mut clamp_engine);
    let paper = pipeline(StHistory::Paper, &mut paper_engine);
    const OFF_AT: u32 = 3;
    for f in 0..OFF_AT {
        let stats = still_frame(clamp, f);
        still_frame(paper, f);
        if f == 0 {
            assert!(outputs(clamp, W, H) == outputs(paper, W, H), "no history yet: the paper's image");
            assert_eq!(stats.history_clamped, [0, 0]);
        }
    }
    (clamp_engine.light, paper_engine.light) = (0.0, 0.0);
    let stats = still_frame(clamp, OFF_AT);
    still_frame(paper, OFF_AT);
    assert!(stats.history_clamped.iter().all(|&n| n > u64::from(W * H) / 2), "{:?}", stats.history_clamped);
    let (shown, lagging) = (outputs(clamp, W, H), outputs(paper, W, H));
    for eye in 0..2 {
        assert!(shown[eye].iter().all(|&v| v == 0f32.to_bits()), "eye {eye}: every pixel shows this frame's black");
        assert!(lagging[eye].iter().all(|&v| f32::from_bits(v) > 0.0), "eye {eye}: the paper's history lags");
    }
    for p in [clamp, paper] {
        expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
    }
}

/// `ST_BLEND_VARIANCE` over the living room's camera path: the first frame (no history yet,
/// both lengths 1) is the fixed blend's bit for bit; once a moving camera's disocclusions
/// restart one eye's history where the other's is long, the blend weighs differently.
#[test]
fn the_variance_blend_is_the_fixed_one_until_the_histories_differ() {
    let run = |blend: StBlend| {
        let mut config = stereotrace_pipeline_config_default();
        (config.mode, config.width, config.height, config.threads) = (StMode::SpatiotemporalBlend as u32, W, H, 1);
        config.blend = blend as u32;
        let mut p = std::ptr::null_mut();
        expect(unsafe { stereotrace_pipeline_create_scene(c"living-room".as_ptr(), &config, &mut p) }, StStatus::Ok);
        let out: Vec<[Vec<u32>; 2]> = (3..8)
            .map(|f| {
                expect(unsafe { stereotrace_pipeline_render_frame(p, f, std::ptr::null_mut()) }, StStatus::Ok);
                outputs(p, W, H)
            })
            .collect();
        expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
        out
    };
    let (fixed, variance) = (run(StBlend::Fixed), run(StBlend::Variance));
    assert_eq!(variance[0], fixed[0], "the first frame: no history, the same blend");
    assert_ne!(variance, fixed, "histories of different lengths met");
    assert!(variance.iter().flatten().flatten().all(|&v| f32::from_bits(v).is_finite()));
}

/// `ST_FILTER_ATROUS`: the output is the unfiltered pipeline's output filtered by the
/// à-trous kernel with the engine's G-buffer as its guide (five passes, default weights),
/// and the frame's statistics report the filter.
#[test]
fn the_atrous_filter_is_the_kernel_applied_to_the_unfiltered_output() {
    use stereotrace_kernels::atrous::{AtrousGuide, AtrousParams, AtrousScratch, GuideNormals, atrous};
    use stereotrace_kernels::{Extent, Plane, RgbBuf, RgbPlanes};

    let run = |filter: StFilter| {
        let mut engine = RoomEngine::new();
        let p = room_pipeline_with(&mut engine, StMode::Temporal, W, H, |c| c.filter = filter as u32);
        let stats: Vec<StFrameStats> = (0..3).map(|f| still_frame(p, f)).collect();
        let out = outputs(p, W, H);
        expect(unsafe { stereotrace_pipeline_destroy(p) }, StStatus::Ok);
        (out, stats.last().copied().unwrap())
    };
    let (plain, plain_stats) = run(StFilter::None);
    let (filtered, stats) = run(StFilter::Atrous);
    assert_eq!(plain_stats.filter_ms, 0.0);
    assert!(stats.filter_ms > 0.0 && stats.filter_out_of_range == [0, 0], "{stats:?}");

    let extent = Extent::new(W as usize, H as usize).unwrap();
    let n = extent.pixels();
    let room = RoomEngine::new().scene;
    for (eye, x) in [-0.03, 0.03].into_iter().enumerate() {
        let values: Vec<f32> = plain[eye].iter().map(|&b| f32::from_bits(b)).collect();
        let plane = |c: usize| Plane::new(&values[c * n..(c + 1) * n], W as usize, H as usize, W as usize);
        let input = RgbPlanes::new(plane(0).unwrap(), plane(1).unwrap(), plane(2).unwrap()).unwrap();
        let view = room.render(&model(&camera(x, W, H)), [0.0; 3]);
        let guide = AtrousGuide {
            depth: view.surfaces.depth.view(),
            normals: GuideNormals::Octahedral(view.surfaces.normal_oct.view()),
        };
        let params = AtrousParams { iterations: 5, ..AtrousParams::default() };
        let mut scratch = AtrousScratch::try_new(extent).unwrap();
        let mut expected = RgbBuf::new(extent, f32::NAN);
        atrous(&input, &guide, &params, &mut scratch, expected.view_mut()).unwrap();
        let expected: Vec<u32> =
            expected.planes().iter().flat_map(|p| p.as_slice().iter().map(|v| v.to_bits())).collect();
        assert_eq!(filtered[eye], expected, "eye {eye}");
        assert_ne!(filtered[eye], plain[eye]);
    }
}
