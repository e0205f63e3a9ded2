//! The image kernels' entry points: backward reprojection, bilinear resampling,
//! accumulation, temporal gradients, the à-trous filter and SSIM, each over an analytic scene edited by the input's trailing bytes.

use glam::{Mat4, Vec3};

use crate::accumulate::{self, BlendParams, EmaInput, EmaParams, EmaState};
use crate::atrous;
use crate::bilinear::{self, ResampleInput, ResampleOutput};
use crate::camera::{CameraModel, look_at_perspective};
use crate::check::same_bits;
use crate::clamp::{self, ClampInput, ClampParams};
use crate::frame::{Extent, FrameError, PlaneBuf, RgbBuf};
use crate::gbuffer::SurfaceLayout;
use crate::gradient::{self, GradientInput};
use crate::isa::Isa;
use crate::reproject::{self, Reason, ReprojectInput, ReprojectOutput, ReprojectParams, TapPolicy, Tolerances};
use crate::synth::{AnalyticScene, SynthFrame, camera_at};

use super::input::Bytes;

fn extent_from(bytes: &mut Bytes<'_>) -> Extent {
    // 1×1 … 40×12, so 1×N and N×1 frames come up often.
    let w = 1 + usize::from(bytes.u8() % 40);
    let h = 1 + usize::from(bytes.u8() % 12);
    Extent::new(w, h).expect("small extent")
}

/// A camera: mostly plausible (a perturbed look-at), sometimes raw matrix bits.
fn camera_from(bytes: &mut Bytes<'_>, extent: Extent) -> Result<CameraModel, FrameError> {
    match bytes.u8() % 4 {
        0 => {
            let m: [f32; 16] = core::array::from_fn(|_| bytes.f32());
            CameraModel::new(Mat4::from_cols_array(&m), extent)
        }
        1 => {
            // Rank-deficient: one row scaled into another.
            let mut m = look_at_perspective(Vec3::ZERO, -Vec3::Z, Vec3::Y, 1.0, extent);
            m.x_axis = m.y_axis * bytes.unit(-2.0, 2.0);
            CameraModel::new(m, extent)
        }
        _ => {
            let eye = Vec3::new(bytes.unit(-0.6, 0.6), bytes.unit(-0.4, 0.4), bytes.unit(-0.6, 0.6));
            let target = eye + Vec3::new(bytes.unit(-0.5, 0.5), bytes.unit(-0.5, 0.5), -1.0);
            let vfov = bytes.unit(0.2, 2.5);
            CameraModel::new(look_at_perspective(eye, target, Vec3::Y, vfov, extent), extent)
        }
    }
}

/// Applies the trailing 6-byte edits to the frame's planes.
fn apply_edits(bytes: &mut Bytes<'_>, frame: &mut SynthFrame) {
    let pixels = frame.extent().pixels();
    while !bytes.is_empty() {
        let plane = bytes.u8() % 11;
        let index = usize::from(u16::from_le_bytes([bytes.u8(), bytes.u8()])) % pixels;
        let value = bytes.f32();
        match plane {
            0 => frame.surfaces.depth.as_mut_slice()[index] = value,
            1..=3 => frame.surfaces.position[usize::from(plane - 1)].as_mut_slice()[index] = value,
            4..=6 => frame.surfaces.normal[usize::from(plane - 4)].as_mut_slice()[index] = value,
            7 => frame.surfaces.normal_oct.as_mut_slice()[index] = value.to_bits(),
            8 => frame.colour.r_mut()[index] = value,
            9 => frame.colour.g_mut()[index] = value,
            _ => frame.colour.b_mut()[index] = value,
        }
    }
}

fn all_finite(p: &PlaneBuf) -> bool {
    p.as_slice().iter().all(|v| v.is_finite())
}

fn assert_bits(what: &str, a: &PlaneBuf, b: &PlaneBuf) {
    for (i, (x, y)) in a.as_slice().iter().zip(b.as_slice()).enumerate() {
        assert!(same_bits(*x, *y), "{what}: SIMD {x:?} != scalar {y:?} at index {i}");
    }
}

/// Fuzzes backward reprojection (both layouts, both policies, with and without the extra
/// channel).
pub fn reproject(data: &[u8]) {
    let mut bytes = Bytes(data);
    // Row padding of every plane (0 = packed); padding holds NaN, which must never be read.
    let pad = usize::from(bytes.u8() % 4);
    let extent = extent_from(&mut bytes);
    let source_extent = if bytes.u8() % 4 == 0 { extent_from(&mut bytes) } else { extent };
    let scene = AnalyticScene::room(bytes.unit(1.0, 12.0));
    let target_camera = camera_at(Vec3::new(bytes.unit(-0.3, 0.3), 0.0, 0.0), extent, bytes.unit(20.0, 100.0));
    let source_camera = match camera_from(&mut bytes, source_extent) {
        Ok(camera) => camera,
        Err(e) => {
            assert_eq!(e, FrameError::SingularCamera, "cameras fail only as singular");
            return;
        }
    };
    let tolerances = Tolerances {
        position: if bytes.u8() % 8 == 0 { bytes.f32() } else { bytes.unit(0.0, 1.0) },
        depth_relative: bytes.unit(0.0, 0.2),
        normal_cos: bytes.unit(-1.0, 1.0),
    };
    let policy = if bytes.u8() % 2 == 0 { TapPolicy::Renormalize } else { TapPolicy::Strict };
    let params = ReprojectParams { tolerances, policy, band_rows: 1 + usize::from(bytes.u8() % 8) };
    // A pixel mask on a quarter, half or three quarters of the pixels, in a scattered
    // pattern (so groups of 8 come out all on, all off and mixed), or none.
    let mask_share = bytes.u8() % 4;
    let mask = (mask_share != 0).then(|| {
        let on =
            (0..extent.pixels()).map(|i| u8::from((i as u32).wrapping_mul(0x9E37_79B9) >> 30 < u32::from(mask_share)));
        PlaneBuf::from_vec(on.collect(), extent).expect("extent matches")
    });
    let motion = motion_from(&mut bytes, extent);
    // Sub-pixel jitter of the two G-buffers, within the pixel it may move.
    let jitter = (bytes.u8() % 2 == 0).then(|| crate::reproject::Jitter {
        target: [bytes.unit(-1.0, 1.0), bytes.unit(-1.0, 1.0)],
        source: [bytes.unit(-1.0, 1.0), bytes.unit(-1.0, 1.0)],
    });
    // Background pixels reprojected by direction (beyond the paper), or discarded.
    let background = (bytes.u8() % 2 == 0).then_some(&target_camera);
    let mut target = scene.render(&target_camera, [0.0; 3]);
    let mut source = scene.render(&source_camera, [0.0; 3]);
    let edit_source = bytes.u8() % 2 == 0;
    apply_edits(&mut bytes, if edit_source { &mut source } else { &mut target });

    let source_finite = source.colour.planes().into_iter().all(all_finite);
    let extra = PlaneBuf::from_vec((0..source_extent.pixels()).map(|i| (i % 7) as f32).collect(), source_extent)
        .expect("extent matches");
    let (target, source) = (Strided::new(&target, pad), Strided::new(&source, pad));
    let (tf, sf) = (target.gbuffer(), source.gbuffer());
    let with = Extras { extra: None, mask: mask.as_ref(), motion: motion.as_ref(), jitter, background };
    check_reprojection(&tf, &sf, &source, with, &params, source_finite);
    let (tc, sc) = (target.compact(), source.compact());
    let with = Extras { extra: Some(&extra), ..with };
    check_reprojection(&tc, &sc, &source, with, &params, source_finite);
}

