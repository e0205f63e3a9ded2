//! The à-trous filter: the SIMD body against the scalar reference on edge values and seeded
//! random inputs, and closed forms from an independent f64 convolution (on a flat surface
//! with the luminance term off, the filter is the à-trous B3 spline), the noise it removes,
//! and the edges it keeps (depth steps, creases, the sky), and bad input refused.

use stereotrace_kernels::atrous::{self, AtrousGuide, AtrousParams, AtrousScratch, AtrousStats, GuideNormals, KERNEL};
use stereotrace_kernels::check::assert_planes_equal;
use stereotrace_kernels::frame::{Extent, FrameError, PlaneBuf, RgbBuf};
use stereotrace_kernels::synth::{self, AnalyticScene, Rng};

fn extent(w: usize, h: usize) -> Extent {
    Extent::new(w, h).unwrap()
}

/// A G-buffer's guide planes, owned.
struct Guide {
    depth: PlaneBuf,
    normal: [PlaneBuf; 3],
    octahedral: PlaneBuf<u32>,
}

impl Guide {
    fn flat(e: Extent, depth: f32) -> Self {
        Self::from_fn(e, |_, _| (depth, [0.0, 0.0, 1.0]))
    }

    fn from_fn(e: Extent, f: impl Fn(usize, usize) -> (f32, [f32; 3])) -> Self {
        let mut g = Self {
            depth: PlaneBuf::new(e, 0.0),
            normal: [0.0; 3].map(|v| PlaneBuf::new(e, v)),
            octahedral: PlaneBuf::new(e, 0),
        };
        for y in 0..e.height() {
            for x in 0..e.width() {
                let (z, n) = f(x, y);
                let i = y * e.width() + x;
                g.depth.as_mut_slice()[i] = z;
                for c in 0..3 {
                    g.normal[c].as_mut_slice()[i] = n[c];
                }
                g.octahedral.as_mut_slice()[i] = stereotrace_kernels::gbuffer::encode_normal(n);
            }
        }
        g
    }

    fn view(&self, octahedral: bool) -> AtrousGuide<'_> {
        let normals = if octahedral {
            GuideNormals::Octahedral(self.octahedral.view())
        } else {
            GuideNormals::Planes(self.normal.each_ref().map(|p| p.view()))
        };
        AtrousGuide { depth: self.depth.view(), normals }
    }
}

fn filter(
    input: &RgbBuf,
    guide: &AtrousGuide<'_>,
    params: &AtrousParams,
    simd: bool,
) -> (AtrousStats, RgbBuf, PlaneBuf) {
    let e = input.extent();
    let mut scratch = AtrousScratch::try_new(e).unwrap();
    let mut out = RgbBuf::new(e, -1.0);
    let run = if simd { atrous::atrous } else { atrous::atrous_scalar };
    let stats = run(&input.view(), guide, params, &mut scratch, out.view_mut()).unwrap();
    (stats, out, scratch.variance(params.iterations).clone())
}

fn assert_same(what: &str, a: &(AtrousStats, RgbBuf, PlaneBuf), b: &(AtrousStats, RgbBuf, PlaneBuf)) {
    assert_eq!(a.0, b.0, "{what}: stats");
    for c in 0..3 {
        assert_planes_equal(what, c, &a.1.planes()[c].view(), &b.1.planes()[c].view());
    }
    assert_planes_equal(what, 3, &a.2.view(), &b.2.view());
}

