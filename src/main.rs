use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Real-time stereoscopic path tracing with spatiotemporal sample reprojection.
#[derive(Parser)]
#[command(
    version,
    about,
    after_help = "Environment: STEREOTRACE_ISA=avx2 forces the 8-lane kernel bodies on an AVX-512 CPU \
                  (default: the widest the CPU has; an unknown value is an error)."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Measure real-time stereo throughput: fps, per-stage times, share traced per eye, and the
    /// same frames fully path traced and mono (time ratios without a budget; under one, what
    /// each schedule traces in it).
    Throughput {
        /// A built-in scene name, a manifest (*.toml) or a scene folder.
        #[arg(long, default_value = "atrium")]
        scene: String,
        /// Resolution per eye, WIDTHxHEIGHT.
        #[arg(long, default_value = "1280x720", value_parser = stereotrace::commands::parse_resolution)]
        res: stereotrace::kernels::Extent,
        /// Worker threads.
        #[arg(long, default_value_t = 2)]
        threads: usize,
        /// Frames to measure (after one warm-up frame).
        #[arg(long, default_value_t = 20, value_parser = stereotrace::commands::parse_frames)]
        frames: u32,
        /// Samples per traced pixel.
        #[arg(long, default_value_t = 1, value_parser = stereotrace::commands::parse_spp)]
        spp: u32,
        /// Pipeline mode.
        #[arg(long, value_enum, default_value_t = stereotrace::pipeline::Mode::Spatiotemporal)]
        mode: stereotrace::pipeline::Mode,
        /// Order of stereo and temporal reprojection (spatiotemporal modes).
        #[arg(long, value_enum, default_value_t = stereotrace::pipeline::Order::Paper)]
        order: stereotrace::pipeline::Order,
        /// G-buffer layout the reprojection reads.
        #[arg(long, value_enum, default_value_t = stereotrace::pipeline::Layout::Compact)]
        layout: stereotrace::pipeline::Layout,
        /// How the G-buffers are made: rasterised (default) or traced (the reference).
        #[arg(long, value_enum, default_value_t = stereotrace::pipeline::GBufferPass::Raster)]
        gbuffer: stereotrace::pipeline::GBufferPass,
        /// Per-frame time budget in milliseconds (tracing stops when it is spent).
        #[arg(long, value_parser = stereotrace::commands::parse_budget_ms)]
        budget_ms: Option<f64>,
        /// Skip the baseline runs (full stereo path tracing and mono frames, with the same
        /// settings and budget as the measured run).
        #[arg(long)]
        no_baseline: bool,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Path trace frames of a scene and write linear HDR EXR files and PNG previews.
    Render {
        /// A built-in scene name (see `stereotrace scenes`), a manifest (*.toml) or a scene folder.
        #[arg(long, default_value = "cornell")]
        scene: String,
        /// Number of frames of the camera path to render.
        #[arg(long, default_value_t = 1, value_parser = stereotrace::commands::parse_frames)]
        frames: u32,
        /// First frame to render.
        #[arg(long, default_value_t = 0)]
        first_frame: u32,
        /// Samples per pixel.
        #[arg(long, default_value_t = 16, value_parser = stereotrace::commands::parse_spp)]
        spp: u32,
        /// Resolution per eye, WIDTHxHEIGHT.
        #[arg(long, default_value = "640x360", value_parser = stereotrace::commands::parse_resolution)]
        res: stereotrace::kernels::Extent,
        /// Which eye(s) to render.
        #[arg(long, value_enum, default_value_t = stereotrace::commands::render::EyeChoice::Both)]
        eye: stereotrace::commands::render::EyeChoice,
        /// Output folder (a subfolder per scene is created).
        #[arg(long, default_value = "out")]
        out: std::path::PathBuf,
        /// Distance between the eyes in metres (0 renders a mono pair).
        #[arg(long, default_value_t = stereotrace::camera::DEFAULT_EYE_SEPARATION)]
        eye_separation: f32,
        /// Seed of the random numbers.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Exposure multiplier for the PNG previews (finite, > 0).
        #[arg(long, default_value_t = 1.0, value_parser = stereotrace::commands::parse_exposure)]
        exposure: f32,
        /// Use the general integrator instead of the one specialised for the scene's effects.
        #[arg(long)]
        general: bool,
        /// Bounces of the estimator: 1 is the paper's (direct light at the primary and the
        /// secondary hit), 0 direct lighting only.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(0..=1))]
        bounces: u32,
    },
    /// Write a scene at frame 0 as a folder in the shared format (scene.obj, scene.mtl,
    /// camera.json, lights.json, textures), e.g. for another renderer.
    ExportScene {
        /// A built-in scene name, a manifest (*.toml) or a scene folder.
        scene: String,
        /// Output folder.
        #[arg(long)]
        out: std::path::PathBuf,
    },
    /// List the built-in scenes (triangle counts, effects), or describe the given scenes.
    Scenes {
        /// Scenes to load and describe: built-in names, manifests (*.toml) or scene folders.
        specs: Vec<String>,
    },
    /// Effective spp of every mode against path tracing (the paper's Tables 1-6, Figures 3-8).
    Eval {
        /// Starting point: `quick` (small, for CI) or `paper` (1280x720, days of CPU time).
        #[arg(long, value_enum, default_value_t = stereotrace::eval::Preset::Quick)]
        preset: stereotrace::eval::Preset,
        /// Scenes (comma-separated built-in names, manifests or folders); default: every built-in.
        #[arg(long, value_delimiter = ',')]
        scenes: Option<Vec<String>>,
        /// Modes (comma-separated): stereo, temporal, spatiotemporal, spatiotemporal-stereo-first,
        /// stereo-blend, spatiotemporal-blend, spatiotemporal-blend-stereo-first; default: all.
        #[arg(long, value_delimiter = ',')]
        modes: Option<Vec<String>>,
        /// Input samples per pixel (comma-separated).
        #[arg(long, value_delimiter = ',', value_parser = stereotrace::commands::parse_spp)]
        spp: Option<Vec<u32>>,
        /// Resolution per eye, WIDTHxHEIGHT.
        #[arg(long, value_parser = stereotrace::commands::parse_resolution)]
        res: Option<stereotrace::kernels::Extent>,
        /// Frames the pipeline renders (0..FRAMES).
        #[arg(long, value_parser = stereotrace::commands::parse_frames)]
        frames: Option<u32>,
        /// Warm-up frames left out of the averages.
        #[arg(long)]
        warmup: Option<u32>,
        /// Samples per pixel of the references.
        #[arg(long, value_parser = stereotrace::commands::parse_spp)]
        reference_spp: Option<u32>,
        /// Last spp of the path-traced error curves.
        #[arg(long, value_parser = stereotrace::commands::parse_spp)]
        curve_spp: Option<u32>,
        /// How the error curves are sampled.
        #[arg(long, value_enum)]
        grid: Option<stereotrace::commands::eval::GridChoice>,
        /// SSIM flavour (the paper's is the 3-D volume).
        #[arg(long, value_enum)]
        ssim: Option<stereotrace::eval::SsimChoice>,
        /// Output folder (default: out/eval-<preset>).
        #[arg(long)]
        out: Option<std::path::PathBuf>,
        /// Cache folder for references, curves and results (default: out/eval-cache).
        #[arg(long)]
        cache: Option<std::path::PathBuf>,
        /// Skip the figures (and the work only they need).
        #[arg(long)]
        no_figures: bool,
        /// Stop after computing this many units (references, curves, configurations); run again to resume.
        #[arg(long)]
        max_units: Option<usize>,
        /// How the pipelines make their G-buffers (default: raster).
        #[arg(long, value_enum)]
        gbuffer: Option<stereotrace::pipeline::GBufferPass>,
        /// Give the pipelines the surfaces' motion (moving area lights' own), which temporal
        /// reprojection follows; without it every surface is taken as still.
        #[arg(long)]
        motion_vectors: bool,
        /// List the run's work units and their estimated CPU time (writes OUT/plan.tsv);
        /// compute nothing.
        #[arg(long, conflicts_with_all = ["shard", "merge"])]
        plan: bool,
        /// Compute only shard K of N (0-based) into the cache, e.g. 2/8; `env` reads a Slurm
        /// array task or a Kubernetes Indexed Job. Shards may run at once on one cache.
        #[arg(long, value_parser = stereotrace::eval::units::Shard::parse, conflicts_with = "merge")]
        shard: Option<stereotrace::eval::units::Shard>,
        /// Write the reports from the cache alone (after every shard); fails naming what is missing.
        #[arg(long)]
        merge: bool,
    },
    /// What accuracy costs in time: sweeps pipeline settings on one scene and measures time
    /// per stereo frame and effective spp (table, CSV, JSON and a plot with the Pareto front).
    Tradeoff {
        /// A built-in scene name, a manifest (*.toml) or a scene folder.
        #[arg(long, default_value = "atrium")]
        scene: String,
        /// Resolution per eye, WIDTHxHEIGHT (time and quality are both measured at it).
        #[arg(long, default_value = "256x144", value_parser = stereotrace::commands::parse_resolution)]
        res: stereotrace::kernels::Extent,
        /// Worker threads.
        #[arg(long, default_value_t = 2)]
        threads: usize,
        /// Frames the pipeline renders (0..FRAMES); frame 0 is not timed.
        #[arg(long, default_value_t = 14, value_parser = stereotrace::commands::parse_frames)]
        frames: u32,
        /// Warm-up frames left out of the quality measurement.
        #[arg(long, default_value_t = 10)]
        warmup: u32,
        /// Input samples per pixel (comma-separated).
        #[arg(long, value_delimiter = ',', default_value = "1,2,4", value_parser = stereotrace::commands::parse_spp)]
        spp: Vec<u32>,
        /// Samples per pixel of the references.
        #[arg(long, default_value_t = 256, value_parser = stereotrace::commands::parse_spp)]
        reference_spp: u32,
        /// Last spp of the path-traced error curves.
        #[arg(long, default_value_t = 128, value_parser = stereotrace::commands::parse_spp)]
        curve_spp: u32,
        /// Budgets as fractions of the unbudgeted spatiotemporal frame time (comma-separated).
        #[arg(long, value_delimiter = ',', default_value = "0.75,0.5,0.25")]
        budgets: Vec<f64>,
        /// Budgets in milliseconds per stereo frame (comma-separated, e.g. 33,50,100).
        #[arg(long, value_delimiter = ',', value_parser = stereotrace::commands::parse_budget_ms)]
        budgets_ms: Vec<f64>,
        /// How the G-buffers are made (the sweep adds one row with the other pass).
        #[arg(long, value_enum, default_value_t = stereotrace::pipeline::GBufferPass::Raster)]
        gbuffer: stereotrace::pipeline::GBufferPass,
        /// Output folder.
        #[arg(long, default_value = "out/tradeoff")]
        out: std::path::PathBuf,
        /// Cache folder for references and curves (shared with `eval`).
        #[arg(long, default_value = "out/eval-cache")]
        cache: std::path::PathBuf,
    },
    /// SSIM (3-D volume and per-channel) and RMSE of two linear EXR images.
    ///
    /// A sample that is NaN, infinite or out of range in either image cannot be compared: by
    /// default any such sample is an error (exit code 1, naming how many); with
    /// `--exclude-nonfinite` they are left out, the figures are over the rest and the count is
    /// printed. A comparison left with no sample at all is an error either way.
    Ssim {
        /// First image (EXR).
        a: std::path::PathBuf,
        /// Second image (EXR).
        b: std::path::PathBuf,
        /// Leave non-finite and out-of-range samples out instead of failing.
        #[arg(long)]
        exclude_nonfinite: bool,
    },
}

