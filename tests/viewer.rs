//! The viewer without its window: a step (camera, frame) and a composition (tone mapping,
//! layout, traced mask, heads-up lines) allocate nothing after the first frame; each layout
//! shows each eye where it should; keys switch the mode and the budget. One test per file:
//! the counting allocator sees the whole process.

use stereotrace::kernels::Extent;
use stereotrace::kernels::check::CountingAllocator;
use stereotrace::pipeline::{Mode, PipelineConfig};
use stereotrace::render::{Renderer, RendererOptions};
use stereotrace::scene::resolve;
use stereotrace::viewer::{Action, Controls, StereoLayout, Viewer};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator::new();

#[test]
fn the_viewer_steps_and_composes_without_allocating_and_its_keys_do_what_they_say() {
    let renderer = Renderer::new(resolve("cornell").unwrap()).unwrap();
    let extent = Extent::new(64, 36).unwrap();
    let mut config = PipelineConfig::paper(Mode::Spatiotemporal, 1, renderer.scene().tolerances.at_height(36));
    config.budget = Some(std::time::Duration::from_millis(50));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let walk = Controls { forward: 1.0, right: 0.5, yaw: 0.01, pitch: -0.005, seconds: 0.03, ..Controls::default() };

    for layout in [StereoLayout::SideBySide, StereoLayout::Left, StereoLayout::Right, StereoLayout::Anaglyph] {
        let mut viewer = Viewer::new(&renderer, RendererOptions::default(), config, extent, layout).unwrap();
        let (w, h) = viewer.size();
        assert_eq!((w, h), if layout == StereoLayout::SideBySide { (128, 36) } else { (64, 36) });
        let mut pixels = vec![0u32; w * h];
        viewer.act(Action::ToggleMask).unwrap();
        let allocated = pool.install(|| {
            for _ in 0..2 {
                viewer.step(&walk).unwrap();
                viewer.compose(&mut pixels);
                viewer.record_loop(30.0);
            }
            let before = GLOBAL.allocations();
            for _ in 0..3 {
                viewer.step(&walk).unwrap();
                viewer.compose(&mut pixels);
                viewer.record_loop(30.0);
            }
            GLOBAL.allocations() - before
        });
        assert_eq!(allocated, 0, "{layout:?}: {allocated} allocations in three frames");
        assert!(pixels.iter().any(|&p| p & 0x00ff_ffff != 0), "{layout:?}: an image");
        assert!((viewer.fps() - 1e3 / 30.0).abs() < 1e-9);
    }

    // Side by side: the left half is the left eye, the right half the right eye (they differ
    // by the disparity, so the halves differ), both lit.
    let mut viewer =
        Viewer::new(&renderer, RendererOptions::default(), config, extent, StereoLayout::SideBySide).unwrap();
    viewer.act(Action::ToggleHud).unwrap();
    let mut pixels = vec![0u32; 128 * 36];
    pool.install(|| viewer.step(&Controls::default())).unwrap();
    viewer.compose(&mut pixels);
    let (left, right): (Vec<u32>, Vec<u32>) =
        pixels.chunks_exact(128).flat_map(|row| row[..64].iter().zip(&row[64..])).map(|(a, b)| (*a, *b)).unzip();
    assert_ne!(left, right);
    assert!(left.iter().filter(|&&p| p != 0).count() > 64 * 36 / 2);

    // Keys: a mode switch and a budget change reconfigure the pipeline.
    viewer.act(Action::Mode(Mode::PathTraced)).unwrap();
    viewer.act(Action::Budget(-45.0)).unwrap();
    viewer.act(Action::Budget(-45.0)).unwrap();
    let stats = pool.install(|| viewer.step(&Controls::default()).cloned()).unwrap();
    assert_eq!(stats.budget, Some(std::time::Duration::from_millis(1)), "the budget stops at 1 ms");
}