#[test]
fn simd_equals_scalar_on_edge_values_and_random_inputs() {
    let mut rng = Rng::new(28);
    for case in 0..48 {
        // Widths around the SIMD body's limits at each step, heights from one row up.
        let e = extent([1, 7, 9, 10, 17, 24, 33, 50, 71, 130][case % 10], 1 + rng.below(40));
        let colour = synth::random_rgb(e, &mut rng, if case % 2 == 0 { 0.2 } else { 0.0 });
        // Depths and normals per pixel: ordinary ones near 1, and a share of edge values.
        let mut guide = Guide::flat(e, 1.0);
        for i in 0..e.pixels() {
            let edge = case % 2 == 0 && rng.below(6) == 0;
            guide.depth.as_mut_slice()[i] = if edge {
                [f32::INFINITY, f32::NAN, 0.0, -1.0, 1e-30, 3e38, f32::NEG_INFINITY][rng.below(7)]
            } else {
                rng.range(1.0, 1.2)
            };
            let n = [rng.range(-0.3, 0.3), rng.range(-0.3, 0.3), 1.0];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let n = if edge && rng.below(2) == 0 { [f32::NAN; 3] } else { n.map(|v| v / len) };
            for c in 0..3 {
                guide.normal[c].as_mut_slice()[i] = n[c];
            }
            guide.octahedral.as_mut_slice()[i] = stereotrace_kernels::gbuffer::encode_normal(n);
        }
        for iterations in [0, 1, 2, 3, 5] {
            let params = AtrousParams {
                iterations,
                sigma_luminance: [4.0, 0.5, 1e6][case % 3],
                sigma_depth: [1.0, 0.1][case % 2],
                band_rows: 1 + case % 5,
            };
            for octahedral in [false, true] {
                let guide = guide.view(octahedral);
                let simd = filter(&colour, &guide, &params, true);
                let scalar = filter(&colour, &guide, &params, false);
                assert_same(&format!("case {case}, {iterations} iterations, octahedral {octahedral}"), &simd, &scalar);
            }
        }
    }
}

#[test]
fn simd_equals_scalar_on_a_rendered_room() {
    // A realistic G-buffer: depth steps at the boxes' edges, a slanted floor, sky.
    let e = extent(97, 61);
    let camera = synth::camera_at(glam::Vec3::new(0.3, 0.2, 0.0), e, 60.0);
    let frame = AnalyticScene::room(6.0).render(&camera, [0.3, 0.5, 0.9]);
    let mut rng = Rng::new(7);
    let mut noisy = frame.colour.clone();
    for p in noisy.slices_mut() {
        for v in p {
            *v *= rng.range(0.0, 2.0);
        }
    }
    let g = &frame.surfaces;
    for octahedral in [false, true] {
        let normals = if octahedral {
            GuideNormals::Octahedral(g.normal_oct.view())
        } else {
            GuideNormals::Planes(g.normal.each_ref().map(|p| p.view()))
        };
        let guide = AtrousGuide { depth: g.depth.view(), normals };
        let params = AtrousParams::default();
        assert_same("room", &filter(&noisy, &guide, &params, true), &filter(&noisy, &guide, &params, false));
    }
}

/// The à-trous B3 spline in f64 (only taps inside the frame, renormalised): what the filter
/// must be on a flat surface with the luminance term off.
fn b3_atrous_f64(img: &[f64], e: Extent, iterations: u32) -> Vec<f64> {
    let (w, h) = (e.width() as isize, e.height() as isize);
    let h1 = [1.0, 4.0, 6.0, 4.0, 1.0].map(|v| v / 16.0);
    let mut cur = img.to_vec();
    for i in 0..iterations {
        let step = 1isize << i;
        let mut next = vec![0.0; cur.len()];
        for y in 0..h {
            for x in 0..w {
                let (mut sum, mut weight) = (0.0, 0.0);
                for (j, hy) in h1.iter().enumerate() {
                    for (k, hx) in h1.iter().enumerate() {
                        let (tx, ty) = (x + (k as isize - 2) * step, y + (j as isize - 2) * step);
                        if (0..w).contains(&tx) && (0..h).contains(&ty) {
                            sum += hx * hy * cur[(ty * w + tx) as usize];
                            weight += hx * hy;
                        }
                    }
                }
                next[(y * w + x) as usize] = sum / weight;
            }
        }
        cur = next;
    }
    cur
}

#[test]
fn on_a_flat_surface_without_the_luminance_term_it_is_the_b3_spline() {
    let e = extent(83, 47);
    let mut rng = Rng::new(3);
    let colour = synth::random_rgb_in(e, &mut rng, 0.0, (0.0, 1.0));
    let guide = Guide::flat(e, 2.5);
    for iterations in [1, 2, 4] {
        // σ_l so large that every luminance exponent rounds to 0: weights are the spline's.
        let params = AtrousParams { iterations, sigma_luminance: 1e30, ..AtrousParams::default() };
        let (_, out, _) = filter(&colour, &guide.view(false), &params, true);
        for c in 0..3 {
            let input: Vec<f64> = colour.planes()[c].as_slice().iter().map(|&v| f64::from(v)).collect();
            let expected = b3_atrous_f64(&input, e, iterations);
            for (i, (&got, want)) in out.planes()[c].as_slice().iter().zip(expected).enumerate() {
                assert!(
                    (f64::from(got) - want).abs() < 2e-6,
                    "{iterations} iterations, pixel {i}: {got} against {want}"
                );
            }
        }
    }
}

