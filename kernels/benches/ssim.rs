//! SSIM + RMSE at 1280×720 RGB: the f64 scalar reference and the fused SIMD kernel in one
//! group, the kernel with every instruction set this CPU has (8-lane AVX2, 16-lane AVX-512)
//! on 1 and 2 threads, both variants, throughput in pixels.
//!
//! Two inputs, built outside the timed loop from fixed seeds:
//! * `ldr`: uniform noise in [0, 1) against itself plus noise (no refinement happens);
//! * `hdr`: a path-tracer-like frame (smooth shading from 0.01 to 10, a 1000-level emitter
//!   with a sharp edge, fireflies up to 10⁶) against a noisier copy. Some tiles need
//!   refinement passes here; the setup prints how many voxels.
//!
//! Run: `cargo bench -p stereotrace-kernels --bench ssim` (add `-- <filter>` to pick a case).

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rayon::ThreadPool;
use stereotrace_kernels::frame::{Extent, RgbBuf};
use stereotrace_kernels::isa::Isa;
use stereotrace_kernels::ssim::{self, SsimParams, SsimVariant};

const WIDTH: usize = 1280;
const HEIGHT: usize = 720;

fn pool(threads: usize) -> ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool")
}

/// xorshift64*: deterministic inputs without a rand dependency.
struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn image(mut f: impl FnMut(usize, usize, usize) -> f32) -> RgbBuf {
    let mut img = RgbBuf::new(Extent::new(WIDTH, HEIGHT).unwrap(), 0.0);
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            img.set(x, y, [0, 1, 2].map(|c| f(x, y, c)));
        }
    }
    img
}

fn ldr() -> (RgbBuf, RgbBuf) {
    let mut r = XorShift(0x5eed_0001);
    let a = image(|_, _, _| r.unit());
    let b = image(|x, y, c| a.get(x, y)[c] + 0.25 * (r.unit() - 0.5));
    (a, b)
}

fn hdr() -> (RgbBuf, RgbBuf) {
    let mut r = XorShift(0x5eed_0002);
    let tint = [1.0f32, 0.8, 0.6];
    let shade = |x: usize, y: usize, c: usize| {
        let (u, v) = (x as f32 / WIDTH as f32, y as f32 / HEIGHT as f32);
        // An emitter (a lamp) with a sharp edge, and diffuse shading over three decades.
        if (0.4..0.6).contains(&u) && (0.05..0.15).contains(&v) {
            1000.0 * tint[c]
        } else {
            tint[c] * (0.01 + 10.0 * (1.0 - v) * (u * 6.0).sin().abs() * (v * 9.0).cos().abs())
        }
    };
    let noisy = |r: &mut XorShift, amount: f32| {
        image(|x, y, c| {
            let v = shade(x, y, c);
            let firefly = r.next().is_multiple_of(20_000);
            if firefly { 1e3 + 1e6 * r.unit() } else { v * (1.0 + amount * (r.unit() - 0.5)) }
        })
    };
    let reference = noisy(&mut r, 0.02);
    let frame = noisy(&mut r, 0.5);
    (reference, frame)
}

fn bench_ssim(c: &mut Criterion) {
    let pixels = (WIDTH * HEIGHT) as u64;
    for (name, (a, b)) in [("ldr", ldr()), ("hdr", hdr())] {
        let mut group = c.benchmark_group(format!("ssim/{name}/1280x720"));
        group.throughput(Throughput::Elements(pixels));
        group.sample_size(10);
        for variant in [SsimVariant::Volume, SsimVariant::PerChannel] {
            let params = SsimParams::with_variant(variant);
            let v = match variant {
                SsimVariant::Volume => "volume",
                SsimVariant::PerChannel => "per-channel",
            };
            let fast = ssim::ssim(&a.view(), &b.view(), &params).unwrap();
            let reference = ssim::ssim_scalar(&a.view(), &b.view(), &params).unwrap();
            eprintln!(
                "{name} {v}: ssim {:.9} (scalar {:.9}, Δ {:.1e}), rmse {:.6}, refined {} of {} voxels",
                fast.ssim,
                reference.ssim,
                fast.ssim - reference.ssim,
                fast.rmse,
                fast.refined,
                fast.voxels
            );
            group.bench_function(BenchmarkId::new(format!("{v}/scalar"), 1), |bench| {
                bench.iter(|| ssim::ssim_scalar(black_box(&a.view()), black_box(&b.view()), &params).unwrap())
            });
            // Every instruction set this CPU has, in the same run (AVX2: 8 lanes; AVX-512:
            // 16 lanes, what `ssim` picks on such a CPU unless STEREOTRACE_ISA=avx2).
            for isa in Isa::supported() {
                for threads in [1, 2] {
                    let pool = pool(threads);
                    let id = BenchmarkId::new(format!("{v}/simd-{}", isa.name()), threads);
                    group.bench_function(id, |bench| {
                        pool.install(|| {
                            bench.iter(|| {
                                ssim::ssim_with(black_box(&a.view()), black_box(&b.view()), &params, isa).unwrap()
                            })
                        })
                    });
                }
            }
        }
        group.finish();
    }
}

criterion_group!(benches, bench_ssim);
criterion_main!(benches);
