//! The C ABI gives exactly what the kernels give when Rust calls them directly (bit for bit,
//! on a scene with depth discontinuities and background), and refuses what it must refuse
//! without writing anything.

// These call the C ABI on pointers made a few lines before each call, as a C caller would;
// what each call requires is its documentation in the header.
#![allow(clippy::undocumented_unsafe_blocks)]

use glam::{Mat4, Vec3};
use stereotrace_capi::*;
use stereotrace_kernels::accumulate::{self, EmaInput, EmaParams, EmaState};
use stereotrace_kernels::reproject::{self, ReprojectInput, ReprojectOutput, ReprojectParams};
use stereotrace_kernels::ssim::{self, SsimParams};
use stereotrace_kernels::synth::{AnalyticScene, SynthFrame};
use stereotrace_kernels::{CameraModel, Extent, PlaneBuf, RgbBuf};

const W: usize = 77;
const H: usize = 41;

fn view_proj(eye: Vec3) -> Mat4 {
    let extent = Extent::new(W, H).unwrap();
    stereotrace_kernels::camera::look_at_perspective(eye, eye - Vec3::Z, Vec3::Y, 60f32.to_radians(), extent)
}

struct Eye {
    frame: SynthFrame,
    c_camera: StCamera,
}

fn eye(x: f32) -> Eye {
    let vp = view_proj(Vec3::new(x, 0.0, 0.0));
    let camera = CameraModel::new(vp, Extent::new(W, H).unwrap()).unwrap();
    let frame = AnalyticScene::room(6.0).render(&camera, [0.1, 0.2, 0.3]);
    Eye { frame, c_camera: StCamera { view_proj: vp.as_dmat4().to_cols_array(), width: W as u32, height: H as u32 } }
}

fn plane(p: &PlaneBuf) -> StPlaneF32 {
    StPlaneF32 { data: p.as_slice().as_ptr(), width: W as u32, height: H as u32, stride: W as u32 }
}

fn plane_mut(p: &mut PlaneBuf) -> StPlaneMutF32 {
    StPlaneMutF32 { data: p.as_mut_slice().as_mut_ptr(), width: W as u32, height: H as u32, stride: W as u32 }
}

fn rgb(b: &RgbBuf) -> StRgb {
    StRgb { r: plane(b.r()), g: plane(b.g()), b: plane(b.b()) }
}

fn rgb_mut(b: &mut RgbBuf) -> StRgbMut {
    let [r, g, bl] = b.slices_mut();
    let p = |s: &mut [f32]| StPlaneMutF32 { data: s.as_mut_ptr(), width: W as u32, height: H as u32, stride: W as u32 };
    StRgbMut { r: p(r), g: p(g), b: p(bl) }
}

fn gbuffer(e: &Eye, layout: StLayout) -> StGBuffer {
    let f = &e.frame;
    StGBuffer {
        layout: layout as u32,
        depth: plane(&f.surfaces.depth),
        position: [0, 1, 2].map(|c| plane(&f.surfaces.position[c])),
        normal: [0, 1, 2].map(|c| plane(&f.surfaces.normal[c])),
        normal_octahedral: StPlaneU32 {
            data: f.surfaces.normal_oct.as_slice().as_ptr(),
            width: W as u32,
            height: H as u32,
            stride: W as u32,
        },
        camera: e.c_camera,
    }
}

fn context() -> *mut StContext {
    let mut ctx = std::ptr::null_mut();
    assert_eq!(unsafe { stereotrace_context_create(2, &mut ctx) }, StStatus::Ok);
    ctx
}

fn extent() -> Extent {
    Extent::new(W, H).unwrap()
}

/// What one reprojection wrote.
#[derive(PartialEq, Debug)]
struct Written {
    colour: RgbBuf,
    extra: PlaneBuf,
    reason: PlaneBuf<u8>,
    weight: PlaneBuf,
    counts: [u64; ST_REASON_COUNT],
}

fn fresh() -> Written {
    Written {
        colour: RgbBuf::new(extent(), -7.0),
        extra: PlaneBuf::new(extent(), -7.0),
        reason: PlaneBuf::new(extent(), 99),
        weight: PlaneBuf::new(extent(), -7.0),
        counts: [0; ST_REASON_COUNT],
    }
}

/// Sub-pixel jitter of the target and source G-buffers (x, y each).
const JITTER: [f32; 4] = [0.25, -0.125, -0.375, 0.5];

/// Small motion vectors, a different one per pixel, with one NaN (that pixel reads invalid).
fn motion() -> [PlaneBuf; 3] {
    std::array::from_fn(|c| {
        let v =
            (0..W * H).map(|i| if i == 5 && c == 1 { f32::NAN } else { 0.002 * ((i * 7 + c * 3) % 11) as f32 - 0.01 });
        PlaneBuf::from_vec(v.collect(), extent()).unwrap()
    })
}

