//! `stereotrace throughput`: the thin real-time driver. Runs the pipeline for a scene and
//! mode on a fixed thread pool, then the same frames with both eyes fully path traced and as
//! mono frames (the right eye alone), and reports frames per second, per-stage times (median
//! and p95), Mrays/s and the share of pixels path traced per eye, all measured in the same
//! run.
//!
//! The three runs (the mode's stereo schedule, full stereo tracing, mono) always share every
//! setting, the budget included. What they are compared on depends on it:
//! - **without a budget** each run traces what its schedule needs, so time is what differs:
//!   the report divides frame times (speed-up over full stereo, stereo over mono);
//! - **under a budget** time is fixed by construction and what differs is what each
//!   schedule buys in it: the share of pixels traced and the samples per pixel per eye. No
//!   time ratio is formed ([`time_ratio`] refuses budgeted runs); the quality side,
//!   effective spp at equal time, is `stereotrace tradeoff`'s.

use std::time::Duration;

use clap::Args;
use serde::Serialize;

use crate::camera::{Eye, StereoRig};
use crate::kernels::Extent;
use crate::kernels::bvh::BuildQuality;
use crate::pipeline::{Background, Blend, Filter, FrameStats, History, Layout, Mode, Order, Pipeline, PipelineConfig};
use crate::render::{Renderer, RendererOptions};
use crate::session::{CameraWalk, Session, View};
use crate::source::RasterPassStats;

use super::args::{GBufferArg, SceneArgs, ThreadsArg, default, parse_budget_ms, parse_frames, parse_spp};

