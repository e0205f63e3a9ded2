//! Temporal gradients: the SIMD body against the scalar reference on edge values and seeded
//! random inputs, and the closed forms (unchanged lighting keeps the history, a light
//! switched off discards it where it fell and nowhere else, the prior multiplies, bad input
//! is refused).

use stereotrace_kernels::check::assert_planes_equal;
use stereotrace_kernels::frame::{Extent, FrameError, PlaneBuf};
use stereotrace_kernels::gradient::{self, GradientInput, GradientStats, STRATUM, strata_extent};
use stereotrace_kernels::synth::Rng;

fn extent(w: usize, h: usize) -> Extent {
    Extent::new(w, h).unwrap()
}

/// A luminance as a fuzzer would pick it: ordinary, zero, negative, huge, infinite, NaN.
fn edge_luma(rng: &mut Rng) -> f32 {
    match rng.below(10) {
        0 => f32::NAN,
        1 => 0.0,
        2 => -rng.range(0.0, 2.0),
        3 => f32::INFINITY,
        4 => 3e38,
        5 => -0.0,
        6 => 1e-40,
        _ => rng.range(0.0, 4.0),
    }
}

fn run(input: &GradientInput<'_>, e: Extent, simd: bool) -> (GradientStats, PlaneBuf) {
    let mut out = PlaneBuf::new(e, -1.0);
    let stats = if simd {
        gradient::history_confidence(input, out.view_mut())
    } else {
        gradient::history_confidence_scalar(input, out.view_mut())
    };
    (stats.unwrap(), out)
}

#[test]
fn simd_equals_scalar_on_edge_values_and_random_inputs() {
    let mut rng = Rng::new(30);
    for case in 0..80 {
        // Widths around the SIMD body's limits: fewer strata than a vector, exactly one
        // vector plus its neighbours, and partial last strata.
        let e = extent([1, 2, 3, 8, 25, 27, 28, 30, 31, 64, 100][case % 11], 1 + rng.below(14));
        let s = strata_extent(e);
        let luma = |rng: &mut Rng| {
            let edges = case % 2 == 0;
            PlaneBuf::from_vec(
                (0..s.pixels()).map(|_| if edges { edge_luma(rng) } else { rng.range(0.0, 2.0) }).collect(),
                s,
            )
            .unwrap()
        };
        let (old, new) = (luma(&mut rng), luma(&mut rng));
        let prior =
            PlaneBuf::from_vec((0..e.pixels()).map(|_| [0.0, 1.0, rng.next_f32()][rng.below(3)]).collect(), e).unwrap();
        let input = GradientInput {
            old: old.view(),
            new: new.view(),
            prior: (case % 3 == 0).then(|| prior.view()),
            gain: [1.0, 0.0, 2.5, 4.0][case % 4],
        };
        let (simd_stats, simd) = run(&input, e, true);
        let (scalar_stats, scalar) = run(&input, e, false);
        assert_eq!(simd_stats, scalar_stats, "case {case}");
        assert_planes_equal("history confidence", 0, &simd.view(), &scalar.view());
        // Every pixel written, each a confidence.
        assert!(simd.as_slice().iter().all(|c| (0.0..=1.0).contains(c)), "case {case}");
    }
}

#[test]
fn unchanged_lighting_keeps_the_history_bit_for_bit() {
    let e = extent(40, 31);
    let s = strata_extent(e);
    let mut rng = Rng::new(4);
    let old = PlaneBuf::from_vec((0..s.pixels()).map(|_| rng.range(0.0, 3.0)).collect(), s).unwrap();
    let input = GradientInput { old: old.view(), new: old.view(), prior: None, gain: 1.0 };
    let (stats, out) = run(&input, e, true);
    assert!(out.as_slice().iter().all(|&c| c == 1.0));
    assert_eq!(stats, GradientStats { samples: s.pixels() as u64, changed: 0 });
}

