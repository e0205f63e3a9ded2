//! `stereotrace tradeoff`: what accuracy costs in time. For one scene, sweeps pipeline
//! settings (input spp, every mode and both spatiotemporal orders, the tap policy, the α
//! ramp, the G-buffer layout and per-frame budgets) and measures, in the same run and at the
//! same resolution, the time per stereo frame and the effective spp of the left eye
//! against the evaluation harness's references and error curves ([`crate::eval`]).
//!
//! Budgets are fractions of the unbudgeted spatiotemporal frame time measured at the same
//! spp in this run, so the sweep shows how quality degrades as the budget shrinks on any
//! machine. The Pareto front (no other setting is both faster and better) is marked in the
//! table and the plot.

use std::path::{Path, PathBuf};
use std::time::Duration;

use clap::Args;
use plotters::coord::Shift;
use plotters::prelude::*;
use serde::Serialize;

use super::throughput::Spread;
use crate::camera::{Eye, StereoRig};
use crate::eval::cache::Cache;
use crate::eval::curve::measure;
use crate::eval::plots::{Figure, both_fig, draw_legend, err, tick};
use crate::eval::run::{SceneBasis, scene_basis};
use crate::eval::stats::Summary;
use crate::eval::{EvalSpec, Metric, Preset, Reporter, Variant};
use crate::kernels::Extent;
use crate::kernels::reproject::TapPolicy;
use crate::pipeline::{Background, Blend, Filter, History, Layout, Mode, Order, Pipeline};
use crate::render::{FirstSample, GBufferPass, RendererOptions};
use crate::session::{CameraWalk, Session};

use super::args::{
    GBufferArg, ReferenceArgs, SceneArgs, ThreadsArg, default, parse_budget_ms, parse_frames, parse_spp,
};

/// Options of `stereotrace tradeoff`.
#[derive(Args, Clone, Debug)]
#[command(mut_arg("scene", default("atrium")), mut_arg("res", default("256x144")))]
pub struct TradeoffOptions {
    /// The scene and the resolution per eye (time and quality are both measured at it).
    #[command(flatten)]
    pub input: SceneArgs,
    /// Worker threads.
    #[command(flatten)]
    pub threads: ThreadsArg,
    /// Frames the pipeline renders (0..FRAMES); frame 0 is not timed, and at least 2 are
    /// needed.
    #[arg(long, default_value_t = 14, value_parser = parse_frames)]
    pub frames: u32,
    /// Warm-up frames left out of the quality measurement.
    #[arg(long, default_value_t = 10)]
    pub warmup: u32,
    /// Input samples per pixel (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "1,2,4", value_parser = parse_spp)]
    pub spp: Vec<u32>,
    /// The references, the error curves and their cache (shared with `eval`; the quick
    /// preset's by default).
    #[command(flatten)]
    pub references: ReferenceArgs,
    /// Budgets as fractions of the unbudgeted spatiotemporal frame time at the same spp
    /// (comma-separated, each in (0, 1]).
    #[arg(long, value_delimiter = ',', default_value = "0.75,0.5,0.25", value_parser = parse_fraction)]
    pub budgets: Vec<f64>,
    /// Budgets in milliseconds per stereo frame (comma-separated, e.g. 33,50,100).
    #[arg(long, value_delimiter = ',', value_parser = parse_budget_ms)]
    pub budgets_ms: Vec<f64>,
    /// How the G-buffers are made (the sweep adds one row with the other pass).
    #[command(flatten)]
    pub gbuffer: GBufferArg,
    /// Output folder.
    #[arg(long, default_value = "out/tradeoff")]
    pub out: PathBuf,
}

/// Parses a budget fraction in (0, 1].
fn parse_fraction(s: &str) -> Result<f64, String> {
    let f: f64 = s.trim().parse().map_err(|_| format!("budget fraction '{s}' is not a number"))?;
    if f > 0.0 && f <= 1.0 { Ok(f) } else { Err(format!("budget fraction {s} is not in (0, 1]")) }
}

