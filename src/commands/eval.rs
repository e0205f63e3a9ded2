//! `stereotrace eval`: the evaluation harness (see [`crate::eval`]) with a progress bar,
//! writing tables, figures and `results.json` into an output folder.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

use crate::eval::cache::Cache;
use crate::eval::paper::PaperTables;
use crate::eval::results::EvalOutcome;
use crate::eval::run::{EvalError, Limits, merge, plan, run_shard};
use crate::eval::units::{Shard, hours_text};
use crate::eval::{EvalSpec, Grid, Preset, Reporter, SsimChoice, Variant, evaluate, plots, report};
use crate::kernels::Extent;

use super::args::{ReferenceArgs, parse_frames, parse_resolution, parse_spp};

/// How the error curves are sampled (CLI form of [`Grid`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GridChoice {
    /// Every spp from 1 to the curve's end, linear interpolation.
    Dense,
    /// A geometric grid (16 points per doubling above 8 spp), log–log interpolation.
    Geometric,
}

/// Options of `stereotrace eval`; a value not given keeps the preset's.
#[derive(Args, Clone, Debug)]
pub struct EvalOptions {
    /// Starting point: `quick` (small, for CI) or `paper` (1280x720, days of CPU time).
    #[arg(long, value_enum, default_value_t = Preset::Quick)]
    pub preset: Preset,
    /// Scenes (comma-separated built-in names, manifests or folders); default: every built-in.
    #[arg(long, value_delimiter = ',')]
    pub scenes: Option<Vec<String>>,
    /// Modes (comma-separated): stereo, temporal, spatiotemporal, spatiotemporal-stereo-first,
    /// stereo-blend, spatiotemporal-blend, spatiotemporal-blend-stereo-first; default: all.
    #[arg(long, value_delimiter = ',', value_parser = Variant::parse)]
    pub modes: Option<Vec<Variant>>,
    /// Input samples per pixel (comma-separated).
    #[arg(long, value_delimiter = ',', value_parser = parse_spp)]
    pub spp: Option<Vec<u32>>,
    /// Resolution per eye, WIDTHxHEIGHT.
    #[arg(long, value_parser = parse_resolution)]
    pub res: Option<Extent>,
    /// Frames the pipeline renders (0..FRAMES).
    #[arg(long, value_parser = parse_frames)]
    pub frames: Option<u32>,
    /// Warm-up frames left out of the averages.
    #[arg(long)]
    pub warmup: Option<u32>,
    /// The references, the error curves and their cache.
    #[command(flatten)]
    pub references: ReferenceArgs,
    /// How the error curves are sampled.
    #[arg(long, value_enum)]
    pub grid: Option<GridChoice>,
    /// SSIM flavour (the paper's is the 3-D volume).
    #[arg(long, value_enum)]
    pub ssim: Option<SsimChoice>,
    /// Output folder (default: `out/eval-<preset>`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Skip the figures (and the work only they need).
    #[arg(long)]
    pub no_figures: bool,
    /// Stop after computing this many units (references, curves, configurations); run again to
    /// resume.
    #[arg(long)]
    pub max_units: Option<usize>,
    /// How the pipelines make their G-buffers (default: raster).
    #[arg(long, value_enum)]
    pub gbuffer: Option<crate::render::GBufferPass>,
    /// Where each pixel's first sample starts (default: jittered, the paper's).
    #[arg(long, value_enum)]
    pub first_sample: Option<crate::render::FirstSample>,
    /// Give the pipelines the surfaces' motion (moving area lights' own), which temporal
    /// reprojection follows; without it every surface is taken as still.
    #[arg(long)]
    pub motion_vectors: bool,
    /// How far the pipelines' EMA trusts a reprojected history: the paper's, or shortened by
    /// temporal gradients where the lighting changed (default: the preset's, the paper's).
    #[arg(long, value_enum)]
    pub history: Option<crate::pipeline::History>,
    /// How the pipelines' stereo blend weighs the eyes: the paper's fixed ½, or by inverse
    /// variance from the history lengths (default: the preset's, the paper's).
    #[arg(long, value_enum)]
    pub blend: Option<crate::pipeline::Blend>,
    /// A spatial filter of the pipelines' shown images after accumulation: none (the
    /// paper's), or the edge-avoiding à-trous filter (default: the preset's, none).
    #[arg(long, value_enum)]
    pub filter: Option<crate::pipeline::Filter>,
    /// What the pipelines' reprojection does with background pixels (sky): the paper's
    /// discards them (`trace`), `reproject` keeps a static sky's history by direction
    /// (default: the preset's, the paper's).
    #[arg(long, value_enum)]
    pub background: Option<crate::pipeline::Background>,
    /// List the run's work units and their estimated CPU time (writes OUT/plan.tsv); compute
    /// nothing.
    #[arg(long, conflicts_with_all = ["shard", "merge"])]
    pub plan: bool,
    /// Compute only shard K of N (0-based) into the cache, e.g. 2/8; `env` reads a Slurm
    /// array task or a Kubernetes Indexed Job. Shards may run at once on one cache.
    #[arg(long, value_parser = Shard::parse, conflicts_with = "merge")]
    pub shard: Option<Shard>,
    /// Write the reports from the cache alone (after every shard); fails naming what is
    /// missing.
    #[arg(long)]
    pub merge: bool,
}

