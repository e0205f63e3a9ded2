//! EMA accumulation and the stereo blend: the SIMD bodies against the scalar references on
//! edge values, and the closed forms (a constant stays constant, the EMA converges to the
//! mean, history resets where it was discarded, a 50/50 mix where valid).

use stereotrace_kernels::accumulate::{self, AccumulateStats, BlendParams, EmaInput, EmaParams, EmaState};
use stereotrace_kernels::check::assert_planes_equal;
use stereotrace_kernels::frame::{Extent, PlaneBuf, RgbBuf};
use stereotrace_kernels::reproject::Reason;
use stereotrace_kernels::synth::{Rng, random_rgb};

fn extent(w: usize, h: usize) -> Extent {
    Extent::new(w, h).unwrap()
}

fn assert_same_planes(what: &str, a: &PlaneBuf, b: &PlaneBuf) {
    assert_planes_equal(what, 0, &a.view(), &b.view());
}

fn random_reasons(e: Extent, rng: &mut Rng) -> PlaneBuf<u8> {
    random_reasons_with(e, rng, 0.7)
}

/// Reasons with a share `reprojected` (at least) of [`Reason::Reprojected`], the rest any code.
fn random_reasons_with(e: Extent, rng: &mut Rng, reprojected: f32) -> PlaneBuf<u8> {
    PlaneBuf::from_vec(
        (0..e.pixels()).map(|_| if rng.next_f32() < reprojected { 0 } else { rng.below(6) as u8 }).collect(),
        e,
    )
    .unwrap()
}

/// Odd cases are mostly clean (few edge values, nearly every pixel reprojected), so that the
/// blend's all-clean fast path runs beside groups that fall back to the general one; even
/// cases are dense with edge values.
fn blend_inputs(case: usize, e: Extent, rng: &mut Rng) -> (RgbBuf, RgbBuf, PlaneBuf<u8>) {
    let (edge_share, reprojected) = if case.is_multiple_of(2) { (0.3, 0.7) } else { (0.004, 0.985) };
    let own = random_rgb(e, rng, edge_share);
    let other = random_rgb(e, rng, edge_share);
    (own, other, random_reasons_with(e, rng, reprojected))
}

#[test]
fn ema_simd_equals_scalar_on_edge_values() {
    let mut rng = Rng::new(5);
    for case in 0..60 {
        let e = extent([1, 7, 8, 9, 17, 40, 203][case % 7], 1 + rng.below(5));
        let new = random_rgb(e, &mut rng, 0.3);
        let history = random_rgb(e, &mut rng, 0.1);
        let len = PlaneBuf::from_vec((0..e.pixels()).map(|_| rng.below(40) as f32).collect(), e).unwrap();
        let reason = random_reasons(e, &mut rng);
        let has_new = PlaneBuf::from_vec((0..e.pixels()).map(|_| (rng.next_f32() < 0.8) as u8).collect(), e).unwrap();
        // A history confidence in half the cases: 0, 1, and values between.
        let confidence =
            PlaneBuf::from_vec((0..e.pixels()).map(|_| [0.0, 1.0, rng.next_f32(), 1e-30][rng.below(4)]).collect(), e)
                .unwrap();
        // A pixel mask in two cases of five: sparse (as the paper-order left eye's), dense, or
        // in runs of eight, so that whole groups are skipped and partial ones selected.
        let density = [0.05, 0.9, 0.5][case % 3];
        let in_mask =
            |i: usize, rng: &mut Rng| if case % 2 == 0 { (i / 8).is_multiple_of(3) } else { rng.next_f32() < density };
        let pixel_mask =
            PlaneBuf::from_vec((0..e.pixels()).map(|i| u8::from(in_mask(i, &mut rng))).collect(), e).unwrap();
        let params =
            EmaParams { alpha: [0.2, 1.0, 0.05, 1e-6][case % 4], ramp: case % 2 == 0, band_rows: 1 + rng.below(3) };
        let input = EmaInput {
            new: new.view(),
            reason: reason.view(),
            has_new: (case % 3 != 0).then(|| has_new.view()),
            confidence: (case % 4 < 2).then(|| confidence.view()),
            pixel_mask: (case % 5 < 2).then(|| pixel_mask.view()),
        };
        let run = |simd: bool| {
            let (mut acc, mut n) = (history.clone(), len.clone());
            let state = EmaState { accum: acc.view_mut(), history_len: Some(n.view_mut()) };
            let stats = if simd {
                accumulate::ema(&input, state, &params)
            } else {
                accumulate::ema_scalar(&input, state, &params)
            };
            (stats.unwrap(), acc, n)
        };
        let (sa, aa, na) = run(true);
        let (sb, ab, nb) = run(false);
        assert_eq!(sa, sb);
        for (a, b) in [(aa.r(), ab.r()), (aa.g(), ab.g()), (aa.b(), ab.b()), (&na, &nb)] {
            assert_same_planes("ema", a, b);
        }
        if input.pixel_mask.is_some() {
            // Outside the mask nothing moved; inside it, the unmasked EMA's bits.
            let (mut whole, mut whole_len) = (history.clone(), len.clone());
            let unmasked = EmaInput { pixel_mask: None, ..input };
            let state = EmaState { accum: whole.view_mut(), history_len: Some(whole_len.view_mut()) };
            accumulate::ema_scalar(&unmasked, state, &params).unwrap();
            for i in 0..e.pixels() {
                let (colour, n) = if pixel_mask.as_slice()[i] == 0 { (&history, &len) } else { (&whole, &whole_len) };
                for (out, want) in [(ab.r(), colour.r()), (ab.g(), colour.g()), (ab.b(), colour.b()), (&nb, n)] {
                    assert_eq!(out.as_slice()[i].to_bits(), want.as_slice()[i].to_bits(), "case {case}: pixel {i}");
                }
            }
        }
        // Nothing non-finite enters the history unless it was already there, and what the
        // EMA wrote is flushed (a pixel outside the mask keeps whatever it held).
        for (i, v) in aa.r().as_slice().iter().enumerate() {
            if input.pixel_mask.is_some() && pixel_mask.as_slice()[i] == 0 {
                continue;
            }
            if history.r().as_slice()[i].is_finite() {
                assert!(v.is_finite(), "{v}");
            }
            assert!(v.is_nan() || *v == 0.0 || v.abs() >= f32::MIN_POSITIVE, "subnormal {v}");
        }
    }
}