/// Options of `stereotrace throughput`.
#[derive(Args, Clone, Debug)]
#[command(mut_arg("scene", default("atrium")), mut_arg("res", default("1280x720")))]
pub struct ThroughputOptions {
    /// The scene and the resolution per eye.
    #[command(flatten)]
    pub input: SceneArgs,
    /// Worker threads.
    #[command(flatten)]
    pub threads: ThreadsArg,
    /// Frames to measure (after one warm-up frame).
    #[arg(long, default_value_t = 20, value_parser = parse_frames)]
    pub frames: u32,
    /// Samples per traced pixel.
    #[arg(long, default_value_t = 1, value_parser = parse_spp)]
    pub spp: u32,
    /// Pipeline mode.
    #[arg(long, value_enum, default_value_t = Mode::Spatiotemporal)]
    pub mode: Mode,
    /// Order of stereo and temporal reprojection (spatiotemporal modes).
    #[arg(long, value_enum, default_value_t = Order::Paper)]
    pub order: Order,
    /// G-buffer layout the reprojection reads.
    #[arg(long, value_enum, default_value_t = Layout::Compact)]
    pub layout: Layout,
    /// How far the EMA trusts a reprojected history: the paper's, or shortened by temporal
    /// gradients where the lighting changed (scenes with moving lights or objects).
    #[arg(long, value_enum, default_value_t = History::Paper)]
    pub history: History,
    /// How the stereo blend weighs the eyes: the paper's fixed ½, or by inverse variance
    /// from each eye's history length (the paper-order spatiotemporal-blend mode).
    #[arg(long, value_enum, default_value_t = Blend::Fixed)]
    pub blend: Blend,
    /// A spatial filter of both eyes' shown images after accumulation: none (the paper's),
    /// or the edge-avoiding à-trous filter (five passes, guided by the G-buffers).
    #[arg(long, value_enum, default_value_t = Filter::None)]
    pub filter: Filter,
    /// What reprojection does with background pixels (sky): the paper's discards them, so
    /// they are traced every frame; `reproject` keeps a static sky's history by direction.
    #[arg(long, value_enum, default_value_t = Background::Trace)]
    pub background: Background,
    /// How the G-buffers are made.
    #[command(flatten)]
    pub gbuffer: GBufferArg,
    /// Give the pipeline the surfaces' motion since the last frame (moving lights' and
    /// objects' own), which temporal reprojection follows, as an engine's motion vectors do;
    /// without it every surface is taken as still and a moving object's pixels are traced.
    #[arg(long)]
    pub motion_vectors: bool,
    /// Per-frame time budget in milliseconds (tracing stops when it is spent).
    #[arg(long, value_parser = parse_budget_ms)]
    pub budget_ms: Option<f64>,
    /// The tracer's tree: the renderer's default, or another build to compare on whole
    /// frames (the images differ only in which triangle wins an exact tie).
    #[arg(long, value_enum, default_value_t = BvhBuild::Default)]
    pub bvh: BvhBuild,
    /// Skip the baseline runs: full stereo path tracing (for the speed-up) and mono frames
    /// (for the cost of stereo), with the same settings and budget as the measured run. They
    /// about double the run time. (The field is true when they run.)
    #[arg(long = "no-baseline", action = clap::ArgAction::SetFalse)]
    pub baseline: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Median and 95th percentile of a series, in milliseconds.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Spread {
    /// The median.
    pub median_ms: f64,
    /// The 95th percentile (nearest rank).
    pub p95_ms: f64,
    /// The largest value.
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

/// Where a rasterised G-buffer pass spends its time (both eyes, medians over frames): the
/// attribution a faster pass starts from.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct RasterSteps {
    /// Triangle setup: culling, clipping, projection.
    pub setup: Spread,
    /// Binning the triangles' records into bands of rows.
    pub binning: Spread,
    /// The fragment loop: coverage and depth test per pixel.
    pub fragments: Spread,
    /// The resolve: each pixel's visible triangle into G-buffer texels.
    pub resolve: Spread,
    /// Triangles the pass was given (the last frame's).
    pub triangles: u64,
    /// Of those, the visible ones in at least one eye (the last frame's).
    pub visible: u64,
    /// Of those, the ones the setup skipped with their whole cluster off screen (the last
    /// frame's).
    pub cluster_culled: u64,
    /// (record, band of rows) pairs the fragment loop walked (the last frame's).
    pub band_records: u64,
    /// Covered pixel centres of tiny triangles depth-tested as points instead of walked
    /// records (the last frame's).
    pub band_points: u64,
    /// Fragments decided on the exact path: uncertain coverage, depth near-ties and
    /// alpha-masked triangles (the last frame's).
    pub exact_fragments: u64,
}

/// Everything the driver measured (the `--json` object).
#[derive(Clone, Debug, Serialize)]
pub struct ThroughputReport {
    /// The scene's name.
    pub scene: String,
    /// Width per eye, in pixels.
    pub width: usize,
    /// Height per eye, in pixels.
    pub height: usize,
    /// Worker threads.
    pub threads: usize,
    /// The pipeline mode measured (`--mode`).
    pub mode: String,
    /// Order of stereo and temporal reprojection.
    pub order: String,
    /// How far the EMA trusted the history (`paper` or `gradient`).
    pub history: String,
    /// How the stereo blend weighed the eyes (`fixed` or `variance`).
    pub blend: String,
    /// The spatial filter of the shown images (`none` or `atrous`).
    pub filter: String,
    /// What reprojection did with background pixels (`trace` or `reproject`).
    pub background: String,
    /// G-buffer layout the reprojection read (`compact` or `full`).
    pub layout: String,
    /// How the G-buffers were made (`raster` or `traced`).
    pub gbuffer_pass: String,
    /// Where each pixel's first sample started (`jittered` or `centre`).
    #[serde(default)]
    pub first_sample: String,
    /// Whether the G-buffers carried the surfaces' motion (`--motion-vectors`).
    #[serde(default)]
    pub motion_vectors: bool,
    /// Samples per traced pixel.
    pub spp: u32,
    /// Frames measured (the warm-up frame left out).
    pub frames_measured: usize,
    /// The kernel bodies the CPU ran (for example `x86-64-v3 (AVX2+FMA)`).
    pub simd_level: String,
    /// Stereo frames per second: frames measured over their total time.
    pub stereo_fps: f64,
    /// Whole-frame times.
    pub frame: Spread,
    /// Both eyes' G-buffer pass.
    pub gbuffer: Spread,
    /// The G-buffer pass's steps when it rasterises (null for the traced pass).
    pub raster: Option<RasterSteps>,
    /// Stereo and temporal reprojection.
    pub reprojection: Spread,
    /// Path tracing.
    pub tracing: Spread,
    /// EMA accumulation and stereo blending.
    pub accumulation: Spread,
    /// Temporal gradients outside their traced samples (zero with the paper's history).
    pub gradients: Spread,
    /// The spatial filter of both eyes (zero without one).
    pub filter_ms: Spread,
    /// Rays traced per second of tracing time, in millions.
    pub mrays_per_s: f64,
    /// Share of left-eye pixels path traced (median over frames).
    pub left_traced_share: f64,
    /// Share of right-eye pixels path traced.
    pub right_traced_share: f64,
    /// Median frame time of the full stereo run (both eyes path traced, same spp and budget
    /// as this run), if measured.
    pub full_stereo_frame_ms: Option<f64>,
    /// `full_stereo_frame_ms / frame.median_ms`, only when neither run had a budget (null
    /// under `--budget-ms`: see `schedules`).
    pub speedup_over_full_stereo: Option<f64>,
    /// Median frame time of the mono run (the right eye alone path traced at the same spp
    /// and budget: primary rays included, nothing reprojected), if measured: what a mono
    /// renderer pays per frame.
    pub mono_frame_ms: Option<f64>,
    /// `frame.median_ms / mono_frame_ms`, what stereo costs over mono, only when neither run
    /// had a budget (null under `--budget-ms`).
    pub stereo_over_mono: Option<f64>,
    /// Every run of this report, this mode's first, each with the budget it ran under (the
    /// same for all): what each schedule traced and how long its frames took. Under a budget
    /// this is the comparison, in pixels and samples, not in time.
    pub schedules: Vec<ScheduleRun>,
    /// The per-frame budget (`--budget-ms`), if any.
    pub budget_ms: Option<f64>,
    /// Frames over the budget.
    pub budget_misses: usize,
    /// Frames over the budget by more than 1 ms (the real-time target is none).
    pub budget_misses_over_1ms: usize,
    /// Worst overrun beyond the budget.
    pub worst_overrun_ms: f64,
    /// Work that runs whatever the budget (G-buffers, reprojection, accumulation, and the
    /// tracing of pixels without valid history: all of a fully traced eye), median.
    pub always_run_ms: f64,
}

/// One run of the driver: a schedule over the measured frames.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ScheduleRun {
    /// `stereo <mode>` (this report's mode), `full stereo` (both eyes path traced) or `mono`
    /// (the right eye alone path traced).
    pub schedule: String,
    /// The budget this run's frames had (equal for every run of a report).
    pub budget_ms: Option<f64>,
    /// Frame times.
    pub frame: Spread,
    /// Share of each eye's pixels path traced, median over frames (`[left, right]`; a mono
    /// run shows no left eye: null).
    pub traced_share: [Option<f64>; 2],
    /// Path-traced samples per pixel of each eye, averaged over the eye's pixels (`share ×
    /// spp`), median over frames.
    pub spp_per_pixel: [Option<f64>; 2],
    /// Frames over the budget (0 without one).
    pub budget_misses: usize,
}

