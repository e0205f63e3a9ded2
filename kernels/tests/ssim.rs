//! SSIM / RMSE: the fused SIMD kernel against the f64 scalar reference and against a brute-force
//! 3-D oracle that knows nothing of the channel-mixing matrix (a direct 11×11×11 window with
//! replicate padding on all three axes, f64, mean first, then centred moments).
//!
//! Tolerances: `|Δssim| ≤ 1e-6` between the fast kernel and either oracle (1280×720 included),
//! and `|Δrmse| ≤ 1e-6·rmse`; counts must agree exactly. The tests run the body of
//! `Isa::active()` (16 lanes on an AVX-512 CPU unless `STEREOTRACE_ISA=avx2`); one test runs
//! every instruction set the CPU has on the same hard inputs and compares them.

// In a module so that `cargo test -p stereotrace-kernels ssim` selects these tests.
mod ssim_tests {
    use stereotrace_kernels::frame::{Plane, RgbBuf, RgbPlanes};
    use stereotrace_kernels::isa::Isa;
    use stereotrace_kernels::ssim::{
        self, MAX_SAMPLE, RADIUS, SsimParams, SsimResult, SsimVariant, TAPS, assert_agrees, channel_mixing_matrix,
        exact_voxel, gaussian_weights,
    };
    use stereotrace_kernels::{Extent, FrameError};

    const TOL: f64 = 1e-6;
    const VARIANTS: [SsimVariant; 2] = [SsimVariant::Volume, SsimVariant::PerChannel];

    /// xorshift64*, enough for test images.
    struct Rng(u64);