/// What of the run this process does.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Scope {
    /// Every unit, then the reports.
    #[default]
    Whole,
    /// List the units and their estimated cost; compute nothing.
    Plan,
    /// Compute one shard's units into the cache; no reports.
    Shard(Shard),
    /// The reports from the cache alone; fails naming what is missing.
    Merge,
}

impl EvalOptions {
    /// What of the run this process does (`--plan`, `--shard` and `--merge` exclude each
    /// other).
    pub fn scope(&self) -> Scope {
        match (self.plan, self.shard, self.merge) {
            (true, ..) => Scope::Plan,
            (_, Some(s), _) => Scope::Shard(s),
            (_, _, true) => Scope::Merge,
            _ => Scope::Whole,
        }
    }

    /// The output folder.
    pub fn out_dir(&self) -> PathBuf {
        self.out.clone().unwrap_or_else(|| PathBuf::from(format!("out/eval-{}", self.preset.name())))
    }
}

/// The spec of the preset with the options' overrides; figure scenes that are not
/// evaluated fall back to the first evaluated scene.
pub fn build_spec(opts: &EvalOptions) -> Result<EvalSpec, String> {
    let mut spec = opts.preset.spec();
    if let Some(scenes) = &opts.scenes {
        spec.scenes = scenes.clone();
    }
    if let Some(modes) = &opts.modes {
        spec.variants = modes.clone();
    }
    if let Some(spp) = &opts.spp {
        let mut spp = spp.clone();
        spp.sort_unstable();
        spp.dedup();
        spec.input_spp = spp;
    }
    if let Some(e) = opts.res {
        (spec.width, spec.height) = (e.width(), e.height());
    }
    if let Some(f) = opts.frames {
        spec.frames = f;
        if opts.warmup.is_none() && spec.warmup >= f {
            spec.warmup = f / 2;
        }
    }
    if let Some(w) = opts.warmup {
        spec.warmup = w;
    }
    opts.references.apply(&mut spec);
    if let Some(g) = opts.grid {
        spec.grid = match g {
            GridChoice::Dense => Grid::Dense,
            GridChoice::Geometric => Grid::Geometric { steps_per_octave: 16 },
        };
    }
    if let Some(s) = opts.ssim {
        spec.ssim = s;
    }
    if let Some(f) = opts.first_sample {
        spec.first_sample = f;
    }
    if let Some(g) = opts.gbuffer {
        spec.gbuffer = g;
    }
    spec.motion_vectors |= opts.motion_vectors;
    if let Some(h) = opts.history {
        spec.history = h;
    }
    if let Some(b) = opts.blend {
        spec.blend = b;
    }
    if let Some(f) = opts.filter {
        spec.filter = f;
    }
    if let Some(b) = opts.background {
        spec.background = b;
    }
    // Figure options name scenes as the run will know them (a manifest's `name`, not its path).
    let names = spec
        .scenes
        .iter()
        .map(|s| crate::scene::scene_name(s).map_err(|e| format!("scene '{s}': {e}")))
        .collect::<Result<Vec<String>, String>>()?;
    let first = names.first().cloned();
    let has = |s: &Option<String>| s.as_ref().is_some_and(|s| names.contains(s));
    if !has(&spec.figures.framewise_scene) {
        spec.figures.framewise_scene = first.clone();
    }
    if !has(&spec.figures.discard_scene) {
        spec.figures.discard_scene = first.clone();
    }
    spec.figures.comparison_scenes.retain(|s| names.contains(s));
    if spec.figures.comparison_scenes.is_empty() {
        spec.figures.comparison_scenes.extend(first);
    }
    if opts.no_figures {
        spec.figures.framewise_scene = None;
        spec.figures.discard_scene = None;
        spec.figures.comparison_scenes.clear();
    }
    spec.validate()?;
    Ok(spec)
}