impl ScheduleRun {
    fn of(
        schedule: &str,
        stats: &[FrameStats],
        extent: Extent,
        spp: u32,
        budget_ms: Option<f64>,
        eyes: [bool; 2],
    ) -> Self {
        let pixels = extent.pixels() as f64;
        let share = |eye: usize| {
            eyes[eye].then(|| {
                let mut v: Vec<f64> = stats.iter().map(|s| s.pixels_traced(eye) as f64 / pixels).collect();
                v.sort_by(f64::total_cmp);
                v[v.len() / 2]
            })
        };
        let traced_share = [share(0), share(1)];
        Self {
            schedule: schedule.to_owned(),
            budget_ms,
            frame: Spread::of(stats.iter().map(|f| ms(f.times.total)).collect()),
            traced_share,
            spp_per_pixel: traced_share.map(|s| s.map(|s| s * f64::from(spp))),
            budget_misses: budget_ms.map_or(0, |b| stats.iter().filter(|s| ms(s.times.total) > b).count()),
        }
    }
}

/// `numerator`'s median frame time over `denominator`'s, only when both ran without a
/// budget: under one, frame time is set by the budget, not by the work, and a ratio of two
/// budgeted times (or of a budgeted and an unbudgeted one) says nothing about the method.
pub fn time_ratio(numerator: &ScheduleRun, denominator: &ScheduleRun) -> Option<f64> {
    (numerator.budget_ms.is_none() && denominator.budget_ms.is_none())
        .then(|| numerator.frame.median_ms / denominator.frame.median_ms)
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Runs `frames + 1` frames (the first, without history, is not measured) and returns the
/// stats of the measured ones; with `mono`, mono frames (the right eye alone path traced,
/// see [`Pipeline::render_mono_frame`]).
fn run_frames(
    renderer: &Renderer,
    options: RendererOptions,
    config: PipelineConfig,
    extent: Extent,
    frames: u32,
    mono: bool,
) -> Result<Vec<FrameStats>, String> {
    let pipeline =
        Pipeline::with_options(renderer, options, config, StereoRig::default(), extent).map_err(|e| e.to_string())?;
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

/// `stereotrace throughput`: runs the driver and returns its report as text or JSON.
pub fn run_command(opts: &ThroughputOptions) -> Result<String, String> {
    let report = run(opts)?;
    if opts.json { serde_json::to_string_pretty(&report).map_err(|e| e.to_string()) } else { Ok(report.text()) }
}

/// The tree `throughput --bvh` builds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BvhBuild {
    /// The renderer's default.
    Default,
    /// obvhs's PLOC, fast preset.
    Fast,
    /// obvhs's PLOC, medium preset.
    Medium,
    /// The binned SAH build without spatial splits.
    Sah,
    /// The binned SAH build with spatial splits.
    Splits,
}

impl BvhBuild {
    fn quality(self) -> BuildQuality {
        match self {
            BvhBuild::Default => BuildQuality::default(),
            BvhBuild::Fast => BuildQuality::Fast,
            BvhBuild::Medium => BuildQuality::Medium,
            BvhBuild::Sah => BuildQuality::Sah,
            BvhBuild::Splits => BuildQuality::SahSplits,
        }
    }
}

/// Runs the driver.
pub fn run(opts: &ThroughputOptions) -> Result<ThroughputReport, String> {
    let pool = opts.threads.pool()?;
    let scene = crate::scene::resolve(&opts.input.scene).map_err(|e| e.to_string())?;
    let name = scene.name.clone();
    let renderer = Renderer::with_bvh_quality(scene, opts.bvh.quality()).map_err(|e| e.to_string())?;
    let tolerances = renderer.scene().tolerances.at_height(opts.input.res.height());
    let mut config = PipelineConfig::paper(opts.mode, opts.spp, tolerances);
    config.order = opts.order;
    config.layout = opts.layout;
    config.history = opts.history;
    config.blend = opts.blend;
    config.filter = opts.filter;
    config.background = opts.background;
    config.motion_vectors = opts.motion_vectors;
    let options = opts.gbuffer.options();
    config.budget = opts.budget_ms.map(crate::pipeline::budget_duration).transpose()?;
    let stats = pool.install(|| run_frames(&renderer, options, config, opts.input.res, opts.frames, false))?;
    // Every run below shares `config`, the budget included: only the schedule differs.
    let schedule = |name: &str, stats: &[FrameStats], eyes: [bool; 2]| {
        ScheduleRun::of(name, stats, opts.input.res, opts.spp, opts.budget_ms, eyes)
    };
    let this_run = schedule(opts.mode.name(), &stats, [true, true]);
    let full_stereo = if opts.mode == Mode::PathTraced {
        Some(this_run.clone())
    } else if opts.baseline {
        let full = PipelineConfig { mode: Mode::PathTraced, ..config };
        let full_stats = pool.install(|| run_frames(&renderer, options, full, opts.input.res, opts.frames, false))?;
        Some(schedule("full stereo", &full_stats, [true, true]))
    } else {
        None
    };
    let mono = if opts.baseline {
        let mono_stats = pool.install(|| run_frames(&renderer, options, config, opts.input.res, opts.frames, true))?;
        Some(schedule("mono", &mono_stats, [false, true]))
    } else {
        None
    };
    let mut schedules = vec![this_run.clone()];
    schedules.extend(full_stereo.iter().filter(|_| opts.mode != Mode::PathTraced).cloned());
    schedules.extend(mono.iter().cloned());

    let series = |f: fn(&FrameStats) -> Duration| Spread::of(stats.iter().map(|s| ms(f(s))).collect());
    let frame = series(|s| s.times.total);
    let pixels = opts.input.res.pixels() as f64;
    let share = |eye: Eye| {
        let mut v: Vec<f64> = stats.iter().map(|s| s.pixels_traced(eye as usize) as f64 / pixels).collect();
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
        width: opts.input.res.width(),
        height: opts.input.res.height(),
        threads: usize::from(opts.threads.threads),
        mode: opts.mode.name().into(),
        order: opts.order.name().into(),
        history: opts.history.name().into(),
        blend: opts.blend.name().into(),
        filter: opts.filter.name().into(),
        background: opts.background.name().into(),
        layout: format!("{:?}", opts.layout).to_lowercase(),
        gbuffer_pass: opts.gbuffer.gbuffer.name().into(),
        first_sample: opts.gbuffer.first_sample.name().into(),
        motion_vectors: opts.motion_vectors,
        spp: opts.spp,
        frames_measured: stats.len(),
        simd_level: crate::cpu::simd_level(),
        stereo_fps: stats.len() as f64 / total_time,
        frame,
        gbuffer: series(|s| s.times.gbuffer),
        raster: raster_steps(&stats),
        reprojection: series(|s| s.times.reprojection),
        tracing: series(|s| s.times.tracing),
        accumulation: series(|s| s.times.accumulation),
        gradients: series(|s| s.times.gradients),
        filter_ms: series(|s| s.times.filter),
        mrays_per_s: if tracing_time > 0.0 { rays as f64 / tracing_time / 1e6 } else { 0.0 },
        left_traced_share: share(Eye::Left),
        right_traced_share: share(Eye::Right),
        full_stereo_frame_ms: full_stereo.as_ref().map(|f| f.frame.median_ms),
        speedup_over_full_stereo: full_stereo.as_ref().and_then(|f| time_ratio(f, &this_run)),
        mono_frame_ms: mono.as_ref().map(|m| m.frame.median_ms),
        stereo_over_mono: mono.as_ref().and_then(|m| time_ratio(&this_run, m)),
        schedules,
        budget_ms: opts.budget_ms,
        budget_misses: misses,
        budget_misses_over_1ms: misses_1ms,
        worst_overrun_ms: worst.max(0.0),
        always_run_ms: Spread::of(
            stats
                .iter()
                .map(|s| {
                    let t = &s.times;
                    ms(t.gbuffer + t.reprojection + t.accumulation + t.gradients + t.filter + t.urgent_tracing)
                })
                .collect(),
        )
        .median_ms,
    })
}