/// Motion planes for the target, or none: one vector for every pixel (any bits, NaN and
/// infinities included), or small per-pixel vectors with a few non-finite ones.
fn motion_from(bytes: &mut Bytes, extent: Extent) -> Option<[PlaneBuf; 3]> {
    let planes = |value: &mut dyn FnMut(usize, usize) -> f32| {
        [0, 1, 2].map(|c| {
            let v = (0..extent.pixels()).map(|i| value(i, c)).collect();
            PlaneBuf::from_vec(v, extent).expect("extent matches")
        })
    };
    match bytes.u8() % 4 {
        0 | 1 => None,
        2 => {
            let m = [bytes.f32(), bytes.f32(), bytes.f32()];
            Some(planes(&mut |_, c| m[c]))
        }
        _ => {
            let scale = bytes.unit(0.0, 1.0);
            let odd = usize::from(bytes.u8());
            Some(planes(&mut |i, c| {
                let h = ((i * 3 + c) as u32).wrapping_mul(0x9E37_79B9);
                if odd != 0 && (i * 3 + c) % (odd + 7) == 0 {
                    [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][(h >> 30) as usize % 3]
                } else {
                    scale * ((h >> 8) as f32 / (1u32 << 24) as f32 - 0.5)
                }
            }))
        }
    }
}

/// The optional inputs of one reprojection call.
#[derive(Clone, Copy)]
struct Extras<'a> {
    extra: Option<&'a PlaneBuf>,
    mask: Option<&'a PlaneBuf<u8>>,
    motion: Option<&'a [PlaneBuf; 3]>,
    jitter: Option<crate::reproject::Jitter>,
    background: Option<&'a CameraModel>,
}

/// A copy of a frame's planes with `pad` extra elements per row (filled with NaN or an
/// invalid normal, so reading padding would show).
struct Strided {
    frame: SynthFrame,
    stride: usize,
    depth: Vec<f32>,
    position: [Vec<f32>; 3],
    normal: [Vec<f32>; 3],
    normal_oct: Vec<u32>,
    colour: [Vec<f32>; 3],
}

fn padded<T: Copy + Send + Sync>(p: &PlaneBuf<T>, stride: usize, fill: T) -> Vec<T> {
    let e = p.extent();
    let mut out = vec![fill; stride * e.height()];
    for y in 0..e.height() {
        out[y * stride..y * stride + e.width()].copy_from_slice(p.view().row(y));
    }
    out
}

impl Strided {
    fn new(frame: &SynthFrame, pad: usize) -> Self {
        let stride = frame.extent().width() + pad;
        let f = |p: &PlaneBuf| padded(p, stride, f32::NAN);
        Self {
            stride,
            depth: f(&frame.surfaces.depth),
            position: frame.surfaces.position.each_ref().map(f),
            normal: frame.surfaces.normal.each_ref().map(f),
            normal_oct: padded(&frame.surfaces.normal_oct, stride, u32::MAX),
            colour: frame.colour.planes().map(f),
            frame: frame.clone(),
        }
    }

    fn plane<'a, T: Copy>(&self, data: &'a [T]) -> crate::frame::Plane<'a, T> {
        let e = self.frame.extent();
        crate::frame::Plane::new(data, e.width(), e.height(), self.stride).expect("padded plane")
    }

    fn gbuffer(&self) -> crate::gbuffer::GBuffer<'_> {
        let [px, py, pz] = &self.position;
        let [nx, ny, nz] = &self.normal;
        let position = [self.plane(px), self.plane(py), self.plane(pz)];
        let normal = [self.plane(nx), self.plane(ny), self.plane(nz)];
        crate::gbuffer::GBuffer::new(self.plane(&self.depth), position, normal).expect("one extent")
    }

    fn compact(&self) -> crate::gbuffer::CompactGBuffer<'_> {
        crate::gbuffer::CompactGBuffer::new(
            self.plane(&self.depth),
            self.plane(&self.normal_oct),
            self.frame.surfaces.camera,
        )
        .expect("one extent")
    }

    fn colour(&self) -> crate::frame::RgbPlanes<'_> {
        let [r, g, b] = &self.colour;
        crate::frame::RgbPlanes::new(self.plane(r), self.plane(g), self.plane(b)).expect("one extent")
    }
}