/// A pixel mask that skips every third pixel, and an extra channel to carry.
fn mask_and_extra() -> (PlaneBuf<u8>, PlaneBuf) {
    let mask = PlaneBuf::from_vec((0..W * H).map(|i| u8::from(i % 3 != 0)).collect(), extent()).unwrap();
    let extra = PlaneBuf::from_vec((0..W * H).map(|i| (i % 17) as f32).collect(), extent()).unwrap();
    (mask, extra)
}

fn through_c(target: &Eye, source: &Eye, layout: StLayout) -> Written {
    let ctx = context();
    let (mask, extra) = mask_and_extra();
    let mut w = fresh();
    let (extra_in, mask_in) = (
        plane(&extra),
        StPlaneU8 { data: mask.as_slice().as_ptr(), width: W as u32, height: H as u32, stride: W as u32 },
    );
    let motion = motion();
    let motion_in = [plane(&motion[0]), plane(&motion[1]), plane(&motion[2])];
    let input = StReprojectInput {
        colour: rgb(&source.frame.colour),
        extra: &extra_in,
        pixel_mask: &mask_in,
        motion: motion_in.as_ptr(),
        jitter: JITTER.as_ptr(),
    };
    let (extra_out, weight_out) = (plane_mut(&mut w.extra), plane_mut(&mut w.weight));
    let output = StReprojectOutput {
        colour: rgb_mut(&mut w.colour),
        extra: &extra_out,
        reason: StPlaneMutU8 {
            data: w.reason.as_mut_slice().as_mut_ptr(),
            width: W as u32,
            height: H as u32,
            stride: W as u32,
        },
        weight: &weight_out,
    };
    let mut counts = StReasonCounts::default();
    let (t, s) = (gbuffer(target, layout), gbuffer(source, layout));
    let status = unsafe { stereotrace_reproject(ctx, &t, &s, &input, &output, std::ptr::null(), &mut counts) };
    assert_eq!(status, StStatus::Ok, "{:?}", unsafe { std::ffi::CStr::from_ptr(stereotrace_last_error()) });
    unsafe { stereotrace_context_destroy(ctx) };
    w.counts = counts.pixels;
    w
}

fn direct<L: stereotrace_kernels::SurfaceLayout>(target: &L, source: &L, source_eye: &Eye) -> Written {
    let (mask, extra) = mask_and_extra();
    let motion = motion();
    let mut w = fresh();
    let input = ReprojectInput {
        target,
        source,
        source_camera: &source_eye.frame.surfaces.camera,
        colour: source_eye.frame.colour.view(),
        extra: Some(extra.view()),
        pixel_mask: Some(mask.view()),
        motion: Some(motion.each_ref().map(|p| p.view())),
        jitter: Some(reproject::Jitter { target: [JITTER[0], JITTER[1]], source: [JITTER[2], JITTER[3]] }),
        background: None,
    };
    let output = ReprojectOutput {
        colour: w.colour.view_mut(),
        extra: Some(w.extra.view_mut()),
        reason: w.reason.view_mut(),
        weight: Some(w.weight.view_mut()),
    };
    w.counts = reproject::reproject(&input, output, &ReprojectParams::default()).unwrap().0;
    w
}

#[test]
fn reprojection_through_the_c_abi_is_the_kernel_bit_for_bit() {
    let (left, right) = (eye(-0.03), eye(0.03));
    let full = through_c(&left, &right, StLayout::Full);
    assert_eq!(full, direct(&left.frame.gbuffer(), &right.frame.gbuffer(), &right));
    let compact = through_c(&left, &right, StLayout::Compact);
    assert_eq!(compact, direct(&left.frame.compact(), &right.frame.compact(), &right));
    // Not a trivial case: pixels both reprojected and discarded, and the mask skipped a
    // third of them (skipped pixels are not counted).
    assert!(full.counts[0] > 0 && full.counts[1] > 0, "{:?}", full.counts);
    assert_eq!(full.counts.iter().sum::<u64>(), (W * H - (W * H).div_ceil(3)) as u64);
    // The NaN motion vector made its pixel invalid.
    assert_eq!(full.reason.as_slice()[5], stereotrace_kernels::reproject::Reason::Invalid as u8);
}