    impl Rng {
        fn new(seed: u64) -> Self {
            Self(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1)
        }
        fn next_u64(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
        }
        /// Uniform in [0, 1).
        fn f32(&mut self) -> f32 {
            (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
        }
        fn f64(&mut self) -> f64 {
            (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
        }
        fn below(&mut self, n: usize) -> usize {
            (self.next_u64() % n as u64) as usize
        }
    }

    fn image(w: usize, h: usize, mut f: impl FnMut(usize, usize, usize) -> f32) -> RgbBuf {
        let mut img = RgbBuf::new(Extent::new(w, h).unwrap(), 0.0);
        for y in 0..h {
            for x in 0..w {
                let px = [0, 1, 2].map(|c| f(x, y, c));
                img.set(x, y, px);
            }
        }
        img
    }

    fn random(w: usize, h: usize, seed: u64) -> RgbBuf {
        let mut r = Rng::new(seed);
        image(w, h, |_, _, _| r.f32())
    }

    /// `base` plus uniform noise of amplitude `amp` (same seed ⇒ same noise pattern).
    fn noisy(base: &RgbBuf, amp: f32, seed: u64) -> RgbBuf {
        let mut r = Rng::new(seed);
        let e = base.extent();
        image(e.width(), e.height(), |x, y, c| base.get(x, y)[c] + amp * (r.f32() - 0.5))
    }

    fn run(a: &RgbBuf, b: &RgbBuf, variant: SsimVariant) -> SsimResult {
        ssim::ssim(&a.view(), &b.view(), &SsimParams::with_variant(variant)).unwrap()
    }

    fn run_scalar(a: &RgbBuf, b: &RgbBuf, variant: SsimVariant) -> SsimResult {
        ssim::ssim_scalar(&a.view(), &b.view(), &SsimParams::with_variant(variant)).unwrap()
    }

    /// Brute-force oracle: `(ssim, per-channel means, used voxels)`.
    fn brute(a: &RgbPlanes<'_>, b: &RgbPlanes<'_>, variant: SsimVariant) -> (f64, [f64; 3], u64) {
        let (w, h) = (a.extent().width(), a.extent().height());
        let g = gaussian_weights();
        let (c1, c2) = (ssim::C1, ssim::C2);
        let clamp = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
        let mut sum = [0.0f64; 3];
        let mut n = [0u64; 3];
        for c in 0..3 {
            for py in 0..h {
                for px in 0..w {
                    // Taps: (weight, x, y). The channel axis is part of the window for Volume.
                    let mut taps = Vec::with_capacity(TAPS * TAPS * TAPS);
                    let channel_taps: Vec<(f64, usize)> = match variant {
                        SsimVariant::Volume => {
                            (0..TAPS).map(|k| (g[k], clamp(c as isize + k as isize - RADIUS as isize, 3))).collect()
                        }
                        SsimVariant::PerChannel => vec![(1.0, c)],
                    };
                    for &(wc, cc) in &channel_taps {
                        for ky in 0..TAPS {
                            for kx in 0..TAPS {
                                let x = clamp(px as isize + kx as isize - RADIUS as isize, w);
                                let y = clamp(py as isize + ky as isize - RADIUS as isize, h);
                                let (u, v) = (a.channels()[cc].get(x, y), b.channels()[cc].get(x, y));
                                taps.push((wc * g[kx] * g[ky], u, v));
                            }
                        }
                    }
                    if taps.iter().any(|&(_, u, v)| !ssim::usable(u) || !ssim::usable(v)) {
                        continue;
                    }
                    let (mut mx, mut my) = (0.0, 0.0);
                    for &(wt, u, v) in &taps {
                        mx += wt * f64::from(u);
                        my += wt * f64::from(v);
                    }
                    let (mut vx, mut vy, mut cxy) = (0.0, 0.0, 0.0);
                    for &(wt, u, v) in &taps {
                        let (du, dv) = (f64::from(u) - mx, f64::from(v) - my);
                        vx += wt * du * du;
                        vy += wt * dv * dv;
                        cxy += wt * du * dv;
                    }
                    sum[c] += ((2.0 * mx * my + c1) * (2.0 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2));
                    n[c] += 1;
                }
            }
        }
        let per = [0, 1, 2].map(|c| sum[c] / n[c] as f64);
        let total: u64 = n.iter().sum();
        let mean = match variant {
            SsimVariant::Volume => sum.iter().sum::<f64>() / total as f64,
            SsimVariant::PerChannel => {
                let used: Vec<f64> = per.iter().copied().filter(|v| !v.is_nan()).collect();
                used.iter().sum::<f64>() / used.len() as f64
            }
        };
        (mean, per, total)
    }

    fn assert_matches_brute(a: &RgbBuf, b: &RgbBuf, variant: SsimVariant, tol: f64) -> SsimResult {
        let fast = run(a, b, variant);
        let (mean, per, voxels) = brute(&a.view(), &b.view(), variant);
        assert_eq!(fast.voxels, voxels, "{variant:?}: used voxels");
        assert!(
            (fast.ssim - mean).abs() <= tol,
            "{variant:?}: fast {} vs brute force {mean} (Δ {:e})",
            fast.ssim,
            fast.ssim - mean
        );
        for c in 0..3 {
            assert!((fast.per_channel[c] - per[c]).abs() <= tol || (per[c].is_nan() && fast.per_channel[c].is_nan()));
        }
        fast
    }

    #[test]
    fn mixing_matrix_equals_brute_force_channel_filter() {
        let m = channel_mixing_matrix();
        let g = gaussian_weights();
        let mut r = Rng::new(7);
        for _ in 0..100 {
            let v = [r.f64() * 10.0 - 5.0, r.f64(), r.f64() * 1e3];
            for c in 0..3 {
                let brute: f64 =
                    (0..TAPS).map(|k| g[k] * v[(c as isize + k as isize - RADIUS as isize).clamp(0, 2) as usize]).sum();
                let mixed: f64 = (0..3).map(|k| m[c][k] * v[k]).sum();
                assert!((brute - mixed).abs() <= 1e-12 * (1.0 + brute.abs()), "{brute} vs {mixed}");
            }
        }
    }

    #[test]
    fn mixing_matrix_after_2d_filter_equals_3d_filter_on_random_volumes() {
        // A full separable 3-D Gaussian filter of a random W×H×3 volume, computed directly,
        // equals the 2-D filter per channel followed by the 3×3 mixing.
        let (w, h) = (9, 6);
        let g = gaussian_weights();
        let m = channel_mixing_matrix();
        let clamp = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
        let mut r = Rng::new(11);
        for _ in 0..3 {
            let vol: Vec<f64> = (0..w * h * 3).map(|_| r.f64()).collect();
            let at = |x: usize, y: usize, c: usize| vol[(c * h + y) * w + x];
            let filt2 = |px: usize, py: usize, c: usize| {
                let mut s = 0.0;
                for ky in 0..TAPS {
                    for kx in 0..TAPS {
                        let x = clamp(px as isize + kx as isize - RADIUS as isize, w);
                        let y = clamp(py as isize + ky as isize - RADIUS as isize, h);
                        s += g[kx] * g[ky] * at(x, y, c);
                    }
                }
                s
            };
            for c in 0..3 {
                for py in 0..h {
                    for px in 0..w {
                        let mut direct = 0.0;
                        for kc in 0..TAPS {
                            let cc = clamp(c as isize + kc as isize - RADIUS as isize, 3);
                            direct += g[kc] * filt2(px, py, cc);
                        }
                        let mixed: f64 = (0..3).map(|k| m[c][k] * filt2(px, py, k)).sum();
                        assert!((direct - mixed).abs() < 1e-14, "{direct} vs {mixed}");
                    }
                }
            }
        }
    }

    #[test]
    fn identical_images_give_exactly_one() {
        let mut r = Rng::new(3);
        let cases = [
            random(37, 23, 1),
            image(40, 20, |_, _, _| 1000.0 + r.f32()),
            image(33, 17, |x, y, c| if (x * 7 + y * 3 + c) % 41 == 0 { 1e6 } else { 0.01 * (x + c) as f32 }),
            image(11, 11, |_, _, _| 0.25),
            image(11, 12, |_, _, c| c as f32),
        ];
        for img in &cases {
            for variant in VARIANTS {
                let res = run(img, img, variant);
                assert_eq!(res.ssim, 1.0, "{variant:?}");
                assert_eq!(res.per_channel, [1.0; 3]);
                assert_eq!(res.rmse, 0.0);
                assert_eq!(res.voxels, 3 * img.extent().pixels() as u64);
                assert_eq!(run_scalar(img, img, variant).ssim, 1.0, "{variant:?} scalar");
            }
        }
    }

    #[test]
    fn symmetric_bit_for_bit() {
        let a = random(70, 41, 5);
        let b = noisy(&a, 0.3, 6);
        let mut r = Rng::new(9);
        let hdr_a = image(70, 41, |x, _, _| if x < 30 { 1000.0 + r.f32() } else { 0.1 * r.f32() });
        let hdr_b = noisy(&hdr_a, 0.5, 10);
        for (a, b) in [(&a, &b), (&hdr_a, &hdr_b)] {
            for variant in VARIANTS {
                let (ab, ba) = (run(a, b, variant), run(b, a, variant));
                assert_eq!(ab.ssim.to_bits(), ba.ssim.to_bits(), "{variant:?}");
                assert_eq!(ab, ba);
            }
        }
    }

    #[test]
    fn bounded_in_minus_one_one() {
        let a = random(30, 30, 12);
        let neg = image(30, 30, |x, y, c| -a.get(x, y)[c]);
        let inv = image(30, 30, |x, y, c| 1.0 - a.get(x, y)[c]);
        let far = image(30, 30, |x, y, c| 1e5 * a.get(x, y)[c]);
        for b in [&neg, &inv, &far, &random(30, 30, 13)] {
            for variant in VARIANTS {
                let res = run(&a, b, variant);
                assert!((-1.0..=1.0).contains(&res.ssim), "{variant:?}: {}", res.ssim);
                for v in res.per_channel {
                    assert!((-1.0..=1.0).contains(&v));
                }
            }
        }
        // Anticorrelated structure with equal means approaches −1 (x against −x does not: both
        // the luminance and the structure term are negative, and their product is positive).
        let res = run(&a, &inv, SsimVariant::PerChannel);
        assert!(res.ssim < -0.9, "{}", res.ssim);
    }

    #[test]
    fn volume_and_per_channel_agree_on_grey_and_differ_on_colour() {
        // Grey: every channel equal. The 3-D statistics equal the 2-D ones exactly (rows of M sum
        // to 1 and the kernel mixes as q_c + Σ M·(q_c' − q_c)), so the values are the same bits.
        let mut r = Rng::new(21);
        let grey_a = image(45, 29, |x, y, _| ((x * 31 + y * 17) % 13) as f32 * 0.05);
        let grey_b = {
            let mut n = Vec::new();
            for _ in 0..45 * 29 {
                n.push(r.f32() * 0.2);
            }
            image(45, 29, |x, y, _| grey_a.get(x, y)[0] + n[y * 45 + x])
        };
        let vol = run(&grey_a, &grey_b, SsimVariant::Volume);
        let per = run(&grey_a, &grey_b, SsimVariant::PerChannel);
        assert_eq!(vol.ssim.to_bits(), per.ssim.to_bits(), "{vol:?} vs {per:?}");
        assert!(vol.ssim < 0.99);
        let (vs, ps) =
            (run_scalar(&grey_a, &grey_b, SsimVariant::Volume), run_scalar(&grey_a, &grey_b, SsimVariant::PerChannel));
        assert!((vs.ssim - ps.ssim).abs() < 1e-12, "{vs:?} vs {ps:?}");

        // Colour: the same structure in every channel of `a`, but `b` moves it between channels.
        // The 3-D window sees the channels' means mix; the per-channel one does not.
        let a = image(40, 24, |x, y, c| [0.9, 0.5, 0.1][c] + 0.05 * ((x + 2 * y) % 5) as f32);
        let b = image(40, 24, |x, y, c| [0.1, 0.5, 0.9][c] + 0.05 * ((x + 2 * y) % 5) as f32);
        let vol = assert_matches_brute(&a, &b, SsimVariant::Volume, TOL);
        let per = assert_matches_brute(&a, &b, SsimVariant::PerChannel, TOL);
        assert!((vol.ssim - per.ssim).abs() > 0.05, "{vol:?} vs {per:?}");
    }

    #[test]
    fn matches_brute_force_3d_on_small_random_images() {
        for (seed, (w, h)) in [(1u64, (37, 23)), (2, (23, 37)), (3, (16, 16)), (4, (65, 12))] {
            let a = random(w, h, seed);
            let b = noisy(&a, 0.4, seed + 100);
            for variant in VARIANTS {
                let fast = assert_matches_brute(&a, &b, variant, TOL);
                assert_agrees(&fast, &run_scalar(&a, &b, variant), TOL);
            }
        }
    }

    #[test]
    fn constant_images() {
        for (u, v) in [(0.25f32, 0.25f32), (0.0, 0.0), (1e6, 1e6), (0.2, 0.7), (0.0, 1.0), (1000.0, 1000.5)] {
            let a = image(19, 11, |_, _, _| u);
            let b = image(19, 11, |_, _, _| v);
            for variant in VARIANTS {
                let res = run(&a, &b, variant);
                assert!(res.ssim.is_finite());
                if u == v {
                    assert_eq!(res.ssim, 1.0);
                }
                // σ = 0: only the luminance term remains.
                let (u, v) = (f64::from(u), f64::from(v));
                let lum = (2.0 * u * v + ssim::C1) / (u * u + v * v + ssim::C1);
                assert!((res.ssim - lum).abs() < 1e-6, "{variant:?}: {} vs {lum}", res.ssim);
                assert!((res.rmse - (u - v).abs()).abs() <= 1e-6 * (u - v).abs());
            }
        }
    }

    #[test]
    fn fireflies_up_to_1e6_match_brute_force() {
        let mut r = Rng::new(31);
        let base = random(41, 27, 30);
        let fire = |img: &RgbBuf, n: usize, r: &mut Rng| {
            let mut out = img.clone();
            for _ in 0..n {
                let (x, y) = (r.below(41), r.below(27));
                let mag = [1e3f32, 1e4, 1e5, 1e6][r.below(4)];
                let mut px = out.get(x, y);
                px[r.below(3)] = mag * (0.5 + r.f32());
                out.set(x, y, px);
            }
            out
        };
        let a = fire(&base, 12, &mut r);
        let b = fire(&noisy(&base, 0.2, 32), 12, &mut r);
        for variant in VARIANTS {
            let fast = assert_matches_brute(&a, &b, variant, TOL);
            assert_agrees(&fast, &run_scalar(&a, &b, variant), TOL);
        }
    }

    #[test]
    fn hdr_levels_and_edges_match_brute_force() {
        // Bright flat regions with tiny noise next to dark ones, inside one tile: the case where
        // a single shift cannot serve every window and the refinement passes are needed.
        let mut r = Rng::new(41);
        let a = image(70, 40, |x, y, c| {
            let level = if (x / 13 + y / 9) % 3 == 0 {
                [1000.0, 300.0, 20.0][c]
            } else if (x / 13 + y / 9) % 3 == 1 {
                0.02
            } else {
                5.0
            };
            level * (1.0 + 0.001 * r.f32())
        });
        let b = noisy(&a, 0.01, 42);
        for variant in VARIANTS {
            let fast = assert_matches_brute(&a, &b, variant, TOL);
            assert_agrees(&fast, &run_scalar(&a, &b, variant), TOL);
            assert!(fast.refined > 0, "{variant:?}: expected refinement on this image, {fast:?}");
        }
    }

    #[test]
    fn non_finite_samples_are_counted_and_excluded() {
        let a = random(40, 30, 50);
        let mut b = noisy(&a, 0.1, 51);
        let mut a2 = a.clone();
        b.set(3, 4, [f32::NAN, 0.5, 0.5]);
        b.set(35, 20, [0.5, f32::INFINITY, 0.5]);
        a2.set(20, 29, [0.1, 0.1, f32::NEG_INFINITY]);
        a2.set(0, 0, [2.0 * MAX_SAMPLE, 0.1, 0.1]);
        for variant in VARIANTS {
            let fast = assert_matches_brute(&a2, &b, variant, TOL);
            assert!(fast.ssim.is_finite() && fast.rmse.is_finite(), "{fast:?}");
            assert_eq!(fast.non_finite, 4);
            assert_eq!(fast.rmse_samples, 3 * 40 * 30 - 4);
            assert!(fast.voxels < 3 * 40 * 30);
            assert_agrees(&fast, &run_scalar(&a2, &b, variant), TOL);
        }
        // The 3-D window spans all channels: one bad sample excludes all three channels there;
        // the per-channel window only its own.
        let vol = run(&a2, &b, SsimVariant::Volume);
        let per = run(&a2, &b, SsimVariant::PerChannel);
        assert!(vol.voxels < per.voxels);
        // Everything unusable: NaN with zero counts, never a panic.
        let nan = image(11, 13, |_, _, _| f32::NAN);
        let res = run(&nan, &nan, SsimVariant::Volume);
        assert!(res.ssim.is_nan() && res.rmse.is_nan());
        assert_eq!((res.voxels, res.rmse_samples, res.non_finite), (0, 0, 2 * 3 * 11 * 13));
    }

    #[test]
    fn edge_values_match_scalar_and_brute_force() {
        // ±0, subnormals, the usable limit itself and just beyond, f32::MAX, negative values:
        // sprinkled over a random image at a fixed set of positions.
        let edge = [
            0.0f32,
            -0.0,
            f32::MIN_POSITIVE / 4.0,
            -f32::MIN_POSITIVE,
            MAX_SAMPLE,
            -MAX_SAMPLE,
            MAX_SAMPLE * (1.0 + f32::EPSILON),
            f32::MAX,
            f32::MIN,
            -3.5,
            1e-30,
        ];
        let mut r = Rng::new(140);
        let mut a = random(29, 21, 141);
        let mut b = noisy(&a, 0.2, 142);
        for (i, &v) in edge.iter().enumerate() {
            let (x, y, c) = (r.below(29), r.below(21), r.below(3));
            let img = if i % 2 == 0 { &mut a } else { &mut b };
            let mut px = img.get(x, y);
            px[c] = v;
            img.set(x, y, px);
        }
        let unusable = [&a, &b]
            .iter()
            .map(|img| {
                (0..21)
                    .flat_map(|y| (0..29).map(move |x| (x, y)))
                    .map(|(x, y)| img.get(x, y).iter().filter(|v| !ssim::usable(**v)).count() as u64)
                    .sum::<u64>()
            })
            .sum::<u64>();
        for variant in VARIANTS {
            let fast = assert_matches_brute(&a, &b, variant, TOL);
            assert_eq!(fast.non_finite, unusable);
            assert_agrees(&fast, &run_scalar(&a, &b, variant), TOL);
        }
        // Subnormal and zero images: still exactly 1 against themselves.
        let tiny = image(17, 11, |x, y, c| f32::from_bits(((x * 31 + y * 7 + c) % 1000) as u32));
        for variant in VARIANTS {
            assert_eq!(run(&tiny, &tiny, variant).ssim, 1.0);
        }
    }

    #[test]
    fn odd_sizes_and_strides() {
        // Both sides at least the window (smaller images are refused: the test below).
        let sizes = [
            (11, 11),
            (11, 40),
            (40, 11),
            (12, 13),
            (15, 11),
            (16, 12),
            (17, 14),
            (63, 11),
            (64, 33),
            (65, 34),
            (130, 12),
        ];
        for (i, &(w, h)) in sizes.iter().enumerate() {
            let a = random(w, h, 60 + i as u64);
            let b = noisy(&a, 0.3, 70 + i as u64);
            for variant in VARIANTS {
                let fast = assert_matches_brute(&a, &b, variant, TOL);
                assert_agrees(&fast, &run_scalar(&a, &b, variant), TOL);
            }
            // The same pixels behind a padded stride (padding full of NaN: must never be read).
            let stride = w + 3;
            let strided = |img: &RgbBuf| -> [Vec<f32>; 3] {
                [0, 1, 2].map(|c| {
                    let mut v = vec![f32::NAN; (h - 1) * stride + w];
                    for y in 0..h {
                        for x in 0..w {
                            v[y * stride + x] = img.get(x, y)[c];
                        }
                    }
                    v
                })
            };
            let (va, vb) = (strided(&a), strided(&b));
            fn planes(v: &[Vec<f32>; 3], w: usize, h: usize, stride: usize) -> RgbPlanes<'_> {
                let p = |c: usize| Plane::new(&v[c][..], w, h, stride).unwrap();
                RgbPlanes::new(p(0), p(1), p(2)).unwrap()
            }
            for variant in VARIANTS {
                let params = SsimParams::with_variant(variant);
                let s = ssim::ssim(&planes(&va, w, h, stride), &planes(&vb, w, h, stride), &params).unwrap();
                assert_eq!(s, run(&a, &b, variant), "{w}x{h} stride {stride}");
            }
        }
    }