fn check_reprojection<L: SurfaceLayout>(
    target: &L,
    source: &L,
    source_frame: &Strided,
    with: Extras<'_>,
    params: &ReprojectParams,
    source_finite: bool,
) {
    let Extras { extra, mask, motion, jitter, background } = with;
    let input = ReprojectInput {
        target,
        source,
        source_camera: &source_frame.frame.surfaces.camera,
        colour: source_frame.colour(),
        extra: extra.map(|p| p.view()),
        pixel_mask: mask.map(|m| m.view()),
        motion: motion.map(|m| m.each_ref().map(|p| p.view())),
        jitter,
        background,
    };
    let e = target.extent();
    if let Err(refusal) = params.tolerances.validate() {
        // Invalid tolerances are refused up front by both bodies, with the same error.
        let mut colour = RgbBuf::new(e, 0.0);
        let mut reason = PlaneBuf::new(e, 0u8);
        let input = ReprojectInput { extra: None, ..input };
        let out = ReprojectOutput { colour: colour.view_mut(), extra: None, reason: reason.view_mut(), weight: None };
        assert_eq!(reproject::reproject(&input, out, params).err(), Some(refusal.clone()));
        let out = ReprojectOutput { colour: colour.view_mut(), extra: None, reason: reason.view_mut(), weight: None };
        assert_eq!(reproject::reproject_scalar(&input, out, params).err(), Some(refusal));
        return;
    }
    // `None`: the scalar reference; `Some(isa)`: that SIMD body.
    let run = |body: Option<Isa>| {
        let mut colour = RgbBuf::new(e, f32::NAN);
        let mut extra_out = PlaneBuf::new(e, f32::NAN);
        let mut reason = PlaneBuf::new(e, u8::MAX);
        let mut weight = PlaneBuf::new(e, f32::NAN);
        let out = ReprojectOutput {
            colour: colour.view_mut(),
            extra: extra.map(|_| extra_out.view_mut()),
            reason: reason.view_mut(),
            weight: Some(weight.view_mut()),
        };
        let counts = match body {
            Some(isa) => reproject::reproject_with(&input, out, params, isa),
            None => reproject::reproject_scalar(&input, out, params),
        };
        (counts.expect("validated input"), colour, extra_out, reason, weight)
    };
    // Every SIMD body this CPU has equals the reference bit for bit, so the checks after this
    // loop read the reference's outputs.
    let (counts, colour, extra_ref, reason, weight) = run(None);
    for isa in Isa::supported() {
        let (counts_simd, colour_simd, extra_simd, reason_simd, weight_simd) = run(Some(isa));
        assert_eq!(counts_simd, counts, "reason counts ({isa:?})");
        assert_eq!(reason_simd, reason, "reason codes ({isa:?})");
        for (a, b) in [(colour_simd.r(), colour.r()), (colour_simd.g(), colour.g()), (colour_simd.b(), colour.b())] {
            assert_bits("colour", a, b);
        }
        if extra.is_some() {
            assert_bits("extra channel", &extra_simd, &extra_ref);
        }
        assert_bits("weight", &weight_simd, &weight);
    }
    assert!(reason.as_slice().iter().all(|&c| Reason::from_code(c).is_some()));
    // Pixels a mask skips keep the NaN the outputs started with and read `Invalid`.
    let on = |i: usize| mask.is_none_or(|m| m.as_slice()[i] != 0);
    let chosen = (0..e.pixels()).filter(|&i| on(i)).count();
    assert_eq!(counts.total(), chosen as u64, "every chosen pixel counted once");
    for i in 0..e.pixels() {
        if on(i) {
            assert!((0.0..=1.0).contains(&weight.as_slice()[i]), "weights in [0, 1]");
            if source_finite {
                for p in colour.planes() {
                    assert!(p.as_slice()[i].is_finite(), "non-finite output from finite source samples");
                }
            }
            let sky = target.surfel(i % e.width(), i / e.width()).depth == f32::INFINITY;
            if sky {
                let code = reason.as_slice()[i];
                if background.is_none() {
                    assert_eq!(code, Reason::Background as u8, "background is discarded without the option");
                }
                assert!(
                    code == Reason::Background as u8 || code == Reason::Reprojected as u8,
                    "a sky pixel is sky or kept"
                );
            }
            let moved_by_nonsense = motion.is_some_and(|m| m.iter().any(|p| !p.as_slice()[i].is_finite()));
            if moved_by_nonsense && !sky {
                assert_eq!(reason.as_slice()[i], Reason::Invalid as u8, "a non-finite motion vector is invalid");
            }
        } else {
            assert_eq!(reason.as_slice()[i], Reason::Invalid as u8, "a skipped pixel reads invalid");
            assert!(weight.as_slice()[i].is_nan(), "a skipped pixel's weight is left as it was");
        }
    }
}

