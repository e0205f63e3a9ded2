//! Stereo and temporal reprojection at 1280×720 in both G-buffer layouts (and with motion
//! planes), the scalar reference beside the SIMD body, on 1 and 2 threads, throughput in
//! pixels; the band height sweep; the memory triad of the same run for the roofline. On an
//! AVX-512 CPU `simd` is the body compiled with AVX-512 and `simd-avx2` the baseline's
//! (`STEREOTRACE_ISA=avx2` makes `simd` the baseline's too).
//!
//! Run: `cargo bench -p stereotrace-kernels --bench reproject` (add `-- <filter>`).

mod common;

use common::{Fixture, Optional, Outputs, pool, run_reprojection};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use stereotrace_kernels::frame::PlaneBuf;
use stereotrace_kernels::isa::Isa;
use stereotrace_kernels::reproject::ReprojectParams;

/// The bodies each group times: `simd` is the one the kernel takes on this CPU
/// ([`Isa::active`]); on an AVX-512 CPU `simd-avx2` is the 8-lane body compiled for the
/// baseline, so the two copies are compared in one run.
fn bodies() -> Vec<(&'static str, Option<Isa>)> {
    let mut bodies = vec![("simd", Some(Isa::active()))];
    if Isa::active() == Isa::Avx512 {
        bodies.push(("simd-avx2", Some(Isa::Avx2)));
    }
    bodies.push(("scalar", None));
    bodies
}

fn reprojection(c: &mut Criterion) {
    let f = Fixture::new();
    let mut out = Outputs::new(f.extent());
    for (group_name, target, source) in
        [("reproject_stereo", &f.left, &f.right), ("reproject_temporal", &f.left, &f.left_prev)]
    {
        let mut group = c.benchmark_group(group_name);
        group.throughput(Throughput::Elements(f.extent().pixels() as u64));
        for threads in [1, 2] {
            let pool = pool(threads);
            for (body, isa) in bodies() {
                group.bench_function(BenchmarkId::new(format!("{body}/compact"), threads), |b| {
                    let (t, s) = (target.compact(), source.compact());
                    b.iter(|| {
                        pool.install(|| run_reprojection(&t, &s, source, &f.params, &mut out, isa, Optional::default()))
                    })
                });
                group.bench_function(BenchmarkId::new(format!("{body}/full"), threads), |b| {
                    let (t, s) = (target.gbuffer(), source.gbuffer());
                    b.iter(|| {
                        pool.install(|| run_reprojection(&t, &s, source, &f.params, &mut out, isa, Optional::default()))
                    })
                });
                if group_name == "reproject_temporal" {
                    // Zero motion vectors: the same result, so this prices reading them.
                    let still = [0; 3].map(|_| PlaneBuf::new(f.extent(), 0.0f32));
                    group.bench_function(BenchmarkId::new(format!("{body}/compact+motion"), threads), |b| {
                        let (t, s) = (target.compact(), source.compact());
                        b.iter(|| {
                            pool.install(|| {
                                run_reprojection(
                                    &t,
                                    &s,
                                    source,
                                    &f.params,
                                    &mut out,
                                    isa,
                                    Optional { motion: Some(&still), ..Optional::default() },
                                )
                            })
                        })
                    });
                }
            }
        }
        group.finish();
    }
}
/// Background pixels reprojected by direction (beyond the paper): both eyes and the left
/// eye's last frame of the fixture's cameras with nothing in view, so every pixel is sky
/// (the stereo pair's footprints are one source row, the turned camera's are gathered).
fn sky(c: &mut Criterion) {
    let f = Fixture::new();
    let empty = stereotrace_kernels::synth::AnalyticScene::default();
    let render = |frame: &stereotrace_kernels::synth::SynthFrame| empty.render(&frame.surfaces.camera, [0.5, 0.6, 0.8]);
    let (left, right, left_prev) = (render(&f.left), render(&f.right), render(&f.left_prev));
    let mut out = Outputs::new(f.extent());
    let mut group = c.benchmark_group("reproject_sky");
    group.throughput(Throughput::Elements(f.extent().pixels() as u64));
    for (name, source) in [("stereo", &right), ("temporal", &left_prev)] {
        for threads in [1, 2] {
            let pool = pool(threads);
            for (body, isa) in bodies() {
                group.bench_function(BenchmarkId::new(format!("{name}/{body}"), threads), |b| {
                    let (t, s) = (left.compact(), source.compact());
                    let optional = Optional { background: Some(&left.surfaces.camera), ..Optional::default() };
                    b.iter(|| pool.install(|| run_reprojection(&t, &s, source, &f.params, &mut out, isa, optional)))
                });
            }
        }
    }
    group.finish();
}

