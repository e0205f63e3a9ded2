//! The pipeline over a frame source that is not this crate's renderer: the engine of
//! `runtime/examples/embed.rs` (included here, so the example an engine copies is the one
//! tested), an analytic scene of rectangles (no BVH, no lights) whose "path-traced" samples
//! are its texture times a deterministic per-pixel noise. Every mode and order runs through
//! `Pipeline`, and the modes whose schedule is one or two kernel calls are checked against
//! those kernel calls made directly on the same buffers, bit for bit.

#[path = "../examples/embed.rs"]
#[allow(dead_code)] // its `main` is the example's, not this test's
mod embed;

use std::time::Duration;

use embed::{Engine, cameras as eye_cameras};
use glam::Vec3;
use stereotrace_runtime::camera::Eye;
use stereotrace_runtime::kernels::accumulate::{self, EmaInput, EmaParams, EmaState};
use stereotrace_runtime::kernels::reproject::{
    self, Reason, ReprojectInput, ReprojectOutput, ReprojectParams, Tolerances,
};
use stereotrace_runtime::kernels::synth::{SynthFrame, camera_at};
use stereotrace_runtime::kernels::{CameraModel, Extent, PlaneBuf, RgbBuf};
use stereotrace_runtime::pipeline::{Mode, Order, Pipeline, PipelineConfig};

const W: usize = 61;
const H: usize = 37;

fn extent() -> Extent {
    Extent::new(W, H).unwrap()
}

fn cameras(f: u32) -> [CameraModel; 2] {
    eye_cameras(f, extent())
}

fn sample(frame: &SynthFrame, eye: Eye, f: u32, x: usize, y: usize) -> [f32; 3] {
    Engine::sample(frame, eye, f, x, y)
}

fn config(mode: Mode, order: Order) -> PipelineConfig {
    // Tolerances for this coarse view of a room 6 units deep (a pixel is ~0.1 units wide).
    let mut c = PipelineConfig::paper(mode, 1, Tolerances::new(0.5, 0.05, 30.0));
    c.order = order;
    c
}

fn pipeline(mode: Mode, order: Order) -> Pipeline<Engine> {
    Pipeline::with_source(Engine::new(Duration::ZERO), config(mode, order), cameras(0)).unwrap()
}

fn rendered(source: &Engine, eye: Eye) -> &SynthFrame {
    source.rendered(eye).expect("G-buffers were filled")
}

/// Every pixel's sample of `eye` at frame `f`.
fn samples(frame: &SynthFrame, eye: Eye, f: u32) -> RgbBuf {
    let mut out = RgbBuf::new(extent(), 0.0);
    for y in 0..H {
        for x in 0..W {
            out.set(x, y, sample(frame, eye, f, x, y));
        }
    }
    out
}

fn params(c: &PipelineConfig) -> ReprojectParams {
    ReprojectParams { tolerances: c.tolerances, policy: c.policy, band_rows: 16 }
}

#[test]
fn every_mode_and_order_runs_over_an_engine_source() {
    for mode in [
        Mode::PathTraced,
        Mode::Stereo,
        Mode::Temporal,
        Mode::Spatiotemporal,
        Mode::StereoBlend,
        Mode::SpatiotemporalBlend,
    ] {
        for order in [Order::Paper, Order::StereoFirst] {
            if order == Order::StereoFirst && !mode.has_order() {
                continue;
            }
            let mut p = pipeline(mode, order);
            for f in 0..3 {
                let stats = p.render_frame_at(f, cameras(f)).unwrap();
                assert!(stats.raster.is_none());
                for eye in Eye::BOTH {
                    let img = p.output(eye);
                    let finite = img.planes().iter().all(|c| c.as_slice().iter().all(|v| v.is_finite() && *v >= 0.0));
                    assert!(finite, "{mode} {order:?} frame {f} {eye:?}: a non-finite or negative pixel");
                    // Every pixel that shows a surface has a value (the room fills the view).
                    let lit = img.r().as_slice().iter().filter(|&&v| v > 0.0).count();
                    assert!(lit > W * H * 9 / 10, "{mode} {order:?} frame {f} {eye:?}: only {lit} lit pixels");
                }
                if mode.stereo() {
                    let left = stats.stereo_reasons[Eye::Left as usize];
                    assert!(left.get(Reason::Reprojected) > (W * H / 2) as u64, "{mode}: {left:?}");
                }
            }
        }
    }
}