/// Fuzzes the whole-image bilinear resampler.
pub fn bilinear(data: &[u8]) {
    let mut bytes = Bytes(data);
    let pad = usize::from(bytes.u8() % 4);
    let source_extent = extent_from(&mut bytes);
    let target_extent = extent_from(&mut bytes);
    let mut source = RgbBuf::new(source_extent, 0.0);
    for (i, v) in source.r_mut().iter_mut().enumerate() {
        *v = i as f32 * 0.25;
    }
    let mut map_x = PlaneBuf::new(target_extent, 0.0f32);
    let mut map_y = PlaneBuf::new(target_extent, 0.0f32);
    let (sw, sh) = (source_extent.width() as f32, source_extent.height() as f32);
    for (i, (x, y)) in map_x.as_mut_slice().iter_mut().zip(map_y.as_mut_slice()).enumerate() {
        *x = (i % target_extent.width()) as f32 * sw / target_extent.width() as f32;
        *y = (i / target_extent.width()) as f32 * sh / target_extent.height() as f32;
    }
    let use_mask = bytes.u8() % 2 == 0;
    let mut valid = PlaneBuf::new(source_extent, 1u8);
    while !bytes.is_empty() {
        let which = bytes.u8() % 6;
        let index = usize::from(u16::from_le_bytes([bytes.u8(), bytes.u8()]));
        let value = bytes.f32();
        match which {
            0 => map_x.as_mut_slice()[index % target_extent.pixels()] = value,
            1 => map_y.as_mut_slice()[index % target_extent.pixels()] = value,
            2 => source.r_mut()[index % source_extent.pixels()] = value,
            3 => source.g_mut()[index % source_extent.pixels()] = value,
            4 => source.b_mut()[index % source_extent.pixels()] = value,
            _ => valid.as_mut_slice()[index % source_extent.pixels()] = value.to_bits() as u8 & 1,
        }
    }
    let source_finite = source.planes().into_iter().all(all_finite);
    // Every input plane with `pad` elements of NaN (or 0 for the mask) after each row.
    let (sw, tw) = (source_extent.width() + pad, target_extent.width() + pad);
    let src = source.planes().map(|p| padded(p, sw, f32::NAN));
    let (mx, my, mask) = (padded(&map_x, tw, f32::NAN), padded(&map_y, tw, f32::NAN), padded(&valid, sw, 0u8));
    fn view(d: &[f32], e: Extent, stride: usize) -> crate::frame::Plane<'_> {
        crate::frame::Plane::new(d, e.width(), e.height(), stride).expect("padded")
    }
    let source_view = crate::frame::RgbPlanes::new(
        view(&src[0], source_extent, sw),
        view(&src[1], source_extent, sw),
        view(&src[2], source_extent, sw),
    )
    .expect("one extent");
    let mask_view = crate::frame::Plane::new(&mask, source_extent.width(), source_extent.height(), sw).expect("padded");
    let input = ResampleInput {
        source: source_view,
        source_valid: use_mask.then_some(mask_view),
        map_x: view(&mx, target_extent, tw),
        map_y: view(&my, target_extent, tw),
    };
    let run = |simd: bool| {
        let mut colour = RgbBuf::new(target_extent, f32::NAN);
        let mut weight = PlaneBuf::new(target_extent, f32::NAN);
        let out = ResampleOutput { colour: colour.view_mut(), weight: weight.view_mut() };
        let result = if simd { bilinear::resample(&input, out) } else { bilinear::resample_scalar(&input, out) };
        result.expect("validated input");
        (colour, weight)
    };
    let (colour, weight) = run(true);
    let (colour_ref, weight_ref) = run(false);
    for (a, b) in [(colour.r(), colour_ref.r()), (colour.g(), colour_ref.g()), (colour.b(), colour_ref.b())] {
        assert_bits("resampled colour", a, b);
    }
    assert_bits("resample weight", &weight, &weight_ref);
    assert!(weight.as_slice().iter().all(|w| (0.0..=1.0).contains(w)), "weights in [0, 1]");
    if source_finite {
        for p in colour.planes() {
            assert!(all_finite(p), "non-finite output from finite source samples");
        }
    }
}

/// Fuzzes the EMA and the stereo blend. Reason codes are mostly defined, sometimes not (about
/// 2 %), and history lengths any f32: a call whose planes hold an undefined code (or, for the
/// EMA, a length that is not a finite count, or a confidence outside [0, 1], at a pixel it
/// reads: with a pixel mask, only where the mask is set) must be refused by both bodies
/// alike, with the outputs untouched; any other call must give the same bits from both.
pub fn accumulate(data: &[u8]) {
    let mut bytes = Bytes(data);
    let e = extent_from(&mut bytes);
    let alpha = bytes.unit(0.0, 1.0).max(1e-6);
    let ramp = bytes.u8() % 2 == 0;
    let own_weight = bytes.unit(0.0, 1.0);
    let mut new = RgbBuf::new(e, 1.0);
    let mut history = RgbBuf::new(e, 2.0);
    let mut len = PlaneBuf::new(e, 3.0f32);
    let mut reason = PlaneBuf::new(e, Reason::Reprojected as u8);
    // A history confidence plane in two inputs of three, edited like the others.
    let mut confidence = (bytes.u8() % 3 != 0).then(|| PlaneBuf::new(e, bytes.unit(0.0, 1.0)));
    // A pixel mask in half the inputs (every pixel in it at first, edited like the others).
    let mut pixel_mask = (bytes.u8() % 2 == 0).then(|| PlaneBuf::new(e, 1u8));
    while !bytes.is_empty() {
        let which = bytes.u8() % 10;
        let index = usize::from(u16::from_le_bytes([bytes.u8(), bytes.u8()])) % e.pixels();
        let value = bytes.f32();
        match which {
            0 => new.r_mut()[index] = value,
            1 => new.g_mut()[index] = value,
            2 => new.b_mut()[index] = value,
            3 => history.r_mut()[index] = value,
            4 => history.g_mut()[index] = value,
            5 => history.b_mut()[index] = value,
            6 => len.as_mut_slice()[index] = value,
            7 => {
                if let Some(c) = &mut confidence {
                    // Mostly within [0, 1], sometimes anything.
                    c.as_mut_slice()[index] = if value.to_bits() % 16 == 0 { value } else { value.abs().fract() };
                }
            }
            8 => {
                let code = value.to_bits() as u8;
                reason.as_mut_slice()[index] = if code < 250 { code % 6 } else { code };
            }
            _ => {
                if let Some(m) = &mut pixel_mask {
                    m.as_mut_slice()[index] = value.to_bits() as u8 % 3;
                }
            }
        }
    }
    let codes_defined = reason.as_slice().iter().all(|&c| usize::from(c) < crate::reproject::REASON_COUNT);
    // With a pixel mask the EMA reads (and checks) lengths and confidences only where it is set.
    let read = |i: usize| pixel_mask.as_ref().is_none_or(|m| m.as_slice()[i] != 0);
    let lengths_are_counts = (0..e.pixels()).filter(|&i| read(i)).all(|i| {
        (0.0..=f32::MAX).contains(&len.as_slice()[i])
            && confidence.as_ref().is_none_or(|c| (0.0..=1.0).contains(&c.as_slice()[i]))
    });
    let history_finite = history.planes().into_iter().all(all_finite);
    let params = EmaParams { alpha, ramp, band_rows: 2 };
    let input = EmaInput {
        new: new.view(),
        reason: reason.view(),
        has_new: None,
        confidence: confidence.as_ref().map(|c| c.view()),
        pixel_mask: pixel_mask.as_ref().map(|m| m.view()),
    };
    let run = |simd: bool| {
        let (mut acc, mut n) = (history.clone(), len.clone());
        let state = EmaState { accum: acc.view_mut(), history_len: Some(n.view_mut()) };
        let stats =
            if simd { accumulate::ema(&input, state, &params) } else { accumulate::ema_scalar(&input, state, &params) };
        (stats, acc, n)
    };
    let (stats, acc, n) = run(true);
    let (stats_ref, acc_ref, n_ref) = run(false);
    // Compared as text: a refusal may carry a NaN, which is not equal to itself.
    assert_eq!(format!("{stats:?}"), format!("{stats_ref:?}"));
    for (a, b) in [(acc.r(), acc_ref.r()), (acc.g(), acc_ref.g()), (acc.b(), acc_ref.b()), (&n, &n_ref)] {
        assert_bits("EMA", a, b);
    }
    match &stats {
        Ok(_) => assert!(codes_defined && lengths_are_counts, "the EMA took an undefined code or length"),
        Err(e) => {
            assert!(matches!(e, FrameError::ValueOutOfRange { .. }), "EMA refused with {e}");
            assert!(!(codes_defined && lengths_are_counts), "the EMA refused defined codes and counts: {e}");
            for (a, b) in [(acc.r(), history.r()), (acc.g(), history.g()), (acc.b(), history.b()), (&n, &len)] {
                assert_bits("a refused EMA wrote", a, b);
            }
        }
    }
    if let (Some(mask), Ok(_)) = (&pixel_mask, &stats) {
        // Outside the mask nothing moved.
        for (i, _) in mask.as_slice().iter().enumerate().filter(|(_, m)| **m == 0) {
            for (a, b) in [(acc.r(), history.r()), (acc.g(), history.g()), (acc.b(), history.b()), (&n, &len)] {
                assert_eq!(a.as_slice()[i].to_bits(), b.as_slice()[i].to_bits(), "the EMA wrote outside its mask");
            }
        }
    }
    if history_finite && stats.is_ok() {
        for p in acc.planes() {
            assert!(all_finite(p), "a non-finite sample entered the history");
        }
    }
    let blend_params = BlendParams { own_weight, band_rows: 3 };
    let run = |simd: bool| {
        let mut out = history.clone();
        let f = if simd { accumulate::blend } else { accumulate::blend_scalar };
        let stats = f(&new.view(), out.view_mut(), &reason.view(), &blend_params);
        (stats, out)
    };
    let (stats, out) = run(true);
    let (stats_ref, out_ref) = run(false);
    assert_eq!(stats, stats_ref);
    assert_eq!(stats.is_ok(), codes_defined, "the blend refuses exactly the undefined codes: {stats:?}");
    for (a, b) in [(out.r(), out_ref.r()), (out.g(), out_ref.g()), (out.b(), out_ref.b())] {
        assert_bits("blend", a, b);
    }
    if stats.is_err() {
        for (a, b) in [(out.r(), history.r()), (out.g(), history.g()), (out.b(), history.b())] {
            assert_bits("a refused blend wrote", a, b);
        }
    }
}

