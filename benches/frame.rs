//! One whole stereo frame per pipeline mode at 1280×720, 1 spp, on 2 threads (the real-time
//! configuration), with history (the pipeline is warmed up before measuring). The head walks
//! the scene's camera path forward and back (`CameraWalk::BackAndForth`, as the `throughput`
//! driver and the C ABI do; before 2026-11-24 it cycled the first 8 frames, jumping back
//! every 8th frame).
//!
//! Run: `cargo bench --bench frame` (scene via `STEREOTRACE_BENCH_SCENE`, default `atrium`).

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use stereotrace::camera::StereoRig;
use stereotrace::kernels::Extent;
use stereotrace::pipeline::{Mode, Order, Pipeline, PipelineConfig};
use stereotrace::render::Renderer;
use stereotrace::scene::resolve;
use stereotrace::session::{CameraWalk, Session};

fn frames(c: &mut Criterion) {
    let name = std::env::var("STEREOTRACE_BENCH_SCENE").unwrap_or_else(|_| "atrium".into());
    let renderer = Renderer::new(resolve(&name).expect("scene")).expect("renderer");
    let extent = Extent::new(1280, 720).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let mut group = c.benchmark_group(format!("stereo_frame/{name}"));
    group.throughput(Throughput::Elements(2 * extent.pixels() as u64));
    group.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(20));
    for mode in Mode::ALL {
        for order in [Order::Paper, Order::StereoFirst] {
            if order == Order::StereoFirst && !mode.has_order() {
                continue;
            }
            let mut config = PipelineConfig::paper(mode, 1, renderer.scene().tolerances.at_height(extent.height()));
            config.order = order;
            let pipeline = Pipeline::new(&renderer, config, StereoRig::default(), extent).expect("pipeline");
            let mut session = Session::new(pipeline, CameraWalk::BackAndForth);
            pool.install(|| session.next_frame().expect("frame"));
            let id = if mode.has_order() { format!("{mode}/{}", order.name()) } else { mode.to_string() };
            group.bench_function(BenchmarkId::from_parameter(id), |b| {
                b.iter(|| pool.install(|| session.next_frame().expect("frame")))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, frames);
criterion_main!(benches);
