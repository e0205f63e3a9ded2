//! The evaluation harness: error curves, the effective spp and its policies, the geometric
//! grid, the cache (corruption, resuming) and the quick preset's tables.
//!
//! Curves here are rendered at 64×36 (frame 30, left eye) against 256-spp references: small
//! enough for CI, large enough that SSIM's 11×11 windows see structure.

use std::sync::OnceLock;

use stereotrace::camera::{Eye, StereoRig};
use stereotrace::eval::Seeds;
use stereotrace::eval::curve::{FrameCurve, Progressive, build_curve, measure};
use stereotrace::eval::effective::{EffectiveSpp, ErrorCurve, Grid, Interpolation, Metric};
use stereotrace::kernels::ssim::SsimVariant;
use stereotrace::kernels::{Extent, RgbBuf};
use stereotrace::render::{FrameView, Renderer};
use stereotrace::scene::{builtin_names, resolve};

const W: usize = 64;
const H: usize = 36;
const FRAME: u32 = 30;
const REFERENCE_SPP: u32 = 256;
const CURVE_SPP: u32 = 64;
const SEEDS: Seeds = Seeds { pipeline: 1, curve: 0xC0_4E5, reference: 0x4EF_E4E7CE };

fn extent() -> Extent {
    Extent::new(W, H).unwrap()
}

fn view(r: &Renderer, frame: u32) -> FrameView {
    FrameView::new(r, &StereoRig::default(), extent(), frame).unwrap()
}

/// One scene's dense curve (1..=CURVE_SPP) and its reference.
struct SceneCurve {
    name: &'static str,
    curve: FrameCurve,
}

/// Dense curves of every built-in, computed once for all tests of this file.
fn builtin_curves() -> &'static [SceneCurve] {
    static CURVES: OnceLock<Vec<SceneCurve>> = OnceLock::new();
    CURVES.get_or_init(|| {
        builtin_names()
            .into_iter()
            .map(|name| {
                let r = Renderer::new(resolve(name).unwrap()).unwrap();
                let v = view(&r, FRAME);
                let (reference, _) =
                    v.render(&r, &v.request(Eye::Left, REFERENCE_SPP, SEEDS.reference, 0), false).unwrap();
                let points: Vec<u32> = (1..=CURVE_SPP).collect();
                let curve =
                    build_curve(&r, &v, SEEDS.curve, Grid::Dense, &points, &reference, SsimVariant::Volume).unwrap();
                SceneCurve { name, curve }
            })
            .collect()
    })
}

#[test]
fn progressive_means_equal_direct_renders_bit_for_bit() {
    for name in ["cornell", "atrium-moving-light", "classroom-mirror"] {
        let r = Renderer::new(resolve(name).unwrap()).unwrap();
        let v = view(&r, 7);
        let mut prog = Progressive::new(extent());
        for m in 1..=6 {
            prog.add_sample(&r, &v, 99, false).unwrap();
            let (direct, _) = v.render(&r, &v.request(Eye::Left, m, 99, 0), false).unwrap();
            assert_eq!(prog.mean(), &direct, "{name}: {m} spp");
        }
        // Resuming from a checkpoint continues with the same numbers.
        let mut resumed = Progressive::resume(prog.samples(), prog.sum().clone());
        resumed.add_sample(&r, &v, 99, false).unwrap();
        assert_eq!(resumed.mean(), &v.render(&r, &v.request(Eye::Left, 7, 99, 0), false).unwrap().0, "{name}: resumed");
    }
}

/// SSIM error falls at every doubling of the spp on every built-in; single steps `m → m+1`
/// rise now and then (measured: 1 to 16 of 63 steps per scene), which the first-crossing
/// policy handles (next test). RMSE of raw HDR radiance is dominated by fireflies: at 64×36
/// its realised curve rises even between doublings on 8 of the 11 built-ins (on
/// `living-room-glossy` E(64) > E(1)), so it is asserted only on the scenes where it was
/// measured monotone at doublings, and the others are printed. The paper uses SSIM only.
const RMSE_MONOTONE: [&str; 3] = ["classroom", "classroom-mirror", "courtyard"];

#[test]
fn error_curves_decrease_with_spp_on_every_builtin() {
    let doublings = [1, 2, 4, 8, 16, 32, 64];
    assert_eq!(builtin_curves().len(), builtin_names().len());
    for sc in builtin_curves() {
        for metric in Metric::ALL {
            let c = sc.curve.curve(metric).unwrap();
            let at: Vec<f64> = doublings.iter().map(|&m| c.error_at(m).unwrap()).collect();
            let monotone = at.windows(2).all(|w| w[1] < w[0]);
            println!(
                "{:26} {:4}: at 1..64 spp by doublings {:?}; rises at {} of 63 single steps",
                sc.name,
                metric.label(),
                at.iter().map(|v| format!("{v:.3e}")).collect::<Vec<_>>(),
                c.rises().len()
            );
            if metric == Metric::Ssim || RMSE_MONOTONE.contains(&sc.name) {
                assert!(monotone, "{}: {} error does not fall at every doubling: {at:?}", sc.name, metric.label());
            }
        }
    }
}