/// Fuzzes SSIM: two images over a small extent (1×1 up to 40×24), edited anywhere with any
/// f32. Both variants, any band height. Extents below the 11×11 window must be refused by
/// both bodies; from 11×11 up (where the window's replicate padding still covers most
/// voxels):
/// Checks the SIMD body against the f64 scalar reference (the counts exactly, SSIM and RMSE to
/// [`crate::ssim::CHECK_TOLERANCE`]), symmetry bit for bit, SSIM within [−1, 1] and RMSE
/// finite and non-negative whenever any sample was usable, NaN exactly when none was.
pub fn ssim(data: &[u8]) {
    use crate::ssim::{self as s, SsimParams, SsimVariant};
    let mut bytes = Bytes(data);
    let extent = {
        let (w, h) = (1 + usize::from(bytes.u8() % 40), 1 + usize::from(bytes.u8() % 24));
        Extent::new(w, h).expect("small extent")
    };
    let variant = if bytes.u8() % 2 == 0 { SsimVariant::Volume } else { SsimVariant::PerChannel };
    let params = SsimParams { variant, band_rows: 1 + usize::from(bytes.u8() % 16) };
    // A smooth base (so the constant-image and gradient cases both come up), then edits.
    let (base_a, base_b, slope) = (bytes.unit(-2.0, 2.0), bytes.unit(-2.0, 2.0), bytes.unit(-0.5, 0.5));
    let mut a = RgbBuf::new(extent, base_a);
    let mut b = RgbBuf::new(extent, base_b);
    for i in 0..extent.pixels() {
        let v = slope * (i % extent.width()) as f32;
        a.r_mut()[i] += v;
        b.g_mut()[i] -= v;
    }
    while !bytes.is_empty() {
        let which = bytes.u8() % 6;
        let index = usize::from(u16::from_le_bytes([bytes.u8(), bytes.u8()])) % extent.pixels();
        let value = bytes.f32();
        let plane = match which {
            0 => a.r_mut(),
            1 => a.g_mut(),
            2 => a.b_mut(),
            3 => b.r_mut(),
            4 => b.g_mut(),
            _ => b.b_mut(),
        };
        plane[index] = value;
    }
    if extent.width() < s::MIN_SIDE || extent.height() < s::MIN_SIDE {
        let refused = FrameError::SmallerThanWindow { extent, window: s::MIN_SIDE };
        assert_eq!(s::ssim(&a.view(), &b.view(), &params).err(), Some(refused.clone()));
        assert_eq!(s::ssim_scalar(&a.view(), &b.view(), &params).err(), Some(refused));
        return;
    }
    // With `check-scalar` (the fuzz build) `ssim` compares itself with `ssim_scalar`;
    // without it, the comparison is made here. Either way one f64 reference per input,
    // not one per SSIM call.
    let fast = s::ssim(&a.view(), &b.view(), &params).expect("validated input");
    #[cfg(not(feature = "check-scalar"))]
    {
        let reference = s::ssim_scalar(&a.view(), &b.view(), &params).expect("validated input");
        s::assert_agrees(&fast, &reference, s::CHECK_TOLERANCE);
    }
    let swapped = s::ssim_unchecked(&b.view(), &a.view(), &params, Isa::active()).expect("validated input");
    // Every other instruction set this CPU has: the same voxels (counts exactly), the means
    // equal up to the order in which lanes sum a row.
    for isa in Isa::supported().filter(|&isa| isa != Isa::active()) {
        let other = s::ssim_unchecked(&a.view(), &b.view(), &params, isa).expect("validated input");
        s::assert_isas_agree(&fast, &other);
    }
    // Bit for bit, except that voxels refined in f64 (ill-conditioned in the first pass) sum
    // in an order that depends on the argument order: the last bits may differ there (found
    // by the fuzzer in CI; the input is a seed).
    let same = |x: f64, y: f64| {
        x.to_bits() == y.to_bits()
            || (x.is_nan() && y.is_nan())
            || (fast.refined > 0 && (x - y).abs() <= 1e-12 * x.abs().max(y.abs()))
    };
    assert!(
        same(fast.ssim, swapped.ssim) && same(fast.rmse, swapped.rmse),
        "SSIM is not symmetric: {fast:?} vs {swapped:?}"
    );
    let samples = 3 * extent.pixels() as u64;
    assert!(fast.voxels <= samples && fast.rmse_samples <= samples && fast.non_finite <= 2 * samples);
    if fast.voxels > 0 {
        assert!((-1.0 - 1e-9..=1.0 + 1e-9).contains(&fast.ssim), "SSIM out of range: {fast:?}");
    } else {
        assert!(fast.ssim.is_nan(), "no usable voxel but SSIM {fast:?}");
    }
    if fast.rmse_samples > 0 {
        assert!(fast.rmse.is_finite() && fast.rmse >= 0.0, "RMSE not finite: {fast:?}");
    } else {
        assert!(fast.rmse.is_nan(), "no usable sample but RMSE {fast:?}");
    }
}

