//! The à-trous filter at 1280×720 on the analytic room with noise (depth steps, a slanted
//! floor): one pass and SVGF's five, the scalar reference beside the SIMD body, on 1 and 2
//! threads, throughput in pixels. Each iteration reads 8 planes (colour, variance, depth,
//! normal) at 25 taps and writes 4; the taps come from L1/L2, so the filter is bound by its
//! arithmetic (about 70 operations a tap), not by memory.
//!
//! Run: `cargo bench -p stereotrace-kernels --bench atrous`.

mod common;

use std::hint::black_box;

use common::{Fixture, pool};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use stereotrace_kernels::atrous::{self, AtrousGuide, AtrousParams, AtrousScratch, GuideNormals};
use stereotrace_kernels::frame::RgbBuf;
use stereotrace_kernels::synth::Rng;

fn atrous_filter(c: &mut Criterion) {
    let f = Fixture::new();
    let e = f.extent();
    let mut rng = Rng::new(44);
    let mut noisy = f.left.colour.clone();
    for plane in noisy.slices_mut() {
        for v in plane {
            // 1-spp-like noise: most samples dark, a few bright.
            *v *= if rng.next_f32() < 0.1 { rng.range(2.0, 8.0) } else { rng.range(0.0, 1.2) };
        }
    }
    let g = &f.left.surfaces;
    let guide = AtrousGuide { depth: g.depth.view(), normals: GuideNormals::Octahedral(g.normal_oct.view()) };
    let mut scratch = AtrousScratch::try_new(e).unwrap();
    let mut out = RgbBuf::new(e, 0.0);
    let mut group = c.benchmark_group("atrous");
    group.throughput(Throughput::Elements(e.pixels() as u64));
    for threads in [1, 2] {
        let pool = pool(threads);
        for iterations in [1, 5] {
            for simd in [true, false] {
                let name = format!("{}/{iterations}", if simd { "simd" } else { "scalar" });
                let params = AtrousParams { iterations, ..AtrousParams::default() };
                group.bench_function(BenchmarkId::new(name, threads), |b| {
                    b.iter(|| {
                        pool.install(|| {
                            let run = if simd { atrous::atrous } else { atrous::atrous_scalar };
                            black_box(run(&noisy.view(), &guide, &params, &mut scratch, out.view_mut()).unwrap())
                        })
                    })
                });
            }
        }
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = atrous_filter
}
criterion_main!(benches);
