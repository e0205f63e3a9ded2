//! The neighbourhood clamp: the SIMD body against the scalar reference on edge values and
//! seeded random inputs, the box against its closed form computed here in f64, and the hard
//! cases (a constant image, a firefly, frame borders and corners, pixels that must be left
//! alone, bad input refused with nothing written).

use stereotrace_kernels::clamp::{self, ClampInput, ClampParams, ClampStats};
use stereotrace_kernels::frame::{Extent, FrameError, PlaneBuf, RgbBuf};
use stereotrace_kernels::reproject::Reason;
use stereotrace_kernels::synth::{Rng, random_rgb};

const REPROJECTED: u8 = Reason::Reprojected as u8;

fn extent(w: usize, h: usize) -> Extent {
    Extent::new(w, h).unwrap()
}

fn run(input: &ClampInput<'_>, history: &RgbBuf, params: &ClampParams, simd: bool) -> (ClampStats, RgbBuf) {
    let mut out = history.clone();
    let stats = if simd {
        clamp::clamp_history(input, out.view_mut(), params)
    } else {
        clamp::clamp_history_scalar(input, out.view_mut(), params)
    };
    (stats.unwrap(), out)
}

fn same_bits(a: &RgbBuf, b: &RgbBuf) -> bool {
    [(a.r(), b.r()), (a.g(), b.g()), (a.b(), b.b())]
        .iter()
        .all(|(a, b)| a.as_slice().iter().zip(b.as_slice()).all(|(x, y)| x.to_bits() == y.to_bits()))
}

#[test]
fn simd_equals_scalar_on_edge_values_and_random_inputs() {
    let mut rng = Rng::new(33);
    for case in 0..120 {
        // Widths around the SIMD body's limits: shorter than a vector with its neighbours,
        // exactly one, and tails.
        let e = extent([1, 2, 8, 9, 10, 11, 17, 18, 25, 64, 100][case % 11], 1 + rng.below(9));
        let edge_share = if case % 3 == 0 { 0.3 } else { 0.0 };
        let history = random_rgb(e, &mut rng, edge_share);
        let new = random_rgb(e, &mut rng, edge_share);
        let has_new = PlaneBuf::from_vec((0..e.pixels()).map(|_| u8::from(rng.below(5) != 0)).collect(), e).unwrap();
        let reason = PlaneBuf::from_vec(
            (0..e.pixels()).map(|_| if rng.below(4) == 0 { rng.below(6) as u8 } else { REPROJECTED }).collect(),
            e,
        )
        .unwrap();
        let params = ClampParams {
            gamma: [1.0, 0.5, 2.5, 1e-3][case % 4],
            min_samples: 1 + rng.below(9) as u32,
            band_rows: 1 + rng.below(4),
        };
        let input =
            ClampInput { new: new.view(), has_new: (case % 2 == 0).then(|| has_new.view()), reason: reason.view() };
        let (stats, simd) = run(&input, &history, &params, true);
        let (stats_ref, scalar) = run(&input, &history, &params, false);
        assert_eq!(stats, stats_ref, "case {case} {e:?}");
        assert!(same_bits(&simd, &scalar), "case {case} {e:?}: SIMD differs from the scalar reference");
    }
}

