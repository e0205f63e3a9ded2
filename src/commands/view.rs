//! `stereotrace view`: the pipeline live in a window (see `crate::viewer`). Both eyes side by
//! side by default; WASD/QE and a mouse drag move the camera, keys switch the mode and the
//! budget. `--frames N --screenshot FILE.png` exits after N frames and keeps the last one, which
//! is how it runs without a screen (under `xvfb-run`).

use std::path::PathBuf;

use clap::Args;

use crate::pipeline::{Mode, PipelineConfig};
use crate::render::Renderer;
use crate::viewer::window::{self, RunOptions, RunSummary};
use crate::viewer::{Action, StereoLayout, Viewer};

use super::args::{GBufferArg, SceneArgs, ThreadsArg, default, parse_budget_ms, parse_frames, parse_spp};

/// Options of `stereotrace view`.
#[derive(Args, Clone, Debug)]
#[command(mut_arg("scene", default("atrium")), mut_arg("res", default("1280x720")))]
pub struct ViewOptions {
    /// The scene and the resolution per eye.
    #[command(flatten)]
    pub input: SceneArgs,
    /// Worker threads for the pipeline.
    #[command(flatten)]
    pub threads: ThreadsArg,
    /// How the two eyes are shown.
    #[arg(long, value_enum, default_value_t = StereoLayout::SideBySide)]
    pub stereo: StereoLayout,
    /// Per-frame time budget in milliseconds (keys + and - change it).
    #[arg(long, default_value_t = 50.0, value_parser = parse_budget_ms)]
    pub budget_ms: f64,
    /// Pipeline mode at the start (keys 1, 2, 3: path traced, spatiotemporal, blend).
    #[arg(long, value_enum, default_value_t = Mode::Spatiotemporal)]
    pub mode: Mode,
    /// Samples per traced pixel.
    #[arg(long, default_value_t = 1, value_parser = parse_spp)]
    pub spp: u32,
    /// How the G-buffers are made.
    #[command(flatten)]
    pub gbuffer: GBufferArg,
    /// Start following the scene's camera path back and forth, as `throughput` does (key P
    /// stops and resumes).
    #[arg(long)]
    pub path: bool,
    /// Exit after this many frames.
    #[arg(long, value_parser = parse_frames)]
    pub frames: Option<u32>,
    /// Write the last frame the window showed to this PNG at exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Write every frame the window shows as DIR/frame_NNNNN.png.
    #[arg(long)]
    pub record: Option<PathBuf>,
}

/// Runs the viewer; the report is the frame rate and stage times it measured.
pub fn run(opts: &ViewOptions) -> Result<String, String> {
    // Before the scene loads: a user without a screen learns it at once.
    window::check_display()?;
    let pool = opts.threads.pool()?;
    let scene = crate::scene::resolve(&opts.input.scene).map_err(|e| e.to_string())?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let name = scene.name.clone();
    let renderer = Renderer::new(scene).map_err(|e| e.to_string())?;
    let extent = opts.input.res;
    let mut config = PipelineConfig::paper(opts.mode, opts.spp, renderer.scene().tolerances.at_height(extent.height()));
    config.budget = Some(crate::pipeline::budget_duration(opts.budget_ms)?);
    let options = opts.gbuffer.options();
    let mut viewer = Viewer::new(&renderer, options, config, extent, opts.stereo)?;
    if opts.path {
        viewer.act(Action::TogglePath)?;
    }
    let run = RunOptions { frames: opts.frames, screenshot: opts.screenshot.clone(), record: opts.record.clone() };
    let summary = window::run(viewer, &pool, run)?;
    Ok(report(&name, opts, &summary))
}

fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn report(scene: &str, opts: &ViewOptions, s: &RunSummary) -> String {
    let loop_ms = median(&s.loop_ms);
    format!(
        "view {scene}{}: {} frames at {}x{} per eye, {} threads, {} mode, budget {} ms: {:.1} fps (median loop {:.1} ms, \
         of which the pipeline's frame {:.1} ms, composition {:.1} ms, presentation {:.1} ms; {} measured after 2 \
         warm-up frames), {} over budget",
        if opts.path { " (following its camera path)" } else { "" },
        s.frames,
        opts.input.res.width(),
        opts.input.res.height(),
        opts.threads.threads,
        opts.mode.name(),
        opts.budget_ms,
        1e3 / loop_ms,
        loop_ms,
        median(&s.frame_ms),
        median(&s.compose_ms),
        median(&s.present_ms),
        s.loop_ms.len(),
        s.budget_misses
    )
}
