//! The per-frame pipeline: each mode's images against the same images composed directly from
//! the renderer and the kernels, determinism, history handling and the budget.

use stereotrace::camera::{Eye, StereoRig};
use stereotrace::kernels::accumulate;
use stereotrace::kernels::atrous::{self, AtrousGuide, AtrousParams, AtrousScratch, GuideNormals};
use stereotrace::kernels::reproject::{self, Reason, ReprojectInput, ReprojectOutput, ReprojectParams};
use stereotrace::kernels::{Extent, PlaneBuf, RgbBuf};
use stereotrace::pipeline::{
    ATROUS_ITERATIONS, Blend, Filter, GBufferView, History, Layout, Mode, Order, Pipeline, PipelineConfig,
};
use stereotrace::render::{FrameView, GBufferBuf, GBufferPass, Renderer, RendererOptions, RendererSource};
use stereotrace::scene::resolve;
use stereotrace::session::RendererPipeline;
use stereotrace::source::{FrameSource, PipelineError, PixelSelection, RasterPassStats, TraceRequest, TraceStats};

const W: usize = 48;
const H: usize = 27;

fn extent() -> Extent {
    Extent::new(W, H).unwrap()
}

fn renderer(name: &str) -> Renderer {
    Renderer::new(resolve(name).unwrap()).unwrap()
}

fn config(r: &Renderer, mode: Mode, spp: u32) -> PipelineConfig {
    PipelineConfig::paper(mode, spp, r.scene().tolerances.at_height(H))
}

/// A full path-traced image of `eye` at `frame`, as the renderer makes it.
fn traced(r: &Renderer, eye: Eye, frame: u32, spp: u32, seed: u64) -> RgbBuf {
    let view = FrameView::new(r, &StereoRig::default(), extent(), frame).unwrap();
    view.render(r, &view.request(eye, spp, seed, 0), false).unwrap().0
}

fn run(p: &mut RendererPipeline<'_>, r: &Renderer, frames: std::ops::Range<u32>) {
    for f in frames {
        p.render_frame(f, &r.scene().camera.pose_at(f as f32)).unwrap();
    }
}

#[test]
fn path_traced_mode_is_the_renderer_image() {
    let r = renderer("cornell");
    let mut p = Pipeline::new(&r, config(&r, Mode::PathTraced, 2), StereoRig::default(), extent()).unwrap();
    run(&mut p, &r, 4..5);
    for eye in Eye::BOTH {
        assert_eq!(p.output(eye), &traced(&r, eye, 4, 2, 1));
    }
}

/// The driver's mono baseline is the renderer's image of the right eye, traced alone.
#[test]
fn a_mono_frame_is_the_right_eye_path_traced_alone() {
    let r = renderer("cornell");
    let mut p = Pipeline::new(&r, config(&r, Mode::PathTraced, 2), StereoRig::default(), extent()).unwrap();
    let stats = p.render_mono_frame(4, &r.scene().camera.pose_at(4.0)).unwrap();
    assert_eq!(p.output(Eye::Right), &traced(&r, Eye::Right, 4, 2, 1));
    assert_eq!(stats.traced_pixels, [0, extent().pixels() as u64]);
    assert!(stats.trace.rays >= 2 * extent().pixels() as u64, "every pixel's primary rays traced");
}

#[test]
fn stereo_mode_reprojects_where_valid_and_traces_only_the_rest() {
    let r = renderer("living-room");
    // The traced G-buffer pass, which the reprojection below is given too (the default
    // fixed-point pass differs from it within its tolerance, tested in raster_gbuffers).
    let options = RendererOptions::with_gbuffer(GBufferPass::Traced);
    let mut p =
        Pipeline::with_options(&r, options, config(&r, Mode::Stereo, 1), StereoRig::default(), extent()).unwrap();
    run(&mut p, &r, 7..8);
    let right = traced(&r, Eye::Right, 7, 1, 1);
    let left = traced(&r, Eye::Left, 7, 1, 1);
    assert_eq!(p.output(Eye::Right), &right);
    // The same reprojection straight from the kernel.
    let view = FrameView::new(&r, &StereoRig::default(), extent(), 7).unwrap();
    let (gl, gr) = (view.gbuffer(&r, Eye::Left), view.gbuffer(&r, Eye::Right));
    let mut expected = RgbBuf::new(extent(), 0.0);
    let mut reason = PlaneBuf::new(extent(), 0u8);
    let (t, s) = (gl.compact(), gr.compact());
    let input = ReprojectInput {
        target: &t,
        source: &s,
        source_camera: &gr.camera,
        colour: right.view(),
        extra: None,
        pixel_mask: None,
        motion: None,
        jitter: None,
        background: None,
    };
    let out = ReprojectOutput { colour: expected.view_mut(), extra: None, reason: reason.view_mut(), weight: None };
    let params = ReprojectParams { tolerances: r.scene().tolerances.at_height(H), ..ReprojectParams::default() };
    reproject::reproject(&input, out, &params).unwrap();
    assert_eq!(p.stereo_reasons(Eye::Left), &reason);
    let out = p.output(Eye::Left);
    let mut discarded = 0;
    for i in 0..extent().pixels() {
        let (x, y) = (i % W, i / W);
        if reason.as_slice()[i] == Reason::Reprojected as u8 {
            assert_eq!(out.get(x, y), expected.get(x, y));
        } else {
            discarded += 1;
            assert_eq!(out.get(x, y), left.get(x, y), "a discarded pixel is the full render's pixel");
        }
    }
    assert!(discarded > 0 && discarded < extent().pixels() / 4, "{discarded} discarded");
}