/// A light over the left 15 pixel columns switches off: the history is discarded (confidence
/// 0) on every stratum whose 3×3 neighbourhood lies in the dark, partly kept on the strata
/// next to the edge, and fully kept (confidence 1) from two strata past the edge.
#[test]
fn a_light_switched_off_discards_the_history_where_it_fell() {
    let e = extent(36, 12);
    let s = strata_extent(e); // 12 × 4
    let old = PlaneBuf::new(s, 2.0);
    let mut new = PlaneBuf::new(s, 2.0);
    for sy in 0..s.height() {
        new.view_mut().row_mut(sy)[..5].fill(0.0);
    }
    let input = GradientInput { old: old.view(), new: new.view(), prior: None, gain: 1.0 };
    let (stats, out) = run(&input, e, true);
    for y in 0..e.height() {
        for x in 0..e.width() {
            let c = out.view().get(x, y);
            match x / STRATUM {
                0..=3 => assert_eq!(c, 0.0, "({x}, {y}) in the dark"),
                4 => assert!(c > 0.0 && c < 1.0, "({x}, {y}) at the edge: {c}"),
                // Stratum 5's neighbourhood includes the dark stratum 4: partly.
                5 => assert!((c - (1.0 - 1.0 / 3.0)).abs() < 1e-6, "({x}, {y}): {c}"),
                _ => assert_eq!(c, 1.0, "({x}, {y}) lit"),
            }
        }
    }
    assert_eq!(stats.changed, 6 * s.height() as u64);
}

#[test]
fn strata_without_a_sample_count_nothing_and_the_prior_multiplies() {
    let e = extent(9, 9);
    let s = strata_extent(e);
    let old = PlaneBuf::new(s, f32::NAN);
    let new = PlaneBuf::new(s, 1.0);
    let prior = PlaneBuf::from_vec((0..e.pixels()).map(|i| (i % 5) as f32 / 4.0).collect(), e).unwrap();
    let input = GradientInput { old: old.view(), new: new.view(), prior: Some(prior.view()), gain: 1.0 };
    let (stats, out) = run(&input, e, true);
    assert_eq!(stats, GradientStats::default());
    assert_eq!(out.as_slice(), prior.as_slice());
    // A firefly's infinite luminance is clamped: its stratum's change stays a number.
    let mut old = PlaneBuf::new(s, 1.0);
    old.view_mut().row_mut(1)[1] = f32::INFINITY;
    let input = GradientInput { old: old.view(), new: new.view(), prior: None, gain: 1.0 };
    let (_, out) = run(&input, e, true);
    assert!(out.as_slice().iter().all(|c| (0.0..=1.0).contains(c)));
    assert!(out.view().get(4, 4) < 1e-6, "{}", out.view().get(4, 4));
}

#[test]
fn bad_input_is_refused() {
    let e = extent(10, 7);
    let s = strata_extent(e);
    let good = PlaneBuf::new(s, 1.0);
    let wrong = PlaneBuf::new(extent(3, 3), 1.0);
    let mut out = PlaneBuf::new(e, 0.0);
    let input = GradientInput { old: wrong.view(), new: good.view(), prior: None, gain: 1.0 };
    assert!(matches!(gradient::history_confidence(&input, out.view_mut()), Err(FrameError::ExtentMismatch { .. })));
    let mut prior = PlaneBuf::new(e, 0.5);
    prior.view_mut().row_mut(6)[9] = f32::NAN;
    let input = GradientInput { old: good.view(), new: good.view(), prior: Some(prior.view()), gain: 1.0 };
    let err = gradient::history_confidence(&input, out.view_mut()).unwrap_err();
    assert!(err.to_string().contains("prior history confidence"), "{err}");
    for gain in [f32::NAN, -1.0, f32::INFINITY] {
        let input = GradientInput { old: good.view(), new: good.view(), prior: None, gain };
        let err = gradient::history_confidence_scalar(&input, out.view_mut()).unwrap_err();
        assert!(err.to_string().contains("gain"), "{err}");
    }
}