fn main() -> ExitCode {
    if let Err(message) = stereotrace::cpu::check_cpu() {
        eprintln!("error: {message}");
        return ExitCode::FAILURE;
    }
    let cli = Cli::parse();
    if let Err(message) = stereotrace::cpu::check_isa_env() {
        eprintln!("error: {message}");
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Throughput {
            scene,
            res,
            threads,
            frames,
            spp,
            mode,
            order,
            layout,
            gbuffer,
            budget_ms,
            no_baseline,
            json,
        } => {
            let opts = stereotrace::commands::throughput::ThroughputOptions {
                scene,
                extent: res,
                threads,
                frames,
                spp,
                mode,
                order,
                layout,
                gbuffer,
                budget_ms,
                baseline: !no_baseline,
            };
            stereotrace::commands::throughput::run(&opts).and_then(|report| {
                if json {
                    println!("{}", serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?);
                } else {
                    print!("{}", report.text());
                }
                Ok(())
            })
        }
        Command::Render {
            scene,
            frames,
            first_frame,
            spp,
            res,
            eye,
            out,
            eye_separation,
            seed,
            exposure,
            general,
            bounces,
        } => {
            let opts = stereotrace::commands::render::RenderOptions {
                scene,
                frames,
                first_frame,
                spp,
                extent: res,
                eyes: eye,
                out,
                separation: eye_separation,
                seed,
                exposure,
                general,
                bounces,
            };
            stereotrace::commands::render::run(&opts).map(|summary| println!("{summary}"))
        }
        Command::ExportScene { scene, out } => {
            stereotrace::commands::export_scene(&scene, &out).map(|s| println!("{s}"))
        }
        Command::Scenes { specs } => {
            stereotrace::scene::command::run(&specs, &mut std::io::stdout().lock()).map_err(|e| e.to_string())
        }
        Command::Eval {
            preset,
            scenes,
            modes,
            spp,
            res,
            frames,
            warmup,
            reference_spp,
            curve_spp,
            grid,
            ssim,
            out,
            cache,
            no_figures,
            max_units,
            gbuffer,
            motion_vectors,
            plan,
            shard,
            merge,
        } => {
            use stereotrace::commands::eval::Scope;
            let scope = match (plan, shard, merge) {
                (true, ..) => Scope::Plan,
                (_, Some(s), _) => Scope::Shard(s),
                (_, _, true) => Scope::Merge,
                _ => Scope::Whole,
            };
            let opts = stereotrace::commands::eval::EvalOptions {
                preset,
                scenes,
                modes,
                spp,
                extent: res,
                frames,
                warmup,
                reference_spp,
                curve_spp,
                grid,
                ssim,
                out,
                cache,
                no_figures,
                max_units,
                gbuffer,
                motion_vectors,
                scope,
            };
            stereotrace::commands::eval::run(&opts).map(|report| println!("{report}"))
        }
        Command::Tradeoff {
            scene,
            res,
            threads,
            frames,
            warmup,
            spp,
            reference_spp,
            curve_spp,
            budgets,
            budgets_ms,
            gbuffer,
            out,
            cache,
        } => {
            let opts = stereotrace::commands::tradeoff::TradeoffOptions {
                scene,
                extent: res,
                threads,
                frames,
                warmup,
                input_spp: spp,
                reference_spp,
                curve_spp,
                budget_fractions: budgets,
                budgets_ms,
                gbuffer,
                out,
                cache,
            };
            stereotrace::commands::tradeoff::run_command(&opts).map(|report| println!("{report}"))
        }
        Command::Ssim { a, b, exclude_nonfinite } => {
            stereotrace::commands::ssim::run(&a, &b, exclude_nonfinite).map(|report| println!("{report}"))
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