    #[test]
    fn tall_images_use_taller_bands() {
        // 20000 rows: more than 256 bands of the default height, so the band height grows.
        let a = random(11, 20_000, 150);
        let b = noisy(&a, 0.3, 151);
        for variant in VARIANTS {
            for band_rows in [1, 64] {
                let params = SsimParams { variant, band_rows };
                let fast = ssim::ssim(&a.view(), &b.view(), &params).unwrap();
                assert_agrees(&fast, &run_scalar(&a, &b, variant), TOL);
            }
        }
    }

    #[test]
    fn simd_matches_scalar_at_1280x720() {
        let a = random(1280, 720, 80);
        let b = noisy(&a, 0.25, 81);
        for variant in VARIANTS {
            let fast = run(&a, &b, variant);
            let reference = run_scalar(&a, &b, variant);
            assert_agrees(&fast, &reference, TOL);
            eprintln!(
                "{variant:?}: fast {:.12} scalar {:.12} Δ {:e}",
                fast.ssim,
                reference.ssim,
                fast.ssim - reference.ssim
            );
        }
    }

    #[test]
    fn simd_matches_scalar_on_seeded_random_inputs() {
        let mut r = Rng::new(90);
        for i in 0..24 {
            let (w, h) = (11 + r.below(80), 11 + r.below(40));
            let scale = [1.0f32, 10.0, 1e3, 1e5][i % 4];
            let mut rr = Rng::new(1000 + i as u64);
            let a = image(w, h, |_, _, _| scale * rr.f32() * rr.f32());
            let b = noisy(&a, 0.1 * scale, 2000 + i as u64);
            for variant in VARIANTS {
                let params = SsimParams { variant, band_rows: 1 + r.below(40) };
                let fast = ssim::ssim(&a.view(), &b.view(), &params).unwrap();
                assert_agrees(&fast, &run_scalar(&a, &b, variant), TOL);
            }
        }
    }

