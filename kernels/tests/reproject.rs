//! Reprojection: SIMD against the scalar reference, and the kernel against closed-form
//! expectations on analytic scenes (bilinear and accumulate have their own test files).

use glam::Vec3;
use stereotrace_kernels::check::same_bits;
use stereotrace_kernels::frame::{Extent, Plane, PlaneBuf, PlaneMut, RgbBuf, RgbPlanes, RgbPlanesMut};
use stereotrace_kernels::gbuffer::{GBuffer, SurfaceLayout};
use stereotrace_kernels::isa::Isa;
use stereotrace_kernels::reproject::{
    self, Reason, ReasonCounts, ReprojectInput, ReprojectOutput, ReprojectParams, TapPolicy, Tolerances,
};
use stereotrace_kernels::synth::{AnalyticScene, EDGE_VALUES, Rect, Rng, SynthFrame, Texture, camera_at, focal_pixels};
use stereotrace_kernels::{CameraModel, FrameError};

fn extent(w: usize, h: usize) -> Extent {
    Extent::new(w, h).unwrap()
}

/// All outputs of one reprojection call.
#[derive(Debug)]
struct Reprojected {
    counts: ReasonCounts,
    colour: RgbBuf,
    extra: PlaneBuf,
    reason: PlaneBuf<u8>,
    weight: PlaneBuf,
}

fn run_reprojection<L: SurfaceLayout>(
    input: &ReprojectInput<'_, L>,
    params: &ReprojectParams,
    simd: bool,
) -> Result<Reprojected, FrameError> {
    run_body(input, params, if simd { Some(Isa::active()) } else { None })
}

/// The SIMD body of `isa`, or the scalar reference for `None`.
fn run_body<L: SurfaceLayout>(
    input: &ReprojectInput<'_, L>,
    params: &ReprojectParams,
    isa: Option<Isa>,
) -> Result<Reprojected, FrameError> {
    let e = input.target.extent();
    // Sentinels: a pixel a mask skips must keep them.
    let mut colour = RgbBuf::new(e, -7.0);
    let mut extra = PlaneBuf::new(e, -7.0);
    let mut reason = PlaneBuf::new(e, 99u8);
    let mut weight = PlaneBuf::new(e, -7.0);
    let out = ReprojectOutput {
        colour: colour.view_mut(),
        extra: input.extra.map(|_| extra.view_mut()),
        reason: reason.view_mut(),
        weight: Some(weight.view_mut()),
    };
    let counts = match isa {
        Some(isa) => reproject::reproject_with(input, out, params, isa)?,
        None => reproject::reproject_scalar(input, out, params)?,
    };
    Ok(Reprojected { counts, colour, extra, reason, weight })
}

/// Every SIMD body this CPU has (the AVX-512 one is the 8-lane source compiled again with
/// AVX-512 enabled, plus its 16-pixel path for compact G-buffers) gives the scalar
/// reference's bits.
fn assert_every_body_matches_scalar<L: SurfaceLayout>(input: &ReprojectInput<'_, L>, params: &ReprojectParams) {
    let reference = run_body(input, params, None).unwrap();
    for isa in Isa::supported() {
        assert_same(&run_body(input, params, Some(isa)).unwrap(), &reference);
    }
}

fn assert_same_planes(what: &str, a: &PlaneBuf, b: &PlaneBuf) {
    let e = a.extent();
    for (i, (x, y)) in a.as_slice().iter().zip(b.as_slice()).enumerate() {
        assert!(same_bits(*x, *y), "{what}: {x:?} vs {y:?} at ({}, {})", i % e.width(), i / e.width());
    }
}

fn assert_same(a: &Reprojected, b: &Reprojected) {
    assert_eq!(a.counts, b.counts);
    assert_eq!(a.reason, b.reason);
    assert_same_planes("red", a.colour.r(), b.colour.r());
    assert_same_planes("green", a.colour.g(), b.colour.g());
    assert_same_planes("blue", a.colour.b(), b.colour.b());
    assert_same_planes("extra", &a.extra, &b.extra);
    assert_same_planes("weight", &a.weight, &b.weight);
}

/// Stereo pair of the standard room, right eye is the source.
fn stereo_room(e: Extent, baseline: f32) -> (SynthFrame, SynthFrame) {
    let scene = AnalyticScene::room(6.0);
    let left = scene.render(&camera_at(Vec3::new(-baseline / 2.0, 0.0, 0.0), e, 60.0), [0.0; 3]);
    let right = scene.render(&camera_at(Vec3::new(baseline / 2.0, 0.0, 0.0), e, 60.0), [0.0; 3]);
    (left, right)
}

fn input_for<'a, L: SurfaceLayout>(
    target: &'a L,
    source: &'a L,
    source_frame: &'a SynthFrame,
    extra: Option<Plane<'a>>,
) -> ReprojectInput<'a, L> {
    ReprojectInput {
        target,
        source,
        source_camera: &source_frame.surfaces.camera,
        colour: source_frame.colour.view(),
        extra,
        pixel_mask: None,
        motion: None,
        jitter: None,
        background: None,
    }
}

/// Test tolerances. The test images are small, so one pixel spans decimetres at these
/// depths: the world-position tolerance must exceed a pixel's footprint or every tap fails.
fn params(policy: TapPolicy) -> ReprojectParams {
    ReprojectParams { tolerances: Tolerances::new(0.5, 0.03, 25.0), policy, band_rows: 3 }
}

#[test]
fn simd_equals_scalar_on_stereo_and_temporal_pairs_at_awkward_widths() {
    for &(w, h) in &[(1, 1), (1, 5), (7, 3), (8, 2), (9, 4), (17, 5), (33, 7), (64, 9)] {
        let e = extent(w, h);
        for &baseline in &[0.065f32, 0.4, 2.0] {
            let (left, right) = stereo_room(e, baseline);
            let extra = PlaneBuf::from_vec((0..e.pixels()).map(|i| (i % 13) as f32).collect(), e).unwrap();
            for policy in [TapPolicy::Renormalize, TapPolicy::Strict] {
                let p = params(policy);
                let (tf, sf) = (left.gbuffer(), right.gbuffer());
                assert_every_body_matches_scalar(&input_for(&tf, &sf, &right, Some(extra.view())), &p);
                let (tc, sc) = (left.compact(), right.compact());
                assert_every_body_matches_scalar(&input_for(&tc, &sc, &right, None), &p);
                // The temporal history's case: compact planes with the history length as a
                // fourth channel (the AVX-512 body's 16-pixel path takes 3 and 4 channels).
                assert_every_body_matches_scalar(&input_for(&tc, &sc, &right, Some(extra.view())), &p);
            }
        }
    }
}

