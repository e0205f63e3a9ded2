//! `stereotrace throughput`: the thin real-time driver. Runs the pipeline for a scene and
//! mode on a fixed thread pool, then the same frames with both eyes fully path traced and as
//! mono frames (the right eye alone), and reports frames per second, per-stage times (median
//! and p95), Mrays/s, the share of left-eye pixels path traced, the speed-up over full stereo
//! path tracing and the cost over mono, all measured in the same run.

use std::time::Duration;

use serde::Serialize;

use crate::camera::{Eye, StereoRig};
use crate::kernels::Extent;
use crate::pipeline::{
    CameraWalk, FrameStats, GBufferPass, Layout, Mode, Order, Pipeline, PipelineConfig, Session, View,
};
use crate::render::Renderer;

/// Options of the throughput command.
#[derive(Clone, Debug)]
pub struct ThroughputOptions {
    pub scene: String,
    pub extent: Extent,
    pub threads: usize,
    pub frames: u32,
    pub spp: u32,
    pub mode: Mode,
    pub order: Order,
    pub layout: Layout,
    pub gbuffer: GBufferPass,
    pub budget_ms: Option<f64>,
    /// Also measure full stereo path tracing (for the speed-up) and mono frames (for the
    /// cost of stereo): about doubles the run time.
    pub baseline: bool,
}

/// Median and 95th percentile of a series, in milliseconds.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Spread {
    pub median_ms: f64,
    pub p95_ms: f64,
    pub max_ms: f64,
}

impl Spread {
    /// The spread of `values` (zeros when empty).
    pub fn of(mut values: Vec<f64>) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        values.sort_by(f64::total_cmp);
        let pick = |q: f64| values[((values.len() - 1) as f64 * q).round() as usize];
        Self { median_ms: pick(0.5), p95_ms: pick(0.95), max_ms: values[values.len() - 1] }
    }
}

