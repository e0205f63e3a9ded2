//! Kernel benches at 1280×720: bilinear resampling, stereo and temporal reprojection (both
//! G-buffer layouts), EMA, stereo blend, and a STREAM-style triad for the memory roofline.
//! Scalar reference and SIMD body sit in one group, on 1 and 2 threads, with throughput in
//! pixels. Inputs are analytic scenes built outside the timed loop (deterministic).
//!
//! Run: `cargo bench --bench kernels` (add `-- <filter>` to pick a group).

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use rayon::ThreadPool;
use stereotrace::kernels::accumulate::{self, BlendParams, EmaInput, EmaParams, EmaState};
use stereotrace::kernels::bilinear::{self, ResampleInput, ResampleOutput};
use stereotrace::kernels::frame::{Extent, PlaneBuf, RgbBuf};
use stereotrace::kernels::gbuffer::SurfaceLayout;
use stereotrace::kernels::reproject::{self, ReprojectInput, ReprojectOutput, ReprojectParams, Tolerances};
use stereotrace::kernels::synth::{AnalyticScene, Rng, SynthFrame, camera_at};

const WIDTH: usize = 1280;
const HEIGHT: usize = 720;

fn pool(threads: usize) -> ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool")
}

/// Left and right eye of the analytic room, plus the left eye one frame earlier (the
/// observer moved 1 cm forward and turned 0.2°).
struct Fixture {
    left: SynthFrame,
    right: SynthFrame,
    left_prev: SynthFrame,
    params: ReprojectParams,
}

impl Fixture {
    fn new() -> Self {
        let e = Extent::new(WIDTH, HEIGHT).unwrap();
        let scene = AnalyticScene::room(6.0);
        let left = scene.render(&camera_at(Vec3::new(-0.0325, 0.0, 0.0), e, 60.0), [0.0; 3]);
        let right = scene.render(&camera_at(Vec3::new(0.0325, 0.0, 0.0), e, 60.0), [0.0; 3]);
        let prev_view = stereotrace::kernels::camera::look_at_perspective(
            Vec3::new(-0.0325, 0.0, 0.01),
            Vec3::new(-0.0325 + 0.2f32.to_radians().tan(), 0.0, -0.99),
            Vec3::Y,
            60f32.to_radians(),
            e,
        );
        let left_prev =
            scene.render(&stereotrace::kernels::CameraModel::new(prev_view, e).expect("valid camera"), [0.0; 3]);
        // 1280×720 at 6 m: a pixel spans ~1 cm, so 5 cm and 3 % are the scene-scale tolerances.
        let params = ReprojectParams { tolerances: Tolerances::new(0.05, 0.03, 25.0), ..ReprojectParams::default() };
        Self { left, right, left_prev, params }
    }

    fn extent(&self) -> Extent {
        self.left.extent()
    }
}

struct Outputs {
    colour: RgbBuf,
    reason: PlaneBuf<u8>,
}

impl Outputs {
    fn new(e: Extent) -> Self {
        Self { colour: RgbBuf::new(e, 0.0), reason: PlaneBuf::new(e, 0) }
    }
}

fn run_reprojection<L: SurfaceLayout>(
    target: &L,
    source: &L,
    source_frame: &SynthFrame,
    params: &ReprojectParams,
    out: &mut Outputs,
    simd: bool,
    motion: Option<&[PlaneBuf; 3]>,
) {
    let input = ReprojectInput {
        target,
        source,
        source_camera: &source_frame.surfaces.camera,
        colour: source_frame.colour.view(),
        extra: None,
        pixel_mask: None,
        motion: motion.map(|m| m.each_ref().map(|p| p.view())),
        jitter: None,
    };
    let o = ReprojectOutput { colour: out.colour.view_mut(), extra: None, reason: out.reason.view_mut(), weight: None };
    let counts =
        if simd { reproject::reproject(&input, o, params) } else { reproject::reproject_scalar(&input, o, params) };
    black_box(counts.expect("valid input"));
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
            for simd in [true, false] {
                let body = if simd { "simd" } else { "scalar" };
                group.bench_function(BenchmarkId::new(format!("{body}/compact"), threads), |b| {
                    let (t, s) = (target.compact(), source.compact());
                    b.iter(|| pool.install(|| run_reprojection(&t, &s, source, &f.params, &mut out, simd, None)))
                });
                group.bench_function(BenchmarkId::new(format!("{body}/full"), threads), |b| {
                    let (t, s) = (target.gbuffer(), source.gbuffer());
                    b.iter(|| pool.install(|| run_reprojection(&t, &s, source, &f.params, &mut out, simd, None)))
                });
                if group_name == "reproject_temporal" {
                    // Zero motion vectors: the same result, so this prices reading them.
                    let still = [0; 3].map(|_| PlaneBuf::new(f.extent(), 0.0f32));
                    group.bench_function(BenchmarkId::new(format!("{body}/compact+motion"), threads), |b| {
                        let (t, s) = (target.compact(), source.compact());
                        b.iter(|| {
                            pool.install(|| run_reprojection(&t, &s, source, &f.params, &mut out, simd, Some(&still)))
                        })
                    });
                }
            }
        }
        group.finish();
    }
}

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
            b.iter(|| pool.install(|| run_reprojection(&t, &s, &f.right, &params, &mut out, true, None)))
        });
    }
    group.finish();
}

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
    for threads in [1, 2] {
        let pool = pool(threads);
        for simd in [true, false] {
            group.bench_function(BenchmarkId::new(if simd { "simd" } else { "scalar" }, threads), |b| {
                b.iter(|| {
                    pool.install(|| {
                        let out = ResampleOutput { colour: colour.view_mut(), weight: weight.view_mut() };
                        let r =
                            if simd { bilinear::resample(&input, out) } else { bilinear::resample_scalar(&input, out) };
                        r.expect("valid input")
                    })
                })
            });
        }
    }
    group.finish();
}

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

/// STREAM triad `a = b + s·c` over three 48 MB arrays (far beyond L3): the memory roofline
/// the reprojection and EMA figures are compared against. Bytes moved per element: 12
/// (read b, read c, write a) plus 4 for the write-allocate read of `a`.
fn triad(c: &mut Criterion) {
    let n = 12 << 20;
    let b_arr = vec![1.0f32; n];
    let c_arr = vec![2.0f32; n];
    let mut a_arr = vec![0.0f32; n];
    let mut group = c.benchmark_group("memory");
    group.throughput(Throughput::Bytes((n * 12) as u64));
    for threads in [1, 2] {
        let pool = pool(threads);
        group.bench_function(BenchmarkId::new("triad", threads), |bencher| {
            use rayon::prelude::*;
            bencher.iter(|| {
                pool.install(|| {
                    a_arr
                        .par_chunks_mut(1 << 16)
                        .zip(b_arr.par_chunks(1 << 16))
                        .zip(c_arr.par_chunks(1 << 16))
                        .for_each(|((a, b), c)| {
                            for i in 0..a.len() {
                                a[i] = b[i] + 3.0 * c[i];
                            }
                        })
                });
                black_box(&a_arr);
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_secs(1)).measurement_time(std::time::Duration::from_secs(3));
    targets = reprojection, band_rows, bilinear_resample, ema_and_blend, triad
}
criterion_main!(benches);