#[test]
fn the_paper_order_left_eye_reprojects_its_history_only_where_stereo_failed() {
    // Frame 1 of the paper-order spatiotemporal mode composed from the kernels: where the
    // stereo reprojection failed, the EMA of the *whole-frame* temporal reprojection of the
    // left history (frame 0's shown image) with the left eye's own samples; elsewhere the
    // stereo sample. The pipeline reprojects the left history only at the failed pixels.
    let r = renderer("living-room");
    let cfg = config(&r, Mode::Spatiotemporal, 1);
    let mut p = Pipeline::new(&r, cfg, StereoRig::default(), extent()).unwrap();
    run(&mut p, &r, 0..1);
    let (prev_gbuffer, prev_image) = (p.gbuffer(Eye::Left).clone(), p.output(Eye::Left).clone());
    let stats = p.render_frame(1, &r.scene().camera.pose_at(1.0)).unwrap();
    let (stereo, temporal) = (p.stereo_reasons(Eye::Left).clone(), p.temporal_reasons(Eye::Left).clone());
    let failed: Vec<bool> = stereo.as_slice().iter().map(|&c| c != Reason::Reprojected as u8).collect();
    let failed_count = failed.iter().filter(|&&f| f).count() as u64;
    assert!(failed_count > 0 && failed_count < extent().pixels() as u64 / 4, "{failed_count} stereo failures");
    assert_eq!(stats.temporal_reasons[Eye::Left as usize].total(), failed_count, "only failed pixels counted");

    let g = p.gbuffer(Eye::Left);
    let mut history = RgbBuf::new(extent(), 0.0);
    let mut reason = PlaneBuf::new(extent(), 0u8);
    let (t, src) = (g.compact(), prev_gbuffer.compact());
    let input = ReprojectInput {
        target: &t,
        source: &src,
        source_camera: &prev_gbuffer.camera,
        colour: prev_image.view(),
        extra: None,
        pixel_mask: None,
        motion: None,
        jitter: None,
        background: None,
    };
    let out = ReprojectOutput { colour: history.view_mut(), extra: None, reason: reason.view_mut(), weight: None };
    let params = ReprojectParams { tolerances: r.scene().tolerances.at_height(H), ..ReprojectParams::default() };
    reproject::reproject(&input, out, &params).unwrap();
    let own = traced(&r, Eye::Left, 1, 1, 1);
    let ema = accumulate::EmaParams { alpha: 0.2, ramp: false, band_rows: 16 };
    let mut checked = 0;
    for i in (0..extent().pixels()).filter(|&i| failed[i]) {
        let (x, y) = (i % W, i / W);
        assert_eq!(temporal.as_slice()[i], reason.as_slice()[i], "({x}, {y}): the temporal reason");
        let valid = reason.as_slice()[i] == Reason::Reprojected as u8;
        let (expected, _) =
            accumulate::ema_pixel(history.get(x, y), 0.0, own.get(x, y), valid, true, &ema, &mut Default::default());
        assert_eq!(p.output(Eye::Left).get(x, y), expected, "({x}, {y})");
        checked += usize::from(valid);
    }
    assert!(checked > 0, "no failed stereo pixel had a valid history to accumulate");
    for i in (0..extent().pixels()).filter(|&i| !failed[i]) {
        assert_eq!(temporal.as_slice()[i], Reason::Invalid as u8, "not reprojected, marked invalid");
    }
}

#[test]
fn temporal_mode_with_alpha_one_is_the_latest_frame() {
    let r = renderer("atrium");
    let mut cfg = config(&r, Mode::Temporal, 1);
    cfg.alpha = 1.0;
    let mut p = Pipeline::new(&r, cfg, StereoRig::default(), extent()).unwrap();
    run(&mut p, &r, 0..3);
    assert_eq!(p.output(Eye::Left), &traced(&r, Eye::Left, 2, 1, 1));
}

#[test]
fn spatiotemporal_accumulation_lowers_the_error() {
    // Frames 0..12 of the atrium at 1 spp, 192×108: the spatiotemporal left eye beats a
    // single 1-spp frame against a 256-spp reference by a wide margin (measured: 0.16 vs
    // 0.39 RMSE in green). Low resolutions blur edges more than they denoise, so this needs
    // a frame of some size.
    let r = renderer("atrium");
    let e = Extent::new(192, 108).unwrap();
    let cfg = PipelineConfig::paper(Mode::Spatiotemporal, 1, r.scene().tolerances.at_height(108));
    let mut p = Pipeline::new(&r, cfg, StereoRig::default(), e).unwrap();
    run(&mut p, &r, 0..12);
    let view = FrameView::new(&r, &StereoRig::default(), e, 11).unwrap();
    let render = |spp, seed| view.render(&r, &view.request(Eye::Left, spp, seed, 0), false).unwrap().0;
    let reference = render(256, 77);
    let rmse = |img: &RgbBuf| {
        let d: f64 =
            img.g().as_slice().iter().zip(reference.g().as_slice()).map(|(a, b)| f64::from(a - b).powi(2)).sum();
        (d / e.pixels() as f64).sqrt()
    };
    let (acc, one) = (rmse(p.output(Eye::Left)), rmse(&render(1, 1)));
    assert!(acc < 0.6 * one, "accumulated {acc} vs single {one}");
}

