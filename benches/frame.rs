//! One whole stereo frame per pipeline mode at 1280×720, 1 spp, on 2 threads (the real-time
//! configuration), with history (the pipeline is warmed up before measuring).
//!
//! Run: `cargo bench --bench frame` (scene via `STEREOTRACE_BENCH_SCENE`, default `atrium`).

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use stereotrace::camera::StereoRig;
use stereotrace::kernels::Extent;
use stereotrace::pipeline::{Mode, Order, Pipeline, PipelineConfig};
use stereotrace::render::Renderer;
use stereotrace::scene::resolve;

fn frames(c: &mut Criterion) {
    let name = std::env::var("STEREOTRACE_BENCH_SCENE").unwrap_or_else(|_| "atrium".into());
    let renderer = Renderer::new(resolve(&name).expect("scene")).expect("renderer");
    let extent = Extent::new(1280, 720).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let poses: Vec<_> = (0..8).map(|f| renderer.scene().camera.pose(f)).collect();
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
            let mut pipeline = Pipeline::new(&renderer, config, StereoRig::default(), extent).expect("pipeline");
            pool.install(|| pipeline.render_frame(0, &poses[0]).expect("frame"));
            let mut i = 1;
            let id = if mode.has_order() { format!("{mode}/{}", order.name()) } else { mode.to_string() };
            group.bench_function(BenchmarkId::from_parameter(id), |b| {
                b.iter(|| {
                    let s = pool.install(|| pipeline.render_frame(i, &poses[i as usize % poses.len()]).expect("frame"));
                    i += 1;
                    s
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, frames);
criterion_main!(benches);
