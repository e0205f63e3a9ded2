//! Temporal gradients (`History::Gradient`) through the pipeline, over an analytic room
//! whose light over the world's left half (x < 0) switches off at one frame: the next frame's
//! history is discarded where the light fell and kept elsewhere, and while nothing changes
//! the images equal the paper's history bit for bit, with the camera still or moving.

use std::cell::Cell;

use glam::Vec3;
use stereotrace_runtime::camera::Eye;
use stereotrace_runtime::kernels::reproject::Tolerances;
use stereotrace_runtime::kernels::synth::{AnalyticScene, camera_at};
use stereotrace_runtime::kernels::{CameraModel, Extent, GBufferBuf, RgbBuf};
use stereotrace_runtime::pipeline::{FrameStats, History, Layout, Mode, Pipeline, PipelineConfig, PipelineError};
use stereotrace_runtime::source::{FrameSource, PixelSelection, RasterPassStats, TraceRequest, TraceStats};

const W: usize = 48;
const H: usize = 30;
/// The first frame with the light off.
const OFF_AT: u32 = 5;

fn extent() -> Extent {
    Extent::new(W, H).unwrap()
}

/// The room, lit everywhere until `switch_off_at`, then only where x ≥ 0; noisy samples
/// whose noise is keyed by the request's frame (the random numbers) and pixel.
struct Room {
    scene: AnalyticScene,
    frame: u32,
    switch_off_at: Option<u32>,
    changes: bool,
    /// Trace calls made with another frame's random numbers (gradient samples).
    reshades: Cell<usize>,
}

impl FrameSource for Room {
    fn begin_frame(&mut self, frame: u32) {
        self.frame = frame;
    }

    fn fill_gbuffers(
        &mut self,
        gbuffers: [&mut GBufferBuf; 2],
        _layout: Layout,
    ) -> Result<Option<RasterPassStats>, PipelineError> {
        for g in gbuffers {
            g.copy_from(&self.scene.render(&g.camera, [0.0; 3]).surfaces)?;
        }
        Ok(None)
    }

    fn trace(
        &self,
        camera: &CameraModel,
        request: &TraceRequest,
        selection: PixelSelection<'_>,
        rows: std::ops::Range<usize>,
        out: &mut RgbBuf,
    ) -> Result<TraceStats, PipelineError> {
        if request.frame != self.frame {
            self.reshades.set(self.reshades.get() + 1);
        }
        let view = self.scene.render(camera, [0.0; 3]);
        let light_off = self.switch_off_at.is_some_and(|f| self.frame >= f);
        for y in rows {
            for x in 0..W {
                if !selection.selects(x, y) {
                    continue;
                }
                let mut h = (request.eye as u64) << 56 ^ u64::from(request.frame) << 32 ^ (y * W + x) as u64;
                h = (h ^ (h >> 33)).wrapping_mul(0xff51_afd7_ed55_8ccd);
                let noise = 0.7 + 0.6 * ((h >> 40) as f32 / (1u64 << 24) as f32);
                let dark = light_off && view.surfaces.position[0].view().get(x, y) < 0.0;
                let light = if dark { 0.0 } else { 1.0 };
                out.set(x, y, view.colour.get(x, y).map(|c| c * noise * light));
            }
        }
        Ok(TraceStats::default())
    }

    fn scene_changes(&self) -> bool {
        self.changes
    }
}

fn pipeline(history: History, switch_off_at: Option<u32>, changes: bool) -> Pipeline<Room> {
    let mut config = PipelineConfig::paper(Mode::Temporal, 1, Tolerances::new(0.5, 0.05, 30.0));
    config.history = history;
    let source = Room { scene: AnalyticScene::room(6.0), frame: 0, switch_off_at, changes, reshades: Cell::new(0) };
    Pipeline::with_source(source, config, cameras(0, false)).unwrap()
}