/// A pixel mask (the paper-order left eye reprojects its history only where its stereo
/// reprojection failed): masked-out pixels keep their old outputs, read `Invalid` and are not
/// counted; the others are exactly what the unmasked call gives; SIMD == scalar.
#[test]
fn pixel_mask_reprojects_only_the_chosen_pixels() {
    let mut rng = Rng::new(0x6d61_736b);
    for &(w, h) in &[(1, 1), (7, 3), (17, 5), (64, 9), (203, 6)] {
        let e = extent(w, h);
        let (left, right) = stereo_room(e, 0.4);
        // Whole groups of 8 on, off and mixed, so every branch of the SIMD body runs.
        for share in [0.0f32, 0.03, 0.5, 1.0] {
            let mask =
                PlaneBuf::from_vec((0..e.pixels()).map(|_| u8::from(rng.next_f32() < share)).collect(), e).unwrap();
            let extra = PlaneBuf::from_vec((0..e.pixels()).map(|i| (i % 5) as f32).collect(), e).unwrap();
            let (tc, sc) = (left.compact(), right.compact());
            let full = input_for(&tc, &sc, &right, Some(extra.view()));
            let masked =
                ReprojectInput { pixel_mask: Some(mask.view()), ..input_for(&tc, &sc, &right, Some(extra.view())) };
            for policy in [TapPolicy::Renormalize, TapPolicy::Strict] {
                let p = params(policy);
                let all = run_reprojection(&full, &p, true).unwrap();
                let a = run_reprojection(&masked, &p, true).unwrap();
                let b = run_reprojection(&masked, &p, false).unwrap();
                assert_same(&a, &b);
                let mut expected = ReasonCounts::default();
                for i in 0..e.pixels() {
                    let on = mask.as_slice()[i] != 0;
                    let planes = [
                        (a.colour.r(), all.colour.r()),
                        (a.colour.g(), all.colour.g()),
                        (a.colour.b(), all.colour.b()),
                        (&a.extra, &all.extra),
                        (&a.weight, &all.weight),
                    ];
                    for (got, unmasked) in planes {
                        let want = if on { unmasked.as_slice()[i] } else { -7.0 };
                        assert!(same_bits(got.as_slice()[i], want), "pixel {i}: {} vs {want}", got.as_slice()[i]);
                    }
                    if on {
                        assert_eq!(a.reason.as_slice()[i], all.reason.as_slice()[i]);
                        expected.0[usize::from(all.reason.as_slice()[i])] += 1;
                    } else {
                        assert_eq!(a.reason.as_slice()[i], Reason::Invalid as u8);
                    }
                }
                assert_eq!(a.counts, expected);
            }
        }
    }
}

/// Replaces a random share of every G-buffer and colour value with edge values.
fn corrupt(frame: &mut SynthFrame, rng: &mut Rng, share: f32) {
    let mut planes: Vec<&mut [f32]> = vec![frame.surfaces.depth.as_mut_slice()];
    planes.extend(frame.surfaces.position.iter_mut().map(PlaneBuf::as_mut_slice));
    planes.extend(frame.surfaces.normal.iter_mut().map(PlaneBuf::as_mut_slice));
    planes.extend(frame.colour.slices_mut());
    for plane in planes {
        for v in plane {
            if rng.next_f32() < share {
                *v = EDGE_VALUES[rng.below(EDGE_VALUES.len())];
            }
        }
    }
    for v in frame.surfaces.normal_oct.as_mut_slice() {
        if rng.next_f32() < share {
            *v = rng.next_u32();
        }
    }
}

#[test]
fn simd_equals_scalar_with_edge_values_and_random_cameras() {
    if !Isa::Avx512.is_supported() {
        eprintln!("SKIP part: this CPU lacks AVX-512; that body is compared where it has it");
    }
    let mut rng = Rng::new(7);
    for case in 0..60 {
        let e = extent(1 + rng.below(40), 1 + rng.below(12));
        let scene = AnalyticScene::room(3.0 + rng.range(0.0, 8.0));
        let eye = |rng: &mut Rng| Vec3::new(rng.range(-0.5, 0.5), rng.range(-0.3, 0.3), rng.range(-0.5, 0.5));
        let cam_t = camera_at(eye(&mut rng), e, rng.range(20.0, 100.0));
        let cam_s = CameraModel::new(
            stereotrace_kernels::camera::look_at_perspective(
                eye(&mut rng),
                Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), -5.0),
                Vec3::Y,
                rng.range(0.3, 1.8),
                e,
            ),
            e,
        )
        .unwrap();
        let mut target = scene.render(&cam_t, [0.0; 3]);
        let mut source = scene.render(&cam_s, [0.0; 3]);
        let share = if case % 3 == 0 { 0.0 } else { 0.15 };
        corrupt(&mut target, &mut rng, share);
        corrupt(&mut source, &mut rng, share);
        let tolerances = match case % 4 {
            0 => Tolerances::new(f32::INFINITY, f32::INFINITY, 180.0),
            1 => Tolerances::new(0.0, 0.0, 0.0),
            _ => Tolerances::new(rng.range(0.01, 0.5), rng.range(0.0, 0.1), rng.range(1.0, 90.0)),
        };
        for policy in [TapPolicy::Renormalize, TapPolicy::Strict] {
            let p = ReprojectParams { tolerances, policy, band_rows: 1 + rng.below(5) };
            // The paper's rule for background pixels, and their reprojection by direction
            // (the corrupted depths include +inf, so every case has some).
            for background in [None, Some(&cam_t)] {
                let (tf, sf) = (target.gbuffer(), source.gbuffer());
                assert_every_body_matches_scalar(
                    &ReprojectInput { background, ..input_for(&tf, &sf, &source, None) },
                    &p,
                );
                let (tc, sc) = (target.compact(), source.compact());
                let extra = Some(source.colour.g().view());
                assert_every_body_matches_scalar(
                    &ReprojectInput { background, ..input_for(&tc, &sc, &source, extra) },
                    &p,
                );
            }
        }
    }
}

#[test]
fn outputs_are_finite_and_weights_in_unit_range_for_finite_sources() {
    let mut rng = Rng::new(11);
    for _ in 0..20 {
        let e = extent(1 + rng.below(30), 1 + rng.below(10));
        let (mut left, mut right) = stereo_room(e, rng.range(0.0, 1.0));
        // Huge but finite colours must not overflow to infinity when summed.
        for v in right.colour.r_mut() {
            *v = if rng.next_f32() < 0.5 { f32::MAX } else { -f32::MAX };
        }
        corrupt(&mut left, &mut rng, 0.05);
        let (tf, sf) = (left.gbuffer(), right.gbuffer());
        let r = run_reprojection(&input_for(&tf, &sf, &right, None), &params(TapPolicy::Renormalize), true).unwrap();
        for c in r.colour.planes() {
            assert!(c.as_slice().iter().all(|v| v.is_finite()));
        }
        assert!(r.weight.as_slice().iter().all(|w| (0.0..=1.0).contains(w)));
        assert!(r.reason.as_slice().iter().all(|&c| Reason::from_code(c).is_some()));
        assert_eq!(r.counts.total(), e.pixels() as u64);
    }
}