/// The paper-order left eye's temporal reprojection, which runs only where its stereo
/// reprojection was discarded: the pixel mask is the stereo call's discarded pixels (0.9 %
/// of this room, along its silhouettes and borders), the pair the temporal one.
fn masked_temporal(c: &mut Criterion) {
    let f = Fixture::new();
    let mask = f.stereo_discarded();
    let (left, prev) = (f.left.compact(), f.left_prev.compact());
    let mut out = Outputs::new(f.extent());
    let mut group = c.benchmark_group("reproject_temporal_masked");
    group.throughput(Throughput::Elements(f.extent().pixels() as u64));
    for threads in [1, 2] {
        let pool = pool(threads);
        for (body, isa) in bodies() {
            group.bench_function(BenchmarkId::new(format!("{body}/compact"), threads), |b| {
                let optional = Optional { pixel_mask: Some(&mask), ..Optional::default() };
                b.iter(|| {
                    pool.install(|| run_reprojection(&left, &prev, &f.left_prev, &f.params, &mut out, isa, optional))
                })
            });
            // As the pipeline runs it: the frame's other stages have moved the planes out of
            // the caches, and the few wanted pixels' lines come from memory. Only the call is
            // timed, not the eviction.
            let mut evict = vec![0u8; EVICT_BYTES];
            group.bench_function(BenchmarkId::new(format!("{body}/compact-cold"), threads), |b| {
                let optional = Optional { pixel_mask: Some(&mask), ..Optional::default() };
                b.iter_custom(|iters| {
                    let mut total = std::time::Duration::ZERO;
                    for i in 0..iters {
                        evict.fill(i as u8);
                        std::hint::black_box(&evict);
                        let start = std::time::Instant::now();
                        pool.install(|| {
                            run_reprojection(&left, &prev, &f.left_prev, &f.params, &mut out, isa, optional)
                        });
                        total += start.elapsed();
                    }
                    total
                })
            });
        }
    }
    group.finish();
}

/// Bytes written between the cold runs: twice the last-level cache of the machines this runs
/// on (32 MiB per Zen 4 or Zen 5 CCD).
const EVICT_BYTES: usize = 64 << 20;

/// Band height sweep for the stereo reprojection (SIMD, compact, 2 threads).
fn band_rows(c: &mut Criterion) {
    let f = Fixture::new();
    let mut out = Outputs::new(f.extent());
    let mut group = c.benchmark_group("reproject_band_rows");
    group.throughput(Throughput::Elements(f.extent().pixels() as u64));
    let pool = pool(2);
    for rows in [2, 4, 8, 16, 32, 64] {
        let params = ReprojectParams { band_rows: rows, ..f.params };
        group.bench_function(BenchmarkId::from_parameter(rows), |b| {
            let (t, s) = (f.left.compact(), f.right.compact());
            b.iter(|| {
                pool.install(|| {
                    run_reprojection(&t, &s, &f.right, &params, &mut out, Some(Isa::active()), Optional::default())
                })
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = reprojection, masked_temporal, sky, band_rows, common::triad
}
criterion_main!(benches);
