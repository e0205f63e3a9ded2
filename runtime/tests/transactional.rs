//! Transactional frames: a frame refused anywhere (its G-buffer call, any of its trace calls,
//! on the first frame or later ones) leaves the pipeline exactly as before the call, so the
//! frames after it equal those of a pipeline that never saw the refused call, bit for bit:
//! outputs, histories, G-buffers, reason planes and every count of the statistics.
//!
//! The source is an analytic room (closed-form G-buffers, noisy deterministic samples) whose
//! cameras slide every frame, wrapped in one that fails on a chosen call.

use std::cell::Cell;

use glam::Vec3;
use stereotrace_runtime::camera::Eye;
use stereotrace_runtime::kernels::reproject::Tolerances;
use stereotrace_runtime::kernels::synth::{AnalyticScene, SynthFrame, camera_at};
use stereotrace_runtime::kernels::{CameraModel, Extent, GBufferBuf, PlaneBuf, RgbBuf};
use stereotrace_runtime::pipeline::{FrameStats, Layout, Mode, Order, Pipeline, PipelineConfig, PipelineError};
use stereotrace_runtime::source::{FrameSource, PixelSelection, RasterPassStats, TraceRequest, TraceStats};

const W: usize = 45;
const H: usize = 29;
const FRAMES: u32 = 6;

fn extent() -> Extent {
    Extent::new(W, H).unwrap()
}

/// Eye cameras of frame `f`: a parallel pair 6 cm apart, sliding right 3 cm per frame.
fn cameras(f: u32) -> [CameraModel; 2] {
    let x = 0.03 * f as f32;
    [-0.03, 0.03].map(|dx| camera_at(Vec3::new(x + dx, 0.0, 0.0), extent(), 60.0))
}

/// Which call of a frame fails.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Fault {
    GBuffers,
    /// The n-th trace call of the frame (0-based).
    Trace(usize),
}

/// The analytic room, failing on `fault` while armed; counts its trace calls per frame.
struct Flaky {
    scene: AnalyticScene,
    frames: [Option<SynthFrame>; 2],
    frame: u32,
    fault: Option<Fault>,
    traces: Cell<usize>,
}

impl FrameSource for Flaky {
    fn begin_frame(&mut self, frame: u32) {
        self.frame = frame;
        self.traces.set(0);
    }