#[test]
fn a_mono_rig_reprojects_every_surface_pixel() {
    let r = renderer("classroom");
    for (mode, order) in
        [(Mode::Stereo, Order::Paper), (Mode::Spatiotemporal, Order::Paper), (Mode::StereoBlend, Order::Paper)]
    {
        let mut cfg = config(&r, mode, 1);
        cfg.order = order;
        let mut p = Pipeline::new(&r, cfg, StereoRig::new(0.0).unwrap(), extent()).unwrap();
        run(&mut p, &r, 0..2);
        let reasons = p.stereo_reasons(Eye::Left).as_slice();
        let depth = p.gbuffer(Eye::Left).depth.as_slice();
        for (i, &c) in reasons.iter().enumerate() {
            let expected = if depth[i].is_infinite() { Reason::Background } else { Reason::Reprojected };
            assert_eq!(Reason::from_code(c), Some(expected), "{mode} pixel {i}");
        }
    }
}

#[test]
fn every_mode_and_order_is_deterministic_and_finite() {
    let r = renderer("living-room-moving-light");
    for mode in Mode::ALL {
        for order in [Order::Paper, Order::StereoFirst] {
            if order == Order::StereoFirst && !mode.has_order() {
                continue;
            }
            let mut cfg = config(&r, mode, 1);
            cfg.order = order;
            cfg.ramp = true;
            let mut a = Pipeline::new(&r, cfg, StereoRig::default(), extent()).unwrap();
            let mut b = Pipeline::new(&r, cfg, StereoRig::default(), extent()).unwrap();
            run(&mut a, &r, 0..4);
            run(&mut b, &r, 0..4);
            for eye in Eye::BOTH {
                assert_eq!(a.output(eye), b.output(eye), "{mode} {order:?} {eye}");
                let img = a.output(eye);
                for p in img.planes() {
                    assert!(p.as_slice().iter().all(|v| v.is_finite()), "{mode} {order:?} {eye}");
                }
            }
        }
    }
}

#[test]
fn the_left_eye_traces_only_a_few_percent_in_stereo_modes() {
    let r = renderer("atrium");
    let cfg = PipelineConfig::paper(Mode::Spatiotemporal, 1, r.scene().tolerances.at_height(90));
    let mut p = Pipeline::new(&r, cfg, StereoRig::default(), Extent::new(160, 90).unwrap()).unwrap();
    let stats = p.render_frame(5, &r.scene().camera.pose_at(5.0)).unwrap();
    let pixels = (160 * 90) as u64;
    assert_eq!(stats.traced_pixels[Eye::Right as usize], pixels);
    let left = stats.traced_pixels[Eye::Left as usize];
    assert!(left > 0 && left < pixels / 10, "left traced {left} of {pixels}");
}

#[test]
fn a_budget_traces_disocclusions_first_and_stops_early() {
    let r = renderer("atrium");
    let mut cfg = config(&r, Mode::Temporal, 1);
    cfg.budget = Some(std::time::Duration::from_nanos(1));
    cfg.tile_rows = 4;
    let mut p = Pipeline::new(&r, cfg, StereoRig::default(), extent()).unwrap();
    // First frame: no history, so every pixel is urgent and gets traced despite the budget.
    let first = p.render_frame(0, &r.scene().camera.pose_at(0.0)).unwrap();
    assert_eq!(first.traced_pixels, first.wanted_pixels);
    assert!(!first.budget_met);
    // Later frames: only the disoccluded pixels (plus at most one tile per eye, started
    // before the time check) are traced; the rest keep their reprojected history.
    let later = p.render_frame(1, &r.scene().camera.pose_at(1.0)).unwrap();
    for eye in Eye::BOTH {
        let discarded = later.temporal_reasons[eye as usize].total()
            - later.temporal_reasons[eye as usize].get(Reason::Reprojected);
        let traced = later.traced_pixels[eye as usize];
        assert!(
            traced >= discarded && traced <= discarded + (4 * W) as u64,
            "{eye}: traced {traced}, discarded {discarded}"
        );
    }
    let img = p.output(Eye::Left);
    assert!(img.r().as_slice().iter().all(|v| v.is_finite()));
}

#[test]
fn invalid_configurations_are_refused() {
    let r = renderer("cornell");
    let mut cfg = config(&r, Mode::Stereo, 0);
    assert!(Pipeline::new(&r, cfg, StereoRig::default(), extent()).is_err());
    cfg.spp = 1;
    cfg.alpha = 0.0;
    let err = Pipeline::new(&r, cfg, StereoRig::default(), extent()).err().unwrap();
    assert!(err.to_string().contains("alpha"), "{err}");
}

/// A pipeline over this crate's renderer resized in place (its rasterised pass's buffers too)
/// renders what a new pipeline of the new size renders; the history is forgotten.
#[test]
fn a_resized_pipeline_renders_what_a_new_one_of_that_size_renders() {
    let r = renderer("living-room");
    let small = Extent::new(33, 19).unwrap();
    let mut p = Pipeline::new(&r, config(&r, Mode::Spatiotemporal, 1), StereoRig::default(), extent()).unwrap();
    run(&mut p, &r, 0..3);
    p.resize(small).unwrap();
    assert_eq!(p.extent(), small);
    assert_eq!(p.frames_since_reset(), 0);
    run(&mut p, &r, 3..5);
    let mut fresh = Pipeline::new(&r, config(&r, Mode::Spatiotemporal, 1), StereoRig::default(), small).unwrap();
    run(&mut fresh, &r, 3..5);
    for eye in Eye::BOTH {
        assert_eq!(p.output(eye), fresh.output(eye), "{eye:?}");
        assert_eq!(p.gbuffer(eye).depth, fresh.gbuffer(eye).depth, "{eye:?}");
    }
    // Back to the first size, as one more resize.
    p.resize(extent()).unwrap();
    run(&mut p, &r, 5..6);
    assert_eq!(p.output(Eye::Left).extent(), extent());
}