/// Fuzzes temporal gradients: luminance pairs over the strata of a small frame and an
/// optional prior confidence, edited anywhere with any f32, and any gain. A prior outside
/// [0, 1] or a gain that is not finite and ≥ 0 must be
/// refused by both bodies alike with the output untouched; any other input must give the
/// same bits and counts from both, every pixel a confidence in [0, 1], and at most as many
/// changed strata as strata.
pub fn gradient(data: &[u8]) {
    let mut bytes = Bytes(data);
    let e = extent_from(&mut bytes);
    let strata = gradient::strata_extent(e);
    let mut old = PlaneBuf::new(strata, bytes.unit(0.0, 4.0));
    let mut new = PlaneBuf::new(strata, bytes.unit(0.0, 4.0));
    let mut prior = (bytes.u8() % 3 == 0).then(|| PlaneBuf::new(e, bytes.unit(0.0, 1.0)));
    // Mostly a plausible gain, sometimes any f32.
    let gain = if bytes.u8() % 8 == 0 { bytes.f32() } else { bytes.unit(0.0, 8.0) };
    while !bytes.is_empty() {
        let which = bytes.u8() % 3;
        let index = usize::from(u16::from_le_bytes([bytes.u8(), bytes.u8()]));
        let value = bytes.f32();
        match which {
            0 => old.as_mut_slice()[index % strata.pixels()] = value,
            1 => new.as_mut_slice()[index % strata.pixels()] = value,
            _ => {
                if let Some(p) = &mut prior {
                    // Mostly within [0, 1], sometimes anything.
                    p.as_mut_slice()[index % e.pixels()] =
                        if value.to_bits() % 16 == 0 { value } else { value.abs().fract() };
                }
            }
        }
    }
    let prior_ok = prior.as_ref().is_none_or(|p| p.as_slice().iter().all(|v| (0.0..=1.0).contains(v)))
        && gain.is_finite()
        && gain >= 0.0;
    let input = GradientInput { old: old.view(), new: new.view(), prior: prior.as_ref().map(|p| p.view()), gain };
    let run = |simd: bool| {
        let mut out = PlaneBuf::new(e, -2.0f32);
        let f = if simd { gradient::history_confidence } else { gradient::history_confidence_scalar };
        (f(&input, out.view_mut()), out)
    };
    let (stats, out) = run(true);
    let (stats_ref, out_ref) = run(false);
    assert_eq!(format!("{stats:?}"), format!("{stats_ref:?}"));
    assert_bits("history confidence", &out, &out_ref);
    match stats {
        Ok(s) => {
            assert!(prior_ok, "a prior outside [0, 1] or a bad gain was taken");
            assert!(out.as_slice().iter().all(|c| (0.0..=1.0).contains(c)), "a confidence outside [0, 1]");
            assert!(s.changed <= strata.pixels() as u64 && s.samples <= strata.pixels() as u64, "{s:?}");
        }
        Err(err) => {
            let refusal = matches!(err, FrameError::ValueOutOfRange { .. } | FrameError::InvalidParameter(_));
            assert!(!prior_ok && refusal, "refused with {err}");
            assert!(out.as_slice().iter().all(|&c| c == -2.0), "a refused call wrote");
        }
    }
}