#[test]
fn ema_and_ssim_through_the_c_abi_are_the_kernels() {
    let (left, right) = (eye(-0.03), eye(0.03));
    let reason = PlaneBuf::from_vec((0..W * H).map(|i| (i % 6) as u8).collect(), extent()).unwrap();
    let ctx = context();

    let mut via_c = right.frame.colour.clone();
    let mut stats = StAccumulateStats::default();
    let reason_c = StPlaneU8 { data: reason.as_slice().as_ptr(), width: W as u32, height: H as u32, stride: W as u32 };
    let (new_c, accum_c) = (rgb(&left.frame.colour), rgb_mut(&mut via_c));
    let status = unsafe {
        stereotrace_ema(
            ctx,
            &new_c,
            &reason_c,
            std::ptr::null(),
            std::ptr::null(),
            &accum_c,
            std::ptr::null(),
            std::ptr::null(),
            &mut stats,
        )
    };
    assert_eq!(status, StStatus::Ok);
    let (direct, want) = kernel_ema(&left.frame.colour, &right.frame.colour, &reason);
    assert_eq!(via_c, direct);
    assert_eq!((stats.non_finite, stats.holes, stats.resets), (want.non_finite, want.holes, want.resets));

    let mut result = StSsimResult::default();
    let (a, b) = (rgb(&left.frame.colour), rgb(&right.frame.colour));
    assert_eq!(unsafe { stereotrace_ssim(ctx, &a, &b, StSsimVariant::Volume as u32, &mut result) }, StStatus::Ok);
    let want = ssim::ssim(&left.frame.colour.view(), &right.frame.colour.view(), &SsimParams::default()).unwrap();
    assert_eq!((result.ssim, result.rmse, result.voxels), (want.ssim, want.rmse, want.voxels));
    assert!(result.ssim < 1.0, "two different views are not identical");
    unsafe { stereotrace_context_destroy(ctx) };
}

/// The Rust kernel's EMA of `history` with `new` (every pixel, the default parameters): the
/// accumulation and what it counted.
fn kernel_ema(new: &RgbBuf, history: &RgbBuf, reason: &PlaneBuf<u8>) -> (RgbBuf, accumulate::AccumulateStats) {
    let mut accum = history.clone();
    let input = EmaInput { new: new.view(), reason: reason.view(), has_new: None, confidence: None, pixel_mask: None };
    let stats = accumulate::ema(&input, EmaState { accum: accum.view_mut(), history_len: None }, &EmaParams::default())
        .unwrap();
    (accum, stats)
}

/// The masked EMA through the C ABI is the kernel's: inside the mask the plain EMA's bits,
/// outside it the history as it was; a null mask is refused with nothing written.
#[test]
fn the_masked_ema_through_the_c_abi_is_the_kernels() {
    let (left, right) = (eye(-0.03), eye(0.03));
    let reason = PlaneBuf::from_vec((0..W * H).map(|i| (i % 6) as u8).collect(), extent()).unwrap();
    let mask = PlaneBuf::from_vec((0..W * H).map(|i| u8::from(i % 7 < 2)).collect(), extent()).unwrap();
    let ctx = context();
    let plane_u8 = |p: &PlaneBuf<u8>| StPlaneU8 {
        data: p.as_slice().as_ptr(),
        width: W as u32,
        height: H as u32,
        stride: W as u32,
    };
    let (reason_c, mask_c) = (plane_u8(&reason), plane_u8(&mask));
    let mut via_c = right.frame.colour.clone();
    let mut stats = StAccumulateStats::default();
    let (new_c, accum_c) = (rgb(&left.frame.colour), rgb_mut(&mut via_c));
    let call = |mask: *const StPlaneU8, stats: &mut StAccumulateStats| unsafe {
        stereotrace_ema_masked(
            ctx,
            &new_c,
            &reason_c,
            std::ptr::null(),
            std::ptr::null(),
            mask,
            &accum_c,
            std::ptr::null(),
            std::ptr::null(),
            stats,
        )
    };
    assert_eq!(call(std::ptr::null(), &mut stats), StStatus::InvalidArgument);
    assert_eq!(via_c, right.frame.colour, "a refused call wrote");
    assert_eq!(call(&mask_c, &mut stats), StStatus::Ok);
    let (whole, _) = kernel_ema(&left.frame.colour, &right.frame.colour, &reason);
    let (c, w, before) = (via_c.planes(), whole.planes(), right.frame.colour.planes());
    for i in 0..W * H {
        let want = if mask.as_slice()[i] != 0 { w } else { before };
        for ch in 0..3 {
            assert_eq!(c[ch].as_slice()[i].to_bits(), want[ch].as_slice()[i].to_bits(), "pixel {i}, channel {ch}");
        }
    }
    let counted = stats.non_finite + stats.holes + stats.resets;
    assert!(counted > 0 && counted <= mask.as_slice().iter().filter(|&&m| m != 0).count() as u64, "{stats:?}");
    unsafe { stereotrace_context_destroy(ctx) };
}