/// Renders frames `frames` of `scene` with a still camera (frame 0's), without and with motion
/// vectors, and checks each G-buffer's motion against the closed form: the pixels whose
/// material is `material` move by the rigid motion `path` makes between the last two frames
/// (checked by the path's inverse transform, not the renderer's barycentric way), all others
/// are still. Returns the pixels of `material` (both eyes) and how many of them kept their
/// history without and with vectors. `pass` makes the G-buffers: the rasterised pass names
/// each pixel's moving triangle, the traced one leaves it to a search of them all.
fn motion_and_history(
    pass: GBufferPass,
    scene: &str,
    material: impl Fn(&Renderer) -> (u32, stereotrace::scene::TransformPath),
    frames: std::ops::Range<u32>,
) -> (usize, [usize; 2]) {
    let r = renderer(scene);
    let e = Extent::new(320, 180).unwrap();
    let head = r.scene().camera.pose_at(0.0);
    let (material, path) = material(&r);
    let last = frames.end as f32 - 1.0;
    let (now, then) = (path.transform(last), path.transform(last - 1.0));
    let (mut pixels, mut kept) = (0usize, [0usize; 2]);
    for motion_vectors in [false, true] {
        let mut cfg = PipelineConfig::paper(Mode::Temporal, 1, r.scene().tolerances.at_height(e.height()));
        cfg.motion_vectors = motion_vectors;
        let options = RendererOptions::with_gbuffer(pass);
        let mut p = Pipeline::with_options(&r, options, cfg, StereoRig::default(), e).unwrap();
        for frame in frames.clone() {
            p.render_frame(frame, &head).unwrap();
        }
        for eye in Eye::BOTH {
            let g = p.gbuffer(eye);
            assert_eq!(g.motion.is_some(), motion_vectors);
            let reasons = p.temporal_reasons(eye).as_slice();
            for (i, &m_id) in g.material.as_slice().iter().enumerate() {
                let moving = m_id == material;
                if moving {
                    pixels += usize::from(motion_vectors);
                    kept[usize::from(motion_vectors)] += usize::from(reasons[i] == Reason::Reprojected as u8);
                }
                let Some(motion) = &g.motion else { continue };
                let (x, y) = (i % e.width(), i / e.width());
                let m = glam::Vec3::from(std::array::from_fn(|c| motion[c].as_slice()[i]));
                if !moving {
                    assert_eq!(m, glam::Vec3::ZERO, "{scene} {pass:?} {eye} ({x}, {y}): still geometry");
                    continue;
                }
                let point = glam::Vec3::from(g.camera.unproject_pixel(x, y, g.depth.as_slice()[i]));
                let expected = point - then.transform_point3(now.inverse().transform_point3(point));
                assert!(
                    (m - expected).length() < 1e-3 * expected.length().max(1e-2),
                    "{scene} {pass:?} {eye} ({x}, {y}): {m} vs {expected}"
                );
            }
        }
    }
    (pixels, kept)
}

/// Motion vectors (`PipelineConfig::motion_vectors`) on the moving sphere of atrium, seen by a
/// still camera: the G-buffer's motion is the sphere's own translation, zero on everything
/// else; and temporal reprojection keeps the sphere's history with the vectors and loses it
/// without (the sphere moves ~0.17 m a frame, more than the position tolerance).
#[test]
fn motion_vectors_follow_a_moving_light_and_keep_its_history() {
    let sphere = |r: &Renderer| {
        let moving = &r.scene().lights.moving;
        assert_eq!(moving.len(), 1);
        (stereotrace::render::MOVING_LIGHT_MATERIAL, moving[0].path.clone())
    };
    for pass in [GBufferPass::Raster, GBufferPass::Traced] {
        let (pixels, [without, with]) = motion_and_history(pass, "atrium-moving-light", sphere, 10..13);
        eprintln!("{pass:?}: sphere pixels {pixels}: history kept on {without} without vectors, {with} with");
        assert!(pixels > 50, "the sphere covers {pixels} pixels");
        assert!(with * 10 >= pixels * 8, "with vectors {with} of {pixels}");
        assert!(without * 5 <= pixels, "without vectors {without} of {pixels}");
    }
}

/// Motion vectors on atrium's moving crate (a non-emissive object that slides and turns): its
/// rigid motion, rotation included, and with vectors its history kept where it stays visible.
#[test]
fn motion_vectors_follow_a_moving_object() {
    let crate_ = |r: &Renderer| {
        let object = &r.scene().moving_objects[0];
        (object.material, object.path.clone())
    };
    for pass in [GBufferPass::Raster, GBufferPass::Traced] {
        let (pixels, [without, with]) = motion_and_history(pass, "atrium-moving-object", crate_, 20..23);
        // Without vectors the sliding crate mostly keeps a history too, but of the wrong
        // texels (its faces slide along themselves and pass the geometric tests); RESULTS.md
        // measures what that costs.
        eprintln!("{pass:?}: crate pixels {pixels}: history kept on {without} without vectors, {with} with");
        assert!(pixels > 500, "the crate covers {pixels} pixels");
        assert!(with * 10 >= pixels * 8, "with vectors {with} of {pixels}");
    }
}

