//! The `stereotrace` binary: parses the command line into a command's options and runs it.
//! Each command's flags, defaults and checks live with its options struct in
//! `stereotrace::commands`; this file only dispatches and reports errors.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use stereotrace::commands::{
    self, ExportOptions, ScenesOptions, compare::CompareOptions, eval::EvalOptions, render::RenderOptions,
    ssim::SsimOptions, throughput::ThroughputOptions, tradeoff::TradeoffOptions, view::ViewOptions,
};

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
    Throughput(ThroughputOptions),
    /// Path trace frames of a scene and write linear HDR EXR files and PNG previews.
    Render(RenderOptions),
    /// Watch the pipeline live in a window: both eyes, WASD and mouse to move, keys for the
    /// mode and the budget, a heads-up line of fps and stage times.
    View(ViewOptions),
    /// Write a scene at frame 0 as a folder in the shared format (scene.obj, scene.mtl,
    /// camera.json, lights.json, textures), e.g. for another renderer.
    ExportScene(ExportOptions),
    /// List the built-in scenes (triangle counts, effects), or describe the given scenes.
    Scenes(ScenesOptions),
    /// Effective spp of every mode against path tracing (the paper's Tables 1-6, Figures 3-8).
    Eval(EvalOptions),
    /// Two evaluation runs side by side (a setting beyond the paper against the paper's):
    /// effective spp per scene, mode and input spp, ratios, and the scene averages in a figure.
    Compare(CompareOptions),
    /// What accuracy costs in time: sweeps pipeline settings on one scene and measures time
    /// per stereo frame and effective spp (table, CSV, JSON and a plot with the Pareto front).
    Tradeoff(TradeoffOptions),
    /// SSIM (3-D volume and per-channel) and RMSE of two linear EXR images.
    ///
    /// A sample that is NaN, infinite or out of range in either image cannot be compared: by
    /// default any such sample is an error (exit code 1, naming how many); with
    /// `--exclude-nonfinite` they are left out, the figures are over the rest and the count is
    /// printed. A comparison left with no sample at all is an error either way.
    Ssim(SsimOptions),
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
    let result = match &cli.command {
        Command::Throughput(options) => commands::throughput::run_command(options),
        Command::Render(options) => commands::render::run(options),
        Command::View(options) => commands::view::run(options),
        Command::ExportScene(options) => commands::export_scene(options),
        Command::Scenes(options) => commands::scenes(options),
        Command::Eval(options) => commands::eval::run(options),
        Command::Compare(options) => commands::compare::run_command(options),
        Command::Tradeoff(options) => commands::tradeoff::run_command(options),
        Command::Ssim(options) => commands::ssim::run_command(options),
    };
    match result {
        Ok(text) => {
            // Reports end with a newline or are one line; `scenes` prints as it goes.
            if !text.is_empty() {
                print!("{text}");
                if !text.ends_with('\n') {
                    println!();
                }
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