/// Reprojected values are flushed as the EMA's are: a source of `f32::MIN_POSITIVE` beside
/// zeros interpolates to subnormals at every split footprint, and every body writes 0 there
/// (the paper-order left eye's stereo samples are its restarted history as they are).
#[test]
fn reprojected_values_below_the_smallest_normal_are_flushed_to_zero() {
    let e = extent(64, 9);
    let (left, mut right) = stereo_room(e, 0.4);
    let tiny = f32::MIN_POSITIVE;
    for (i, v) in right.colour.r_mut().iter_mut().enumerate() {
        *v = if i % 2 == 0 { tiny } else { 0.0 };
    }
    for (i, v) in right.colour.g_mut().iter_mut().enumerate() {
        *v = if i % 3 == 0 { -tiny } else { tiny * 0.5 };
    }
    let extra = PlaneBuf::from_vec((0..e.pixels()).map(|i| if i % 2 == 1 { tiny } else { 0.0 }).collect(), e).unwrap();
    let p = params(TapPolicy::Renormalize);
    let (tc, sc) = (left.compact(), right.compact());
    for extra in [None, Some(extra.view())] {
        let input = input_for(&tc, &sc, &right, extra);
        assert_every_body_matches_scalar(&input, &p);
        let r = run_reprojection(&input, &p, false).unwrap();
        assert!(r.counts.get(Reason::Reprojected) > e.pixels() as u64 / 2, "{:?}", r.counts);
        let mut planes = vec![r.colour.r(), r.colour.g(), r.colour.b()];
        if extra.is_some() {
            planes.push(&r.extra);
        }
        for plane in planes {
            for &v in plane.as_slice() {
                assert!(v == 0.0 || v.abs() >= tiny, "a subnormal was written: {v:e}");
                assert!(v.to_bits() != (-0.0f32).to_bits(), "-0 was written");
            }
        }
    }
}

#[test]
fn identity_camera_copies_the_source_exactly() {
    for &(w, h) in &[(1, 1), (9, 4), (64, 36), (127, 33)] {
        let e = extent(w, h);
        let scene = AnalyticScene::room(5.0);
        let frame = scene.render(&camera_at(Vec3::new(0.1, 0.2, 0.0), e, 70.0), [0.0; 3]);
        for layout_full in [true, false] {
            let r = if layout_full {
                let g = frame.gbuffer();
                run_reprojection(&input_for(&g, &g, &frame, None), &params(TapPolicy::Strict), true).unwrap()
            } else {
                let g = frame.compact();
                run_reprojection(&input_for(&g, &g, &frame, None), &params(TapPolicy::Strict), true).unwrap()
            };
            for i in 0..e.pixels() {
                if frame.surfaces.depth.as_slice()[i].is_infinite() {
                    assert_eq!(r.reason.as_slice()[i], Reason::Background as u8);
                    continue;
                }
                assert_eq!(r.reason.as_slice()[i], Reason::Reprojected as u8, "pixel {i}");
                assert_eq!(r.colour.r().as_slice()[i], frame.colour.r().as_slice()[i]);
                assert_eq!(r.colour.g().as_slice()[i], frame.colour.g().as_slice()[i]);
                assert_eq!(r.colour.b().as_slice()[i], frame.colour.b().as_slice()[i]);
                assert_eq!(r.weight.as_slice()[i], 1.0);
            }
        }
    }
}

/// A fronto-parallel textured plane filling the view at depth `z`.
fn wall(z: f32, texture: Texture) -> AnalyticScene {
    AnalyticScene {
        rects: vec![Rect {
            centre: Vec3::new(0.0, 0.0, -z),
            axis_u: Vec3::X,
            axis_v: Vec3::Y,
            half: (1e3, 1e3),
            texture,
        }],
    }
}