/// A scene pipeline renders its G-buffers with the stated jitter (the rasterised pass takes the
/// jittered pair as a parallel rig), keeps the traced images on the unjittered grid, and with
/// a still head reprojects its history on nearly every pixel whatever the jitter.
#[test]
fn a_jittered_scene_pipeline_keeps_its_history() {
    let r = renderer("cornell");
    let head = r.scene().camera.pose_at(0.0);
    let e = Extent::new(160, 90).unwrap();
    let cfg = PipelineConfig::paper(Mode::Temporal, 1, r.scene().tolerances.at_height(e.height()));
    let mut p = Pipeline::new(&r, cfg, StereoRig::default(), e).unwrap();
    for (frame, jitter) in [[0.0f32, 0.0], [0.25, -0.25], [-0.375, 0.125], [0.125, 0.375]].into_iter().enumerate() {
        p.set_jitter(jitter).unwrap();
        p.render_frame(frame as u32, &head).unwrap();
        for eye in Eye::BOTH {
            let g = p.gbuffer(eye);
            assert_eq!(g.jitter, jitter);
            let unjittered = StereoRig::default().eye_camera(&head, eye, e).unwrap();
            assert_eq!(g.camera, unjittered.jittered(jitter).unwrap());
            if frame > 0 {
                let surfaces = g.depth.as_slice().iter().filter(|d| d.is_finite()).count();
                let kept =
                    p.temporal_reasons(eye).as_slice().iter().filter(|&&c| c == Reason::Reprojected as u8).count();
                assert!(kept * 100 >= surfaces * 95, "{eye} frame {frame}: {kept} of {surfaces} kept");
            }
        }
    }
    assert!(p.set_jitter([0.0, -1.5]).is_err());
}

/// An engine's own G-buffer planes, at a stride wider than the frame (zero-copy input).
struct EnginePlanes {
    stride: usize,
    depth: Vec<f32>,
    normal_oct: Vec<u32>,
    position: [Vec<f32>; 3],
    normal: [Vec<f32>; 3],
    motion: [Vec<f32>; 3],
}

impl EnginePlanes {
    /// A strided copy of `g` (what an engine's rasteriser would have written), padding NaN.
    fn copy_of(g: &GBufferBuf) -> Self {
        let (w, h) = (g.extent().width(), g.extent().height());
        let stride = w + 5;
        fn strided<T: Copy>(src: &[T], w: usize, h: usize, stride: usize, pad: T) -> Vec<T> {
            let mut out = vec![pad; stride * h];
            for y in 0..h {
                out[y * stride..y * stride + w].copy_from_slice(&src[y * w..(y + 1) * w]);
            }
            out
        }
        let f = |p: &PlaneBuf| strided(p.as_slice(), w, h, stride, f32::NAN);
        let motion = match &g.motion {
            Some(m) => m.each_ref().map(f),
            None => [vec![], vec![], vec![]],
        };
        Self {
            stride,
            depth: f(&g.depth),
            normal_oct: strided(g.normal_oct.as_slice(), w, h, stride, 0),
            position: g.position.each_ref().map(f),
            normal: g.normal.each_ref().map(f),
            motion,
        }
    }

    fn view(&self, e: Extent, layout: Layout) -> stereotrace::pipeline::GBufferView<'_> {
        use stereotrace::kernels::Plane;
        let (w, h, s) = (e.width(), e.height(), self.stride);
        fn plane(d: &[f32], w: usize, h: usize, s: usize) -> Plane<'_> {
            Plane::new(d, w, h, s).unwrap()
        }
        let plane = |d| plane(d, w, h, s);
        stereotrace::pipeline::GBufferView {
            depth: plane(&self.depth),
            normal_oct: (layout == Layout::Compact).then(|| Plane::new(&self.normal_oct, w, h, s).unwrap()),
            position: (layout == Layout::Full).then(|| self.position.each_ref().map(|p| plane(p))),
            normal: (layout == Layout::Full).then(|| self.normal.each_ref().map(|p| plane(p))),
            history_confidence: None,
            motion: (!self.motion[0].is_empty()).then(|| self.motion.each_ref().map(|p| plane(p))),
        }
    }
}

