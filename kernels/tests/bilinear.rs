//! Bilinear resampling: the SIMD body against the scalar reference on edge values, random
//! and coherent maps, and against a closed form on a linear ramp.

use stereotrace_kernels::bilinear::{self, ResampleInput, ResampleOutput};
use stereotrace_kernels::check::assert_planes_equal;
use stereotrace_kernels::frame::{Extent, PlaneBuf, RgbBuf};
use stereotrace_kernels::synth::{EDGE_VALUES, Rng, random_rgb_in};

fn extent(w: usize, h: usize) -> Extent {
    Extent::new(w, h).unwrap()
}

fn assert_same_planes(what: &str, a: &PlaneBuf, b: &PlaneBuf) {
    assert_planes_equal(what, 0, &a.view(), &b.view());
}

fn resample_both(src: &RgbBuf, valid: Option<&PlaneBuf<u8>>, mx: &PlaneBuf, my: &PlaneBuf) -> [(RgbBuf, PlaneBuf); 2] {
    let input =
        ResampleInput { source: src.view(), source_valid: valid.map(|v| v.view()), map_x: mx.view(), map_y: my.view() };
    [true, false].map(|simd| {
        let mut colour = RgbBuf::new(mx.extent(), -1.0);
        let mut weight = PlaneBuf::new(mx.extent(), -1.0);
        let out = ResampleOutput { colour: colour.view_mut(), weight: weight.view_mut() };
        if simd {
            bilinear::resample(&input, out).unwrap()
        } else {
            bilinear::resample_scalar(&input, out).unwrap()
        }
        (colour, weight)
    })
}

#[test]
fn bilinear_simd_equals_scalar_on_edge_values_and_random_maps() {
    let mut rng = Rng::new(3);
    for case in 0..80 {
        let se = extent(1 + rng.below(20), 1 + rng.below(6));
        let te = extent([1, 7, 8, 9, 17, 31][case % 6], 1 + rng.below(5));
        let src = random_rgb_in(se, &mut rng, 0.3, (-2.0, 5.0));
        let coordinate = |rng: &mut Rng, size: usize| {
            if rng.next_f32() < 0.2 {
                EDGE_VALUES[rng.below(EDGE_VALUES.len())]
            } else if rng.next_f32() < 0.3 {
                // Exactly on centres and edges.
                (rng.below(size + 2) as f32 - 1.0) + [0.0, 0.5, 0.5 + 1e-4][rng.below(3)]
            } else {
                rng.range(-2.0, size as f32 + 2.0)
            }
        };
        let mx = PlaneBuf::from_vec((0..te.pixels()).map(|_| coordinate(&mut rng, se.width())).collect(), te).unwrap();
        let my = PlaneBuf::from_vec((0..te.pixels()).map(|_| coordinate(&mut rng, se.height())).collect(), te).unwrap();
        let valid = PlaneBuf::from_vec((0..se.pixels()).map(|_| (rng.next_f32() < 0.8) as u8).collect(), se).unwrap();
        for mask in [None, Some(&valid)] {
            let [(ca, wa), (cb, wb)] = resample_both(&src, mask, &mx, &my);
            for (a, b) in [(ca.r(), cb.r()), (ca.g(), cb.g()), (ca.b(), cb.b()), (&wa, &wb)] {
                assert_same_planes("resample", a, b);
            }
            assert!(wa.as_slice().iter().all(|w| (0.0..=1.0).contains(w)));
        }
    }
}

/// Shifted and slightly scaled maps make most 8-pixel groups coherent (consecutive source
/// columns on one row), the contiguous-load path; groups that straddle a repeated column,
/// the frame border or a NaN fall back to gathers. Both must equal the scalar reference.
#[test]
fn bilinear_simd_equals_scalar_on_coherent_shifted_maps() {
    let mut rng = Rng::new(11);
    for case in 0..40 {
        let se = extent(9 + rng.below(40), 2 + rng.below(6));
        let te = extent([8, 9, 16, 17, 31, 40][case % 6], 1 + rng.below(5));
        let src = random_rgb_in(se, &mut rng, 0.1, (-2.0, 5.0));
        let (shift_x, shift_y) = (rng.range(-3.0, 6.0), rng.range(-1.0, 2.0));
        let scale = [1.0, 0.993, 1.01][case % 3];
        let mut mx: Vec<f32> = (0..te.pixels()).map(|i| (i % te.width()) as f32 * scale + 0.5 + shift_x).collect();
        if case % 4 == 0 {
            mx[rng.below(te.pixels())] = f32::NAN;
        }
        let mx = PlaneBuf::from_vec(mx, te).unwrap();
        let my = PlaneBuf::from_vec((0..te.pixels()).map(|i| (i / te.width()) as f32 + 0.5 + shift_y).collect(), te)
            .unwrap();
        let valid = PlaneBuf::from_vec((0..se.pixels()).map(|_| (rng.next_f32() < 0.85) as u8).collect(), se).unwrap();
        for mask in [None, Some(&valid)] {
            let [(ca, wa), (cb, wb)] = resample_both(&src, mask, &mx, &my);
            for (a, b) in [(ca.r(), cb.r()), (ca.g(), cb.g()), (ca.b(), cb.b()), (&wa, &wb)] {
                assert_same_planes("coherent resample", a, b);
            }
        }
    }
}

#[test]
fn bilinear_interpolates_a_linear_ramp_exactly_enough() {
    let se = extent(16, 8);
    let ramp = PlaneBuf::from_vec((0..se.pixels()).map(|i| (i % 16) as f32 + 0.5).collect(), se).unwrap();
    let src = RgbBuf::from_planes(ramp.clone(), ramp.clone(), ramp).unwrap();
    let te = extent(9, 1);
    let xs = [0.5f32, 1.0, 1.25, 3.75, 8.0, 10.3, 15.5, 0.0, 16.0];
    let mx = PlaneBuf::from_vec(xs.to_vec(), te).unwrap();
    let my = PlaneBuf::new(te, 4.0);
    let [(c, w), _] = resample_both(&src, None, &mx, &my);
    for (i, &x) in xs.iter().enumerate() {
        // At the border (x < 0.5 or x > 15.5) renormalisation keeps the only in-frame column.
        let want = x.clamp(0.5, 15.5);
        assert!((c.r().as_slice()[i] - want).abs() < 1e-5, "{x}: {}", c.r().as_slice()[i]);
        assert!(w.as_slice()[i] > 0.0);
    }
}