/// The box of pixel `(x, y)`'s neighbourhood in f64, from the definition.
fn box_f64(new: &RgbBuf, x: usize, y: usize, c: usize, gamma: f64) -> (f64, f64) {
    let e = new.extent();
    let mut v = Vec::new();
    for ny in y.saturating_sub(1)..(y + 2).min(e.height()) {
        for nx in x.saturating_sub(1)..(x + 2).min(e.width()) {
            v.push(f64::from(new.get(nx, ny)[c]));
        }
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let sigma = (v.iter().map(|a| (a - mean) * (a - mean)).sum::<f64>() / n).sqrt();
    let (lo, hi) =
        (v.iter().copied().fold(f64::INFINITY, f64::min), v.iter().copied().fold(f64::NEG_INFINITY, f64::max));
    ((mean - gamma * sigma).clamp(lo, hi), (mean + gamma * sigma).clamp(lo, hi))
}

#[test]
fn a_history_outside_the_box_lands_on_its_closed_form_edge_and_one_inside_stays() {
    let mut rng = Rng::new(34);
    let e = extent(37, 11);
    let new = random_rgb(e, &mut rng, 0.0);
    let reason = PlaneBuf::new(e, REPROJECTED);
    let input = ClampInput { new: new.view(), has_new: None, reason: reason.view() };
    let params = ClampParams::default();
    // Far above, far below, and exactly the neighbourhood's mean (inside every box).
    for (name, value) in [("above", Some(50.0f32)), ("below", Some(-50.0)), ("mean", None)] {
        let mut history = RgbBuf::new(e, 0.0);
        for y in 0..e.height() {
            for x in 0..e.width() {
                let mean = |c| {
                    let (lo, hi) = box_f64(&new, x, y, c, 0.0);
                    ((lo + hi) / 2.0) as f32
                };
                history.set(x, y, value.map_or([mean(0), mean(1), mean(2)], |v| [v; 3]));
            }
        }
        let (stats, out) = run(&input, &history, &params, true);
        assert_eq!(stats.checked, e.pixels() as u64);
        for y in 0..e.height() {
            for x in 0..e.width() {
                for c in 0..3 {
                    let (lo, hi) = box_f64(&new, x, y, c, 1.0);
                    let got = f64::from(out.get(x, y)[c]);
                    let want = match value {
                        Some(v) if v > 0.0 => hi,
                        Some(_) => lo,
                        None => f64::from(history.get(x, y)[c]),
                    };
                    assert!((got - want).abs() <= 1e-5 * want.abs().max(1.0), "{name} ({x}, {y}) {c}: {got} != {want}");
                }
            }
        }
    }
}

#[test]
fn a_constant_image_clamps_to_its_exact_constant_and_keeps_its_own_history() {
    for &value in &[0.1f32, 3.3, 1e-30, 7e37] {
        let e = extent(21, 5);
        let new = RgbBuf::new(e, value);
        let reason = PlaneBuf::new(e, REPROJECTED);
        let input = ClampInput { new: new.view(), has_new: None, reason: reason.view() };
        for simd in [true, false] {
            // The same constant in the history: nothing moves, bit for bit.
            let (stats, out) = run(&input, &new, &ClampParams::default(), simd);
            assert_eq!(stats.clamped, 0, "{value}");
            assert!(same_bits(&out, &new), "{value}");
            // Another constant: every pixel becomes exactly this frame's.
            let (stats, out) = run(&input, &RgbBuf::new(e, 2.0 * value + 1.0), &ClampParams::default(), simd);
            assert_eq!(stats.clamped, e.pixels() as u64, "{value}");
            assert!(same_bits(&out, &new), "{value}");
        }
    }
}

#[test]
fn a_firefly_widens_the_box_and_nothing_overflows() {
    let e = extent(20, 6);
    let mut new = RgbBuf::new(e, 1.0);
    new.set(9, 3, [3e38; 3]);
    new.set(3, 2, [f32::INFINITY, f32::NAN, 1.0]); // not a sample: left out of every box
    let reason = PlaneBuf::new(e, REPROJECTED);
    let input = ClampInput { new: new.view(), has_new: None, reason: reason.view() };
    let history = RgbBuf::new(e, 5.0);
    let (stats, out) = run(&input, &history, &ClampParams::default(), true);
    for y in 0..e.height() {
        for x in 0..e.width() {
            let got = out.get(x, y);
            assert!(got.iter().all(|v| v.is_finite()), "({x}, {y}): {got:?}");
            let near_firefly = x.abs_diff(9) <= 1 && y.abs_diff(3) <= 1;
            if (x, y) == (3, 2) {
                assert_eq!(got, [5.0; 3], "a pixel without a sample keeps its history");
            } else if near_firefly {
                // Σv² overflows, so the box is the neighbourhood's min–max: 5 is inside.
                assert_eq!(got, [5.0; 3], "({x}, {y})");
            } else {
                assert_eq!(got, [1.0; 3], "({x}, {y})");
            }
        }
    }
    assert_eq!(stats.clamped, e.pixels() as u64 - 10);
}

#[test]
fn invalid_histories_pixels_without_samples_and_thin_neighbourhoods_are_left_alone() {
    let e = extent(24, 5);
    let new = RgbBuf::new(e, 1.0);
    let mut reason = PlaneBuf::new(e, REPROJECTED);
    reason.as_mut_slice()[30] = Reason::DepthOrPosition as u8;
    let mut has_new = PlaneBuf::new(e, 1u8);
    has_new.as_mut_slice()[40] = 0;
    let mut history = RgbBuf::new(e, 4.0);
    history.set(10, 2, [f32::NAN, 4.0, 4.0]);
    let input = ClampInput { new: new.view(), has_new: Some(has_new.view()), reason: reason.view() };
    let (_, out) = run(&input, &history, &ClampParams::default(), true);
    assert_eq!(out.get(30 % 24, 1), [4.0; 3], "an invalid history");
    assert_eq!(out.get(40 % 24, 1), [4.0; 3], "no sample at the pixel");
    assert!(out.get(10, 2)[0].is_nan() && out.get(10, 2)[1] == 4.0, "a non-finite history");
    assert_eq!(out.get(0, 2), [1.0; 3], "a border pixel has six samples");
    assert_eq!(out.get(0, 0), [1.0; 3], "a corner has four");
    // A corner's four samples are fewer than five: left alone.
    let params = ClampParams { min_samples: 5, ..ClampParams::default() };
    let (_, out) = run(&input, &history, &params, true);
    assert_eq!((out.get(0, 0), out.get(0, 2)), ([4.0; 3], [1.0; 3]));
}

#[test]
fn bad_input_is_refused_and_nothing_written() {
    let e = extent(16, 4);
    let new = RgbBuf::new(e, 1.0);
    let reason = PlaneBuf::new(e, REPROJECTED);
    let small = RgbBuf::new(extent(15, 4), 1.0);
    let mut bad_code = PlaneBuf::new(e, REPROJECTED);
    bad_code.as_mut_slice()[7] = 9;
    let good = ClampInput { new: new.view(), has_new: None, reason: reason.view() };
    let cases: [(ClampInput<'_>, ClampParams); 7] = [
        (good, ClampParams { gamma: 0.0, ..ClampParams::default() }),
        (good, ClampParams { gamma: f32::NAN, ..ClampParams::default() }),
        (good, ClampParams { gamma: f32::INFINITY, ..ClampParams::default() }),
        (good, ClampParams { min_samples: 0, ..ClampParams::default() }),
        (good, ClampParams { min_samples: 10, ..ClampParams::default() }),
        (ClampInput { new: small.view(), ..good }, ClampParams::default()),
        (ClampInput { reason: bad_code.view(), ..good }, ClampParams::default()),
    ];
    for (i, (input, params)) in cases.iter().enumerate() {
        for simd in [true, false] {
            let mut history = RgbBuf::new(e, 9.0);
            let f = if simd { clamp::clamp_history } else { clamp::clamp_history_scalar };
            let err = f(input, history.view_mut(), params).expect_err("refused");
            assert!(
                matches!(
                    err,
                    FrameError::InvalidParameter(_)
                        | FrameError::ValueOutOfRange { .. }
                        | FrameError::ExtentMismatch { .. }
                ),
                "case {i}: {err}"
            );
            assert!(same_bits(&history, &RgbBuf::new(e, 9.0)), "case {i}: a refused clamp wrote");
        }
    }
}