/// The history confidence against its closed form, and at its ends: 1 is the plain EMA bit
/// for bit, 0 the new sample; values outside [0, 1] are refused.
#[test]
fn history_confidence_scales_the_historys_weight() {
    let e = extent(19, 2);
    let reason = PlaneBuf::new(e, Reason::Reprojected as u8);
    let new = RgbBuf::new(e, 0.0);
    let run = |c: f32, ramp: bool| {
        let mut acc = RgbBuf::new(e, 1.0);
        let mut len = PlaneBuf::new(e, 4.0);
        let conf = PlaneBuf::new(e, c);
        let input = trusting(&new, &reason, &conf);
        let params = EmaParams { alpha: 0.2, ramp, band_rows: 4 };
        accumulate::ema(&input, EmaState { accum: acc.view_mut(), history_len: Some(len.view_mut()) }, &params)
            .unwrap();
        (acc.get(18, 1)[0], len.as_slice()[37])
    };
    // α' = 0.2 + 0.8·(1 − 0.5) = 0.6: 1 + 0.6·(0 − 1) = 0.4; the length 4·0.5 + 1.
    assert!((run(0.5, false).0 - 0.4).abs() < 1e-6 && run(0.5, false).1 == 3.0);
    assert_eq!(run(0.0, false), (0.0, 1.0));
    // The ramp counts the history as c·n samples: n = 4·0.25 = 1, α = max(0.2, 1/2) = 0.5,
    // α' = 0.5 + 0.5·0.75 = 0.875.
    assert!((run(0.25, true).0 - 0.125).abs() < 1e-6);
    let plain = {
        let mut acc = RgbBuf::new(e, 1.0);
        let mut len = PlaneBuf::new(e, 4.0);
        let input =
            EmaInput { new: new.view(), reason: reason.view(), has_new: None, confidence: None, pixel_mask: None };
        let params = EmaParams { alpha: 0.2, ramp: true, band_rows: 4 };
        accumulate::ema(&input, EmaState { accum: acc.view_mut(), history_len: Some(len.view_mut()) }, &params)
            .unwrap();
        (acc.get(18, 1)[0], len.as_slice()[37])
    };
    assert_eq!(run(1.0, true).0.to_bits(), plain.0.to_bits());
    assert_eq!(run(1.0, true).1, plain.1);
    for bad in [-0.01, 1.01, f32::NAN] {
        let mut acc = RgbBuf::new(e, 1.0);
        let conf = PlaneBuf::from_vec((0..e.pixels()).map(|i| if i == 25 { bad } else { 0.5 }).collect(), e).unwrap();
        let input = trusting(&new, &reason, &conf);
        let err = accumulate::ema(&input, EmaState { accum: acc.view_mut(), history_len: None }, &EmaParams::default())
            .unwrap_err();
        assert!(
            err.to_string().contains("history confidence plane holds") && err.to_string().contains("(6, 1)"),
            "{err}"
        );
        assert!(acc.r().as_slice().iter().all(|&v| v == 1.0), "a refused call wrote");
    }
}

