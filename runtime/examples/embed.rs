//! An engine embedding the runtime: its own G-buffers and its own "path tracer" behind
//! [`FrameSource`], stereotrace's reprojection, accumulation and budget planner on top. It
//! names the runtime through one module, `stereotrace_runtime::engine`.
//!
//! The engine renders an analytic room (rectangles ray-cast per pixel, no BVH) and its
//! tracer returns the surface colour times a deterministic per-pixel noise, at a simulated
//! cost per pixel so that a budget has something to cut. `main` walks a camera sideways for
//! 24 frames in the paper's spatiotemporal mode with a per-frame budget and prints what each
//! frame did.
//!
//! `runtime/tests/frame_source.rs` includes this file and checks the pipeline over this very
//! [`Engine`] against the kernels called directly, bit for bit: the example an engine
//! copies is the one the tests prove.
//!
//! `cargo run --release -p stereotrace-runtime --example embed [BUDGET_MS]` (default 15 ms).
//! Exits non-zero if an image holds a non-finite or negative value, if the left eye traced a
//! pixel its stereo reprojection kept, or if that reprojection discarded more than 5 % of the
//! left eye.

use std::time::{Duration, Instant};

use glam::Vec3;
use stereotrace_runtime::engine::{
    CameraModel, Extent, Eye, FrameSource, GBufferBuf, Layout, Mode, Pipeline, PipelineConfig, PipelineError,
    PixelSelection, RasterPassStats, RgbBuf, Tolerances, TraceRequest, TraceStats,
};
// The engine's own stand-in scene (a test utility of the kernels crate), not runtime API.
use stereotrace_runtime::kernels::synth::{AnalyticScene, SynthFrame, camera_at};

/// The engine: a scene, what it rendered for each eye this frame, and what its tracer
/// pretends a pixel costs.
pub struct Engine {
    scene: AnalyticScene,
    /// Each eye's frame as last rendered by `fill_gbuffers` (the tracer's surfaces).
    frames: [Option<SynthFrame>; 2],
    frame: u32,
    pixel_cost: Duration,
}

impl Engine {
    /// A room 6 units deep whose tracer spins `pixel_cost` per traced pixel (zero in tests).
    pub fn new(pixel_cost: Duration) -> Self {
        Self { scene: AnalyticScene::room(6.0), frames: [None, None], frame: 0, pixel_cost }
    }

    /// What `eye` rendered this frame (after `fill_gbuffers`).
    pub fn rendered(&self, eye: Eye) -> Option<&SynthFrame> {
        self.frames[eye as usize].as_ref()
    }

    /// The "path-traced" sample of pixel `(x, y)`: the surface's colour times a noise in
    /// [0.8, 1.2) that depends on eye, frame and pixel only (so accumulation over frames has
    /// something to average).
    pub fn sample(rendered: &SynthFrame, eye: Eye, frame: u32, x: usize, y: usize) -> [f32; 3] {
        let width = rendered.colour.extent().width();
        let mut h = (eye as u64) << 56 ^ u64::from(frame) << 32 ^ (y * width + x) as u64;
        h = (h ^ (h >> 33)).wrapping_mul(0xff51_afd7_ed55_8ccd);
        h = (h ^ (h >> 33)).wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        let noise = 0.8 + 0.4 * ((h >> 40) as f32 / (1u64 << 24) as f32);
        rendered.colour.get(x, y).map(|c| c * noise)
    }
}

impl FrameSource for Engine {
    fn begin_frame(&mut self, frame: u32) {
        self.frame = frame;
    }

