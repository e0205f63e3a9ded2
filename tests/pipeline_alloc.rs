//! A frame through a warmed-up pipeline allocates nothing, in every mode and with either
//! G-buffer pass (one test per file: the counting allocator sees the whole process).

use stereotrace::camera::StereoRig;
use stereotrace::kernels::Extent;
use stereotrace::kernels::check::CountingAllocator;
use stereotrace::pipeline::{GBufferPass, Mode, Order, Pipeline, PipelineConfig};
use stereotrace::render::Renderer;
use stereotrace::scene::resolve;

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator::new();

#[test]
fn frames_after_the_first_allocate_nothing() {
    // The moving-light scene exercises the per-frame light table too.
    let renderer = Renderer::new(resolve("living-room-moving-light").unwrap()).unwrap();
    let e = Extent::new(64, 36).unwrap();
    let poses: Vec<_> = (0..4).map(|f| renderer.scene().camera.pose_at(f as f32)).collect();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let cases = Mode::ALL.into_iter().flat_map(|mode| {
        [Order::Paper, Order::StereoFirst].into_iter().flat_map(move |order| {
            [GBufferPass::Raster, GBufferPass::Traced].into_iter().map(move |pass| (mode, order, pass))
        })
    });
    for (mode, order, pass) in cases {
        for budget in [None, Some(std::time::Duration::from_micros(300))] {
            let mut cfg = PipelineConfig::paper(mode, 1, renderer.scene().tolerances.at_height(36));
            cfg.order = order;
            cfg.gbuffer = pass;
            cfg.ramp = true;
            cfg.budget = budget;
            let mut pipeline = Pipeline::new(&renderer, cfg, StereoRig::default(), e).unwrap();
            let allocated = pool.install(|| {
                for f in 0..2 {
                    pipeline.render_frame(f, &poses[f as usize]).unwrap();
                }
                let before = GLOBAL.allocations();
                for f in 2..4 {
                    pipeline.render_frame(f, &poses[f as usize]).unwrap();
                }
                GLOBAL.allocations() - before
            });
            assert_eq!(
                allocated, 0,
                "{mode} {order:?} {pass:?} G-buffer, budget {budget:?}: {allocated} allocations in two frames"
            );
        }
    }
}
