//! A frame through a warmed-up pipeline, driven as every frame loop drives it (a `Session`),
//! allocates nothing, in every mode, with either G-buffer pass, with motion vectors, and for
//! temporal gradients, the variance blend and the à-trous filter, and for the mono baseline
//! (one test per file: the counting allocator sees the whole process).

use stereotrace::camera::StereoRig;
use stereotrace::kernels::Extent;
use stereotrace::kernels::check::CountingAllocator;
use stereotrace::pipeline::{Background, Blend, Filter, History, Mode, Order, Pipeline, PipelineConfig};
use stereotrace::render::{GBufferPass, Renderer, RendererOptions};
use stereotrace::scene::resolve;
use stereotrace::session::{CameraWalk, Session, View};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator::new();

#[test]
fn frames_after_the_first_allocate_nothing() {
    // The moving-light scene exercises the per-frame light table too.
    let renderer = Renderer::new(resolve("living-room-moving-light").unwrap()).unwrap();
    let e = Extent::new(64, 36).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let cases = Mode::ALL.into_iter().flat_map(|mode| {
        [Order::Paper, Order::StereoFirst].into_iter().flat_map(move |order| {
            [GBufferPass::Raster, GBufferPass::Traced, GBufferPass::Exact]
                .into_iter()
                .map(move |pass| (mode, order, pass))
        })
    });
    for (mode, order, pass) in cases {
        for budget in [None, Some(std::time::Duration::from_micros(300))] {
            let mut cfg = PipelineConfig::paper(mode, 1, renderer.scene().tolerances.at_height(36));
            cfg.order = order;
            cfg.ramp = true;
            cfg.budget = budget;
            let options = RendererOptions::with_gbuffer(pass);
            let pipeline = Pipeline::with_options(&renderer, options, cfg, StereoRig::default(), e).unwrap();
            let allocated = warm_then_count(&pool, Session::new(pipeline, CameraWalk::Path));
            assert_eq!(
                allocated, 0,
                "{mode} {order:?} {pass:?} G-buffer, budget {budget:?}: {allocated} allocations in two frames"
            );
        }
    }
    // Beyond the paper: temporal gradients (the light moves, so they trace), the variance
    // blend and the à-trous filter, all at once.
    for mode in [Mode::Spatiotemporal, Mode::SpatiotemporalBlend] {
        let mut cfg = PipelineConfig::paper(mode, 1, renderer.scene().tolerances.at_height(36));
        (cfg.history, cfg.blend, cfg.filter) = (History::Gradient, Blend::Variance, Filter::Atrous);
        let pipeline = Pipeline::new(&renderer, cfg, StereoRig::default(), e).unwrap();
        let allocated = warm_then_count(&pool, Session::new(pipeline, CameraWalk::Path));
        assert_eq!(allocated, 0, "{mode} with gradients, the variance blend and the filter");
        cfg.history = History::Clamp;
        let pipeline = Pipeline::new(&renderer, cfg, StereoRig::default(), e).unwrap();
        assert_eq!(warm_then_count(&pool, Session::new(pipeline, CameraWalk::Path)), 0, "{mode} with the clamp");
    }
    // The sky reprojected by direction (courtyard's open sky), under a budget and without.
    let courtyard = Renderer::new(resolve("courtyard").unwrap()).unwrap();
    for budget in [None, Some(std::time::Duration::from_micros(300))] {
        let mut cfg = PipelineConfig::paper(Mode::Spatiotemporal, 1, courtyard.scene().tolerances.at_height(36));
        (cfg.background, cfg.budget) = (Background::Reproject, budget);
        let pipeline = Pipeline::new(&courtyard, cfg, StereoRig::default(), e).unwrap();
        let allocated = warm_then_count(&pool, Session::new(pipeline, CameraWalk::Path));
        assert_eq!(allocated, 0, "the sky's reprojection, budget {budget:?}");
    }
    // Motion vectors, written where a moving area light is seen (atrium's sphere).
    let atrium = Renderer::new(resolve("atrium-moving-light").unwrap()).unwrap();
    let mut cfg = PipelineConfig::paper(Mode::Spatiotemporal, 1, atrium.scene().tolerances.at_height(36));
    cfg.motion_vectors = true;
    let pipeline = Pipeline::new(&atrium, cfg, StereoRig::default(), e).unwrap();
    assert_eq!(warm_then_count(&pool, Session::new(pipeline, CameraWalk::Path)), 0, "motion vectors allocate");
    let cfg = PipelineConfig::paper(Mode::PathTraced, 1, renderer.scene().tolerances.at_height(36));
    let pipeline = Pipeline::new(&renderer, cfg, StereoRig::default(), e).unwrap();
    let mono = Session::new(pipeline, CameraWalk::BackAndForth).with_view(View::Mono);
    assert_eq!(warm_then_count(&pool, mono), 0, "mono frames allocate");
}

/// Allocations in frames 2 and 3 of `session` (frames 0 and 1 warm it up).
fn warm_then_count(pool: &rayon::ThreadPool, mut session: Session<&Renderer>) -> u64 {
    pool.install(|| {
        for _ in 0..2 {
            session.next_frame().unwrap();
        }
        let before = GLOBAL.allocations();
        for _ in 0..2 {
            session.next_frame().unwrap();
        }
        GLOBAL.allocations() - before
    })
}