#[test]
fn path_traced_and_stereo_frames_are_the_kernels_on_the_same_buffers() {
    let mut p = pipeline(Mode::PathTraced, Order::Paper);
    p.render_frame_at(1, cameras(1)).unwrap();
    for eye in Eye::BOTH {
        assert_eq!(p.output(eye), &samples(rendered(p.source(), eye), eye, 1));
    }

    let mut p = pipeline(Mode::Stereo, Order::Paper);
    p.render_frame_at(2, cameras(2)).unwrap();
    let (left, right) = (rendered(p.source(), Eye::Left), rendered(p.source(), Eye::Right));
    // Right: traced. Left: the right eye's samples reprojected, traced where discarded.
    let right_samples = samples(right, Eye::Right, 2);
    assert_eq!(p.output(Eye::Right), &right_samples);
    let mut expected = RgbBuf::new(extent(), 0.0);
    let mut reason = PlaneBuf::new(extent(), 0u8);
    let (t, s) = (left.compact(), right.compact());
    let input = ReprojectInput {
        target: &t,
        source: &s,
        source_camera: &right.surfaces.camera,
        colour: right_samples.view(),
        extra: None,
        pixel_mask: None,
        motion: None,
        jitter: None,
        background: None,
    };
    let out = ReprojectOutput { colour: expected.view_mut(), extra: None, reason: reason.view_mut(), weight: None };
    reproject::reproject(&input, out, &params(p.config())).unwrap();
    for y in 0..H {
        for x in 0..W {
            if reason.as_slice()[y * W + x] != Reason::Reprojected as u8 {
                expected.set(x, y, sample(left, Eye::Left, 2, x, y));
            }
        }
    }
    assert_eq!(p.output(Eye::Left), &expected);
    assert_eq!(p.stereo_reasons(Eye::Left), &reason);
}

#[test]
fn temporal_frames_are_reprojection_then_ema_on_the_same_buffers() {
    let mut p = pipeline(Mode::Temporal, Order::Paper);
    p.render_frame_at(0, cameras(0)).unwrap();
    let first: Vec<(SynthFrame, RgbBuf)> =
        Eye::BOTH.iter().map(|&eye| (rendered(p.source(), eye).clone(), p.output(eye).clone())).collect();
    for eye in Eye::BOTH {
        // No history yet: the first frame is its samples.
        assert_eq!(&first[eye as usize].1, &samples(&first[eye as usize].0, eye, 0));
    }
    p.render_frame_at(1, cameras(1)).unwrap();
    for eye in Eye::BOTH {
        let (prev, prev_history) = &first[eye as usize];
        let now = rendered(p.source(), eye);
        let mut history = RgbBuf::new(extent(), 0.0);
        let mut reason = PlaneBuf::new(extent(), 0u8);
        let (t, s) = (now.compact(), prev.compact());
        let input = ReprojectInput {
            target: &t,
            source: &s,
            source_camera: &prev.surfaces.camera,
            colour: prev_history.view(),
            extra: None,
            pixel_mask: None,
            motion: None,
            jitter: None,
            background: None,
        };
        let out = ReprojectOutput { colour: history.view_mut(), extra: None, reason: reason.view_mut(), weight: None };
        let counts = reproject::reproject(&input, out, &params(p.config())).unwrap();
        assert!(counts.get(Reason::Reprojected) > (W * H / 2) as u64, "{counts:?}");
        let new = samples(now, eye, 1);
        let ema =
            EmaInput { new: new.view(), reason: reason.view(), has_new: None, confidence: None, pixel_mask: None };
        let alpha = EmaParams { alpha: p.config().alpha, ramp: false, band_rows: 16 };
        accumulate::ema(&ema, EmaState { accum: history.view_mut(), history_len: None }, &alpha).unwrap();
        assert_eq!(p.output(eye), &history, "{eye:?}");
    }
}

#[test]
fn eye_cameras_of_another_size_are_refused() {
    let mut p = pipeline(Mode::Stereo, Order::Paper);
    let other = Extent::new(W + 1, H).unwrap();
    let wrong = [-0.03, 0.03].map(|dx| camera_at(Vec3::new(dx, 0.0, 0.0), other, 60.0));
    let err = p.render_frame_at(0, wrong).unwrap_err();
    assert!(err.to_string().contains("eye camera"), "{err}");
    // A pipeline made over a source has no rig to turn a head pose into eyes.
    let head = stereotrace_runtime::camera::CameraPose {
        eye: Vec3::ZERO,
        forward: -Vec3::Z,
        up: Vec3::Y,
        right: Vec3::X,
        vfov_deg: 60.0,
    };
    let err = p.render_frame(0, &head).unwrap_err();
    assert!(err.to_string().contains("render_frame_at"), "{err}");
}