#[test]
fn integer_pixel_shift_is_an_exact_copy() {
    let e = extent(96, 40);
    let vfov = 50.0;
    let f = focal_pixels(e, vfov);
    let z = 4.0f32;
    for shift in [1i32, 3, 8, 17] {
        // Baseline that moves the plane by exactly `shift` pixels: d = f·b/z.
        let b = (f64::from(shift) * f64::from(z) / f) as f32;
        let scene = wall(z, Texture::pattern([0.5, 0.4, 0.3], 0.3, 7.0));
        let left = scene.render(&camera_at(Vec3::new(-b / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
        let right = scene.render(&camera_at(Vec3::new(b / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
        let (tg, sg) = (left.compact(), right.compact());
        let r = run_reprojection(&input_for(&tg, &sg, &right, None), &params(TapPolicy::Strict), true).unwrap();
        for y in 0..e.height() {
            for x in 0..e.width() {
                let i = y * e.width() + x;
                let sx = x as i32 - shift;
                if sx < 0 {
                    assert_eq!(r.reason.as_slice()[i], Reason::OutOfFrame as u8, "({x}, {y}) shift {shift}");
                    continue;
                }
                assert_eq!(r.reason.as_slice()[i], Reason::Reprojected as u8, "({x}, {y}) shift {shift}");
                assert_eq!(r.colour.view().get(x, y), right.colour.get(sx as usize, y), "({x}, {y}) shift {shift}");
            }
        }
    }
}

/// Independent bilinear lookup in f64 at continuous position (sx, sy), renormalised over
/// in-frame taps.
fn bilinear_f64(img: &PlaneBuf, sx: f64, sy: f64) -> Option<f64> {
    let e = img.extent();
    let (u, v) = (sx - 0.5, sy - 0.5);
    let (x0, y0) = (u.floor(), v.floor());
    let (fx, fy) = (u - x0, v - y0);
    let mut sum = 0.0;
    let mut total = 0.0;
    for (dx, dy, w) in
        [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)]
    {
        let (x, y) = (x0 as i64 + dx, y0 as i64 + dy);
        if w > 0.0 && x >= 0 && y >= 0 && (x as usize) < e.width() && (y as usize) < e.height() {
            sum += w * f64::from(img.as_slice()[y as usize * e.width() + x as usize]);
            total += w;
        }
    }
    (total > 0.0).then(|| sum / total)
}

#[test]
fn parallel_cameras_on_a_textured_plane_give_disparity_f_b_over_z() {
    let e = extent(160, 90);
    let vfov = 60.0;
    let f = focal_pixels(e, vfov);
    let (z, b) = (3.0f32, 0.065f32);
    let disparity = f * f64::from(b) / f64::from(z);
    let scene = wall(z, Texture::pattern([0.0, 0.5, 0.4], 0.3, 5.0));
    let left = scene.render(&camera_at(Vec3::new(-b / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
    let mut right = scene.render(&camera_at(Vec3::new(b / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
    // The right image's red channel records each pixel's own x centre, a linear function that
    // bilinear interpolation reproduces exactly: the reprojected red value *is* the source
    // position the kernel computed.
    for (i, v) in right.colour.r_mut().iter_mut().enumerate() {
        *v = (i % e.width()) as f32 + 0.5;
    }
    let (tg, sg) = (left.gbuffer(), right.gbuffer());
    let r = run_reprojection(&input_for(&tg, &sg, &right, None), &params(TapPolicy::Renormalize), true).unwrap();
    let first_full = disparity.ceil() as usize + 1;
    for y in 0..e.height() {
        for x in first_full..e.width() {
            let i = y * e.width() + x;
            assert_eq!(r.reason.as_slice()[i], Reason::Reprojected as u8);
            // Disparity: the source position is the target position minus f·b/z.
            let measured = (x as f64 + 0.5) - f64::from(r.colour.r().as_slice()[i]);
            assert!((measured - disparity).abs() < 2e-3, "disparity {measured} vs f·b/z = {disparity} at ({x}, {y})");
            // The image: bilinear of the right image at (x + 0.5 − d, y + 0.5).
            let sx = x as f64 + 0.5 - disparity;
            for (plane, got) in [(right.colour.g(), r.colour.g()), (right.colour.b(), r.colour.b())] {
                let want = bilinear_f64(plane, sx, y as f64 + 0.5).unwrap();
                let got = f64::from(got.as_slice()[i]);
                assert!((got - want).abs() < 1e-3, "({x}, {y}): {got} vs {want}");
            }
        }
    }
}

#[test]
fn occlusion_band_behind_a_foreground_strip_is_discarded_for_depth() {
    let e = extent(200, 60);
    let vfov = 60.0;
    let f = focal_pixels(e, vfov);
    let (z_back, z_front, b) = (8.0f32, 2.0f32, 0.2f32);
    let mut scene = wall(z_back, Texture::pattern([0.5, 0.5, 0.5], 0.2, 3.0));
    scene.rects.push(Rect {
        centre: Vec3::new(0.0, 0.0, -z_front),
        axis_u: Vec3::X,
        axis_v: Vec3::Y,
        half: (0.3, 10.0),
        texture: Texture::flat([0.9, 0.1, 0.1]),
    });
    let left = scene.render(&camera_at(Vec3::new(-b / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
    let right = scene.render(&camera_at(Vec3::new(b / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
    let (tg, sg) = (left.compact(), right.compact());
    let r = run_reprojection(&input_for(&tg, &sg, &right, None), &params(TapPolicy::Strict), true).unwrap();
    // In the left image the strip's left edge is at x_e; the background within
    // f·b·(1/z_front − 1/z_back) pixels left of it is hidden behind the strip in the right eye.
    let cx = e.width() as f64 / 2.0;
    let strip_left_edge = cx + f * (-0.3 + f64::from(b) / 2.0) / f64::from(z_front);
    let band = f * f64::from(b) * (1.0 / f64::from(z_front) - 1.0 / f64::from(z_back));
    let y = e.height() / 2;
    for x in 0..e.width() {
        let centre = x as f64 + 0.5;
        let code = Reason::from_code(r.reason.as_slice()[y * e.width() + x]).unwrap();
        if centre > strip_left_edge - band + 1.5 && centre < strip_left_edge - 1.5 {
            assert_eq!(code, Reason::DepthOrPosition, "x = {x}: inside the occluded band");
        } else if (centre < strip_left_edge - band - 1.5 && centre > f * b as f64 / z_back as f64 + 2.0)
            || (centre > strip_left_edge + 1.5 && centre < strip_left_edge + 10.0)
        {
            assert_eq!(code, Reason::Reprojected, "x = {x}: visible in both eyes");
        }
    }
    assert!(r.counts.get(Reason::DepthOrPosition) as f64 >= (band - 3.0) * e.height() as f64);
}

#[test]
fn flipped_source_normals_are_discarded_for_normal() {
    let e = extent(40, 20);
    let (left, mut right) = stereo_room(e, 0.065);
    for n in right.surfaces.normal.iter_mut() {
        for v in n.as_mut_slice() {
            *v = -*v;
        }
    }
    let (tg, sg) = (left.gbuffer(), right.gbuffer());
    let r = run_reprojection(&input_for(&tg, &sg, &right, None), &params(TapPolicy::Renormalize), true).unwrap();
    assert_eq!(r.counts.get(Reason::Reprojected), 0);
    assert!(r.counts.get(Reason::Normal) > (e.pixels() as u64) / 2, "{:?}", r.counts);
}

#[test]
fn frame_borders_are_out_of_frame_under_strict_and_renormalised_otherwise() {
    let e = extent(64, 16);
    let vfov = 60.0;
    let f = focal_pixels(e, vfov);
    let z = 3.0f32;
    // A disparity of 2.5 pixels: left columns 0 and 1 land left of the source frame.
    let b = (2.5 * f64::from(z) / f) as f32;
    let scene = wall(z, Texture::flat([1.0, 2.0, 3.0]));
    let left = scene.render(&camera_at(Vec3::new(-b / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
    let right = scene.render(&camera_at(Vec3::new(b / 2.0, 0.0, 0.0), e, vfov), [0.0; 3]);
    let (tg, sg) = (left.gbuffer(), right.gbuffer());
    let input = input_for(&tg, &sg, &right, None);
    let strict = run_reprojection(&input, &params(TapPolicy::Strict), true).unwrap();
    let renorm = run_reprojection(&input, &params(TapPolicy::Renormalize), true).unwrap();
    for y in 0..e.height() {
        let code = |r: &Reprojected, x: usize| Reason::from_code(r.reason.as_slice()[y * e.width() + x]).unwrap();
        // x = 0: source position −2.0 → no tap in frame under either policy.
        assert_eq!(code(&strict, 0), Reason::OutOfFrame);
        assert_eq!(code(&renorm, 0), Reason::OutOfFrame);
        // x = 2: source position 0.0 → taps at −1 and 0, half the weight in frame.
        assert_eq!(code(&strict, 2), Reason::OutOfFrame);
        assert_eq!(code(&renorm, 2), Reason::Reprojected);
        let i = y * e.width() + 2;
        assert!((renorm.weight.as_slice()[i] - 0.5).abs() < 2e-3);
        // Renormalised over the accepted taps: the flat colour survives exactly.
        assert_eq!(renorm.colour.view().get(2, y), [1.0, 2.0, 3.0]);
        assert_eq!(code(&strict, 3), Reason::Reprojected);
    }
}

#[test]
fn background_and_nan_targets_get_their_own_reasons() {
    let e = extent(24, 8);
    let (mut left, right) = stereo_room(e, 0.065);
    left.surfaces.depth.as_mut_slice()[5] = f32::INFINITY;
    left.surfaces.position[1].as_mut_slice()[9] = f32::NAN;
    left.surfaces.normal[2].as_mut_slice()[10] = f32::NAN;
    left.surfaces.depth.as_mut_slice()[11] = -1.0;
    let (tg, sg) = (left.gbuffer(), right.gbuffer());
    let r = run_reprojection(&input_for(&tg, &sg, &right, None), &params(TapPolicy::Renormalize), true).unwrap();
    assert_eq!(r.reason.as_slice()[5], Reason::Background as u8);
    for i in [9, 10, 11] {
        assert_eq!(r.reason.as_slice()[i], Reason::Invalid as u8);
        assert_eq!(r.colour.r().as_slice()[i], 0.0);
        assert_eq!(r.weight.as_slice()[i], 0.0);
    }
}

#[test]
fn source_samples_that_are_not_finite_are_never_used() {
    let e = extent(32, 8);
    let (left, mut right) = stereo_room(e, 0.065);
    for (i, v) in right.colour.g_mut().iter_mut().enumerate() {
        if i % 2 == 0 {
            *v = f32::NAN;
        }
    }
    let (tg, sg) = (left.gbuffer(), right.gbuffer());
    let r = run_reprojection(&input_for(&tg, &sg, &right, None), &params(TapPolicy::Renormalize), true).unwrap();
    assert!(r.colour.g().as_slice().iter().all(|v| v.is_finite()));
}

#[test]
fn bad_inputs_are_refused_with_named_errors() {
    let (left, right) = stereo_room(extent(16, 8), 0.065);
    let other = AnalyticScene::room(5.0).render(&camera_at(Vec3::ZERO, extent(8, 8), 60.0), [0.0; 3]);
    let (tg, sg) = (left.gbuffer(), other.gbuffer());
    // Source colour extent differs from the source G-buffer.
    let input = ReprojectInput {
        target: &tg,
        source: &sg,
        source_camera: &other.surfaces.camera,
        colour: right.colour.view(),
        extra: None,
        pixel_mask: None,
        motion: None,
        jitter: None,
        background: None,
    };
    let err = run_reprojection(&input, &params(TapPolicy::Strict), true).unwrap_err();
    assert!(err.to_string().contains("source colour"), "{err}");
    // Tolerances with NaN.
    let (sg, tg) = (right.gbuffer(), left.gbuffer());
    let input = input_for(&tg, &sg, &right, None);
    let mut p = params(TapPolicy::Strict);
    p.tolerances.position = f32::NAN;
    assert!(matches!(run_reprojection(&input, &p, true), Err(FrameError::InvalidParameter(_))));
    // Output of the wrong size.
    let mut small = RgbBuf::new(extent(15, 8), 0.0);
    let mut reason = PlaneBuf::new(extent(16, 8), 0u8);
    let out = ReprojectOutput { colour: small.view_mut(), extra: None, reason: reason.view_mut(), weight: None };
    let err = reproject::reproject(&input, out, &params(TapPolicy::Strict)).unwrap_err();
    assert!(err.to_string().contains("output colour"), "{err}");
    // Extra channel on one side only.
    let mut colour = RgbBuf::new(extent(16, 8), 0.0);
    let input = input_for(&tg, &sg, &right, Some(right.colour.r().view()));
    let out = ReprojectOutput { colour: colour.view_mut(), extra: None, reason: reason.view_mut(), weight: None };
    assert!(matches!(
        reproject::reproject(&input, out, &params(TapPolicy::Strict)),
        Err(FrameError::InvalidParameter(_))
    ));
}

#[test]
fn strided_views_give_the_same_result_as_packed_ones() {
    let e = extent(19, 7);
    let (left, right) = stereo_room(e, 0.1);
    let stride = e.width() + 5;
    let pad = |p: &PlaneBuf| {
        let mut v = vec![f32::NAN; stride * e.height()];
        for y in 0..e.height() {
            v[y * stride..y * stride + e.width()].copy_from_slice(&p.as_slice()[y * e.width()..(y + 1) * e.width()]);
        }
        v
    };
    let planes: Vec<Vec<f32>> = std::iter::once(&left.surfaces.depth)
        .chain(left.surfaces.position.iter())
        .chain(left.surfaces.normal.iter())
        .map(pad)
        .collect();
    fn view(v: &[f32], e: Extent, stride: usize) -> Plane<'_> {
        Plane::new(v, e.width(), e.height(), stride).unwrap()
    }
    let v = |i: usize| view(&planes[i], e, stride);
    let strided = GBuffer::new(v(0), [v(1), v(2), v(3)], [v(4), v(5), v(6)]).unwrap();
    let packed = left.gbuffer();
    let source = right.gbuffer();
    let p = params(TapPolicy::Renormalize);
    let a = run_reprojection(&input_for(&strided, &source, &right, None), &p, true).unwrap();
    let b = run_reprojection(&input_for(&packed, &source, &right, None), &p, true).unwrap();
    assert_same(&a, &b);
    // Strided output too.
    let mut out_planes: Vec<Vec<f32>> = (0..3).map(|_| vec![0.0; stride * e.height()]).collect();
    let mut reason = vec![0u8; stride * e.height()];
    let [r, g, bl] = &mut out_planes[..] else { unreachable!() };
    let colour = RgbPlanesMut::new(
        PlaneMut::new(r, e.width(), e.height(), stride).unwrap(),
        PlaneMut::new(g, e.width(), e.height(), stride).unwrap(),
        PlaneMut::new(bl, e.width(), e.height(), stride).unwrap(),
    )
    .unwrap();
    let out = ReprojectOutput {
        colour,
        extra: None,
        reason: PlaneMut::new(&mut reason, e.width(), e.height(), stride).unwrap(),
        weight: None,
    };
    let counts = reproject::reproject(&input_for(&packed, &source, &right, None), out, &p).unwrap();
    assert_eq!(counts, b.counts);
    for y in 0..e.height() {
        for x in 0..e.width() {
            assert!(same_bits(out_planes[1][y * stride + x], b.colour.g().as_slice()[y * e.width() + x]));
            assert_eq!(reason[y * stride + x], b.reason.as_slice()[y * e.width() + x]);
        }
    }
}

#[test]
fn rgb_views_of_different_planes_are_checked() {
    let e = extent(4, 4);
    let a = PlaneBuf::new(e, 0.0f32);
    let b = PlaneBuf::new(extent(4, 3), 0.0f32);
    assert!(RgbPlanes::new(a.view(), b.view(), a.view()).is_err());
}

/// Motion planes (x, y, z) from one closure over target pixels.
fn motion_planes(e: Extent, mut m: impl FnMut(usize, usize) -> [f32; 3]) -> [PlaneBuf; 3] {
    let mut planes = [0; 3].map(|_| PlaneBuf::new(e, 0.0));
    for y in 0..e.height() {
        for x in 0..e.width() {
            let v = m(x, y);
            for c in 0..3 {
                planes[c].as_mut_slice()[y * e.width() + x] = v[c];
            }
        }
    }
    planes
}

#[test]
fn zero_motion_is_static_geometry_bit_for_bit() {
    for &(w, h) in &[(1, 1), (9, 4), (33, 7)] {
        let e = extent(w, h);
        let (left, right) = stereo_room(e, 0.4);
        let zero = motion_planes(e, |_, _| [0.0; 3]);
        for simd in [true, false] {
            let (tc, sc) = (left.compact(), right.compact());
            let still = input_for(&tc, &sc, &right, None);
            let moving =
                ReprojectInput { motion: Some(zero.each_ref().map(|p| p.view())), ..input_for(&tc, &sc, &right, None) };
            let p = params(TapPolicy::Renormalize);
            assert_same(&run_reprojection(&still, &p, simd).unwrap(), &run_reprojection(&moving, &p, simd).unwrap());
        }
    }
}

/// A strip in front of a wall moves sideways by a whole number of pixels between two frames of
/// a still camera. Without motion vectors the strip's pixels that overlap its old place pass
/// every geometric test (same depth, same normal, within the position tolerance) and fetch the
/// wrong texel: the ghost trail of a moving object. With the true motion every pixel inside the
/// strip reprojects to its own texel (the texture moves with the strip), and the wall it
/// uncovered is discarded either way.
#[test]
fn motion_vectors_make_a_moving_strip_reproject_its_own_texels() {
    let e = extent(200, 60);
    let vfov = 60.0;
    let f = focal_pixels(e, vfov);
    let (z_back, z_front, shift) = (8.0f32, 2.0f32, 6.0f64);
    let d = (shift * f64::from(z_front) / f) as f32;
    let strip_at = |cx: f32| {
        let mut scene = wall(z_back, Texture::pattern([0.5, 0.5, 0.5], 0.2, 3.0));
        scene.rects.push(Rect {
            centre: Vec3::new(cx, 0.0, -z_front),
            axis_u: Vec3::X,
            axis_v: Vec3::Y,
            half: (0.3, 10.0),
            texture: Texture::pattern([0.6, 0.3, 0.2], 0.3, 9.0),
        });
        scene.render(&camera_at(Vec3::ZERO, e, vfov), [0.0; 3])
    };
    let (previous, current) = (strip_at(0.0), strip_at(d));
    let on_strip =
        |frame: &SynthFrame, x: usize, y: usize| frame.surfaces.depth.view().get(x, y) < 0.5 * (z_front + z_back);
    let motion = motion_planes(e, |x, y| if on_strip(&current, x, y) { [d, 0.0, 0.0] } else { [0.0; 3] });
    let (tc, sc) = (current.compact(), previous.compact());
    let p = params(TapPolicy::Strict);
    let without = run_reprojection(&input_for(&tc, &sc, &previous, None), &p, true).unwrap();
    let with_input =
        ReprojectInput { motion: Some(motion.each_ref().map(|p| p.view())), ..input_for(&tc, &sc, &previous, None) };
    let with = run_reprojection(&with_input, &p, true).unwrap();
    assert_same(&with, &run_reprojection(&with_input, &p, false).unwrap());

    let y = e.height() / 2;
    let strip_pixels: Vec<usize> = (0..e.width()).filter(|&x| on_strip(&current, x, y)).collect();
    assert!(strip_pixels.len() > 12, "the strip spans {} pixels", strip_pixels.len());
    let (first, last) = (strip_pixels[0], *strip_pixels.last().unwrap());
    let (mut ghost_error, mut ghost_pixels) = (0.0f32, 0);
    for x in first + 1..last {
        let i = y * e.width() + x;
        let own = current.colour.get(x, y);
        assert_eq!(with.reason.as_slice()[i], Reason::Reprojected as u8, "x = {x} with motion");
        let got = with.colour.view().get(x, y);
        for c in 0..3 {
            assert!((got[c] - own[c]).abs() < 2e-3, "x = {x}: {got:?} against its own texel {own:?}");
        }
        // Without motion: the strip's old place gives a wrong texel, the wall a depth failure.
        let code = Reason::from_code(without.reason.as_slice()[i]).unwrap();
        if on_strip(&previous, x, y) && on_strip(&previous, x - 1, y) && on_strip(&previous, x + 1, y) {
            assert_eq!(code, Reason::Reprojected, "x = {x} without motion: a ghost, not a failure");
            let ghost = without.colour.view().get(x, y);
            ghost_error += (0..3).map(|c| (ghost[c] - own[c]).abs()).sum::<f32>();
            ghost_pixels += 1;
        } else if !on_strip(&previous, x, y) && !on_strip(&previous, x - 1, y) && !on_strip(&previous, x + 1, y) {
            assert_eq!(code, Reason::DepthOrPosition, "x = {x} without motion: the wall behind");
        }
    }
    assert!(
        ghost_pixels > 4 && ghost_error / ghost_pixels as f32 > 0.05,
        "ghost error {ghost_error} over {ghost_pixels}"
    );
    // The wall the strip uncovered has no history with or without vectors (the wall is still).
    for x in 0..e.width() {
        if !on_strip(&current, x, y) && on_strip(&previous, x, y) && x > 0 && on_strip(&previous, x - 1, y) {
            let i = y * e.width() + x;
            assert_eq!(with.reason.as_slice()[i], Reason::DepthOrPosition as u8, "x = {x}: uncovered wall");
            assert_eq!(with.reason.as_slice()[i], without.reason.as_slice()[i]);
        }
    }
}

#[test]
fn motion_with_edge_values_matches_the_scalar_reference_and_is_invalid_where_not_finite() {
    let mut rng = Rng::new(0x6d6f_7665);
    for case in 0..40 {
        let e = extent(1 + rng.below(40), 1 + rng.below(12));
        let scene = AnalyticScene::room(3.0 + rng.range(0.0, 8.0));
        let target = scene.render(&camera_at(Vec3::new(rng.range(-0.3, 0.3), 0.0, 0.0), e, 60.0), [0.0; 3]);
        let source = scene.render(&camera_at(Vec3::new(rng.range(-0.3, 0.3), 0.0, 0.0), e, 60.0), [0.0; 3]);
        let share = if case % 2 == 0 { 0.0 } else { 0.2 };
        let motion = motion_planes(e, |_, _| {
            [0; 3].map(|_| {
                if rng.next_f32() < share { EDGE_VALUES[rng.below(EDGE_VALUES.len())] } else { rng.range(-0.2, 0.2) }
            })
        });
        let p = ReprojectParams { band_rows: 1 + rng.below(5), ..params(TapPolicy::Renormalize) };
        let (tc, sc) = (target.compact(), source.compact());
        let input =
            ReprojectInput { motion: Some(motion.each_ref().map(|p| p.view())), ..input_for(&tc, &sc, &source, None) };
        assert_every_body_matches_scalar(&input, &p);
        let simd = run_reprojection(&input, &p, true).unwrap();
        for i in 0..e.pixels() {
            let finite = (0..3).all(|c| motion[c].as_slice()[i].is_finite());
            let background = target.surfaces.depth.as_slice()[i] == f32::INFINITY;
            if !finite && !background {
                assert_eq!(simd.reason.as_slice()[i], Reason::Invalid as u8, "pixel {i} of case {case}");
            }
        }
        assert!(
            [simd.colour.r(), simd.colour.g(), simd.colour.b()]
                .iter()
                .all(|p| p.as_slice().iter().all(|v| v.is_finite()))
        );
    }
}

#[test]
fn motion_planes_of_another_extent_are_refused() {
    let (left, right) = stereo_room(extent(16, 8), 0.065);
    let (tc, sc) = (left.compact(), right.compact());
    let mut motion = [0; 3].map(|_| PlaneBuf::new(extent(16, 8), 0.0));
    motion[1] = PlaneBuf::new(extent(16, 7), 0.0);
    let input =
        ReprojectInput { motion: Some(motion.each_ref().map(|p| p.view())), ..input_for(&tc, &sc, &right, None) };
    let err = run_reprojection(&input, &params(TapPolicy::Strict), true).unwrap_err();
    assert!(err.to_string().contains("motion y"), "{err}");
}

#[test]
fn a_jittered_camera_sees_what_the_camera_sees_a_sub_pixel_away() {
    let e = extent(64, 36);
    let camera = camera_at(Vec3::new(0.3, -0.2, 1.0), e, 55.0);
    assert_eq!(camera.jittered([0.0, 0.0]).unwrap(), camera, "no jitter is the camera itself");
    for jitter in [[0.5f32, 0.0], [-0.25, 0.375], [1.0, -1.0]] {
        let moved = camera.jittered(jitter).unwrap();
        assert_eq!(moved.centre, camera.centre);
        for (x, y) in [(0.5f32, 0.5f32), (13.5, 20.5), (63.5, 35.5)] {
            let (a, b) = (Vec3::from(moved.ray(x, y)), Vec3::from(camera.ray(x + jitter[0], y + jitter[1])));
            assert!((a - b).length() < 1e-5 * b.length(), "{jitter:?} at ({x}, {y}): {a} vs {b}");
        }
    }
    for bad in [[f32::NAN, 0.0], [0.0, 1.5], [f32::INFINITY, 0.0]] {
        assert!(matches!(camera.jittered(bad), Err(FrameError::InvalidParameter(_))), "{bad:?}");
    }
}

/// Temporal reprojection of a ramp-textured wall (bilinear interpolation is exact on it) seen
/// by a camera that moved and whose G-buffers were rendered with different sub-pixel jitters,
/// while the colour is on the unjittered grid: with the jitter stated the reprojected colour is
/// the unjittered image of the target frame; without it, it is off by the ramp's slope times
/// the jitter difference.
#[test]
fn stated_jitter_reprojects_onto_the_unjittered_grid() {
    let e = extent(80, 40);
    let vfov = 50.0;
    let scene = wall(5.0, Texture::ramp([0.2, 0.3, 0.4], [0.1, -0.05, 0.07]));
    let (target_camera, source_camera) =
        (camera_at(Vec3::new(0.013, 0.0, 0.0), e, vfov), camera_at(Vec3::new(-0.021, 0.007, 0.0), e, vfov));
    let reference = scene.render(&target_camera, [0.0; 3]);
    let source_colour = scene.render(&source_camera, [0.0; 3]);
    for (jt, js) in [([0.25f32, -0.25f32], [-0.375f32, 0.125f32]), ([0.5, 0.5], [0.0, 0.0])] {
        let target = scene.render(&target_camera.jittered(jt).unwrap(), [0.0; 3]);
        let source = scene.render(&source_camera.jittered(js).unwrap(), [0.0; 3]);
        let (tc, sc) = (target.compact(), source.compact());
        let p = params(TapPolicy::Renormalize);
        let stated = ReprojectInput {
            jitter: Some(reproject::Jitter { target: jt, source: js }),
            ..input_for(&tc, &sc, &source, None)
        };
        let stated = ReprojectInput { colour: source_colour.colour.view(), ..stated };
        let with = run_reprojection(&stated, &p, true).unwrap();
        assert_same(&with, &run_reprojection(&stated, &p, false).unwrap());
        let unstated = ReprojectInput { jitter: None, ..stated };
        let without = run_reprojection(&unstated, &p, true).unwrap();
        let (mut worst_with, mut worst_without) = (0.0f32, 0.0f32);
        for y in 2..e.height() - 2 {
            for x in 2..e.width() - 2 {
                let i = y * e.width() + x;
                assert_eq!(with.reason.as_slice()[i], Reason::Reprojected as u8, "({x}, {y})");
                let want = reference.colour.get(x, y);
                let err = |r: &Reprojected| {
                    (0..3).map(|c| (r.colour.view().get(x, y)[c] - want[c]).abs()).fold(0.0, f32::max)
                };
                (worst_with, worst_without) = (worst_with.max(err(&with)), worst_without.max(err(&without)));
            }
        }
        assert!(worst_with < 2e-5, "{jt:?} {js:?}: stated jitter leaves {worst_with}");
        assert!(worst_without > 20.0 * worst_with.max(1e-6), "{jt:?} {js:?}: unstated {worst_without}");
    }
    // Refused: an offset past a pixel.
    let frame = scene.render(&target_camera, [0.0; 3]);
    let (tc, sc) = (frame.compact(), frame.compact());
    let bad = ReprojectInput {
        jitter: Some(reproject::Jitter { target: [0.0, 1.5], source: [0.0; 2] }),
        ..input_for(&tc, &sc, &frame, None)
    };
    assert!(matches!(run_reprojection(&bad, &params(TapPolicy::Strict), true), Err(FrameError::InvalidParameter(_))));
}

/// A window onto the sky: one textured rectangle in the middle of the view at depth 3, and
/// background everywhere else.
fn window() -> AnalyticScene {
    AnalyticScene {
        rects: vec![Rect {
            centre: Vec3::new(0.1, -0.05, -3.0),
            axis_u: Vec3::X,
            axis_v: Vec3::Y,
            half: (0.6, 0.4),
            texture: Texture::ramp([0.2, 0.3, 0.4], [0.1, 0.0, -0.1]),
        }],
    }
}

/// Source samples that differ at every pixel, smoothly: `x + 0.25·y` in red.
fn numbered(frame: &mut SynthFrame) {
    let w = frame.extent().width();
    for (i, v) in frame.colour.r_mut().iter_mut().enumerate() {
        *v = (i % w) as f32 + 0.25 * (i / w) as f32;
    }
}

/// Bilinear interpolation in f64 at `(sx, sy)` over the taps `keep` accepts, renormalised
/// (`None` where no tap with a positive weight is accepted).
fn bilinear_where(img: &PlaneBuf, sx: f64, sy: f64, keep: impl Fn(usize, usize) -> bool) -> Option<f64> {
    let e = img.extent();
    let (u, v) = (sx - 0.5, sy - 0.5);
    let (x0, y0) = (u.floor(), v.floor());
    let (fx, fy) = (u - x0, v - y0);
    let (mut sum, mut total) = (0.0, 0.0);
    for (dx, dy, w) in
        [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)]
    {
        let (x, y) = (x0 as i64 + dx, y0 as i64 + dy);
        let inside = x >= 0 && y >= 0 && (x as usize) < e.width() && (y as usize) < e.height();
        if w > 0.0 && inside && keep(x as usize, y as usize) {
            sum += w * f64::from(img.as_slice()[y as usize * e.width() + x as usize]);
            total += w;
        }
    }
    (total > 0.0).then(|| sum / total)
}

#[test]
fn background_pixels_reproject_by_direction_as_the_closed_form_says() {
    let e = extent(72, 40);
    let vfov = 60.0f32;
    let scene = window();
    // The target camera looks down −Z from (0.2, 0, 0); the source stands elsewhere and is
    // turned (yaw and pitch), as a moving camera between frames.
    let target_eye = Vec3::new(0.2, 0.0, 0.0);
    let cam_t = camera_at(target_eye, e, vfov);
    let source_eye = Vec3::new(-0.4, 0.1, 0.5);
    let vp_s = stereotrace_kernels::camera::look_at_perspective(
        source_eye,
        source_eye + Vec3::new(0.12, 0.05, -1.0),
        Vec3::Y,
        vfov.to_radians(),
        e,
    );
    let cam_s = CameraModel::new(vp_s, e).unwrap();
    let target = scene.render(&cam_t, [0.0; 3]);
    let mut source = scene.render(&cam_s, [0.0; 3]);
    numbered(&mut source);
    let sky = |frame: &SynthFrame, x: usize, y: usize| {
        frame.surfaces.depth.as_slice()[y * frame.extent().width() + x] == f32::INFINITY
    };
    let p = params(TapPolicy::Renormalize);
    let strict = params(TapPolicy::Strict);
    let (tc, sc) = (target.compact(), source.compact());
    let paper = run_reprojection(&input_for(&tc, &sc, &source, None), &p, true).unwrap();
    let input = ReprojectInput { background: Some(&cam_t), ..input_for(&tc, &sc, &source, None) };
    let kept = run_reprojection(&input, &p, true).unwrap();
    let kept_strict = run_reprojection(&input, &strict, true).unwrap();
    // Every body gives the reference's bits (the sky's coherent rows and its gathers alike).
    for params in [&p, &strict] {
        assert_every_body_matches_scalar(&input, params);
        let (tf, sf) = (target.gbuffer(), source.gbuffer());
        let extra = Some(source.colour.g().view());
        assert_every_body_matches_scalar(
            &ReprojectInput { background: Some(&cam_t), ..input_for(&tf, &sf, &source, extra) },
            params,
        );
    }
    // The closed form, in f64: the target pixel's direction from the field of view, and its
    // place in the source from the source's view-projection applied to (d, 0).
    let tan = (f64::from(vfov).to_radians() / 2.0).tan();
    let aspect = e.width() as f64 / e.height() as f64;
    let vp = vp_s.as_dmat4();
    let (mut checked, mut refused, mut partial) = (0, 0, 0);
    for y in 0..e.height() {
        for x in 0..e.width() {
            let i = y * e.width() + x;
            if !sky(&target, x, y) {
                assert_eq!(
                    kept.reason.as_slice()[i],
                    paper.reason.as_slice()[i],
                    "surfaces as the paper's at ({x}, {y})"
                );
                continue;
            }
            assert_eq!(paper.reason.as_slice()[i], Reason::Background as u8, "the paper discards sky");
            let ndc =
                [2.0 * (x as f64 + 0.5) / e.width() as f64 - 1.0, 1.0 - 2.0 * (y as f64 + 0.5) / e.height() as f64];
            let d = glam::DVec4::new(ndc[0] * tan * aspect, ndc[1] * tan, -1.0, 0.0);
            let c = vp * d;
            let (sx, sy) = ((c.x / c.w + 1.0) * 0.5 * e.width() as f64, (1.0 - c.y / c.w) * 0.5 * e.height() as f64);
            // Away from the tap boundaries, where which taps take part is not in doubt.
            let (fx, fy) = ((sx - 0.5).rem_euclid(1.0), (sy - 0.5).rem_euclid(1.0));
            if fx.min(1.0 - fx) < 0.01 || fy.min(1.0 - fy) < 0.01 {
                continue;
            }
            let all = bilinear_where(source.colour.r(), sx, sy, |_, _| true);
            let sky_only = bilinear_where(source.colour.r(), sx, sy, |tx, ty| sky(&source, tx, ty));
            let reason = kept.reason.as_slice()[i];
            match sky_only {
                Some(expected) => {
                    assert_eq!(reason, Reason::Reprojected as u8, "sky kept at ({x}, {y})");
                    let got = f64::from(kept.colour.r().as_slice()[i]);
                    assert!((got - expected).abs() < 2e-3, "({x}, {y}): {got} against {expected}");
                    checked += 1;
                    // Strict: only where every tap in the footprint is sky and in frame.
                    let whole = all == sky_only
                        && (sx - 0.5).floor() >= 0.0
                        && (sy - 0.5).floor() >= 0.0
                        && (sx + 0.5) < e.width() as f64
                        && (sy + 0.5) < e.height() as f64;
                    let strict_reason = kept_strict.reason.as_slice()[i];
                    if whole {
                        assert_eq!(strict_reason, Reason::Reprojected as u8, "strict keeps a whole sky footprint");
                    } else {
                        assert_eq!(strict_reason, Reason::Background as u8, "strict refuses a mixed footprint");
                        partial += 1;
                    }
                }
                None => {
                    assert_eq!(reason, Reason::Background as u8, "no sky tap at ({x}, {y})");
                    assert_eq!(kept.colour.r().as_slice()[i], 0.0);
                    assert_eq!(kept.weight.as_slice()[i], 0.0);
                    refused += 1;
                }
            }
        }
    }
    assert!(checked > 500 && refused > 20 && partial > 5, "checked {checked}, refused {refused}, partial {partial}");
    // The counts say the same as the reason plane.
    let count = |r: &Reprojected, reason: Reason| r.reason.as_slice().iter().filter(|&&c| c == reason as u8).count();
    assert_eq!(kept.counts.get(Reason::Reprojected), count(&kept, Reason::Reprojected) as u64);
    assert_eq!(kept.counts.get(Reason::Background), count(&kept, Reason::Background) as u64);
}

#[test]
fn a_parallel_stereo_pair_copies_its_sky_pixel_for_pixel() {
    // At infinity a parallel rig has no disparity: each sky pixel is the other eye's same pixel.
    let e = extent(64, 36);
    let scene = window();
    let left = scene.render(&camera_at(Vec3::new(-0.032, 0.0, 0.0), e, 60.0), [0.0; 3]);
    let mut right = scene.render(&camera_at(Vec3::new(0.032, 0.0, 0.0), e, 60.0), [0.0; 3]);
    numbered(&mut right);
    let (tc, sc) = (left.compact(), right.compact());
    let input = ReprojectInput { background: Some(&left.surfaces.camera), ..input_for(&tc, &sc, &right, None) };
    let r = run_reprojection(&input, &params(TapPolicy::Strict), true).unwrap();
    assert_every_body_matches_scalar(&input, &params(TapPolicy::Strict));
    let mut copied = 0;
    for i in 0..e.pixels() {
        let both_sky =
            left.surfaces.depth.as_slice()[i] == f32::INFINITY && right.surfaces.depth.as_slice()[i] == f32::INFINITY;
        if both_sky {
            assert_eq!(r.reason.as_slice()[i], Reason::Reprojected as u8);
            assert!(same_bits(r.colour.r().as_slice()[i], right.colour.r().as_slice()[i]), "pixel {i}");
            copied += 1;
        }
    }
    assert!(copied > e.pixels() / 2, "{copied} sky pixels");
}

#[test]
fn a_background_camera_of_another_extent_is_refused() {
    let e = extent(16, 8);
    let (left, right) = stereo_room(e, 0.065);
    let other = camera_at(Vec3::ZERO, extent(8, 8), 60.0);
    let (tc, sc) = (left.compact(), right.compact());
    let input = ReprojectInput { background: Some(&other), ..input_for(&tc, &sc, &right, None) };
    let err = run_reprojection(&input, &params(TapPolicy::Renormalize), true).unwrap_err();
    assert!(err.to_string().contains("background"), "{err}");
}