/// Lent G-buffers (the engine's own planes, strided, read in place) give the frames the
/// source's G-buffers give, bit for bit, in every mode and both layouts; the engine lends
/// the previous frame's planes too, and a lent frame without them is refused and changes
/// nothing.
#[test]
fn lent_g_buffers_give_the_frames_the_source_gives() {
    let r = renderer("atrium-moving-object");
    let e = extent();
    let rig = StereoRig::default();
    for layout in [Layout::Compact, Layout::Full] {
        for mode in Mode::ALL {
            let mut cfg = config(&r, mode, 1);
            (cfg.layout, cfg.motion_vectors) = (layout, mode.temporal());
            let mut owned = Pipeline::new(&r, cfg, rig, e).unwrap();
            let mut lent = Pipeline::new(&r, cfg, rig, e).unwrap();
            let mut previous: Option<[EnginePlanes; 2]> = None;
            for frame in 20..24 {
                let head = r.scene().camera.pose_at(frame as f32);
                owned.render_frame(frame, &head).unwrap();
                let current = Eye::BOTH.map(|eye| EnginePlanes::copy_of(owned.gbuffer(eye)));
                let cameras = Eye::BOTH.map(|eye| rig.eye_camera(&head, eye, e).unwrap());
                fn views(p: &[EnginePlanes; 2], e: Extent, layout: Layout) -> [GBufferView<'_>; 2] {
                    [p[0].view(e, layout), p[1].view(e, layout)]
                }
                let views = |p| views(p, e, layout);
                if let Some(p) = &previous {
                    // Without the previous frame's planes a lent frame is refused, untouched.
                    let before = lent.output(Eye::Right).clone();
                    let err = lent.render_frame_lent(frame, cameras, views(&current), None).unwrap_err();
                    assert!(err.to_string().contains("previous"), "{err}");
                    assert_eq!(lent.output(Eye::Right), &before);
                    lent.render_frame_lent(frame, cameras, views(&current), Some(views(p))).unwrap();
                } else {
                    lent.render_frame_lent(frame, cameras, views(&current), None).unwrap();
                }
                for eye in Eye::BOTH {
                    let what = format!("{mode:?} {layout:?} frame {frame} {eye}");
                    assert_eq!(lent.output(eye), owned.output(eye), "{what}: output");
                    assert_eq!(lent.temporal_reasons(eye), owned.temporal_reasons(eye), "{what}: reasons");
                }
                previous = Some(current);
            }
        }
    }
}

/// A lent view that does not fit the configuration is refused by name.
#[test]
fn lent_g_buffers_are_checked() {
    use stereotrace::kernels::Plane;
    let r = renderer("cornell");
    let e = extent();
    let mut p = Pipeline::new(&r, config(&r, Mode::Temporal, 1), StereoRig::default(), e).unwrap();
    let head = r.scene().camera.pose_at(0.0);
    let cameras = Eye::BOTH.map(|eye| StereoRig::default().eye_camera(&head, eye, e).unwrap());
    let depth = vec![1.0f32; W * H];
    let normals = vec![0u32; W * H];
    let small = vec![1.0f32; (W - 1) * H];
    let good = GBufferView::compact(Plane::packed(&depth, W, H).unwrap(), Plane::packed(&normals, W, H).unwrap());
    let mut no_normals = good;
    no_normals.normal_oct = None;
    let mut narrow = good;
    narrow.depth = Plane::packed(&small, W - 1, H).unwrap();
    let mut extra = good;
    extra.motion = Some([good.depth; 3]);
    for (view, needle) in [(no_normals, "normal_oct plane is missing"), (narrow, "depth"), (extra, "motion_vectors")] {
        let err = p.render_frame_lent(0, cameras, [good, view], None).unwrap_err().to_string();
        assert!(err.contains(needle), "{err}");
    }
    p.render_frame_lent(0, cameras, [good, good], None).unwrap();
}

/// Temporal gradients with the renderer: a static scene traces no gradient samples and gives
/// the paper's images bit for bit in every temporal mode; a scene with a moving light traces
/// about one per 3×3 stratum, re-shading the last frame's samples, and shortens its history
/// somewhere (the light moves every frame).
#[test]
fn temporal_gradients_run_only_where_the_scene_changes() {
    let modes = [Mode::Temporal, Mode::Spatiotemporal, Mode::SpatiotemporalBlend];
    for (scene, changes) in [("cornell", false), ("atrium-moving-light", true)] {
        let r = renderer(scene);
        for mode in modes {
            let paper = config(&r, mode, 1);
            let gradient = PipelineConfig { history: History::Gradient, ..paper };
            let mut a = Pipeline::new(&r, paper, StereoRig::default(), extent()).unwrap();
            let mut b = Pipeline::new(&r, gradient, StereoRig::default(), extent()).unwrap();
            let mut changed = 0;
            for f in 3..7 {
                let pose = r.scene().camera.pose_at(f as f32);
                a.render_frame(f, &pose).unwrap();
                let stats = b.render_frame(f, &pose).unwrap();
                changed += stats.gradient_changed.iter().sum::<u64>();
                let samples = stats.gradient_samples[Eye::Right as usize];
                if !changes {
                    assert_eq!(stats.gradient_samples, [0, 0], "{scene} {mode}");
                    for eye in Eye::BOTH {
                        assert_eq!(a.output(eye), b.output(eye), "{scene} {mode} {eye} frame {f}");
                    }
                } else if f > 3 {
                    // Most strata have a reprojected pixel whose source was traced.
                    let strata = (W / 3 * H / 3) as u64;
                    assert!(samples > strata / 2 && samples <= strata, "{scene} {mode}: {samples} of {strata}");
                    assert!(stats.trace.samples > a_samples(&stats), "{scene} {mode}");
                }
            }
            assert_eq!(changed > 0, changes, "{scene} {mode}: {changed} strata changed");
        }
    }
}