/// Fuzzes the variance-guided stereo blend: own and reprojected images, reason codes (~2 %
/// undefined) and both eyes' history lengths, edited anywhere with any f32, any α. Undefined
/// codes, lengths that are not finite counts and an α outside (0, 1] must be refused by both
/// bodies alike with nothing written; anything else must give the same bits and counts from
/// both, and equal lengths everywhere the fixed 50/50 blend's bits.
pub fn variance_blend(data: &[u8]) {
    let mut bytes = Bytes(data);
    let e = extent_from(&mut bytes);
    let alpha = if bytes.u8() % 8 == 0 { bytes.f32() } else { bytes.unit(0.0, 1.0).max(1e-6) };
    let band_rows = 1 + usize::from(bytes.u8() % 4);
    let mut own = RgbBuf::new(e, 1.0);
    let mut reprojected = RgbBuf::new(e, 2.0);
    let mut reason = PlaneBuf::new(e, Reason::Reprojected as u8);
    let mut own_len = PlaneBuf::new(e, bytes.unit(0.0, 20.0));
    let mut other_len = PlaneBuf::new(e, bytes.unit(0.0, 20.0));
    while !bytes.is_empty() {
        let which = bytes.u8() % 9;
        let index = usize::from(u16::from_le_bytes([bytes.u8(), bytes.u8()])) % e.pixels();
        let value = bytes.f32();
        match which {
            0 => own.r_mut()[index] = value,
            1 => own.g_mut()[index] = value,
            2 => own.b_mut()[index] = value,
            3 => reprojected.r_mut()[index] = value,
            4 => reprojected.g_mut()[index] = value,
            5 => reprojected.b_mut()[index] = value,
            6 => own_len.as_mut_slice()[index] = value,
            7 => other_len.as_mut_slice()[index] = value,
            _ => {
                let code = value.to_bits() as u8;
                reason.as_mut_slice()[index] = if code < 250 { code % 6 } else { code };
            }
        }
    }
    let counts = |p: &PlaneBuf| p.as_slice().iter().all(|&v| (0.0..=f32::MAX).contains(&v));
    let acceptable = reason.as_slice().iter().all(|&c| usize::from(c) < crate::reproject::REASON_COUNT)
        && counts(&own_len)
        && counts(&other_len)
        && alpha > 0.0
        && alpha <= 1.0;
    let lengths = accumulate::BlendLengths { own: own_len.view(), other: other_len.view(), alpha };
    let run = |simd: bool| {
        let mut out = reprojected.clone();
        let f = if simd { accumulate::blend_by_variance } else { accumulate::blend_by_variance_scalar };
        (f(&own.view(), out.view_mut(), &reason.view(), &lengths, band_rows), out)
    };
    let (stats, out) = run(true);
    let (stats_ref, out_ref) = run(false);
    assert_eq!(format!("{stats:?}"), format!("{stats_ref:?}"));
    for (a, b) in [(out.r(), out_ref.r()), (out.g(), out_ref.g()), (out.b(), out_ref.b())] {
        assert_bits("variance blend", a, b);
    }
    assert_eq!(stats.is_ok(), acceptable, "the variance blend refuses exactly the bad inputs: {stats:?}");
    if stats.is_err() {
        for (a, b) in [(out.r(), reprojected.r()), (out.g(), reprojected.g()), (out.b(), reprojected.b())] {
            assert_bits("a refused variance blend wrote", a, b);
        }
        return;
    }
    if own_len.as_slice() == other_len.as_slice() {
        let mut fixed = reprojected.clone();
        let params = BlendParams { own_weight: 0.5, band_rows };
        accumulate::blend(&own.view(), fixed.view_mut(), &reason.view(), &params).expect("accepted above");
        for (a, b) in [(out.r(), fixed.r()), (out.g(), fixed.g()), (out.b(), fixed.b())] {
            assert_bits("variance blend of equal lengths against 50/50", a, b);
        }
    }
}

/// Fuzzes the neighbourhood clamp: a history and this frame's samples, a new-sample mask
/// and reason codes (~2 % undefined), edited anywhere with any f32 (NaN, ±∞, huge), any γ
/// and sample minimum. Undefined codes and parameters out of range must be refused by both
/// bodies alike with nothing written; anything else must give the same bits and counts from
/// both, move only valid, finite histories of pixels with a sample, and only into the range
/// of the samples around them (checked here by brute force), and leave nothing to clamp a
/// second time.
pub fn clamp(data: &[u8]) {
    let mut bytes = Bytes(data);
    let e = extent_from(&mut bytes);
    let gamma = if bytes.u8() % 8 == 0 { bytes.f32() } else { bytes.unit(0.0, 3.0).max(1e-3) };
    let min_samples = if bytes.u8() % 8 == 0 { u32::from(bytes.u8()) } else { 1 + u32::from(bytes.u8() % 9) };
    let params = ClampParams { gamma, min_samples, band_rows: 1 + usize::from(bytes.u8() % 4) };
    let mut history = RgbBuf::new(e, bytes.unit(0.0, 4.0));
    let mut new = RgbBuf::new(e, bytes.unit(0.0, 4.0));
    let mut has_new = (bytes.u8() % 2 == 0).then(|| PlaneBuf::new(e, 1u8));
    let mut reason = PlaneBuf::new(e, Reason::Reprojected as u8);
    while !bytes.is_empty() {
        let which = bytes.u8() % 8;
        let index = usize::from(u16::from_le_bytes([bytes.u8(), bytes.u8()])) % e.pixels();
        let value = bytes.f32();
        match which {
            0 => history.r_mut()[index] = value,
            1 => history.g_mut()[index] = value,
            2 => history.b_mut()[index] = value,
            3 => new.r_mut()[index] = value,
            4 => new.g_mut()[index] = value,
            5 => new.b_mut()[index] = value,
            6 => {
                if let Some(m) = &mut has_new {
                    m.as_mut_slice()[index] = (value.to_bits() % 3) as u8;
                }
            }
            _ => {
                let code = value.to_bits() as u8;
                reason.as_mut_slice()[index] = if code < 250 { code % 6 } else { code };
            }
        }
    }
    let acceptable = reason.as_slice().iter().all(|&c| usize::from(c) < crate::reproject::REASON_COUNT)
        && gamma.is_finite()
        && gamma > 0.0
        && (1..=9).contains(&min_samples);
    let input = ClampInput { new: new.view(), has_new: has_new.as_ref().map(|m| m.view()), reason: reason.view() };
    let run = |simd: bool, from: &RgbBuf| {
        let mut out = from.clone();
        let f = if simd { clamp::clamp_history } else { clamp::clamp_history_scalar };
        (f(&input, out.view_mut(), &params), out)
    };
    let (stats, out) = run(true, &history);
    let (stats_ref, out_ref) = run(false, &history);
    assert_eq!(format!("{stats:?}"), format!("{stats_ref:?}"));
    for (a, b) in [(out.r(), out_ref.r()), (out.g(), out_ref.g()), (out.b(), out_ref.b())] {
        assert_bits("clamped history", a, b);
    }
    assert_eq!(stats.is_ok(), acceptable, "the clamp refuses exactly the bad inputs: {stats:?}");
    let Ok(stats) = stats else {
        for (a, b) in [(out.r(), history.r()), (out.g(), history.g()), (out.b(), history.b())] {
            assert_bits("a refused clamp wrote", a, b);
        }
        return;
    };
    assert!(stats.clamped <= stats.checked && stats.checked <= e.pixels() as u64, "{stats:?}");
    let sample = |x: usize, y: usize| {
        let present = has_new.as_ref().is_none_or(|m| m.as_slice()[y * e.width() + x] != 0);
        let v = new.get(x, y);
        (present && v.iter().all(|c| c.is_finite())).then_some(v)
    };
    let mut moved = 0;
    for y in 0..e.height() {
        for x in 0..e.width() {
            let (before, after) = (history.get(x, y), out.get(x, y));
            if before.iter().zip(&after).all(|(a, b)| same_bits(*a, *b)) {
                continue;
            }
            moved += 1;
            assert!(reason.as_slice()[y * e.width() + x] == Reason::Reprojected as u8, "moved an invalid history");
            assert!(sample(x, y).is_some() && before.iter().all(|c| c.is_finite()), "moved at ({x}, {y})");
            let around: Vec<[f32; 3]> = (y.saturating_sub(1)..(y + 2).min(e.height()))
                .flat_map(|ny| (x.saturating_sub(1)..(x + 2).min(e.width())).map(move |nx| (nx, ny)))
                .filter_map(|(nx, ny)| sample(nx, ny))
                .collect();
            assert!(around.len() >= min_samples as usize, "moved with {} samples", around.len());
            for c in 0..3 {
                let lo = around.iter().map(|v| v[c]).fold(f32::INFINITY, f32::min);
                let hi = around.iter().map(|v| v[c]).fold(f32::NEG_INFINITY, f32::max);
                assert!(
                    after[c] == before[c] || (lo <= after[c] && after[c] <= hi),
                    "({x}, {y}) channel {c}: {} outside [{lo}, {hi}]",
                    after[c]
                );
            }
        }
    }
    assert_eq!(moved, stats.clamped, "the count of moved pixels");
    let (again, twice) = run(true, &out);
    assert_eq!(again.expect("accepted above").clamped, 0, "a clamped history clamped again");
    for (a, b) in [(twice.r(), out.r()), (twice.g(), out.g()), (twice.b(), out.b())] {
        assert_bits("a second clamp", a, b);
    }
}

