//! What the kernel benches share: 1280×720 analytic frames built outside the timed loop
//! (deterministic), thread pools, and the STREAM triad that gives the memory roofline the
//! kernels are compared against in the same run.

#![allow(dead_code)] // each bench uses part of it

use std::hint::black_box;

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, BenchmarkId, Criterion, Throughput};
use glam::Vec3;
use rayon::ThreadPool;
use stereotrace_kernels::frame::{Extent, PlaneBuf, RgbBuf};
use stereotrace_kernels::gbuffer::SurfaceLayout;
use stereotrace_kernels::isa::Isa;
use stereotrace_kernels::reproject::{self, Reason, ReprojectInput, ReprojectOutput, ReprojectParams, Tolerances};
use stereotrace_kernels::synth::{AnalyticScene, SynthFrame, camera_at};

pub const WIDTH: usize = 1280;
pub const HEIGHT: usize = 720;

pub fn pool(threads: usize) -> ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool")
}

/// Times `run(simd)` as `simd/T` and `scalar/T` in `group` on T = 1 and 2 threads: a
/// kernel's SIMD body beside its scalar reference, in one run.
pub fn simd_and_scalar<R: Send>(group: &mut BenchmarkGroup<'_, WallTime>, mut run: impl FnMut(bool) -> R + Send) {
    for threads in [1, 2] {
        let pool = pool(threads);
        for simd in [true, false] {
            group.bench_function(BenchmarkId::new(if simd { "simd" } else { "scalar" }, threads), |b| {
                b.iter(|| pool.install(|| black_box(run(simd))))
            });
        }
    }
}

/// Left and right eye of the analytic room, plus the left eye one frame earlier (the
/// observer moved 1 cm forward and turned 0.2°).
pub struct Fixture {
    pub left: SynthFrame,
    pub right: SynthFrame,
    pub left_prev: SynthFrame,
    pub params: ReprojectParams,
}

impl Fixture {
    pub fn new() -> Self {
        let e = Extent::new(WIDTH, HEIGHT).unwrap();
        let scene = AnalyticScene::room(6.0);
        let left = scene.render(&camera_at(Vec3::new(-0.0325, 0.0, 0.0), e, 60.0), [0.0; 3]);
        let right = scene.render(&camera_at(Vec3::new(0.0325, 0.0, 0.0), e, 60.0), [0.0; 3]);
        let prev_view = stereotrace_kernels::camera::look_at_perspective(
            Vec3::new(-0.0325, 0.0, 0.01),
            Vec3::new(-0.0325 + 0.2f32.to_radians().tan(), 0.0, -0.99),
            Vec3::Y,
            60f32.to_radians(),
            e,
        );
        let left_prev =
            scene.render(&stereotrace_kernels::CameraModel::new(prev_view, e).expect("valid camera"), [0.0; 3]);
        // 1280×720 at 6 m: a pixel spans ~1 cm, so 5 cm and 3 % are the scene-scale tolerances.
        let params = ReprojectParams { tolerances: Tolerances::new(0.05, 0.03, 25.0), ..ReprojectParams::default() };
        Self { left, right, left_prev, params }
    }

    pub fn extent(&self) -> Extent {
        self.left.extent()
    }

    /// 1 where the right eye's stereo reprojection into the left eye is discarded (0.9 % of
    /// the room): the pixels the paper-order left eye traces, reprojects its history for and
    /// accumulates.
    pub fn stereo_discarded(&self) -> PlaneBuf<u8> {
        let mut stereo = Outputs::new(self.extent());
        let (target, source) = (self.left.compact(), self.right.compact());
        run_reprojection(
            &target,
            &source,
            &self.right,
            &self.params,
            &mut stereo,
            Some(Isa::active()),
            Optional::default(),
        );
        let discarded = stereo.reason.as_slice().iter().map(|&r| u8::from(r != Reason::Reprojected as u8)).collect();
        PlaneBuf::from_vec(discarded, self.extent()).unwrap()
    }
}

pub struct Outputs {
    pub colour: RgbBuf,
    pub reason: PlaneBuf<u8>,
}

impl Outputs {
    pub fn new(e: Extent) -> Self {
        Self { colour: RgbBuf::new(e, 0.0), reason: PlaneBuf::new(e, 0) }
    }
}

/// The optional inputs of a reprojection a bench may add (none by default).
#[derive(Clone, Copy, Default)]
pub struct Optional<'a> {
    /// Motion planes of the target's surfaces.
    pub motion: Option<&'a [PlaneBuf; 3]>,
    /// Only the pixels where it is non-zero are reprojected.
    pub pixel_mask: Option<&'a PlaneBuf<u8>>,
    /// The target camera: background pixels reprojected by direction.
    pub background: Option<&'a stereotrace_kernels::CameraModel>,
}

pub fn run_reprojection<L: SurfaceLayout>(
    target: &L,
    source: &L,
    source_frame: &SynthFrame,
    params: &ReprojectParams,
    out: &mut Outputs,
    body: Option<Isa>,
    optional: Optional<'_>,
) {
    let input = ReprojectInput {
        target,
        source,
        source_camera: &source_frame.surfaces.camera,
        colour: source_frame.colour.view(),
        extra: None,
        pixel_mask: optional.pixel_mask.map(|m| m.view()),
        motion: optional.motion.map(|m| m.each_ref().map(|p| p.view())),
        jitter: None,
        background: optional.background,
    };
    let o = ReprojectOutput { colour: out.colour.view_mut(), extra: None, reason: out.reason.view_mut(), weight: None };
    let counts = match body {
        Some(isa) => reproject::reproject_with(&input, o, params, isa),
        None => reproject::reproject_scalar(&input, o, params),
    };
    black_box(counts.expect("valid input"));
}

/// STREAM triad `a = b + s·c` over three 48 MB arrays (far beyond L3): the memory roofline
/// the reprojection and EMA figures are compared against. Bytes moved per element: 12
/// (read b, read c, write a) plus 4 for the write-allocate read of `a`.
pub fn triad(c: &mut Criterion) {
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

/// The configuration every kernel bench runs with: 20 samples of 3 s after 1 s of warm-up.
pub fn criterion() -> Criterion {
    Criterion::default()
        .sample_size(20)
        .warm_up_time(std::time::Duration::from_secs(1))
        .measurement_time(std::time::Duration::from_secs(3))
}
