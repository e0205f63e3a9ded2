//! The SSIM kernel allocates nothing, including its refinement passes and its exact f64
//! fallback, on a two-thread rayon pool.
//!
//! A counting global allocator sees every allocation in the process, on every thread, so
//! this file holds a single test (the test harness itself allocates between tests).

use stereotrace_kernels::check::CountingAllocator;
use stereotrace_kernels::frame::{Extent, RgbBuf};
use stereotrace_kernels::ssim::{self, SsimParams, SsimVariant};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator::new();

#[test]
// With `check-scalar`, every call also runs the (allocating) scalar reference.
#[cfg_attr(feature = "check-scalar", ignore)]
fn ssim_allocates_nothing() {
    let e = Extent::new(203, 77).unwrap();
    // Bright flat blocks with tiny noise beside dark ones (refinement passes and, with the
    // 1e5 level, the exact fallback), a NaN and a firefly.
    let mut a = RgbBuf::new(e, 0.0);
    let mut b = RgbBuf::new(e, 0.0);
    let mut rng = stereotrace_kernels::synth::Rng::new(0x1234_5678);
    let mut noise = || rng.next_f32();
    for y in 0..e.height() {
        for x in 0..e.width() {
            let level = [1e5f32, 0.02, 5.0, 1000.0][(x / 9 + y / 7) % 4];
            let px = [0, 1, 2].map(|c| level * (1.0 + 1e-4 * noise()) * [1.0, 0.7, 0.4][c]);
            a.set(x, y, px);
            b.set(x, y, px.map(|v| v + 0.01 * (noise() - 0.5)));
        }
    }
    b.set(100, 40, [f32::NAN, 1.0, 1.0]);
    b.set(10, 10, [1e6, 1.0, 1.0]);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    for variant in [SsimVariant::Volume, SsimVariant::PerChannel] {
        let params = SsimParams::with_variant(variant);
        let first = pool.install(|| ssim::ssim(&a.view(), &b.view(), &params).unwrap());
        assert!(first.refined > 0, "{variant:?}: the image should need refinement: {first:?}");
        // rayon itself allocates now and then (its job queues grow in blocks), so one call
        // in a few sees an allocation that is not the kernel's; a kernel allocation would
        // show in every call.
        let mut fewest = u64::MAX;
        for _ in 0..8 {
            let before = GLOBAL.allocations();
            let again = pool.install(|| ssim::ssim(&a.view(), &b.view(), &params).unwrap());
            fewest = fewest.min(GLOBAL.allocations() - before);
            assert_eq!(first, again);
        }
        assert_eq!(fewest, 0, "{variant:?}: every call allocated");
    }
}