/// With a pixel mask the EMA reads the confidence and the length only where the mask is set,
/// and checks only those: a bad value outside the mask (in a group of eight that has masked
/// pixels, or in an empty stretch) is accepted and left as it was, the same value at a masked
/// pixel is refused by name, by both bodies, before anything is written.
#[test]
fn a_masked_ema_checks_the_values_it_reads() {
    // 77 columns: groups of eight, stretches of 32 and a scalar tail of five.
    let e = extent(77, 3);
    let reason = PlaneBuf::new(e, Reason::Reprojected as u8);
    let new = RgbBuf::new(e, 0.0);
    // Set: pixel (9, 1), inside a group with unmasked lanes, and (75, 2), in the tail.
    let masked = [77 + 9, 2 * 77 + 75];
    let mask = PlaneBuf::from_vec((0..e.pixels()).map(|i| u8::from(masked.contains(&i))).collect(), e).unwrap();
    type Ema = fn(&EmaInput<'_>, EmaState<'_>, &EmaParams) -> Result<AccumulateStats, stereotrace_kernels::FrameError>;
    let bodies: [(&str, Ema); 2] = [("SIMD", accumulate::ema), ("scalar", accumulate::ema_scalar)];
    for (body, ema) in bodies {
        for (bad_at, refused) in
            [(77 + 10, None), (2, None), (2 * 77 + 40, None), (77 + 9, Some("(9, 1)")), (2 * 77 + 75, Some("(75, 2)"))]
        {
            for (bad_confidence, bad_length) in [(f32::NAN, 4.0), (0.5, -1.0), (1.5, f32::INFINITY)] {
                let conf = PlaneBuf::from_vec(
                    (0..e.pixels()).map(|i| if i == bad_at { bad_confidence } else { 0.5 }).collect(),
                    e,
                )
                .unwrap();
                let lengths: Vec<f32> = (0..e.pixels()).map(|i| if i == bad_at { bad_length } else { 4.0 }).collect();
                let mut len = PlaneBuf::from_vec(lengths.clone(), e).unwrap();
                let mut acc = RgbBuf::new(e, 1.0);
                let input = EmaInput { pixel_mask: Some(mask.view()), ..trusting(&new, &reason, &conf) };
                let params = EmaParams { alpha: 0.2, ramp: true, band_rows: 2 };
                let result =
                    ema(&input, EmaState { accum: acc.view_mut(), history_len: Some(len.view_mut()) }, &params);
                let what =
                    format!("{body}, bad values at pixel {bad_at}: confidence {bad_confidence}, length {bad_length}");
                match refused {
                    None => {
                        result.unwrap_or_else(|err| panic!("{what}: refused ({err})"));
                        // Only the masked pixels moved; the bad length is as it was.
                        for i in 0..e.pixels() {
                            let kept = !masked.contains(&i);
                            assert_eq!(kept, acc.r().as_slice()[i] == 1.0, "{what}: pixel {i}");
                            if kept {
                                assert_eq!(len.as_slice()[i].to_bits(), lengths[i].to_bits(), "{what}: pixel {i}");
                            }
                        }
                    }
                    Some(pixel) => {
                        let err = result.expect_err(&what).to_string();
                        assert!(err.contains(pixel), "{what}: {err}");
                        assert!(acc.r().as_slice().iter().all(|&v| v == 1.0), "{what}: a refused call wrote");
                    }
                }
            }
        }
    }
}

/// EMA inputs of `new` with a history confidence plane (every pixel, every sample present).
fn trusting<'a>(new: &'a RgbBuf, reason: &'a PlaneBuf<u8>, confidence: &'a PlaneBuf) -> EmaInput<'a> {
    EmaInput {
        new: new.view(),
        reason: reason.view(),
        has_new: None,
        confidence: Some(confidence.view()),
        pixel_mask: None,
    }
}

fn ema_step(acc: &mut RgbBuf, new: &RgbBuf, reason: &PlaneBuf<u8>, params: &EmaParams) -> AccumulateStats {
    let input = EmaInput { new: new.view(), reason: reason.view(), has_new: None, confidence: None, pixel_mask: None };
    accumulate::ema(&input, EmaState { accum: acc.view_mut(), history_len: None }, params).unwrap()
}