impl TradeoffOptions {
    /// The command's defaults on `scene`, with `flags` as on the command line (for example
    /// `["--frames", "4"]`).
    pub fn new(scene: &str, flags: &[&str]) -> Result<Self, String> {
        use clap::FromArgMatches;
        let command = Self::augment_args(clap::Command::new("tradeoff").no_binary_name(true));
        let matches =
            command.try_get_matches_from(["--scene", scene].iter().chain(flags)).map_err(|e| e.to_string())?;
        Self::from_arg_matches(&matches).map_err(|e| e.to_string())
    }

    /// The evaluation spec whose references and curves the sweep measures against.
    pub fn eval_spec(&self) -> EvalSpec {
        let mut spec = Preset::Quick.spec();
        spec.preset = "tradeoff".into();
        spec.scenes = vec![self.input.scene.clone()];
        (spec.width, spec.height) = (self.input.res.width(), self.input.res.height());
        spec.frames = self.frames;
        spec.warmup = self.warmup;
        spec.input_spp = self.spp.clone();
        self.references.apply(&mut spec);
        spec.gbuffer = self.gbuffer.gbuffer;
        spec.first_sample = self.gbuffer.first_sample;
        spec
    }

    fn validate(&self) -> Result<(), String> {
        if self.spp.is_empty() {
            return Err("--spp must be a non-empty list".into());
        }
        if self.frames < 2 {
            return Err("--frames must be at least 2 (frame 0 has no history and is not timed)".into());
        }
        Ok(())
    }
}

/// One point of the sweep: a pipeline configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setting {
    /// The pipeline mode.
    pub mode: Mode,
    /// Order of stereo and temporal reprojection.
    pub order: Order,
    /// Samples per traced pixel.
    pub spp: u32,
    /// What reprojection does with a pixel some of whose taps failed.
    pub policy: TapPolicy,
    /// The EMA's α ramp over a pixel's history length.
    pub ramp: bool,
    /// The G-buffer layout reprojection reads.
    pub layout: Layout,
    /// How the G-buffers are made.
    pub gbuffer: GBufferPass,
    /// Where each pixel's first sample starts.
    pub first_sample: FirstSample,
    /// How far the EMA trusts a reprojected history.
    pub history: History,
    /// How the stereo blend weighs the eyes.
    pub blend: Blend,
    /// The spatial filter of the shown images.
    pub filter: Filter,
    /// What reprojection does with background pixels.
    pub background: Background,
    /// A fraction of the unbudgeted spatiotemporal (paper order) time at the same spp.
    pub budget_fraction: Option<f64>,
    /// A budget in milliseconds.
    pub budget_ms: Option<f64>,
}

impl Setting {
    fn paper(mode: Mode, order: Order, spp: u32, gbuffer: GBufferPass, first_sample: FirstSample) -> Self {
        let order = if mode.has_order() { order } else { Order::Paper };
        Self {
            mode,
            order,
            spp,
            policy: TapPolicy::Renormalize,
            ramp: false,
            layout: Layout::Compact,
            gbuffer,
            first_sample,
            history: History::Paper,
            blend: Blend::Fixed,
            filter: Filter::None,
            background: Background::Trace,
            budget_fraction: None,
            budget_ms: None,
        }
    }