    #[test]
    fn thread_count_does_not_change_the_bits() {
        let a = random(200, 150, 100);
        let b = noisy(&a, 0.3, 101);
        for variant in VARIANTS {
            let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
            // Ten bands, finishing in whatever order the two workers take them.
            let params = SsimParams { variant, band_rows: 15 };
            let one = pool(1).install(|| ssim::ssim(&a.view(), &b.view(), &params).unwrap());
            for _ in 0..4 {
                let two = pool(2).install(|| ssim::ssim(&a.view(), &b.view(), &params).unwrap());
                assert_eq!(one, two);
            }
        }
    }

    #[test]
    fn monotonic_in_noise() {
        let clean =
            image(96, 64, |x, y, c| 0.5 + 0.4 * (((x as f32) * 0.2 + c as f32).sin() * ((y as f32) * 0.15).cos()));
        for variant in VARIANTS {
            let mut prev: Option<SsimResult> = None;
            for amp in [1.0f32, 0.5, 0.25, 0.1, 0.05, 0.02, 0.01] {
                let res = run(&clean, &noisy(&clean, amp, 7), variant);
                if let Some(p) = prev {
                    assert!(res.ssim > p.ssim, "{variant:?}: SSIM {} then {} at amp {amp}", p.ssim, res.ssim);
                    assert!(res.rmse < p.rmse);
                }
                prev = Some(res);
            }
        }
    }