#[test]
fn ema_of_a_constant_is_that_constant_and_alpha_one_returns_the_new_sample() {
    let e = extent(21, 3);
    let reason = PlaneBuf::new(e, Reason::Reprojected as u8);
    for c in [0.1f32, 0.7, 3.3, 1e-3, 12345.678, 1e30] {
        let constant = RgbBuf::new(e, c);
        let mut acc = constant.clone();
        for _ in 0..50 {
            ema_step(&mut acc, &constant, &reason, &EmaParams::default());
        }
        assert_eq!(acc, constant, "constant {c}");
    }
    let mut rng = Rng::new(9);
    let new = random_rgb(e, &mut rng, 0.0);
    let mut acc = random_rgb(e, &mut rng, 0.0);
    ema_step(&mut acc, &new, &reason, &EmaParams { alpha: 1.0, ..EmaParams::default() });
    assert_eq!(acc, new);
}

#[test]
fn ema_converges_to_the_mean_and_resets_where_history_was_discarded() {
    let e = extent(9, 1);
    let mut acc = RgbBuf::new(e, 0.0);
    let mut reason = PlaneBuf::new(e, Reason::Reprojected as u8);
    reason.as_mut_slice()[4] = Reason::DepthOrPosition as u8;
    let mut rng = Rng::new(1);
    let mut mean = 0.0f64;
    let frames = 400;
    for _ in 0..frames {
        let v = rng.range(0.0, 2.0);
        mean += f64::from(v) / frames as f64;
        let stats = ema_step(&mut acc, &RgbBuf::new(e, v), &reason, &EmaParams::default());
        assert_eq!(stats.resets, 1);
        assert_eq!(acc.r().as_slice()[4], v, "discarded history resets to the new sample");
    }
    assert!((f64::from(acc.r().as_slice()[0]) - mean).abs() < 0.5, "{} vs {mean}", acc.r().as_slice()[0]);
}

#[test]
fn non_finite_samples_fall_back_to_history_or_become_holes() {
    let e = extent(10, 1);
    let mut new = RgbBuf::new(e, 1.0);
    new.g_mut()[1] = f32::NAN;
    new.b_mut()[2] = f32::INFINITY;
    new.r_mut()[9] = f32::NEG_INFINITY;
    let mut reason = PlaneBuf::new(e, Reason::Reprojected as u8);
    reason.as_mut_slice()[2] = Reason::OutOfFrame as u8;
    let mut acc = RgbBuf::new(e, 5.0);
    let mut len = PlaneBuf::new(e, 3.0f32);
    let input = EmaInput { new: new.view(), reason: reason.view(), has_new: None, confidence: None, pixel_mask: None };
    let stats = accumulate::ema(
        &input,
        EmaState { accum: acc.view_mut(), history_len: Some(len.view_mut()) },
        &EmaParams::default(),
    )
    .unwrap();
    assert_eq!(stats, AccumulateStats { non_finite: 3, holes: 1, resets: 0 });
    assert_eq!(acc.get(1, 0), [5.0; 3]);
    assert_eq!(len.as_slice()[1], 3.0);
    assert_eq!(acc.get(2, 0), [0.0; 3]);
    assert_eq!(len.as_slice()[2], 0.0);
    assert_eq!(acc.get(0, 0), [4.2; 3]);
    assert_eq!(len.as_slice()[0], 4.0);
}

#[test]
fn blend_simd_equals_scalar_and_is_a_50_50_mix_where_valid() {
    let mut rng = Rng::new(21);
    for case in 0..80 {
        let e = extent([1, 7, 8, 9, 17, 40, 203][case % 7], 1 + rng.below(5));
        let (own, other, reason) = blend_inputs(case, e, &mut rng);
        let params = BlendParams { own_weight: [0.5, 0.0, 1.0, 0.3][case % 4], band_rows: 2 };
        let run = |simd: bool| {
            let mut out = other.clone();
            let f = if simd { accumulate::blend } else { accumulate::blend_scalar };
            let stats = f(&own.view(), out.view_mut(), &reason.view(), &params).unwrap();
            (stats, out)
        };
        let (sa, a) = run(true);
        let (sb, b) = run(false);
        assert_eq!(sa, sb);
        for (x, y) in [(a.r(), b.r()), (a.g(), b.g()), (a.b(), b.b())] {
            assert_same_planes("blend", x, y);
        }
    }
    let e = extent(3, 1);
    let own = RgbBuf::new(e, 1.0);
    let mut other = RgbBuf::new(e, 3.0);
    let reason = PlaneBuf::from_vec(vec![0, 1, 0], e).unwrap();
    accumulate::blend(&own.view(), other.view_mut(), &reason.view(), &BlendParams::default()).unwrap();
    assert_eq!(other.r().as_slice(), &[2.0, 1.0, 2.0]);
}

