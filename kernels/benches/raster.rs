//! The visibility-buffer rasterisers at 1280×720, both eyes of a stereo pair in one call, on
//! the built-in scenes' own triangles seen by their camera path's first pose (6.5 cm eye
//! separation): the exact rasteriser (`raster`) and the fixed-point one (`raster::fixed`),
//! each with the SIMD body and its scalar reference, on 1 and 2 threads. Throughput is in
//! pixels of both eyes (criterion's "elem/s"). No alpha masks (the scenes' masked materials
//! are the renderer's business: `tests/raster_gbuffers.rs` in the root crate covers them).
//!
//! The G-buffer pass around this kernel (resolving the visibility ids into depth, position,
//! normal and material planes) is in the root crate's `render` bench.
//!
//! Run: `cargo bench -p stereotrace-kernels --bench raster` (add `-- <filter>` such as
//! `raster/atrium` to pick scenes).

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rayon::ThreadPool;
use stereotrace_kernels::bvh::TriVerts;
use stereotrace_kernels::raster::fixed::FixedRasterizer;
use stereotrace_kernels::raster::{Body, NoMasks, Rasterizer, Triangles, VisibilityBuffer};
use stereotrace_kernels::{CameraModel, Extent};
use stereotrace_runtime::camera::{Eye, StereoRig};

const WIDTH: usize = 1280;
const HEIGHT: usize = 720;

/// The built-in scenes with distinct geometry (the glossy, mirror and moving-light variants
/// share theirs).
const SCENES: [&str; 5] = ["cornell", "atrium", "living-room", "classroom", "courtyard"];

fn pool(threads: usize) -> ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool")
}

/// A scene's triangles, both eyes' cameras and the near plane the renderer uses for it.
struct Fixture {
    tris: Vec<TriVerts>,
    cameras: [CameraModel; 2],
    near: f32,
}

fn fixture(name: &str) -> Fixture {
    let scene = stereotrace_runtime::scene::resolve(name).expect("built-in scenes load");
    let extent = Extent::new(WIDTH, HEIGHT).expect("1280×720");
    let head = scene.camera.pose_at(0.0);
    let rig = StereoRig::default();
    let cameras = Eye::BOTH.map(|eye| rig.eye_camera(&head, eye, extent).expect("a valid camera"));
    let tris = bytemuck::cast_slice(&scene.mesh.positions).to_vec();
    // The renderer's near plane: a millionth of the scene's diagonal.
    let near = (scene.bounds().extent().length() * 1e-6).max(1e-9);
    Fixture { tris, cameras, near }
}

fn raster(c: &mut Criterion) {
    let extent = Extent::new(WIDTH, HEIGHT).expect("1280×720");
    for name in SCENES {
        let f = fixture(name);
        let mut g = c.benchmark_group(format!("raster/{name}"));
        g.throughput(Throughput::Elements(2 * extent.pixels() as u64));
        let mut out = [VisibilityBuffer::new(extent), VisibilityBuffer::new(extent)];
        for threads in [1, 2] {
            let pool = pool(threads);
            for body in [Body::Simd, Body::Scalar] {
                let tris = Triangles { main: &f.tris, extra: &[] };
                let cams = [&f.cameras[0], &f.cameras[1]];
                let mut exact = Rasterizer::new();
                g.bench_function(BenchmarkId::new(format!("exact_{body:?}"), format!("{threads}t")), |b| {
                    b.iter(|| {
                        let [l, r] = &mut out;
                        pool.install(|| exact.rasterize(tris, cams, &NoMasks, f.near, [l, r], body)).unwrap();
                        black_box(&out);
                    })
                });
                let mut fixed = FixedRasterizer::new();
                g.bench_function(BenchmarkId::new(format!("fixed_{body:?}"), format!("{threads}t")), |b| {
                    b.iter(|| {
                        let [l, r] = &mut out;
                        pool.install(|| fixed.rasterize(tris, cams, &NoMasks, f.near, [l, r], body)).unwrap();
                        black_box(&out);
                    })
                });
            }
        }
        g.finish();
    }
}

criterion_group!(benches, raster);
criterion_main!(benches);