/// Fuzzes the à-trous filter: an analytic room's G-buffer and colour (depth steps, a slanted
/// floor, sky) at up to 64×40 pixels (so every step up to 4 reaches the SIMD body), edited
/// anywhere with any f32 (NaN, ±∞, huge or negative colours and depths, raw octahedral
/// normals), with either normal layout, any number of passes and any sigmas. Too many iterations
/// and sigmas that are not finite and positive must be refused by both bodies alike with
/// nothing written; anything else must give the same bits and counts from both, every output
/// value in [0, `VALUE_MAX`], a finite variance, and the sky (no surface) its clamped input.
pub fn atrous(data: &[u8]) {
    let mut bytes = Bytes(data);
    let extent = Extent::new(1 + usize::from(bytes.u8() % 64), 1 + usize::from(bytes.u8() % 40)).expect("small extent");
    let camera = camera_at(Vec3::new(bytes.unit(-0.3, 0.3), 0.0, 0.0), extent, bytes.unit(20.0, 100.0));
    let mut frame = AnalyticScene::room(bytes.unit(1.0, 12.0)).render(&camera, [0.2, 0.3, 0.5]);
    let octahedral = bytes.u8() % 2 == 0;
    let sigma =
        |bytes: &mut Bytes<'_>, plausible: f32| if bytes.u8().is_multiple_of(8) { bytes.f32() } else { plausible };
    let params = atrous::AtrousParams {
        // Mostly 0–6 passes (step 32 is past any SIMD body at these sizes), sometimes the
        // largest accepted (10) or too many (11–14).
        iterations: match bytes.u8() % 16 {
            15 => 11 + u32::from(bytes.u8() % 4),
            14 => atrous::MAX_ITERATIONS,
            v => u32::from(v % 7),
        },
        sigma_luminance: sigma(&mut bytes, 4.0),
        sigma_depth: sigma(&mut bytes, 1.0),
        band_rows: 1 + usize::from(bytes.u8() % 8),
    };
    apply_edits(&mut bytes, &mut frame);
    let acceptable = params.iterations <= atrous::MAX_ITERATIONS
        && [params.sigma_luminance, params.sigma_depth].iter().all(|s| s.is_finite() && *s > 0.0);
    let g = &frame.surfaces;
    let normals = if octahedral {
        atrous::GuideNormals::Octahedral(g.normal_oct.view())
    } else {
        atrous::GuideNormals::Planes(g.normal.each_ref().map(|p| p.view()))
    };
    let guide = atrous::AtrousGuide { depth: g.depth.view(), normals };
    let run = |simd: bool| {
        let mut scratch = atrous::AtrousScratch::try_new(extent).expect("small scratch");
        let mut out = RgbBuf::new(extent, -3.0);
        let f = if simd { atrous::atrous } else { atrous::atrous_scalar };
        let stats = f(&frame.colour.view(), &guide, &params, &mut scratch, out.view_mut());
        let variance = scratch.variance(params.iterations.min(atrous::MAX_ITERATIONS)).clone();
        (stats, out, variance)
    };
    let (stats, out, variance) = run(true);
    let (stats_ref, out_ref, variance_ref) = run(false);
    assert_eq!(format!("{stats:?}"), format!("{stats_ref:?}"));
    for (a, b) in [(out.r(), out_ref.r()), (out.g(), out_ref.g()), (out.b(), out_ref.b())] {
        assert_bits("à-trous colour", a, b);
    }
    assert_eq!(stats.is_ok(), acceptable, "the filter refuses exactly the bad parameters: {stats:?}");
    if stats.is_err() {
        assert!(out.planes().iter().all(|p| p.as_slice().iter().all(|&v| v == -3.0)), "a refused call wrote");
        return;
    }
    assert_bits("à-trous variance", &variance, &variance_ref);
    assert!(all_finite(&variance), "a variance that is not finite");
    for p in out.planes() {
        assert!(p.as_slice().iter().all(|v| (0.0..=atrous::VALUE_MAX).contains(v)), "a colour outside [0, max]");
    }
    for (i, &z) in g.depth.as_slice().iter().enumerate() {
        if !(z > 0.0 && z < f32::INFINITY) {
            for (o, input) in out.planes().into_iter().zip(frame.colour.planes()) {
                let v = input.as_slice()[i];
                let clamped = if v > atrous::VALUE_MAX {
                    atrous::VALUE_MAX
                } else if v > 0.0 {
                    v
                } else {
                    0.0
                };
                assert!(same_bits(o.as_slice()[i], clamped), "the sky changed at {i}");
            }
        }
    }
}