    fn fill_gbuffers(
        &mut self,
        gbuffers: [&mut GBufferBuf; 2],
        _layout: Layout,
    ) -> Result<Option<RasterPassStats>, PipelineError> {
        for (eye, g) in gbuffers.into_iter().enumerate() {
            let f = self.scene.render(&g.camera, [0.0; 3]);
            g.copy_from(&f.surfaces)?;
            self.frames[eye] = Some(f);
            // Fail after writing part of the buffers: what a real failure leaves behind.
            if self.fault == Some(Fault::GBuffers) && eye == 0 {
                return Err(PipelineError::Source("injected G-buffer failure".into()));
            }
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
        let call = self.traces.get();
        self.traces.set(call + 1);
        // A mono frame has no G-buffers: its surfaces are rendered here.
        let rendered;
        let frame = match &self.frames[request.eye as usize] {
            Some(frame) => frame,
            None => {
                rendered = self.scene.render(camera, [0.0; 3]);
                &rendered
            }
        };
        for y in rows.clone() {
            for x in 0..W {
                if selection.selects(x, y) {
                    let mut h = (request.eye as u64) << 56 ^ u64::from(self.frame) << 32 ^ (y * W + x) as u64;
                    h = (h ^ (h >> 33)).wrapping_mul(0xff51_afd7_ed55_8ccd);
                    let noise = 0.7 + 0.6 * ((h >> 40) as f32 / (1u64 << 24) as f32);
                    out.set(x, y, frame.colour.get(x, y).map(|c| c * noise));
                }
            }
            // Fail half-way through the rows: the output planes are partly written.
            if self.fault == Some(Fault::Trace(call)) && y >= (rows.start + rows.end) / 2 {
                return Err(PipelineError::Source("injected trace failure".into()));
            }
        }
        Ok(TraceStats::default())
    }
}

fn pipeline(mode: Mode, order: Order) -> Pipeline<Flaky> {
    let mut config = PipelineConfig::paper(mode, 1, Tolerances::new(0.5, 0.05, 30.0));
    config.order = order;
    let source =
        Flaky { scene: AnalyticScene::room(6.0), frames: [None, None], frame: 0, fault: None, traces: Cell::new(0) };
    Pipeline::with_source(source, config, cameras(0)).unwrap()
}

/// Everything a caller can read of a pipeline, as bits.
#[derive(Debug, PartialEq)]
struct Snapshot {
    outputs: [Vec<u32>; 2],
    histories: [Vec<u32>; 2],
    depths: [Vec<u32>; 2],
    stereo_reasons: [Vec<u8>; 2],
    temporal_reasons: [Vec<u8>; 2],
    frames_since_reset: u32,
}

fn rgb_bits(b: &RgbBuf) -> Vec<u32> {
    b.planes().iter().flat_map(|p| p.as_slice().iter().map(|v| v.to_bits())).collect()
}

fn plane_bits(p: &PlaneBuf) -> Vec<u32> {
    p.as_slice().iter().map(|v| v.to_bits()).collect()
}

fn snapshot(p: &Pipeline<Flaky>) -> Snapshot {
    let both = |f: &dyn Fn(Eye) -> Vec<u32>| [f(Eye::Left), f(Eye::Right)];
    let both_u8 = |f: &dyn Fn(Eye) -> Vec<u8>| [f(Eye::Left), f(Eye::Right)];
    Snapshot {
        outputs: both(&|e| rgb_bits(p.output(e))),
        histories: both(&|e| rgb_bits(p.history(e))),
        depths: both(&|e| plane_bits(&p.gbuffer(e).depth)),
        stereo_reasons: both_u8(&|e| p.stereo_reasons(e).as_slice().to_vec()),
        temporal_reasons: both_u8(&|e| p.temporal_reasons(e).as_slice().to_vec()),
        frames_since_reset: p.frames_since_reset(),
    }
}

/// A frame's statistics without its (measured, so varying) times.
fn counts(s: &FrameStats) -> FrameStats {
    FrameStats { times: Default::default(), ..*s }
}

fn schedules() -> Vec<(Mode, Order)> {
    let mut v = Vec::new();
    for mode in Mode::ALL {
        v.push((mode, Order::Paper));
        if mode.has_order() {
            v.push((mode, Order::StereoFirst));
        }
    }
    v
}

#[test]
fn a_refused_frame_leaves_output_history_and_statistics_as_if_never_called() {
    let mut cases = 0;
    for (mode, order) in schedules() {
        // The reference: every frame succeeds. Its state after each frame, and the trace
        // calls each frame makes (the positions a failure can take).
        let mut reference = pipeline(mode, order);
        let fresh = snapshot(&reference);
        let (mut states, mut stats, mut trace_calls) = (Vec::new(), Vec::new(), Vec::new());
        for f in 0..FRAMES {
            stats.push(counts(&reference.render_frame_at(f, cameras(f)).unwrap()));
            states.push(snapshot(&reference));
            trace_calls.push(reference.source().traces.get());
        }
        for failing in [0, 1, 3] {
            let faults = std::iter::once(Fault::GBuffers).chain((0..trace_calls[failing as usize]).map(Fault::Trace));
            for fault in faults {
                let what = format!("{mode} {order:?}, {fault:?} failing at frame {failing}");
                let mut p = pipeline(mode, order);
                for f in 0..failing {
                    p.render_frame_at(f, cameras(f)).unwrap();
                }
                p.source_mut().fault = Some(fault);
                let refused = p.render_frame_at(failing, cameras(failing));
                assert!(matches!(refused, Err(PipelineError::Source(_))), "{what}: {refused:?}");
                let before = if failing == 0 { &fresh } else { &states[failing as usize - 1] };
                assert!(snapshot(&p) == *before, "{what}: the refused call changed the pipeline");
                // The same frame again, and the rest: identical to the reference.
                p.source_mut().fault = None;
                for f in failing..FRAMES {
                    let s = counts(&p.render_frame_at(f, cameras(f)).unwrap());
                    assert_eq!(s, stats[f as usize], "{what}: statistics of frame {f}");
                    assert!(snapshot(&p) == states[f as usize], "{what}: frame {f} differs from the reference");
                }
                cases += 1;
            }
        }
    }
    // 8 schedules × 3 failing frames × (1 G-buffer + at least 1 trace call) at the least.
    assert!(cases >= 8 * 3 * 2, "only {cases} cases ran");
}

#[test]
fn a_refused_mono_frame_leaves_the_image_as_it_was() {
    let mut p = pipeline(Mode::Spatiotemporal, Order::Paper);
    p.render_mono_frame_at(0, cameras(0)[1]).unwrap();
    let before = snapshot(&p);
    p.source_mut().fault = Some(Fault::Trace(0));
    assert!(p.render_mono_frame_at(1, cameras(1)[1]).is_err());
    assert!(snapshot(&p) == before, "a refused mono frame changed the pipeline");
}