#[test]
fn non_monotone_stretches_of_real_curves_use_the_first_crossing() {
    let mut checked = 0;
    for sc in builtin_curves() {
        for metric in Metric::ALL {
            let c = sc.curve.curve(metric).unwrap();
            let (e, m) = (c.errors(), c.spp());
            let (first, last) = (e[0], e[e.len() - 1]);
            for i in c.rises() {
                // An error inside the rise is crossed at least twice.
                let target = 0.5 * (e[i] + e[i + 1]);
                if !(last <= target && target <= first) {
                    continue;
                }
                let EffectiveSpp::InRange { spp, last_crossing } = c.effective_spp(target) else {
                    panic!("{}: in-range error reported out of range", sc.name)
                };
                assert!(
                    spp <= f64::from(m[i]) && last_crossing >= f64::from(m[i + 1]) - 0.5,
                    "{}: {spp} {last_crossing}",
                    sc.name
                );
                // The first crossing is the smallest m whose interpolated error reaches the target.
                let k = e.iter().position(|&v| v <= target).unwrap();
                assert!(spp > f64::from(m[k - 1]) && spp <= f64::from(m[k]), "{}: {spp} vs segment {k}", sc.name);
                checked += 1;
            }
        }
    }
    assert!(checked > 50, "only {checked} rises checked");
}

#[test]
fn out_of_range_frames_are_reported_as_such() {
    let sc = builtin_curves().iter().find(|s| s.name == "atrium").unwrap();
    let r = Renderer::new(resolve("atrium").unwrap()).unwrap();
    let v = view(&r, FRAME);
    let (reference, _) = v.render(&r, &v.request(Eye::Left, REFERENCE_SPP, SEEDS.reference, 0), false).unwrap();
    let black = RgbBuf::new(extent(), 0.0);
    let nan = RgbBuf::new(extent(), f32::NAN);
    for metric in Metric::ALL {
        let c = sc.curve.curve(metric).unwrap();
        let e = |img: &RgbBuf| measure(img, &reference, SsimVariant::Volume).unwrap().error(metric);
        assert_eq!(c.effective_spp(e(&black)), EffectiveSpp::BelowRange, "{metric:?}: black frame");
        assert_eq!(c.effective_spp(e(&reference)), EffectiveSpp::AboveRange { max_spp: CURVE_SPP }, "{metric:?}");
        assert_eq!(c.effective_spp(e(&nan)), EffectiveSpp::Undefined, "{metric:?}: NaN frame");
    }
}

#[test]
fn effective_spp_of_path_traced_frames_is_their_spp() {
    // A path-traced n-spp frame with a seed of its own is distributed like the curve's own
    // n-spp point, so its effective spp is n up to the noise of both. One curve is one noisy
    // realisation, and the n-spp frames of one seed share their samples across n (as the
    // points of one curve do), so a few seeds' luck carries over all n: 12 curve seeds × 12
    // frame seeds per n, and the median over the 144 pairs must be within 20% of n (SSIM;
    // measured worst: classroom 4 spp, +14.5%) or 25% (RMSE, on the scenes where it is
    // monotone; measured worst: classroom 2 spp, +17.5%). At n = 1 the median is at the
    // range's edge, so the check is that 25–75% of the pairs are below range.
    let curve_seeds = 0x100..0x10cu64;
    let frame_seeds = 0x200..0x20cu64;
    for name in ["cornell", "atrium", "classroom", "courtyard"] {
        let r = Renderer::new(resolve(name).unwrap()).unwrap();
        let v = view(&r, FRAME);
        let (reference, _) = v.render(&r, &v.request(Eye::Left, REFERENCE_SPP, SEEDS.reference, 0), false).unwrap();
        let points: Vec<u32> = (1..=32).collect();
        let curves: Vec<FrameCurve> = curve_seeds
            .clone()
            .map(|s| build_curve(&r, &v, s, Grid::Dense, &points, &reference, SsimVariant::Volume).unwrap())
            .collect();
        for metric in Metric::ALL {
            let mut line = Vec::new();
            for n in [1, 2, 4, 8, 16] {
                let mut eff = Vec::new();
                let (mut below, mut above) = (0, 0);
                for seed in frame_seeds.clone() {
                    let (img, _) = v.render(&r, &v.request(Eye::Left, n, seed, 0), false).unwrap();
                    let e = measure(&img, &reference, SsimVariant::Volume).unwrap().error(metric);
                    for c in &curves {
                        match c.curve(metric).unwrap().effective_spp(e) {
                            EffectiveSpp::InRange { spp, .. } => eff.push(spp),
                            EffectiveSpp::BelowRange => {
                                below += 1;
                                eff.push(0.0)
                            }
                            EffectiveSpp::AboveRange { .. } => {
                                above += 1;
                                eff.push(f64::INFINITY)
                            }
                            EffectiveSpp::Undefined => panic!("{name}: undefined"),
                        }
                    }
                }
                eff.sort_by(f64::total_cmp);
                let q = |f: f64| eff[((eff.len() - 1) as f64 * f).round() as usize];
                let median = q(0.5);
                line.push(format!(
                    "n={n}: median {median:.2} (q25 {:.2} q75 {:.2}, {below}< {above}>)",
                    q(0.25),
                    q(0.75)
                ));
                let checked = metric == Metric::Ssim || RMSE_MONOTONE.contains(&name);
                if !checked {
                    continue;
                }
                if n == 1 {
                    // Half of all 1-spp frames are worse than the curve's 1-spp point.
                    let share = below as f64 / eff.len() as f64;
                    assert!((0.25..=0.75).contains(&share), "{name} {metric:?}: {below} of {} below range", eff.len());
                } else {
                    let tol = if metric == Metric::Ssim { 0.2 } else { 0.25 };
                    assert!(
                        (median / f64::from(n) - 1.0).abs() <= tol,
                        "{name} {metric:?}: median effective spp {median:.2} of {n}-spp frames"
                    );
                }
            }
            println!("{name:20} {:4} {}", metric.label(), line.join("  "));
        }
    }
}