#[test]
fn noise_on_a_flat_surface_falls_by_the_splines_closed_form() {
    // One pass of a linear filter with weights w scales white noise's variance by Σw²; for
    // the separable B3 spline Σw² = (Σh²)² = (70/256)².
    let e = extent(256, 256);
    let mut rng = Rng::new(11);
    let colour = synth::random_rgb_in(e, &mut rng, 0.0, (0.0, 1.0));
    let params = AtrousParams { iterations: 1, sigma_luminance: 1e30, ..AtrousParams::default() };
    let (_, out, _) = filter(&colour, &Guide::flat(e, 1.0).view(true), &params, true);
    let interior_variance = |img: &RgbBuf| {
        let values: Vec<f64> = (4..252)
            .flat_map(|y| (4..252).map(move |x| (x, y)))
            .map(|(x, y)| f64::from(img.g().view().get(x, y)))
            .collect();
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / values.len() as f64
    };
    let ratio = interior_variance(&out) / interior_variance(&colour);
    let expected = (70.0f64 / 256.0).powi(2);
    assert!((ratio / expected - 1.0).abs() < 0.08, "variance ratio {ratio}, closed form {expected}");
}

#[test]
fn the_default_filter_removes_noise_and_keeps_depth_steps_creases_and_the_sky() {
    // Left third: a wall at depth 1; middle third: depth 3 (a step); right third: depth 3,
    // normals turned 90° (a crease); bottom rows: sky. Each region has its own grey level
    // with noise, which the filter must smooth without mixing the regions.
    let e = extent(96, 64);
    let guide = Guide::from_fn(e, |x, y| match (x / 32, y >= 56) {
        (_, true) => (f32::INFINITY, [f32::NAN; 3]),
        (0, _) => (1.0, [0.0, 0.0, 1.0]),
        (1, _) => (3.0, [0.0, 0.0, 1.0]),
        _ => (3.0, [1.0, 0.0, 0.0]),
    });
    let level = |x: usize| [0.2f32, 0.9, 0.5][x / 32];
    let mut rng = Rng::new(5);
    let mut noisy = RgbBuf::new(e, 0.0);
    let mut clean = RgbBuf::new(e, 0.0);
    for y in 0..e.height() {
        for x in 0..e.width() {
            let v = if y >= 56 { 0.7 } else { level(x) };
            clean.set(x, y, [v; 3]);
            let n = if y >= 56 { 0.0 } else { rng.range(-0.1, 0.1) };
            noisy.set(x, y, [v + n; 3]);
        }
    }
    let (stats, out, _) = filter(&noisy, &guide.view(true), &AtrousParams::default(), true);
    assert_eq!(stats.out_of_range, 0);
    let error = |img: &RgbBuf, region: usize| {
        let (mut sum, mut n) = (0.0f64, 0);
        for y in 0..56 {
            for x in region * 32..(region + 1) * 32 {
                sum += f64::from(img.g().view().get(x, y) - clean.g().view().get(x, y)).powi(2);
                n += 1;
            }
        }
        (sum / n as f64).sqrt()
    };
    for region in 0..3 {
        let (before, after) = (error(&noisy, region), error(&out, region));
        assert!(after < before * 0.5, "region {region}: RMSE {before} → {after}");
    }
    // No bleeding: the pixels next to each edge stay at their own level (the noise
    // removed, not the neighbour's grey mixed in).
    for y in 8..48 {
        for (x, neighbour) in [(31, 32), (32, 31), (63, 64), (64, 63)] {
            let v = out.g().view().get(x, y);
            let (own, other) = (level(x), level(neighbour));
            assert!((v - own).abs() < 0.1 * (own - other).abs(), "pixel ({x}, {y}) = {v}: own {own}, other {other}");
        }
    }
    // The sky keeps its colour exactly.
    for y in 56..64 {
        for x in 0..96 {
            assert_eq!(out.get(x, y), noisy.get(x, y));
        }
    }
}