fn cameras(f: u32, moving: bool) -> [CameraModel; 2] {
    let x = if moving { 0.02 * f as f32 } else { 0.0 };
    [-0.03, 0.03].map(|dx| camera_at(Vec3::new(x + dx, 0.0, 0.0), extent(), 60.0))
}

fn bits(b: &RgbBuf) -> Vec<u32> {
    b.planes().iter().flat_map(|p| p.as_slice().iter().map(|v| v.to_bits())).collect()
}

fn render(p: &mut Pipeline<Room>, f: u32, moving: bool) -> FrameStats {
    p.render_frame_at(f, cameras(f, moving)).unwrap()
}

#[test]
fn a_light_switched_off_discards_the_history_where_it_fell_and_keeps_it_elsewhere() {
    let mut gradient = pipeline(History::Gradient, Some(OFF_AT), true);
    let mut paper = pipeline(History::Paper, Some(OFF_AT), true);
    for f in 0..OFF_AT {
        let stats = render(&mut gradient, f, false);
        render(&mut paper, f, false);
        // Nothing changed yet: the same images, though the gradients were measured.
        assert_eq!(bits(gradient.output(Eye::Right)), bits(paper.output(Eye::Right)), "frame {f}");
        if f > 0 {
            assert!(stats.gradient_samples[1] as usize >= (W / 3) * (H / 3) * 9 / 10, "{:?}", stats.gradient_samples);
            assert_eq!(stats.gradient_changed, [0, 0]);
        }
    }
    let stats = render(&mut gradient, OFF_AT, false);
    render(&mut paper, OFF_AT, false);
    assert!(stats.gradient_changed[1] > 0);
    let room = gradient.source().scene.render(&cameras(OFF_AT, false)[1], [0.0; 3]);
    let x_world = room.surfaces.position[0].view();
    let (mut discarded, mut kept) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            let shown = gradient.output(Eye::Right).get(x, y);
            let lagging = paper.output(Eye::Right).get(x, y);
            // Two strata (6 pixels) from the edge of the light, the 9×9 box has one side only.
            let (left, right) = (x_world.get(x.saturating_sub(6), y), x_world.get((x + 6).min(W - 1), y));
            if right < 0.0 {
                // In the dark: the history is gone, the pixel shows this frame's sample (0),
                // where the paper's history still shows 80 % of the old light.
                assert_eq!(shown, [0.0; 3], "({x}, {y})");
                assert!(lagging.iter().all(|&c| c > 0.0), "({x}, {y}) {lagging:?}");
                discarded += 1;
            } else if left >= 0.0 {
                assert_eq!(shown.map(f32::to_bits), lagging.map(f32::to_bits), "({x}, {y}) lit: history kept");
                kept += 1;
            }
        }
    }
    assert!(discarded > W * H / 4 && kept > W * H / 4, "{discarded} discarded, {kept} kept");
}

#[test]
fn unchanged_lighting_under_a_moving_camera_keeps_the_papers_images() {
    let mut gradient = pipeline(History::Gradient, None, true);
    let mut paper = pipeline(History::Paper, None, true);
    for f in 0..6 {
        let stats = render(&mut gradient, f, true);
        render(&mut paper, f, true);
        for eye in Eye::BOTH {
            assert_eq!(bits(gradient.output(eye)), bits(paper.output(eye)), "frame {f} {eye}");
        }
        if f > 0 {
            assert!(stats.gradient_samples.iter().all(|&n| n > 0), "{:?}", stats.gradient_samples);
        }
    }
    assert!(gradient.source().reshades.get() > 0);
}

#[test]
fn a_scene_that_cannot_change_traces_no_gradient_samples() {
    let mut gradient = pipeline(History::Gradient, None, false);
    let mut paper = pipeline(History::Paper, None, false);
    for f in 0..4 {
        let stats = render(&mut gradient, f, true);
        render(&mut paper, f, true);
        assert_eq!(stats.gradient_samples, [0, 0]);
        assert_eq!(bits(gradient.output(Eye::Right)), bits(paper.output(Eye::Right)));
    }
    assert_eq!(gradient.source().reshades.get(), 0);
}