/// The raster pass's steps over `stats`, if every frame rasterised.
fn raster_steps(stats: &[FrameStats]) -> Option<RasterSteps> {
    let passes: Vec<_> = stats.iter().map(|s| s.raster).collect::<Option<_>>()?;
    let last = passes.last()?;
    let series = |f: fn(&RasterPassStats) -> Duration| Spread::of(passes.iter().map(|p| ms(f(p))).collect());
    Some(RasterSteps {
        setup: series(|p| p.raster.setup),
        binning: series(|p| p.raster.binning),
        fragments: series(|p| p.raster.fragments),
        resolve: series(|p| p.resolve),
        triangles: last.raster.triangles,
        visible: last.raster.visible,
        cluster_culled: last.raster.cluster_culled,
        band_records: last.raster.band_records,
        band_points: last.raster.band_points,
        exact_fragments: last.raster.exact,
    })
}

impl ThroughputReport {
    /// The human-readable summary.
    pub fn text(&self) -> String {
        let stage =
            |name: &str, s: &Spread| format!("  {name:<13} {:>9.2} ms median {:>9.2} ms p95\n", s.median_ms, s.p95_ms);
        let mut out = format!(
            "{} {}x{} {} threads, mode {} (order {}, {} history, {} blend, filter {}, {} {} G-buffer{}, {} first sample), {} spp, {}: {} frames measured\n",
            self.scene,
            self.width,
            self.height,
            self.threads,
            self.mode,
            self.order,
            self.history,
            self.blend,
            self.filter,
            self.layout,
            self.gbuffer_pass,
            if self.motion_vectors { " with motion vectors" } else { "" },
            self.first_sample,
            self.spp,
            self.simd_level,
            self.frames_measured
        );
        out += &format!("  stereo fps    {:>9.2}\n", self.stereo_fps);
        out += &stage("frame", &self.frame);
        out += &stage("g-buffers", &self.gbuffer);
        if let Some(r) = &self.raster {
            out += &format!(
                "    raster       setup {:.2}, binning {:.2}, fragments {:.2}, resolve {:.2} ms (medians; {} of {} triangles visible, {} skipped in off-screen clusters, {} fragments on the exact path)\n",
                r.setup.median_ms,
                r.binning.median_ms,
                r.fragments.median_ms,
                r.resolve.median_ms,
                r.visible,
                r.triangles,
                r.cluster_culled,
                r.exact_fragments
            );
        }
        out += &stage("reprojection", &self.reprojection);
        out += &stage("path tracing", &self.tracing);
        out += &stage("accumulation", &self.accumulation);
        if self.history == History::Gradient.name() {
            out += &stage("gradients", &self.gradients);
        }
        if self.filter != Filter::None.name() {
            out += &stage("filter", &self.filter_ms);
        }
        out += &format!("  Mrays/s       {:>9.2} (while tracing)\n", self.mrays_per_s);
        out += &format!(
            "  traced        {:>8.1} % of left-eye pixels, {:.1} % of right-eye pixels\n",
            100.0 * self.left_traced_share,
            100.0 * self.right_traced_share
        );
        if let (Some(full), Some(speedup)) = (self.full_stereo_frame_ms, self.speedup_over_full_stereo) {
            out += &format!(
                "  full stereo   {full:>9.2} ms median (both eyes path traced, no budget): speed-up {speedup:.2}x\n"
            );
        }
        if let (Some(mono), Some(ratio)) = (self.mono_frame_ms, self.stereo_over_mono) {
            out += &format!(
                "  mono          {mono:>9.2} ms median (right eye alone path traced, no budget): stereo costs {ratio:.3}x\n"
            );
        }
        if let Some(b) = self.budget_ms {
            out += &format!(
                "  budget        {b:>9.2} ms: {} of {} frames over ({} by more than 1 ms), worst overrun {:.2} ms\n",
                self.budget_misses, self.frames_measured, self.budget_misses_over_1ms, self.worst_overrun_ms
            );
            if self.schedules.len() > 1 {
                out += &self.budgeted_comparison(b);
            }
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

    /// Under a budget: what each schedule traced in the same budget, and where the quality
    /// side is measured; no time ratio.
    fn budgeted_comparison(&self, budget_ms: f64) -> String {
        let pct = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |v| format!("{:.1} %", 100.0 * v));
        let spp = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |v| format!("{v:.3}"));
        let mut out = format!(
            "  every schedule under the same {budget_ms:.2} ms budget at {} spp (medians over frames):\n\
             \x20   schedule          frame ms  left traced right traced  left spp right spp  over budget\n",
            self.spp
        );
        for run in &self.schedules {
            out += &format!(
                "    {:<15} {:>10.2} {:>12} {:>12} {:>9} {:>9} {:>6} of {}\n",
                run.schedule,
                run.frame.median_ms,
                pct(run.traced_share[0]),
                pct(run.traced_share[1]),
                spp(run.spp_per_pixel[0]),
                spp(run.spp_per_pixel[1]),
                run.budget_misses,
                self.frames_measured
            );
        }
        out += "  full stereo and mono frames have no reprojected data to fall back on, so they trace every \
                pixel whatever the budget.\n";
        out += &format!(
            "  no time ratio under a budget (frame time is set by the budget, not by the work); for \
             effective spp at equal time run `stereotrace tradeoff --scene {} --budgets {budget_ms}`\n",
            self.scene
        );
        out
    }
}