    #[test]
    fn rmse_is_over_all_values() {
        let a = random(23, 11, 110);
        let b = noisy(&a, 0.5, 111);
        let mut sq = 0.0f64;
        for y in 0..11 {
            for x in 0..23 {
                for c in 0..3 {
                    let d = f64::from(a.get(x, y)[c]) - f64::from(b.get(x, y)[c]);
                    sq += d * d;
                }
            }
        }
        let expected = (sq / (23.0 * 11.0 * 3.0)).sqrt();
        let res = run(&a, &b, SsimVariant::Volume);
        assert!((res.rmse - expected).abs() <= 1e-6 * expected);
        assert_eq!(res.rmse_samples, 23 * 11 * 3);
    }

    #[test]
    fn exact_voxel_matches_brute_force() {
        let a = random(13, 12, 120);
        let b = noisy(&a, 0.3, 121);
        for variant in VARIANTS {
            let (mean, _, n) = brute(&a.view(), &b.view(), variant);
            let mut sum = 0.0;
            for c in 0..3 {
                for y in 0..12 {
                    for x in 0..13 {
                        sum += exact_voxel(&a.view(), &b.view(), variant, x, y, c).unwrap();
                    }
                }
            }
            assert!((sum / n as f64 - mean).abs() < 1e-12);
        }
    }