fn random_lengths(e: Extent, rng: &mut Rng) -> PlaneBuf {
    let pick = |rng: &mut Rng| [0.0, 1.0, 2.0, 9.0, 1e9, f32::MAX, rng.range(0.0, 40.0), 0.5][rng.below(8)];
    PlaneBuf::from_vec((0..e.pixels()).map(|_| pick(rng)).collect(), e).unwrap()
}

#[test]
fn variance_blend_simd_equals_scalar_on_edge_values() {
    let mut rng = Rng::new(31);
    for case in 0..60 {
        let e = extent([1, 7, 8, 9, 17, 40, 203][case % 7], 1 + rng.below(5));
        let (own, reprojected, reason) = blend_inputs(case, e, &mut rng);
        let (own_len, other_len) = (random_lengths(e, &mut rng), random_lengths(e, &mut rng));
        let lengths = accumulate::BlendLengths {
            own: own_len.view(),
            other: other_len.view(),
            alpha: [0.2, 1.0, 0.05, 1e-6][case % 4],
        };
        let band_rows = 1 + rng.below(3);
        let run = |simd: bool| {
            let mut out = reprojected.clone();
            let f = if simd { accumulate::blend_by_variance } else { accumulate::blend_by_variance_scalar };
            (f(&own.view(), out.view_mut(), &reason.view(), &lengths, band_rows).unwrap(), out)
        };
        let (sa, a) = run(true);
        let (sb, b) = run(false);
        assert_eq!(sa, sb);
        for (x, y) in [(a.r(), b.r()), (a.g(), b.g()), (a.b(), b.b())] {
            assert_same_planes("variance blend", x, y);
        }
    }
}

/// Equal history lengths are the paper's 50/50 blend bit for bit; an eye whose history just
/// restarted (1 sample) beside a long one (the EMA's steady `α/(2 − α)` = 1/9 of a sample's
/// variance at α = 0.2) takes `t = 1/(1 + 1/9) = 0.9` of the other eye's reprojection.
#[test]
fn variance_blend_is_50_50_for_equal_lengths_and_leans_on_the_longer_history() {
    let e = extent(19, 3);
    let mut rng = Rng::new(32);
    let own = random_rgb(e, &mut rng, 0.0);
    let reprojected = random_rgb(e, &mut rng, 0.0);
    let reason = PlaneBuf::new(e, Reason::Reprojected as u8);
    // A tiny α lets a long history count as up to 2/α samples: the weights' sum must not
    // overflow at the largest lengths.
    for (n, alpha) in [(0.0, 0.2), (1.0, 0.2), (3.5, 0.2), (9.0, 0.2), (1e9, 0.2), (f32::MAX, 1e-38), (f32::MAX, 1e-45)]
    {
        let len = PlaneBuf::new(e, n);
        let lengths = accumulate::BlendLengths { own: len.view(), other: len.view(), alpha };
        let mut by_variance = reprojected.clone();
        accumulate::blend_by_variance(&own.view(), by_variance.view_mut(), &reason.view(), &lengths, 4).unwrap();
        let mut fixed = reprojected.clone();
        accumulate::blend(&own.view(), fixed.view_mut(), &reason.view(), &BlendParams::default()).unwrap();
        assert_eq!(by_variance, fixed, "length {n}");
    }
    let (short, long) = (PlaneBuf::new(e, 1.0), PlaneBuf::new(e, 1e6));
    let lengths = accumulate::BlendLengths { own: short.view(), other: long.view(), alpha: 0.2 };
    let mut out = reprojected.clone();
    accumulate::blend_by_variance(&own.view(), out.view_mut(), &reason.view(), &lengths, 4).unwrap();
    assert!((accumulate::variance_blend_toward(1.0, 1e6, 0.2) - 0.9).abs() < 1e-6);
    for y in 0..3 {
        for x in 0..19 {
            let (o, r, got) = (own.get(x, y), reprojected.get(x, y), out.get(x, y));
            for c in 0..3 {
                let want = o[c] + 0.9 * (r[c] - o[c]);
                assert!((got[c] - want).abs() <= 1e-5 * want.abs().max(1.0), "({x}, {y}) {got:?} {want}");
            }
        }
    }
    // A length that is not a count is refused.
    let bad = PlaneBuf::new(e, f32::NAN);
    let lengths = accumulate::BlendLengths { own: bad.view(), other: long.view(), alpha: 0.2 };
    let mut out = reprojected.clone();
    assert!(accumulate::blend_by_variance(&own.view(), out.view_mut(), &reason.view(), &lengths, 4).is_err());
    assert_eq!(out, reprojected, "a refused blend wrote");
}