    fn fill_gbuffers(
        &mut self,
        gbuffers: [&mut GBufferBuf; 2],
        _layout: Layout,
    ) -> Result<Option<RasterPassStats>, PipelineError> {
        // The analytic pass writes every plane, so whichever layout the pipeline reads is
        // there.
        for (eye, g) in gbuffers.into_iter().enumerate() {
            // The engine's G-buffer pass, then a copy into the pipeline's planes.
            let rendered = self.scene.render(&g.camera, [0.0; 3]);
            g.copy_from(&rendered.surfaces)?;
            self.frames[eye] = Some(rendered);
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
        let rendered = self.rendered(request.eye).ok_or(PipelineError::Source("no G-buffer".into()))?;
        if rendered.surfaces.camera != *camera {
            return Err(PipelineError::Source("asked to trace with a camera the G-buffer was not made with".into()));
        }
        let mut traced = 0u32;
        for y in rows {
            for x in 0..out.extent().width() {
                if selection.selects(x, y) {
                    out.set(x, y, Self::sample(rendered, request.eye, self.frame, x, y));
                    traced += 1;
                }
            }
        }
        // The simulated cost of path tracing those pixels.
        let until = Instant::now() + self.pixel_cost * traced;
        while Instant::now() < until {
            std::hint::spin_loop();
        }
        Ok(TraceStats::default())
    }
}

/// Eye cameras (`[left, right]`) of frame `frame`: a parallel pair 6.5 cm apart, sliding right
/// 1 cm per frame.
pub fn cameras(frame: u32, extent: Extent) -> [CameraModel; 2] {
    let x = 0.01 * frame as f32;
    [-0.0325, 0.0325].map(|dx| camera_at(Vec3::new(x + dx, 0.0, 0.0), extent, 60.0))
}

fn main() -> Result<(), String> {
    let budget_ms: f64 = std::env::args().nth(1).map_or(Ok(15.0), |b| b.parse().map_err(|e| format!("budget: {e}")))?;
    let extent = Extent::new(160, 90).map_err(|e| e.to_string())?;
    let mut config = PipelineConfig::paper(Mode::Spatiotemporal, 1, Tolerances::new(0.15, 0.03, 25.0));
    config.budget = Some(Duration::from_secs_f64(budget_ms / 1e3));
    let engine = Engine::new(Duration::from_micros(1));
    let mut pipeline = Pipeline::with_source(engine, config, cameras(0, extent)).map_err(|e| e.to_string())?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().map_err(|e| e.to_string())?;

    println!("frame  total ms  G-buffers  reprojection  tracing  left traced  right traced  budget");
    let pixels = extent.pixels() as f64;
    for frame in 0..24 {
        let s = pool.install(|| pipeline.render_frame_at(frame, cameras(frame, extent))).map_err(|e| e.to_string())?;
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        println!(
            "{frame:>5}  {:>8.2}  {:>9.2}  {:>12.2}  {:>7.2}  {:>10.1} %  {:>11.1} %  {}",
            ms(s.times.total),
            ms(s.times.gbuffer),
            ms(s.times.reprojection),
            ms(s.times.tracing),
            100.0 * s.traced_pixels[0] as f64 / pixels,
            100.0 * s.traced_pixels[1] as f64 / pixels,
            if s.budget_met { "met" } else { "over" },
        );
        // What must hold whatever the machine's load (so not "left traced less than right":
        // the left eye's disocclusions are traced even when the budget leaves the right eye
        // nothing beyond its own, which a loaded machine showed): the left eye traces only
        // what its stereo reprojection discarded, and in this room that is a few pixels.
        let left_wanted = s.wanted_pixels[0];
        if s.traced_pixels[0] > left_wanted {
            return Err(format!("frame {frame}: the left eye traced pixels its stereo reprojection kept"));
        }
        if left_wanted as f64 > 0.05 * pixels {
            return Err(format!("frame {frame}: stereo reprojection discarded {left_wanted} left-eye pixels"));
        }
    }
    for eye in Eye::BOTH {
        let image = pipeline.output(eye);
        if !image.planes().iter().all(|p| p.as_slice().iter().all(|v| v.is_finite() && *v >= 0.0)) {
            return Err(format!("{eye:?} image has a non-finite or negative value"));
        }
    }
    println!("both eyes finite and non-negative after 24 frames");
    Ok(())
}