    #[test]
    fn images_smaller_than_the_window_are_refused_by_both_bodies() {
        for w in 1..=ssim::MIN_SIDE {
            for h in 1..=ssim::MIN_SIDE {
                let (a, b) = (random(w, h, 3), random(w, h, 4));
                for variant in VARIANTS {
                    let params = SsimParams::with_variant(variant);
                    let (fast, reference) =
                        (ssim::ssim(&a.view(), &b.view(), &params), ssim::ssim_scalar(&a.view(), &b.view(), &params));
                    if w < ssim::MIN_SIDE || h < ssim::MIN_SIDE {
                        let refused = FrameError::SmallerThanWindow { extent: a.extent(), window: ssim::MIN_SIDE };
                        assert_eq!((fast, reference), (Err(refused.clone()), Err(refused)), "{w}x{h}");
                    } else {
                        assert_agrees(&fast.unwrap(), &reference.unwrap(), ssim::CHECK_TOLERANCE);
                    }
                }
            }
        }
    }

    #[test]
    fn mismatched_extents_are_refused() {
        let a = random(12, 12, 1);
        let b = random(12, 13, 2);
        let err = ssim::ssim(&a.view(), &b.view(), &SsimParams::default()).unwrap_err();
        assert!(matches!(err, FrameError::ExtentMismatch { .. }), "{err}");
    }