    /// What differs from the paper's settings, e.g. `strict taps`, `budget 50%`.
    pub fn change(&self) -> String {
        let mut parts = Vec::new();
        if self.policy == TapPolicy::Strict {
            parts.push("strict taps".to_owned());
        }
        if self.ramp {
            parts.push("α ramp".to_owned());
        }
        if self.layout == Layout::Full {
            parts.push("full G-buffer".to_owned());
        }
        if self.gbuffer != GBufferPass::default() {
            parts.push(format!("{} G-buffer", self.gbuffer.name()));
        }
        if self.first_sample != FirstSample::default() {
            parts.push(format!("{} first sample", self.first_sample.name()));
        }
        if self.history != History::Paper {
            parts.push(format!("{} history", self.history.name()));
        }
        if self.blend != Blend::Fixed {
            parts.push(format!("{} blend", self.blend.name()));
        }
        if self.filter != Filter::None {
            parts.push(format!("{} filter", self.filter.name()));
        }
        if self.background != Background::Trace {
            parts.push(format!("{} background", self.background.name()));
        }
        if let Some(f) = self.budget_fraction {
            parts.push(format!("budget {:.0}%", f * 100.0));
        }
        if let Some(b) = self.budget_ms {
            parts.push(format!("budget {b} ms"));
        }
        if parts.is_empty() { "paper".to_owned() } else { parts.join(", ") }
    }

    /// `spatiotemporal-stereo-first`, `path-traced`, ...
    pub fn mode_name(&self) -> String {
        if self.mode == Mode::PathTraced {
            Mode::PathTraced.name().to_owned()
        } else {
            Variant::new(self.mode, self.order).name()
        }
    }

    fn is_spatiotemporal_paper(&self) -> bool {
        self.mode == Mode::Spatiotemporal && self.order == Order::Paper
    }
}

/// The settings swept at each input spp: full stereo path tracing, every mode and order of
/// the paper, and the spatiotemporal mode with each option changed in turn (the other
/// G-buffer pass among them) and under each budget. The unbudgeted spatiotemporal setting
/// comes before its budgeted ones.
pub fn settings(opts: &TradeoffOptions) -> Vec<Setting> {
    let mut out = Vec::new();
    let other_pass = match opts.gbuffer.gbuffer {
        GBufferPass::Raster | GBufferPass::Exact => GBufferPass::Traced,
        GBufferPass::Traced => GBufferPass::Raster,
    };
    for &spp in &opts.spp {
        let first = opts.gbuffer.first_sample;
        let paper = |mode, order| Setting::paper(mode, order, spp, opts.gbuffer.gbuffer, first);
        out.push(paper(Mode::PathTraced, Order::Paper));
        for v in Variant::ALL {
            out.push(paper(v.mode, v.order));
        }
        let base = paper(Mode::Spatiotemporal, Order::Paper);
        out.push(Setting { policy: TapPolicy::Strict, ..base });
        out.push(Setting { ramp: true, ..base });
        out.push(Setting { layout: Layout::Full, ..base });
        out.push(Setting { gbuffer: other_pass, ..base });
        // The first sample at the pixel centre, its hit from the G-buffer pass: less tracing,
        // no antialiasing within a frame.
        let other_first = match first {
            FirstSample::Jittered => FirstSample::Centre,
            FirstSample::Centre => FirstSample::Jittered,
        };
        out.push(Setting { first_sample: other_first, ..base });
        // Temporal gradients: the same points as the paper's on a scene where nothing moves
        // (it traces no gradient samples there).
        out.push(Setting { history: History::Gradient, ..base });
        // TAA's neighbourhood clamp of the history: it follows changes from this frame's
        // samples alone, and pays for that in noise where nothing changed.
        out.push(Setting { history: History::Clamp, ..base });
        // The variance-guided blend changes the blend of histories only.
        let blend = paper(Mode::SpatiotemporalBlend, Order::Paper);
        out.push(Setting { blend: Blend::Variance, ..blend });
        // The à-trous filter of the shown images (the denoising study's point).
        out.push(Setting { filter: Filter::Atrous, ..base });
        // The sky's history kept by direction: less tracing on scenes with an open sky, the
        // paper's points where there is none.
        out.push(Setting { background: Background::Reproject, ..base });
        for &f in &opts.budgets {
            out.push(Setting { budget_fraction: Some(f), ..base });
        }
        for &b in &opts.budgets_ms {
            out.push(Setting { budget_ms: Some(b), ..base });
        }
    }
    out
}