/// The neighbourhood clamp with the renderer: a mode without a temporal history runs no
/// clamp (the paper's images bit for bit, nothing counted); a temporal mode's first frame
/// has no history to clamp, and later frames move histories toward this frame's noisy
/// samples somewhere in the fully traced eye, with finite images.
#[test]
fn the_neighbourhood_clamp_runs_only_on_temporal_histories() {
    let r = renderer("cornell");
    for mode in [Mode::Stereo, Mode::StereoBlend, Mode::Temporal, Mode::Spatiotemporal, Mode::SpatiotemporalBlend] {
        let paper = config(&r, mode, 1);
        let clamp = PipelineConfig { history: History::Clamp, ..paper };
        let mut a = Pipeline::new(&r, paper, StereoRig::default(), extent()).unwrap();
        let mut b = Pipeline::new(&r, clamp, StereoRig::default(), extent()).unwrap();
        let mut clamped = 0;
        for f in 3..7 {
            let pose = r.scene().camera.pose_at(f as f32);
            a.render_frame(f, &pose).unwrap();
            let stats = b.render_frame(f, &pose).unwrap();
            clamped += stats.history_clamped.iter().sum::<u64>();
            let same = Eye::BOTH.iter().all(|&eye| a.output(eye) == b.output(eye));
            if f == 3 || !mode.temporal() {
                assert_eq!(stats.history_clamped, [0, 0], "{mode} frame {f}");
                assert!(same, "{mode} frame {f}: nothing to clamp");
            }
            for eye in Eye::BOTH {
                assert!(b.output(eye).r().as_slice().iter().all(|v| v.is_finite()), "{mode} {eye}");
            }
        }
        assert_eq!(clamped > 0, mode.temporal(), "{mode}: {clamped} histories clamped");
    }
}

/// Samples a frame traced for its pixels alone (the gradient samples come on top).
fn a_samples(stats: &stereotrace::pipeline::FrameStats) -> u64 {
    stats.traced_pixels.iter().sum()
}

/// The renderer as a source that claims its scene may change: the pipeline then re-shades
/// every stratum's gradient sample even on a static scene.
struct ClaimsChange<'r>(RendererSource<&'r Renderer>);

impl FrameSource for ClaimsChange<'_> {
    fn begin_frame(&mut self, frame: u32) {
        self.0.begin_frame(frame);
    }
    fn fill_gbuffers(
        &mut self,
        gbuffers: [&mut GBufferBuf; 2],
        layout: Layout,
    ) -> Result<Option<RasterPassStats>, PipelineError> {
        self.0.fill_gbuffers(gbuffers, layout)
    }
    fn trace(
        &self,
        camera: &stereotrace::kernels::CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
    ) -> Result<TraceStats, PipelineError> {
        self.0.trace(camera, request, selection, rows, out)
    }
}

/// A gradient sample re-shades exactly the path the last frame traced: on a static scene
/// with a moving camera, every re-shaded sample equals its old one bit for bit, so no stratum
/// changes and the images are the paper's, in every temporal mode (the renderer's random
/// numbers are keyed by pixel, frame and sample, whatever else is traced beside them).
#[test]
fn a_gradient_sample_re_shades_the_last_frames_path_exactly() {
    let r = renderer("living-room");
    for mode in [Mode::Temporal, Mode::Spatiotemporal, Mode::SpatiotemporalBlend] {
        let paper = config(&r, mode, 2);
        let gradient = PipelineConfig { history: History::Gradient, ..paper };
        let mut a = Pipeline::new(&r, paper, StereoRig::default(), extent()).unwrap();
        let head = r.scene().camera.pose_at(3.0);
        let source = ClaimsChange(RendererSource::new(&r, RendererOptions::default(), extent()).unwrap());
        let mut b = Pipeline::with_rig(source, gradient, StereoRig::default(), &head, extent()).unwrap();
        for f in 3..7 {
            let pose = r.scene().camera.pose_at(f as f32);
            a.render_frame(f, &pose).unwrap();
            let stats = b.render_frame(f, &pose).unwrap();
            if f > 3 {
                assert!(stats.gradient_samples[Eye::Right as usize] > 0, "{mode}");
            }
            assert_eq!(stats.gradient_changed, [0, 0], "{mode} frame {f}");
            for eye in Eye::BOTH {
                assert_eq!(a.output(eye), b.output(eye), "{mode} {eye} frame {f}");
            }
        }
    }
}

/// The variance-guided blend changes only the paper-order spatiotemporal blend (every other
/// mode's images are the fixed blend's bit for bit), gives the fixed blend's image where no
/// history exists yet (the first frame: both lengths 1), and weighs differently somewhere
/// once histories of different lengths meet (a moving camera's disocclusions).
#[test]
fn the_variance_blend_changes_only_the_blend_of_histories() {
    let r = renderer("living-room");
    for mode in Mode::ALL {
        for order in [Order::Paper, Order::StereoFirst] {
            let fixed = PipelineConfig { order, ..config(&r, mode, 1) };
            let variance = PipelineConfig { blend: Blend::Variance, ..fixed };
            let mut a = Pipeline::new(&r, fixed, StereoRig::default(), extent()).unwrap();
            let mut b = Pipeline::new(&r, variance, StereoRig::default(), extent()).unwrap();
            let blends_histories = mode == Mode::SpatiotemporalBlend && order == Order::Paper;
            let mut differs = false;
            for f in 3..8 {
                let pose = r.scene().camera.pose_at(f as f32);
                a.render_frame(f, &pose).unwrap();
                b.render_frame(f, &pose).unwrap();
                for eye in Eye::BOTH {
                    let same = a.output(eye) == b.output(eye);
                    if !blends_histories || f == 3 {
                        assert!(same, "{mode} {order:?} {eye} frame {f}");
                    }
                    differs |= !same;
                    assert!(b.output(eye).planes().iter().all(|p| p.as_slice().iter().all(|v| v.is_finite())));
                }
            }
            assert_eq!(differs, blends_histories, "{mode} {order:?}");
        }
    }
}