#[test]
fn a_constant_image_stays_constant() {
    let e = extent(70, 40);
    let img = RgbBuf::new(e, 0.37);
    let (_, out, variance) = filter(&img, &Guide::flat(e, 4.0).view(false), &AtrousParams::default(), true);
    for c in 0..3 {
        for &v in out.planes()[c].as_slice() {
            // A weighted mean of equal values is the value up to rounding: a few ulps a pass.
            assert!((v - 0.37).abs() <= 0.37 * 16.0 * f32::EPSILON, "{v}");
        }
    }
    assert!(variance.as_slice().iter().all(|&v| v == 0.0));
}

#[test]
fn fireflies_and_non_finite_values_are_clamped_and_counted() {
    let e = extent(40, 30);
    let mut img = RgbBuf::new(e, 0.5);
    let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -2.0, 1e30];
    for (i, &v) in bad.iter().enumerate() {
        img.set(5 + 6 * i, 15, [v, 0.5, v]);
    }
    for params in [AtrousParams::default(), AtrousParams { iterations: 0, ..AtrousParams::default() }] {
        let (stats, out, variance) = filter(&img, &Guide::flat(e, 1.0).view(true), &params, true);
        assert_eq!(stats.out_of_range, 2 * bad.len() as u64);
        for p in out.planes() {
            assert!(p.as_slice().iter().all(|v| v.is_finite() && *v >= 0.0 && *v <= atrous::VALUE_MAX));
        }
        assert!(variance.as_slice().iter().all(|v| v.is_finite()));
    }
}

#[test]
fn zero_iterations_copy_the_clamped_input() {
    let e = extent(20, 10);
    let mut rng = Rng::new(1);
    let img = synth::random_rgb_in(e, &mut rng, 0.0, (0.0, 1.0));
    let params = AtrousParams { iterations: 0, ..AtrousParams::default() };
    let (_, out, _) = filter(&img, &Guide::flat(e, 1.0).view(false), &params, true);
    assert_eq!(out, img);
}

#[test]
fn bad_input_is_refused() {
    let e = extent(16, 16);
    let img = RgbBuf::new(e, 0.0);
    let guide = Guide::flat(e, 1.0);
    let mut scratch = AtrousScratch::try_new(e).unwrap();
    let mut out = RgbBuf::new(e, 0.0);
    let mut run = |guide: &AtrousGuide<'_>, params: AtrousParams, scratch: &mut AtrousScratch| {
        atrous::atrous(&img.view(), guide, &params, scratch, out.view_mut())
    };
    let ok = AtrousParams::default();
    for params in [
        AtrousParams { iterations: atrous::MAX_ITERATIONS + 1, ..ok },
        AtrousParams { sigma_luminance: 0.0, ..ok },
        AtrousParams { sigma_luminance: f32::NAN, ..ok },
        AtrousParams { sigma_depth: f32::INFINITY, ..ok },
        AtrousParams { sigma_depth: -1.0, ..ok },
    ] {
        assert!(
            matches!(run(&guide.view(true), params, &mut scratch), Err(FrameError::InvalidParameter(_))),
            "{params:?}"
        );
    }
    let small = Guide::flat(extent(8, 16), 1.0);
    assert!(matches!(run(&small.view(true), ok, &mut scratch), Err(FrameError::ExtentMismatch { .. })));
    let mut small_scratch = AtrousScratch::try_new(extent(16, 8)).unwrap();
    assert!(matches!(run(&guide.view(false), ok, &mut small_scratch), Err(FrameError::ExtentMismatch { .. })));
    assert!(run(&guide.view(false), ok, &mut scratch).is_ok());
    // Every kernel weight the module names is the B3 spline's.
    assert_eq!(KERNEL.iter().sum::<f32>(), 1.0);
}

#[test]
fn exp_neg_is_close_to_exp() {
    let mut worst = 0.0f64;
    for i in 0..=40_000 {
        let x = i as f32 * 1e-3;
        let got = f64::from(atrous::exp_neg(x));
        let want = (-f64::from(x)).exp();
        worst = worst.max((got / want - 1.0).abs());
    }
    assert!(worst < 5e-6, "relative error {worst}");
    assert_eq!(atrous::exp_neg(0.0), 1.0);
}
