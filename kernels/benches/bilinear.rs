//! Bilinear resampling at 1280×720 along a near-identity map, the scalar reference beside the
//! SIMD body, on 1 and 2 threads, throughput in pixels.
//!
//! Run: `cargo bench -p stereotrace-kernels --bench bilinear`.

mod common;

use common::{Fixture, WIDTH, simd_and_scalar};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use stereotrace_kernels::bilinear::{self, ResampleInput, ResampleOutput};
use stereotrace_kernels::frame::{PlaneBuf, RgbBuf};

fn bilinear_resample(c: &mut Criterion) {
    let f = Fixture::new();
    let e = f.extent();
    // A smooth warp (a slight zoom and shear): sub-pixel positions everywhere.
    let map_x = PlaneBuf::from_vec(
        (0..e.pixels()).map(|i| (i % WIDTH) as f32 * 0.993 + 3.3 + (i / WIDTH) as f32 * 0.01).collect(),
        e,
    )
    .unwrap();
    let map_y = PlaneBuf::from_vec((0..e.pixels()).map(|i| (i / WIDTH) as f32 * 1.007 + 0.7).collect(), e).unwrap();
    let input =
        ResampleInput { source: f.right.colour.view(), source_valid: None, map_x: map_x.view(), map_y: map_y.view() };
    let mut colour = RgbBuf::new(e, 0.0);
    let mut weight = PlaneBuf::new(e, 0.0f32);
    let mut group = c.benchmark_group("bilinear");
    group.throughput(Throughput::Elements(e.pixels() as u64));
    simd_and_scalar(&mut group, |simd| {
        let out = ResampleOutput { colour: colour.view_mut(), weight: weight.view_mut() };
        if simd { bilinear::resample(&input, out) } else { bilinear::resample_scalar(&input, out) }
            .expect("valid input")
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = common::criterion();
    targets = bilinear_resample
}
criterion_main!(benches);