/// The geometric grid's points are the dense curve's at the same m (the curve is built
/// progressively either way), so its curve is the dense one's subset. For 401 errors
/// spanning each in-range curve of every built-in (both metrics), the geometric estimate
/// must lie within 5% of the dense one's [first, last] crossing interval and within 0.5% on
/// average, at 16 steps per octave (the CLI's; measured: worst 3.8%, mean 0.06%; 8 steps:
/// 9.8% / 0.2%; 4 steps: 14% / 0.5%). Between consecutive integers both interpolate
/// linearly; with log–log there too, 1–2 spp alone differed by 10%.
#[test]
fn geometric_grids_agree_with_dense_curves() {
    for steps in [16, 8, 4] {
        let grid = Grid::Geometric { steps_per_octave: steps };
        let pts = grid.points(CURVE_SPP);
        let mut worst = [(0.0f64, "", ""); 2];
        let mut sum = [0.0; 2];
        let mut n = [0; 2];
        for sc in builtin_curves() {
            for metric in Metric::ALL {
                let dense = sc.curve.curve(metric).unwrap();
                let sub: Vec<f64> = pts.iter().map(|&m| dense.error_at(m).unwrap()).collect();
                let geo = ErrorCurve::new(pts.clone(), sub, Interpolation::LogLog).unwrap();
                let (hi, lo) = (dense.errors()[0], *dense.errors().last().unwrap());
                if lo >= hi {
                    continue;
                }
                for k in 0..=400 {
                    let e = (hi * (lo / hi).powf(k as f64 / 400.0)).clamp(lo, hi);
                    let (EffectiveSpp::InRange { spp: d1, last_crossing: d2 }, Some(g)) =
                        (dense.effective_spp(e), geo.effective_spp(e).value())
                    else {
                        panic!("{}: the classification differs at {e}", sc.name)
                    };
                    let rel = if g < d1 {
                        (d1 - g) / d1
                    } else if g > d2 {
                        (g - d2) / d2
                    } else {
                        0.0
                    };
                    let key = usize::from(d1 != d2);
                    if rel > worst[key].0 {
                        worst[key] = (rel, sc.name, metric.label());
                    }
                    sum[key] += rel;
                    n[key] += 1;
                }
            }
        }
        println!(
            "{steps} steps/octave ({} points to 64): unambiguous: worst {:?} mean {:.5} (n {}); ambiguous: worst {:?} mean {:.5} (n {})",
            pts.len(),
            worst[0],
            sum[0] / n[0] as f64,
            n[0],
            worst[1],
            sum[1] / n[1] as f64,
            n[1]
        );
        if steps == 16 {
            for k in 0..2 {
                assert!(worst[k].0 <= 0.05 && sum[k] / n[k] as f64 <= 0.005, "16 steps/octave: {:?}", worst[k]);
            }
        }
    }
}

#[test]
fn ssim_of_the_same_images_is_bit_identical_across_calls() {
    let r = Renderer::new(resolve("cornell").unwrap()).unwrap();
    let v = FrameView::new(&r, &StereoRig::default(), Extent::new(32, 18).unwrap(), 2).unwrap();
    let (a, _) = v.render(&r, &v.request(Eye::Left, 2, 5, 0), false).unwrap();
    let (b, _) = v.render(&r, &v.request(Eye::Left, 16, 6, 0), false).unwrap();
    let first = measure(&a, &b, SsimVariant::Volume).unwrap();
    for i in 0..200 {
        let m = measure(&a, &b, SsimVariant::Volume).unwrap();
        assert_eq!(
            (m.ssim.to_bits(), m.rmse.to_bits()),
            (first.ssim.to_bits(), first.rmse.to_bits()),
            "call {i}: {m:?} vs {first:?}"
        );
    }
}