#[test]
fn refused_calls_write_nothing_and_say_why() {
    let (left, right) = (eye(-0.03), eye(0.03));
    let ctx = context();
    let mut w = fresh();
    let before = fresh();
    let reason_out = StPlaneMutU8 {
        data: w.reason.as_mut_slice().as_mut_ptr(),
        width: W as u32,
        height: H as u32,
        stride: W as u32,
    };
    let colour_out = rgb_mut(&mut w.colour);
    let (t, s) = (gbuffer(&left, StLayout::Full), gbuffer(&right, StLayout::Full));
    let run = |input: &StReprojectInput, output: &StReprojectOutput, t: &StGBuffer| unsafe {
        let status = stereotrace_reproject(ctx, t, &s, input, output, std::ptr::null(), std::ptr::null_mut());
        (status, std::ffi::CStr::from_ptr(stereotrace_last_error()).to_string_lossy().into_owned())
    };
    let input = StReprojectInput {
        colour: rgb(&right.frame.colour),
        extra: std::ptr::null(),
        pixel_mask: std::ptr::null(),
        motion: std::ptr::null(),
        jitter: std::ptr::null(),
    };
    let output =
        StReprojectOutput { colour: colour_out, extra: std::ptr::null(), reason: reason_out, weight: std::ptr::null() };

    // An output that starts inside an input plane (a partial overlap, not the same pointer).
    let mut inside = output;
    inside.reason.data = unsafe { right.frame.surfaces.depth.as_slice().as_ptr().add(10).cast::<u8>().cast_mut() };
    let (status, message) = run(&input, &inside, &t);
    assert_eq!(status, StStatus::Aliasing, "{message}");
    assert!(message.contains("output.reason overlaps source.depth"), "{message}");

    // The extra channel must be present on both sides or neither.
    let extra = plane(&right.frame.surfaces.depth);
    let with_extra = StReprojectInput { extra: &extra, ..input };
    let (status, message) = run(&with_extra, &output, &t);
    assert_eq!(status, StStatus::InvalidArgument, "{message}");

    // A plane claiming more rows than a frame may have.
    let mut huge = t;
    huge.depth.height = u32::MAX;
    let (status, message) = run(&input, &output, &huge);
    assert_eq!(status, StStatus::InvalidArgument, "{message}");
    assert!(message.contains("too large"), "{message}");

    assert_eq!(w, before, "a refused call wrote to its outputs");
    let (status, message) = run(&input, &output, &t);
    assert_eq!((status, message.as_str()), (StStatus::Ok, ""), "a good call clears the last error");
    unsafe { stereotrace_context_destroy(ctx) };
}

#[test]
fn a_scene_pipeline_through_the_c_abi_renders_what_the_rust_pipeline_renders() {
    use stereotrace_runtime::camera::{Eye, StereoRig};
    use stereotrace_runtime::pipeline::{Pipeline, PipelineConfig};
    use stereotrace_runtime::render::Renderer;

    let (w, h) = (64u32, 36u32);
    let mut config = stereotrace_pipeline_config_default();
    (config.width, config.height, config.threads, config.spp) = (w, h, 2, 2);
    let mut p = std::ptr::null_mut();
    let scene = c"cornell";
    assert_eq!(unsafe { stereotrace_pipeline_create_scene(scene.as_ptr(), &config, &mut p) }, StStatus::Ok);

    let renderer = Renderer::new(stereotrace_runtime::scene::resolve("cornell").unwrap()).unwrap();
    let e = Extent::new(w as usize, h as usize).unwrap();
    let rust_config = PipelineConfig::paper(
        stereotrace_runtime::pipeline::Mode::Spatiotemporal,
        2,
        renderer.scene().tolerances.at_height(h as usize),
    );
    let mut rust = Pipeline::new(&renderer, rust_config, StereoRig::default(), e).unwrap();
    for frame in 0..3 {
        assert_eq!(unsafe { stereotrace_pipeline_render_frame(p, frame, std::ptr::null_mut()) }, StStatus::Ok);
        rust.render_frame(frame, &renderer.scene().camera.pose_back_and_forth(frame)).unwrap();
    }
    for eye in Eye::BOTH {
        let mut via_c = RgbBuf::new(e, -1.0);
        let [r, g, b] =
            via_c.slices_mut().map(|s| StPlaneMutF32 { data: s.as_mut_ptr(), width: w, height: h, stride: w });
        let out = StRgbMut { r, g, b };
        assert_eq!(unsafe { stereotrace_pipeline_output(p, eye as u32, &out) }, StStatus::Ok);
        assert_eq!(&via_c, rust.output(eye), "{eye:?}");
    }
    unsafe { stereotrace_pipeline_destroy(p) };
}