    #[test]
    fn every_instruction_set_gives_the_same_voxels_on_hard_inputs() {
        // The inputs of the tests above that reach every path of the body: plain noise, HDR
        // levels that need refinement passes, fireflies, non-finite and edge values, constant
        // images, every width modulo 16 (tails and the fast path's full vectors), one band or
        // many.
        let mut cases: Vec<(String, RgbBuf, RgbBuf)> = Vec::new();
        let mut r = Rng::new(700);
        for w in [11usize, 12, 15, 16, 17, 31, 33, 63, 64, 65, 79, 80, 81, 130] {
            let h = 11 + r.below(30);
            let a = random(w, h, 701 + w as u64);
            cases.push((format!("noise {w}x{h}"), a.clone(), noisy(&a, 0.25, 702 + w as u64)));
        }
        let levels = image(70, 40, |x, y, c| {
            let level = [[1000.0, 300.0, 20.0][c], 0.02, 5.0][(x / 13 + y / 9) % 3];
            level * (1.0 + 0.001 * ((x * 7 + y * 3 + c) % 11) as f32)
        });
        cases.push(("hdr levels".into(), levels.clone(), noisy(&levels, 0.01, 703)));
        let mut fire = random(41, 27, 704);
        let mut edges = noisy(&fire, 0.2, 705);
        let edge = [0.0f32, -0.0, f32::MIN_POSITIVE / 4.0, MAX_SAMPLE, MAX_SAMPLE * 1.01, f32::MAX, f32::NAN];
        for i in 0..40 {
            let (x, y, c) = (r.below(41), r.below(27), r.below(3));
            let mut px = fire.get(x, y);
            px[c] = [1e3f32, 1e4, 1e5, 1e6][i % 4] * (0.5 + r.f32());
            fire.set(x, y, px);
            let mut px = edges.get(x, y);
            px[c] = edge[i % edge.len()];
            edges.set(x, y, px);
        }
        cases.push(("fireflies and edge values".into(), fire, edges));
        cases.push(("constant".into(), image(33, 20, |_, _, _| 0.75), image(33, 20, |_, _, _| 0.75)));
        let a = random(1280, 720, 706);
        cases.push(("1280x720".into(), a.clone(), noisy(&a, 0.25, 707)));

        let isas: Vec<Isa> = Isa::supported().collect();
        if isas.len() < Isa::ALL.len() {
            eprintln!("SKIP part: this CPU runs only {isas:?}; the other bodies are compared where it has them");
        }
        for (name, a, b) in &cases {
            for variant in VARIANTS {
                for band_rows in [1, 7, 64] {
                    let params = SsimParams { variant, band_rows };
                    let reference = ssim::ssim_scalar(&a.view(), &b.view(), &params).unwrap();
                    let results: Vec<SsimResult> =
                        isas.iter().map(|&isa| ssim::ssim_with(&a.view(), &b.view(), &params, isa).unwrap()).collect();
                    for (isa, result) in isas.iter().zip(&results) {
                        // The per-voxel tolerance of the kernel's contract: a few voxels of a
                        // tiny image cannot average their rounding away (see the module docs).
                        let tol = if result.voxels < 1000 { ssim::CHECK_TOLERANCE } else { TOL };
                        std::panic::catch_unwind(|| assert_agrees(result, &reference, tol))
                            .unwrap_or_else(|_| panic!("{name}, {variant:?}, {isa:?} against the scalar reference"));
                    }
                    for pair in results.windows(2) {
                        std::panic::catch_unwind(|| ssim::assert_isas_agree(&pair[0], &pair[1]))
                            .unwrap_or_else(|_| panic!("{name}, {variant:?}, band rows {band_rows}: {isas:?}"));
                    }
                }
            }
        }
    }
}