/// Everything the driver measured (the `--json` object).
#[derive(Clone, Debug, Serialize)]
pub struct ThroughputReport {
    pub scene: String,
    pub width: usize,
    pub height: usize,
    pub threads: usize,
    pub mode: String,
    pub order: String,
    pub layout: String,
    /// How the G-buffers were made (`raster` or `traced`).
    pub gbuffer_pass: String,
    pub spp: u32,
    pub frames_measured: usize,
    pub simd_level: String,
    pub stereo_fps: f64,
    pub frame: Spread,
    pub gbuffer: Spread,
    pub reprojection: Spread,
    pub tracing: Spread,
    pub accumulation: Spread,
    pub mrays_per_s: f64,
    /// Share of left-eye pixels path traced (median over frames).
    pub left_traced_share: f64,
    /// Share of right-eye pixels path traced.
    pub right_traced_share: f64,
    /// Median frame time of full stereo path tracing at the same spp, if measured.
    pub full_stereo_frame_ms: Option<f64>,
    /// `full_stereo_frame_ms / frame.median_ms`.
    pub speedup_over_full_stereo: Option<f64>,
    /// Median frame time of the right eye alone path traced at the same spp (primary rays
    /// included, nothing reprojected), if measured: what a mono renderer pays per frame.
    pub mono_frame_ms: Option<f64>,
    /// `frame.median_ms / mono_frame_ms`: what stereo costs over mono (the target for
    /// spatiotemporal at 1 spp is ≤ 1.05).
    pub stereo_over_mono: Option<f64>,
    pub budget_ms: Option<f64>,
    pub budget_misses: usize,
    /// Frames over the budget by more than 1 ms (the real-time target is none).
    pub budget_misses_over_1ms: usize,
    /// Worst overrun beyond the budget.
    pub worst_overrun_ms: f64,
    /// Work that runs whatever the budget (G-buffers, reprojection, accumulation, and the
    /// tracing of pixels without valid history: all of a fully traced eye), median.
    pub always_run_ms: f64,
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Runs `frames + 1` frames (the first, without history, is not measured) and returns the
/// stats of the measured ones; with `mono`, mono frames (the right eye alone path traced,
/// see [`Pipeline::render_mono_frame`]).
fn run_frames(
    renderer: &Renderer,
    config: PipelineConfig,
    extent: Extent,
    frames: u32,
    mono: bool,
) -> Result<Vec<FrameStats>, String> {
    let pipeline = Pipeline::new(renderer, config, StereoRig::default(), extent).map_err(|e| e.to_string())?;
    let view = if mono { View::Mono } else { View::Stereo };
    let mut session = Session::new(pipeline, CameraWalk::BackAndForth).with_view(view);
    let mut stats = Vec::with_capacity(frames as usize);
    for i in 0..=frames {
        let s = session.next_frame().map_err(|e| format!("frame {i}: {e}"))?;
        if i > 0 {
            stats.push(s);
        }
    }
    Ok(stats)
}

/// Runs the driver.
pub fn run(opts: &ThroughputOptions) -> Result<ThroughputReport, String> {
    if opts.frames == 0 {
        return Err("--frames must be at least 1".into());
    }
    if opts.threads == 0 {
        return Err("--threads must be at least 1".into());
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.threads)
        .build()
        .map_err(|e| format!("cannot start {} threads: {e}", opts.threads))?;
    let scene = crate::scene::resolve(&opts.scene).map_err(|e| e.to_string())?;
    let name = scene.name.clone();
    let renderer = Renderer::new(scene).map_err(|e| e.to_string())?;
    let tolerances = renderer.scene().tolerances.at_height(opts.extent.height());
    let mut config = PipelineConfig::paper(opts.mode, opts.spp, tolerances);
    config.order = opts.order;
    config.layout = opts.layout;
    config.gbuffer = opts.gbuffer;
    config.budget = opts.budget_ms.map(super::budget_duration).transpose()?;
    let stats = pool.install(|| run_frames(&renderer, config, opts.extent, opts.frames, false))?;
    let frame_ms = |s: &[FrameStats]| Spread::of(s.iter().map(|f| ms(f.times.total)).collect());
    let baseline = if opts.baseline && opts.mode != Mode::PathTraced {
        let full = PipelineConfig { mode: Mode::PathTraced, budget: None, ..config };
        Some(frame_ms(&pool.install(|| run_frames(&renderer, full, opts.extent, opts.frames, false))?))
    } else if opts.mode == Mode::PathTraced {
        Some(frame_ms(&stats))
    } else {
        None
    };
    let mono = if opts.baseline {
        let mono = PipelineConfig { budget: None, ..config };
        Some(frame_ms(&pool.install(|| run_frames(&renderer, mono, opts.extent, opts.frames, true))?))
    } else {
        None
    };

    let series = |f: fn(&FrameStats) -> Duration| Spread::of(stats.iter().map(|s| ms(f(s))).collect());
    let frame = series(|s| s.times.total);
    let pixels = opts.extent.pixels() as f64;
    let share = |eye: Eye| {
        let mut v: Vec<f64> = stats.iter().map(|s| s.traced_pixels[eye as usize] as f64 / pixels).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let total_time: f64 = stats.iter().map(|s| s.times.total.as_secs_f64()).sum();
    let rays: u64 = stats.iter().map(|s| s.trace.rays).sum();
    let tracing_time: f64 = stats.iter().map(|s| s.times.tracing.as_secs_f64()).sum();
    let (misses, misses_1ms, worst) = match opts.budget_ms {
        Some(b) => stats.iter().fold((0, 0, 0.0f64), |(n, n1, w), s| {
            let t = ms(s.times.total);
            (n + usize::from(t > b), n1 + usize::from(t > b + 1.0), w.max(t - b))
        }),
        None => (0, 0, 0.0),
    };
    Ok(ThroughputReport {
        scene: name,
        width: opts.extent.width(),
        height: opts.extent.height(),
        threads: opts.threads,
        mode: opts.mode.name().into(),
        order: opts.order.name().into(),
        layout: format!("{:?}", opts.layout).to_lowercase(),
        gbuffer_pass: opts.gbuffer.name().into(),
        spp: opts.spp,
        frames_measured: stats.len(),
        simd_level: crate::cpu::simd_level(),
        stereo_fps: stats.len() as f64 / total_time,
        frame,
        gbuffer: series(|s| s.times.gbuffer),
        reprojection: series(|s| s.times.reprojection),
        tracing: series(|s| s.times.tracing),
        accumulation: series(|s| s.times.accumulation),
        mrays_per_s: if tracing_time > 0.0 { rays as f64 / tracing_time / 1e6 } else { 0.0 },
        left_traced_share: share(Eye::Left),
        right_traced_share: share(Eye::Right),
        full_stereo_frame_ms: baseline.map(|b| b.median_ms),
        speedup_over_full_stereo: baseline.map(|b| b.median_ms / frame.median_ms),
        mono_frame_ms: mono.map(|m| m.median_ms),
        stereo_over_mono: mono.map(|m| frame.median_ms / m.median_ms),
        budget_ms: opts.budget_ms,
        budget_misses: misses,
        budget_misses_over_1ms: misses_1ms,
        worst_overrun_ms: worst.max(0.0),
        always_run_ms: Spread::of(
            stats
                .iter()
                .map(|s| ms(s.times.gbuffer + s.times.reprojection + s.times.accumulation + s.times.urgent_tracing))
                .collect(),
        )
        .median_ms,
    })
}

impl ThroughputReport {
    /// The human-readable summary.
    pub fn text(&self) -> String {
        let stage =
            |name: &str, s: &Spread| format!("  {name:<13} {:>9.2} ms median {:>9.2} ms p95\n", s.median_ms, s.p95_ms);
        let mut out = format!(
            "{} {}x{} {} threads, mode {} (order {}, {} {} G-buffer), {} spp, {}: {} frames measured\n",
            self.scene,
            self.width,
            self.height,
            self.threads,
            self.mode,
            self.order,
            self.layout,
            self.gbuffer_pass,
            self.spp,
            self.simd_level,
            self.frames_measured
        );
        out += &format!("  stereo fps    {:>9.2}\n", self.stereo_fps);
        out += &stage("frame", &self.frame);
        out += &stage("g-buffers", &self.gbuffer);
        out += &stage("reprojection", &self.reprojection);
        out += &stage("path tracing", &self.tracing);
        out += &stage("accumulation", &self.accumulation);
        out += &format!("  Mrays/s       {:>9.2} (while tracing)\n", self.mrays_per_s);
        out += &format!(
            "  traced        {:>8.1} % of left-eye pixels, {:.1} % of right-eye pixels\n",
            100.0 * self.left_traced_share,
            100.0 * self.right_traced_share
        );
        if let (Some(full), Some(speedup)) = (self.full_stereo_frame_ms, self.speedup_over_full_stereo) {
            out += &format!("  full stereo   {full:>9.2} ms median (both eyes path traced): speed-up {speedup:.2}x\n");
        }
        if let (Some(mono), Some(ratio)) = (self.mono_frame_ms, self.stereo_over_mono) {
            out += &format!(
                "  mono          {mono:>9.2} ms median (right eye alone path traced): stereo costs {ratio:.3}x\n"
            );
        }
        if let Some(b) = self.budget_ms {
            out += &format!(
                "  budget        {b:>9.2} ms: {} of {} frames over ({} by more than 1 ms), worst overrun {:.2} ms\n",
                self.budget_misses, self.frames_measured, self.budget_misses_over_1ms, self.worst_overrun_ms
            );
            if self.always_run_ms > b {
                out += &format!(
                    "  note: the work that always runs (G-buffers, reprojection, accumulation, and tracing the \
                     pixels without valid history) takes {:.2} ms, more than the budget\n",
                    self.always_run_ms
                );
            }
        }
        out
    }
}