/// One measured setting.
#[derive(Clone, Debug, Serialize)]
pub struct TradeoffRow {
    /// The mode, with its order where it has one.
    pub mode: String,
    /// What differs from the paper's settings (`paper` for none, else a list such as `strict taps, budget 50%`).
    pub change: String,
    /// Samples per traced pixel.
    pub spp: u32,
    /// The per-frame budget the setting ran under, if any.
    pub budget_ms: Option<f64>,
    /// Time per stereo frame over frames `1..frames`.
    pub frame: Spread,
    /// Left-eye pixels path traced (mean share over the timed frames).
    pub left_traced_share: f64,
    /// Right-eye pixels path traced (mean share over the timed frames).
    pub right_traced_share: f64,
    /// Timed frames over the budget.
    pub budget_misses: usize,
    /// Worst overrun beyond the budget.
    pub worst_overrun_ms: f64,
    /// Effective spp of the left eye on the evaluated frames.
    pub effective_ssim: Summary,
    /// Effective spp of the left eye by RMSE on the same frames.
    pub effective_rmse: Summary,
    /// Mean SSIM of the left eye on the evaluated frames.
    pub mean_ssim: f64,
    /// On the Pareto front of (median ms, effective spp by SSIM).
    pub pareto: bool,
}

/// Everything the sweep measured (the JSON file).
#[derive(Clone, Debug, Serialize)]
pub struct TradeoffReport {
    /// The scene's spec as given.
    pub scene: String,
    /// Width per eye, in pixels.
    pub width: usize,
    /// Height per eye, in pixels.
    pub height: usize,
    /// Worker threads.
    pub threads: usize,
    /// Frames rendered per setting (`0..frames`).
    pub frames: u32,
    /// Warm-up frames left out of the quality measurement.
    pub warmup: u32,
    /// Samples per pixel of the references.
    pub reference_spp: u32,
    /// Last spp of the error curves.
    pub curve_spp: u32,
    /// The kernel bodies the CPU ran.
    pub simd_level: String,
    /// One row per setting, in sweep order.
    pub rows: Vec<TradeoffRow>,
    /// Non-fatal problems of the references and curves, in the order they were reported.
    pub warnings: Vec<String>,
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Runs one setting over all frames: times each frame, measures the evaluated ones.
fn measure_setting(
    basis: &SceneBasis,
    spec: &EvalSpec,
    setting: &Setting,
    budget_ms: Option<f64>,
    extent: Extent,
) -> Result<TradeoffRow, String> {
    let renderer = &basis.renderer;
    let tolerances = renderer.scene().tolerances.at_height(extent.height());
    let mut config =
        crate::eval::run::pipeline_config(spec, Variant::new(setting.mode, setting.order), setting.spp, tolerances);
    config.mode = setting.mode;
    config.policy = setting.policy;
    config.ramp = setting.ramp;
    config.layout = setting.layout;
    config.history = setting.history;
    config.filter = setting.filter;
    config.blend = setting.blend;
    config.background = setting.background;
    config.budget = budget_ms.map(crate::pipeline::budget_duration).transpose()?;
    let rig = StereoRig::new(spec.eye_separation)?;
    let options = RendererOptions::with_first_sample(setting.gbuffer, setting.first_sample);
    let pipeline = Pipeline::with_options(renderer, options, config, rig, extent).map_err(|e| e.to_string())?;
    let mut session = Session::new(pipeline, CameraWalk::Path);
    let variant = spec.ssim.kernel();
    let pixels = extent.pixels() as f64;
    let (mut times, mut left, mut right) = (Vec::new(), Vec::new(), Vec::new());
    let (mut eff_ssim, mut eff_rmse, mut ssim_values) = (Vec::new(), Vec::new(), Vec::new());
    let (mut misses, mut worst) = (0, 0.0f64);
    for f in 0..spec.frames {
        let stats = session.next_frame().map_err(|e| format!("frame {f}: {e}"))?;
        if f > 0 {
            let t = ms(stats.times.total);
            times.push(t);
            left.push(stats.pixels_traced(Eye::Left as usize) as f64 / pixels);
            right.push(stats.pixels_traced(Eye::Right as usize) as f64 / pixels);
            if let Some(b) = budget_ms {
                misses += usize::from(t > b);
                worst = worst.max(t - b);
            }
        }
        if let (Some(reference), Some(curve)) = (basis.references.get(&f), basis.curves.get(&f)) {
            let m = measure(session.pipeline().output(Eye::Left), reference, variant)?;
            ssim_values.push(m.ssim);
            eff_ssim.push(curve.curve(Metric::Ssim)?.effective_spp(m.error(Metric::Ssim)));
            eff_rmse.push(curve.curve(Metric::Rmse)?.effective_spp(m.error(Metric::Rmse)));
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    Ok(TradeoffRow {
        mode: setting.mode_name(),
        change: setting.change(),
        spp: setting.spp,
        budget_ms,
        frame: Spread::of(times),
        left_traced_share: mean(&left),
        right_traced_share: mean(&right),
        budget_misses: misses,
        worst_overrun_ms: worst,
        effective_ssim: Summary::of_frames(&eff_ssim),
        effective_rmse: Summary::of_frames(&eff_rmse),
        mean_ssim: mean(&ssim_values),
        pareto: false,
    })
}

/// Marks the rows no other row beats on both time (lower) and effective spp (higher).
pub fn mark_pareto(rows: &mut [TradeoffRow]) {
    let point = |r: &TradeoffRow| r.effective_ssim.mean.map(|q| (r.frame.median_ms, q));
    let points: Vec<Option<(f64, f64)>> = rows.iter().map(point).collect();
    for (i, row) in rows.iter_mut().enumerate() {
        row.pareto = points[i].is_some_and(|(t, q)| {
            !points
                .iter()
                .enumerate()
                .any(|(j, p)| j != i && p.is_some_and(|(tj, qj)| tj <= t && qj >= q && (tj < t || qj > q)))
        });
    }
}

/// Runs the sweep with a progress bar, writes its files into `opts.out`, and returns the
/// Markdown table and the files written.
pub fn run_command(opts: &TradeoffOptions) -> Result<String, String> {
    let bar = super::eval::Bar::new();
    let result = sweep(opts, &bar);
    bar.bar.finish_and_clear();
    let report = result?;
    let written = report.write(&opts.out)?;
    let mut text = report.markdown();
    text += "\nWritten:\n";
    for w in written {
        text += &format!("  {}\n", w.display());
    }
    Ok(text)
}

/// Runs the sweep (references and curves from `cache` or computed into it).
pub fn sweep(opts: &TradeoffOptions, reporter: &dyn Reporter) -> Result<TradeoffReport, String> {
    opts.validate()?;
    let spec = opts.eval_spec();
    spec.validate()?;
    let pool = opts.threads.pool()?;
    let cache = Cache::open(&opts.references.cache)?;
    reporter.status(&format!("{}: references and error curves", opts.input.scene));
    let basis = pool.install(|| scene_basis(&spec, &opts.input.scene, &cache, reporter)).map_err(|e| e.to_string())?;
    let settings = settings(opts);
    let mut rows: Vec<TradeoffRow> = Vec::with_capacity(settings.len());
    // Unbudgeted spatiotemporal time per spp, the unit of the budgets.
    let mut unbudgeted_ms: Vec<(u32, f64)> = Vec::new();
    reporter.begin(settings.len() as u64);
    for (i, s) in settings.iter().enumerate() {
        let budget_ms = match s.budget_fraction {
            None => s.budget_ms,
            Some(f) => {
                let base = unbudgeted_ms.iter().find(|(spp, _)| *spp == s.spp).map(|(_, t)| *t);
                Some(f * base.ok_or("a budgeted setting came before its unbudgeted one")?)
            }
        };
        reporter.status(&format!("[{}/{}] {} at {} spp ({})", i + 1, settings.len(), s.mode_name(), s.spp, s.change()));
        let row = pool.install(|| measure_setting(&basis, &spec, s, budget_ms, opts.input.res))?;
        if s.is_spatiotemporal_paper() && s.change() == "paper" {
            unbudgeted_ms.push((s.spp, row.frame.median_ms));
        }
        rows.push(row);
        reporter.advance(1);
    }
    mark_pareto(&mut rows);
    Ok(TradeoffReport {
        scene: opts.input.scene.clone(),
        width: opts.input.res.width(),
        height: opts.input.res.height(),
        threads: usize::from(opts.threads.threads),
        frames: opts.frames,
        warmup: opts.warmup,
        reference_spp: spec.reference_spp,
        curve_spp: spec.curve_spp,
        simd_level: crate::cpu::simd_level(),
        rows,
        warnings: basis.warnings,
    })
}

fn opt_ms(v: Option<f64>) -> String {
    v.map_or_else(String::new, |b| format!("{b:.2}"))
}

impl TradeoffReport {
    /// The Markdown table, sorted by time.
    pub fn markdown(&self) -> String {
        let mut out = format!(
            "# Trade-off: {} at {}×{} ({} threads, {})\n\nTime per stereo frame (median and p95 over frames 1–{}) \
             against the left eye's effective spp (SSIM and RMSE, mean ± std over frames {}–{}; references \
             {} spp, curves 1–{} spp). `*` marks the Pareto front.\n\n",
            self.scene,
            self.width,
            self.height,
            self.threads,
            self.simd_level,
            self.frames - 1,
            self.warmup,
            self.frames - 1,
            self.reference_spp,
            self.curve_spp
        );
        out += "| front | mode | change | spp | budget ms | median ms | p95 ms | left traced | right traced | \
                eff. spp (SSIM) | ± | eff. spp (RMSE) | ± | SSIM | budget misses |\n";
        out += "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
        let mut order: Vec<&TradeoffRow> = self.rows.iter().collect();
        order.sort_by(|a, b| a.frame.median_ms.total_cmp(&b.frame.median_ms));
        for r in order {
            out += &format!(
                "| {} | {} | {} | {} | {} | {:.2} | {:.2} | {:.1} % | {:.1} % | {} | {} | {} | {} | {:.4} | {} |\n",
                if r.pareto { "*" } else { "" },
                r.mode,
                r.change,
                r.spp,
                opt_ms(r.budget_ms),
                r.frame.median_ms,
                r.frame.p95_ms,
                100.0 * r.left_traced_share,
                100.0 * r.right_traced_share,
                r.effective_ssim.mean_text(2),
                r.effective_ssim.std_text(2),
                r.effective_rmse.mean_text(2),
                r.effective_rmse.std_text(2),
                r.mean_ssim,
                r.budget_misses,
            );
        }
        if !self.warnings.is_empty() {
            out += "\nWarnings:\n\n";
            for w in &self.warnings {
                out += &format!("- {w}\n");
            }
        }
        out
    }

    /// The CSV table, in sweep order.
    pub fn csv(&self) -> String {
        let mut out = String::from(
            "mode,change,spp,budget_ms,median_ms,p95_ms,left_traced_share,right_traced_share,\
             effective_spp_ssim,effective_spp_ssim_std,effective_spp_ssim_bound,effective_spp_rmse,\
             effective_spp_rmse_std,mean_ssim,budget_misses,worst_overrun_ms,pareto\n",
        );
        let num = |v: Option<f64>| v.map_or_else(String::new, |v| format!("{v:.4}"));
        for r in &self.rows {
            out += &format!(
                "{},\"{}\",{},{},{:.4},{:.4},{:.5},{:.5},{},{},{:?},{},{},{:.6},{},{:.4},{}\n",
                r.mode,
                r.change,
                r.spp,
                opt_ms(r.budget_ms),
                r.frame.median_ms,
                r.frame.p95_ms,
                r.left_traced_share,
                r.right_traced_share,
                num(r.effective_ssim.mean),
                num(r.effective_ssim.std),
                r.effective_ssim.bound,
                num(r.effective_rmse.mean),
                num(r.effective_rmse.std),
                r.mean_ssim,
                r.budget_misses,
                r.worst_overrun_ms,
                r.pareto
            );
        }
        out
    }

    /// Writes `tradeoff.{md,csv,json,png,svg}` into `dir`; returns the files written.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>, String> {
        std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        let mut written = Vec::new();
        let json = serde_json::to_string_pretty(self).map_err(|e| e.to_string())?;
        for (name, text) in [("tradeoff.md", self.markdown()), ("tradeoff.csv", self.csv()), ("tradeoff.json", json)] {
            let path = dir.join(name);
            std::fs::write(&path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            written.push(path);
        }
        both_fig(&dir.join("tradeoff"), (960, 640), &TradeoffPlot { report: self }, &mut written)?;
        Ok(written)
    }
}

/// Effective spp against milliseconds per stereo frame, one colour per mode, the Pareto
/// front as a line.
struct TradeoffPlot<'a> {
    report: &'a TradeoffReport,
}

impl Figure for TradeoffPlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), String> {
        root.fill(&WHITE).map_err(err)?;
        let pts: Vec<(&TradeoffRow, f64, f64)> = self
            .report
            .rows
            .iter()
            .filter_map(|r| Some((r, r.frame.median_ms, r.effective_ssim.mean?)))
            .filter(|(_, t, q)| *t > 0.0 && *q > 0.0)
            .collect();
        if pts.is_empty() {
            return Err("no setting has an effective spp to plot".into());
        }
        let range = |f: fn(&(&TradeoffRow, f64, f64)) -> f64| {
            pts.iter().map(f).fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)))
        };
        let (t0, t1) = range(|p| p.1);
        let (q0, q1) = range(|p| p.2);
        let r = self.report;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "{} at {}×{}, {} threads: effective spp (SSIM) against time",
                    r.scene, r.width, r.height, r.threads
                ),
                ("sans-serif", 16),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(((t0 / 1.2)..(t1 * 1.2)).log_scale(), ((q0 / 1.3)..(q1 * 1.3)).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("ms per stereo frame (median)")
            .y_desc("effective spp of the left eye (SSIM)")
            .x_label_formatter(&|v| tick(*v))
            .y_label_formatter(&|v| tick(*v))
            .draw()
            .map_err(err)?;
        let mut front: Vec<(f64, f64)> = pts.iter().filter(|p| p.0.pareto).map(|p| (p.1, p.2)).collect();
        front.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(front.iter().copied(), BLACK.stroke_width(2)))
            .map_err(err)?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
        let mut modes: Vec<String> = pts.iter().map(|p| p.0.mode.clone()).collect();
        modes.dedup();
        modes.sort();
        modes.dedup();
        for (i, mode) in modes.iter().enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            let of_mode: Vec<_> = pts.iter().filter(|p| &p.0.mode == mode).collect();
            // Filled: the paper's settings; hollow: an option changed or a budget.
            chart
                .draw_series(of_mode.iter().map(|p| {
                    let style = if p.0.change == "paper" { colour.filled() } else { colour.stroke_width(2) };
                    Circle::new((p.1, p.2), 5, style)
                }))
                .map_err(err)?
                .label(mode.as_str())
                .legend(move |(x, y)| Circle::new((x + 10, y), 5, colour.filled()));
        }
        chart
            .draw_series(pts.iter().filter(|p| p.0.pareto).map(|p| {
                Text::new(format!("{} {}spp {}", p.0.mode, p.0.spp, p.0.change), (p.1, p.2), ("sans-serif", 10))
            }))
            .map_err(err)?;
        draw_legend(&mut chart, SeriesLabelPosition::LowerRight)?;
        root.present().map_err(err)
    }
}
