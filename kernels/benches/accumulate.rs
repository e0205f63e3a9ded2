//! EMA accumulation, the stereo blend, the neighbourhood clamp and temporal gradients' history confidence at 1280×720, the scalar references beside the SIMD
//! bodies, on 1 and 2 threads, throughput in pixels; the memory triad of the same run for the
//! roofline.
//!
//! Run: `cargo bench -p stereotrace-kernels --bench accumulate`.

mod common;

use std::hint::black_box;

use common::{Fixture, pool, simd_and_scalar};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use stereotrace_kernels::accumulate::{self, BlendParams, EmaInput, EmaParams, EmaState};
use stereotrace_kernels::clamp::{self, ClampInput, ClampParams};
use stereotrace_kernels::frame::PlaneBuf;
use stereotrace_kernels::gradient::{self, GradientInput};
use stereotrace_kernels::synth::Rng;

fn ema_and_blend(c: &mut Criterion) {
    let f = Fixture::new();
    let e = f.extent();
    let mut rng = Rng::new(42);
    let reason = PlaneBuf::from_vec((0..e.pixels()).map(|_| u8::from(rng.next_f32() < 0.03)).collect(), e).unwrap();
    let history = f.left_prev.colour.clone();
    let mut acc = history.clone();
    let mut len = PlaneBuf::new(e, 5.0f32);
    let mut group = c.benchmark_group("ema");
    group.throughput(Throughput::Elements(e.pixels() as u64));
    for threads in [1, 2] {
        let pool = pool(threads);
        for simd in [true, false] {
            for ramp in [false, true] {
                let name = format!("{}/{}", if simd { "simd" } else { "scalar" }, if ramp { "ramp" } else { "plain" });
                let params = EmaParams { ramp, ..EmaParams::default() };
                group.bench_function(BenchmarkId::new(name, threads), |b| {
                    b.iter(|| {
                        pool.install(|| {
                            let input = EmaInput {
                                new: f.left.colour.view(),
                                reason: reason.view(),
                                has_new: None,
                                confidence: None,
                                pixel_mask: None,
                            };
                            let state = EmaState { accum: acc.view_mut(), history_len: ramp.then(|| len.view_mut()) };
                            let r = if simd {
                                accumulate::ema(&input, state, &params)
                            } else {
                                accumulate::ema_scalar(&input, state, &params)
                            };
                            black_box(r.expect("valid input"))
                        })
                    })
                });
            }
        }
    }
    // The paper-order left eye's EMA: only the pixels its stereo reprojection discarded (the
    // pixel mask), the rest already restarted by the stereo pass. Beside `simd/plain`, it is
    // what the fused restart saves.
    let mask = f.stereo_discarded();
    let share = mask.as_slice().iter().filter(|&&m| m != 0).count() as f64 / e.pixels() as f64;
    println!("ema/simd-masked: the stereo-discarded mask holds {:.1} % of the pixels", 100.0 * share);
    let whole_frame = EmaInput {
        new: f.left.colour.view(),
        reason: reason.view(),
        has_new: None,
        confidence: None,
        pixel_mask: None,
    };
    for threads in [1, 2] {
        let pool = pool(threads);
        let params = EmaParams::default();
        group.bench_function(BenchmarkId::new("simd-masked/plain", threads), |b| {
            b.iter(|| {
                pool.install(|| {
                    let input = EmaInput { pixel_mask: Some(mask.view()), ..whole_frame };
                    let state = EmaState { accum: acc.view_mut(), history_len: None };
                    black_box(accumulate::ema(&input, state, &params).expect("valid input"))
                })
            })
        });
    }
    group.finish();

    let mut group = c.benchmark_group("blend");
    group.throughput(Throughput::Elements(e.pixels() as u64));
    let mut out = f.right.colour.clone();
    simd_and_scalar(&mut group, |simd| {
        let blend = if simd { accumulate::blend } else { accumulate::blend_scalar };
        blend(&f.left.colour.view(), out.view_mut(), &reason.view(), &BlendParams::default()).expect("valid input")
    });
    group.finish();

    // The variance-guided blend: the same pixels, weighed by the two eyes' history lengths
    // (one eye's restarted at a sprinkle of disocclusions), the boundary checks of both
    // length planes included.
    let mut group = c.benchmark_group("blend_by_variance");
    group.throughput(Throughput::Elements(e.pixels() as u64));
    let own_len =
        PlaneBuf::from_vec((0..e.pixels()).map(|_| if rng.next_f32() < 0.03 { 1.0 } else { 12.0 }).collect(), e)
            .unwrap();
    let other_len = PlaneBuf::new(e, 9.0f32);
    let lengths = accumulate::BlendLengths { own: own_len.view(), other: other_len.view(), alpha: 0.2 };
    simd_and_scalar(&mut group, |simd| {
        let blend = if simd { accumulate::blend_by_variance } else { accumulate::blend_by_variance_scalar };
        blend(&f.left.colour.view(), out.view_mut(), &reason.view(), &lengths, 16).expect("valid input")
    });
    group.finish();
}

/// The neighbourhood clamp of a 1280×720 history (the left eye's previous frame) into the
/// boxes of this frame's samples, 97 % of the pixels reprojected; the work is the same
/// whether a history moves or not (every box is computed), so repeating it in place is fair.
fn neighbourhood_clamp(c: &mut Criterion) {
    let f = Fixture::new();
    let e = f.extent();
    let mut rng = Rng::new(44);
    let reason = PlaneBuf::from_vec((0..e.pixels()).map(|_| u8::from(rng.next_f32() < 0.03)).collect(), e).unwrap();
    let mut history = f.left_prev.colour.clone();
    let mut group = c.benchmark_group("clamp");
    group.throughput(Throughput::Elements(e.pixels() as u64));
    simd_and_scalar(&mut group, |simd| {
        let input = ClampInput { new: f.left.colour.view(), has_new: None, reason: reason.view() };
        let run = if simd { clamp::clamp_history } else { clamp::clamp_history_scalar };
        run(&input, history.view_mut(), &ClampParams::default()).expect("valid input")
    });
    group.finish();
}

/// The history confidence of a 1280×720 frame from its 427×240 strata: luminance pairs with
/// a change on a third of them (a moving light's share), throughput in pixels written.
fn gradients(c: &mut Criterion) {
    let e = Fixture::new().extent();
    let strata = gradient::strata_extent(e);
    let mut rng = Rng::new(43);
    let old = PlaneBuf::from_vec((0..strata.pixels()).map(|_| rng.range(0.0, 2.0)).collect(), strata).unwrap();
    let new = PlaneBuf::from_vec(
        old.as_slice().iter().map(|&v| if rng.next_f32() < 0.33 { v * rng.range(0.0, 2.0) } else { v }).collect(),
        strata,
    )
    .unwrap();
    let mut out = PlaneBuf::new(e, 0.0f32);
    let mut group = c.benchmark_group("gradient_confidence");
    group.throughput(Throughput::Elements(e.pixels() as u64));
    simd_and_scalar(&mut group, |simd| {
        let input = GradientInput { old: old.view(), new: new.view(), prior: None, gain: 1.0 };
        let run = if simd { gradient::history_confidence } else { gradient::history_confidence_scalar };
        run(&input, out.view_mut()).expect("valid input")
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = ema_and_blend, neighbourhood_clamp, gradients, common::triad
}
criterion_main!(benches);