/// The à-trous filter is a display filter: in every mode and order, each eye's unfiltered
/// image is the unfiltered pipeline's bit for bit frame after frame (nothing filtered feeds
/// a history or the other eye), and the shown image is the kernel's filter of it, guided by
/// the eye's G-buffer. A mono frame afterwards shows its traced image.
#[test]
fn the_atrous_filter_filters_the_shown_image_and_nothing_else() {
    let r = renderer("living-room");
    for mode in Mode::ALL {
        for order in [Order::Paper, Order::StereoFirst] {
            let plain = PipelineConfig { order, ..config(&r, mode, 1) };
            let filtered = PipelineConfig { filter: Filter::Atrous, ..plain };
            let mut a = Pipeline::new(&r, plain, StereoRig::default(), extent()).unwrap();
            let mut b = Pipeline::new(&r, filtered, StereoRig::default(), extent()).unwrap();
            for f in 3..6 {
                let pose = r.scene().camera.pose_at(f as f32);
                a.render_frame(f, &pose).unwrap();
                let stats = b.render_frame(f, &pose).unwrap();
                assert!(stats.times.filter > std::time::Duration::ZERO);
                for eye in Eye::BOTH {
                    assert_eq!(a.output(eye), b.unfiltered_output(eye), "{mode} {order:?} {eye} frame {f}");
                    let g = b.gbuffer(eye);
                    let guide =
                        AtrousGuide { depth: g.depth.view(), normals: GuideNormals::Octahedral(g.normal_oct.view()) };
                    let params = AtrousParams { iterations: ATROUS_ITERATIONS, ..AtrousParams::default() };
                    let mut scratch = AtrousScratch::try_new(extent()).unwrap();
                    let mut expected = RgbBuf::new(extent(), 0.0);
                    let input = b.unfiltered_output(eye).view();
                    atrous::atrous(&input, &guide, &params, &mut scratch, expected.view_mut()).unwrap();
                    assert_eq!(b.output(eye), &expected, "{mode} {order:?} {eye} frame {f}");
                    assert_ne!(b.output(eye), b.unfiltered_output(eye), "{mode} {order:?} {eye} frame {f}");
                }
            }
            if mode == Mode::PathTraced {
                let pose = r.scene().camera.pose_at(6.0);
                b.render_mono_frame(6, &pose).unwrap();
                assert_eq!(b.output(Eye::Right), b.unfiltered_output(Eye::Right));
            }
        }
    }
}

/// `Background::Reproject` keeps the sky's history by direction and changes nothing else:
/// on courtyard (an open sky), every surface pixel of both eyes is the paper's setting's bit
/// for bit frame after frame, the left eye traces exactly the sky pixels the stereo
/// reprojection now keeps fewer, and the kept sky's mean is the traced sky's.
#[test]
fn reprojected_background_keeps_the_sky_and_changes_no_surface() {
    use stereotrace::pipeline::Background;
    const L: usize = Eye::Left as usize;
    const R: usize = Eye::Right as usize;
    let r = renderer("courtyard");
    for mode in [Mode::Spatiotemporal, Mode::Temporal, Mode::SpatiotemporalBlend] {
        let paper = config(&r, mode, 1);
        let kept = PipelineConfig { background: Background::Reproject, ..paper };
        let mut a = Pipeline::new(&r, paper, StereoRig::default(), extent()).unwrap();
        let mut b = Pipeline::new(&r, kept, StereoRig::default(), extent()).unwrap();
        let (mut sky_pixels, mut sky_paper, mut sky_kept) = (0usize, 0.0f64, 0.0f64);
        for f in 3..8 {
            let pose = r.scene().camera.pose_at(f as f32);
            let sa = a.render_frame(f, &pose).unwrap();
            let sb = b.render_frame(f, &pose).unwrap();
            if mode == Mode::Spatiotemporal {
                let gained =
                    sb.stereo_reasons[L].get(Reason::Reprojected) - sa.stereo_reasons[L].get(Reason::Reprojected);
                assert!(gained > 0, "frame {f}: the stereo reprojection keeps sky");
                assert_eq!(sa.traced_pixels[L] - sb.traced_pixels[L], gained, "frame {f}: the kept sky is not traced");
            }
            if f > 3 && mode != Mode::SpatiotemporalBlend {
                let right = |s: &stereotrace::pipeline::FrameStats| s.temporal_reasons[R].get(Reason::Reprojected);
                assert!(right(&sb) > right(&sa), "frame {f}: the temporal reprojection keeps sky");
            }
            for eye in Eye::BOTH {
                let depth = b.gbuffer(eye).depth.as_slice().to_vec();
                let (pa, pb) = (a.output(eye).planes(), b.output(eye).planes());
                for (i, &d) in depth.iter().enumerate() {
                    for c in 0..3 {
                        let (va, vb) = (pa[c].as_slice()[i], pb[c].as_slice()[i]);
                        assert!(vb.is_finite(), "{mode} frame {f} {eye}");
                        if d.is_finite() {
                            assert_eq!(va.to_bits(), vb.to_bits(), "{mode} frame {f} {eye}: surface pixel {i}");
                        } else {
                            sky_pixels += 1;
                            (sky_paper, sky_kept) = (sky_paper + f64::from(va), sky_kept + f64::from(vb));
                        }
                    }
                }
            }
        }
        assert!(sky_pixels > 100, "{mode}: {sky_pixels} sky values");
        // A sky pixel's traced sample may hit the geometry its jitter reaches, so single
        // pixels differ; the sky's mean brightness must not.
        let bias = (sky_kept - sky_paper) / sky_paper;
        assert!(bias.abs() < 0.05, "{mode}: the kept sky's mean is {bias:+.3} off the traced one");
    }
}
