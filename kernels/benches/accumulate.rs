//! EMA accumulation and the stereo blend at 1280×720, the scalar references beside the SIMD
//! bodies, on 1 and 2 threads, throughput in pixels; the memory triad of the same run for the
//! roofline.
//!
//! Run: `cargo bench -p stereotrace-kernels --bench accumulate`.

mod common;

use std::hint::black_box;

use common::{Fixture, pool};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use stereotrace_kernels::accumulate::{self, BlendParams, EmaInput, EmaParams, EmaState};
use stereotrace_kernels::frame::PlaneBuf;
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
    group.finish();

    let mut group = c.benchmark_group("blend");
    group.throughput(Throughput::Elements(e.pixels() as u64));
    let mut out = f.right.colour.clone();
    for threads in [1, 2] {
        let pool = pool(threads);
        for simd in [true, false] {
            group.bench_function(BenchmarkId::new(if simd { "simd" } else { "scalar" }, threads), |b| {
                b.iter(|| {
                    pool.install(|| {
                        let f_blend = if simd { accumulate::blend } else { accumulate::blend_scalar };
                        black_box(
                            f_blend(&f.left.colour.view(), out.view_mut(), &reason.view(), &BlendParams::default())
                                .expect("valid input"),
                        )
                    })
                })
            });
        }
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = ema_and_blend, common::triad
}
criterion_main!(benches);