/// The progress bar (with plain status lines when stderr is not a terminal, e.g. in CI).
pub(crate) struct Bar {
    pub(crate) bar: ProgressBar,
    start: Instant,
}

impl Bar {
    /// A bar on stderr, ticking while work runs.
    pub(crate) fn new() -> Self {
        let bar = ProgressBar::new(0).with_style(
            ProgressStyle::with_template(
                "{spinner} {elapsed_precise} [{bar:30}] {percent:>3}% ETA {eta_precise}  {wide_msg}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        bar.enable_steady_tick(std::time::Duration::from_millis(250));
        Self { bar, start: Instant::now() }
    }
}

impl Reporter for Bar {
    fn begin(&self, total: u64) {
        self.bar.set_length(total);
        self.bar.reset_eta();
        if self.bar.is_hidden() {
            eprintln!(
                "[{:>7.1} s] {:.1} G pixel samples to compute",
                self.start.elapsed().as_secs_f64(),
                total as f64 / 1e9
            );
        }
    }
    fn add_work(&self, extra: u64) {
        self.bar.inc_length(extra);
    }
    fn skip_work(&self, work: u64) {
        self.bar.set_length(self.bar.length().unwrap_or(0).saturating_sub(work));
    }
    fn advance(&self, done: u64) {
        self.bar.inc(done);
    }
    fn status(&self, message: &str) {
        self.bar.set_message(message.to_owned());
        if self.bar.is_hidden() {
            eprintln!("[{:>7.1} s] {message}", self.start.elapsed().as_secs_f64());
        }
    }
    fn warn(&self, message: &str) {
        if self.bar.is_hidden() {
            eprintln!("warning: {message}");
        } else {
            self.bar.println(format!("warning: {message}"));
        }
    }
}

/// Runs the command; returns the report printed on stdout.
pub fn run(opts: &EvalOptions) -> Result<String, String> {
    let spec = build_spec(opts)?;
    let cache = Cache::open(&opts.references.cache)?;
    let reporter = Bar::new();
    let limits = Limits { max_computed_units: opts.max_units, max_samples: None };
    let result = match opts.scope() {
        Scope::Whole => evaluate(&spec, &cache, &reporter, limits).map(|o| Done::Outcome(Box::new(o))),
        Scope::Merge => merge(&spec, &cache, &reporter).map(|o| Done::Outcome(Box::new(o))),
        Scope::Plan => plan(&spec, &cache, &reporter).map(|p| Done::Text(plan_text(&p, opts))),
        Scope::Shard(shard) => run_shard(&spec, &cache, &reporter, shard, limits).map(|o| {
            let c = o.counters;
            Done::Text(format!(
                "shard {shard}: {} of {} units; computed {} references, {} curves, {} configurations, {} figure \
                 images ({:.3} G pixel samples); loaded from cache: {} entries; {} warnings; wall time: {:.1} s\n\
                 the cache in {} holds them: `eval --merge` with the same options writes the reports once every \
                 shard is done",
                o.units,
                o.total_units,
                c.references,
                c.curves,
                c.configs,
                c.figure_images,
                c.samples as f64 / 1e9,
                c.cache_hits,
                o.warnings.len(),
                o.seconds,
                cache.root().display()
            ))
        }),
    };
    reporter.bar.finish_and_clear();
    match result {
        Ok(Done::Outcome(outcome)) => write_outcome(&outcome, opts),
        Ok(Done::Text(text)) => Ok(text),
        Err(EvalError::Interrupted { computed, counters }) => Ok(format!(
            "stopped after computing {computed} units ({} references, {} curves, {} configurations); the cache in \
             {} holds them: run the same command again to continue",
            counters.references,
            counters.curves,
            counters.configs,
            cache.root().display()
        )),
        Err(e) => Err(e.to_string()),
    }
}

/// What a scope ends with.
enum Done {
    Outcome(Box<EvalOutcome>),
    Text(String),
}

/// The plan's summary, and its units as a TSV file in the output folder.
fn plan_text(p: &crate::eval::units::Plan, opts: &EvalOptions) -> String {
    let cpus = rayon::current_num_threads();
    let mut text = p.summary(cpus);
    let out = opts.out_dir();
    let path = out.join("plan.tsv");
    let mut tsv = String::from("unit\tkind\tscene\tpixel_samples\tcpu_seconds\tdependencies\tentry\n");
    for u in &p.units {
        tsv.push_str(&format!(
            "{u}\t{}\t{}\t{}\t{:.3}\t{}\t{}\n",
            u.kind.label(),
            u.scene_name,
            u.samples,
            u.cpu_seconds,
            u.dependencies,
            u.entry.as_deref().unwrap_or("-")
        ));
    }
    match std::fs::create_dir_all(&out).and_then(|_| std::fs::write(&path, tsv)) {
        Ok(()) => text.push_str(&format!("every unit: {}\n", path.display())),
        Err(e) => text.push_str(&format!("warning: {}: cannot write the unit list: {e}\n", path.display())),
    }
    let rates: Vec<String> =
        p.seconds_per_sample.iter().map(|(s, r)| format!("{s} {:.1} M/s", 1e-6 / r.max(1e-30))).collect();
    text.push_str(&format!(
        "path-tracing rate per CPU (measured now, frame 0 at ≤160×90): {}\nall units on this machine's {cpus} \
         CPUs: {}",
        rates.join(", "),
        hours_text(p.cpu_seconds() / cpus as f64)
    ));
    text
}

/// Writes the reports, figures and warnings of a finished run; the text printed on stdout.
fn write_outcome(outcome: &EvalOutcome, opts: &EvalOptions) -> Result<String, String> {
    let out = opts.out_dir();
    let mut written = report::write_reports(outcome, &out)?;
    let (figures, failed) = plots::write_figures(&outcome.results, &outcome.artifacts, &out);
    written.extend(figures);
    let warnings_path = out.join("warnings.txt");
    if !outcome.warnings.is_empty() {
        std::fs::write(&warnings_path, outcome.warnings.join("\n") + "\n")
            .map_err(|e| format!("{}: cannot write: {e}", warnings_path.display()))?;
        written.push(warnings_path);
    } else if warnings_path.exists() {
        // A file left by an earlier run would contradict this run's report of none.
        std::fs::remove_file(&warnings_path).map_err(|e| format!("{}: cannot remove: {e}", warnings_path.display()))?;
    }
    let c = outcome.counters;
    let mut text = report::summary_table(&outcome.results, &PaperTables::load());
    text.push_str(&format!(
        "\n{} files written to {}\ncomputed: {} references, {} curves, {} configurations, {} figure images \
         ({:.3} G pixel samples); loaded from cache: {} entries; corrupt entries recomputed: {}\nwall time: {:.1} s",
        written.len(),
        out.display(),
        c.references,
        c.curves,
        c.configs,
        c.figure_images,
        c.samples as f64 / 1e9,
        c.cache_hits,
        c.corrupt_entries,
        outcome.seconds
    ));
    if !outcome.warnings.is_empty() {
        text.push_str(&format!("\n{} warnings (see {})", outcome.warnings.len(), out.join("warnings.txt").display()));
    }
    for f in failed {
        text.push_str(&format!("\nwarning: figure not written: {f}"));
    }
    Ok(text)
}
