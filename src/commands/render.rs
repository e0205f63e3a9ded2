//! `stereotrace render`: path traces frames of a scene for one or both eyes and writes linear
//! HDR EXR files plus tonemapped PNG previews.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

use crate::camera::{Eye, StereoRig};
use crate::image_io::{write_exr, write_png_preview};
use crate::kernels::RgbBuf;
use crate::render::{FrameView, Renderer};
use crate::source::TraceStats;

use super::args::{SceneArgs, default, parse_exposure, parse_frames, parse_spp};

/// Which eyes to render.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EyeChoice {
    /// The left eye alone.
    Left,
    /// The right eye alone.
    Right,
    /// Both eyes.
    Both,
}

impl EyeChoice {
    /// The eyes rendered, left first.
    pub fn eyes(self) -> &'static [Eye] {
        match self {
            EyeChoice::Left => &[Eye::Left],
            EyeChoice::Right => &[Eye::Right],
            EyeChoice::Both => &Eye::BOTH,
        }
    }
}

/// Options of `stereotrace render`.
#[derive(Args, Clone, Debug)]
#[command(mut_arg("scene", default("cornell")), mut_arg("res", default("640x360")))]
pub struct RenderOptions {
    /// The scene and the resolution per eye.
    #[command(flatten)]
    pub input: SceneArgs,
    /// Number of frames of the camera path to render.
    #[arg(long, default_value_t = 1, value_parser = parse_frames)]
    pub frames: u32,
    /// First frame to render.
    #[arg(long, default_value_t = 0)]
    pub first_frame: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 16, value_parser = parse_spp)]
    pub spp: u32,
    /// Which eye(s) to render.
    #[arg(long, value_enum, default_value_t = EyeChoice::Both)]
    pub eye: EyeChoice,
    /// Output folder (a subfolder per scene is created).
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// Distance between the eyes in metres (0 renders a mono pair).
    #[arg(long, default_value_t = crate::camera::DEFAULT_EYE_SEPARATION)]
    pub eye_separation: f32,
    /// Seed of the random numbers.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Exposure multiplier for the PNG previews (finite, > 0).
    #[arg(long, default_value_t = 1.0, value_parser = parse_exposure)]
    pub exposure: f32,
    /// Use the general integrator instead of the one specialised for the scene's effects.
    #[arg(long)]
    pub general: bool,
    /// Bounces of the estimator: 1 is the paper's (direct light at the primary and the
    /// secondary hit), 0 direct lighting only (see [`Renderer::set_bounces`]).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(0..=1))]
    pub bounces: u32,
}

/// Runs the command; returns a one-line summary.
pub fn run(opts: &RenderOptions) -> Result<String, String> {
    let rig = StereoRig::new(opts.eye_separation)?;
    let load = Instant::now();
    let scene = crate::scene::resolve(&opts.input.scene).map_err(|e| e.to_string())?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let last = opts.first_frame.checked_add(opts.frames).filter(|&l| l <= scene.frame_count()).ok_or_else(|| {
        format!(
            "frames {}..{} are outside the scene's camera path of {} frames",
            opts.first_frame,
            opts.first_frame as u64 + opts.frames as u64,
            scene.frame_count()
        )
    })?;
    let diagonal = scene.bounds().extent().length();
    if opts.eye_separation > diagonal {
        eprintln!(
            "warning: the eye separation of {} m is wider than the scene ({diagonal:.3} m across): the eyes may see \
             little or nothing of it",
            opts.eye_separation
        );
    }
    let name = scene.name.clone();
    let mut renderer = Renderer::new(scene).map_err(|e| e.to_string())?;
    renderer.set_bounces(opts.bounces).map_err(|e| e.to_string())?;
    eprintln!(
        "{name}: {} triangles, BVH built in {:.2?}, integrator: {}, loaded in {:.2?}",
        renderer.scene().triangle_count(),
        renderer.bvh_build_time(),
        if opts.general { "general".into() } else { crate::render::effects::describe(renderer.effect_bits()) },
        load.elapsed()
    );
    let dir = opts.out.join(&name);
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: cannot create output folder: {e}", dir.display()))?;

    let jobs = u64::from(opts.frames) * opts.eye.eyes().len() as u64;
    let bar = ProgressBar::new(jobs).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} images  {elapsed_precise} elapsed, ETA {eta}  {msg}")
            .expect("valid template"),
    );
    let mut image = RgbBuf::new(opts.input.res, 0.0);
    let mut stats = TraceStats::default();
    let start = Instant::now();
    let mut view = FrameView::new(&renderer, &rig, opts.input.res, opts.first_frame).map_err(|e| e.to_string())?;
    for frame in opts.first_frame..last {
        view.set_frame(&renderer, &rig, frame).map_err(|e| e.to_string())?;
        for &eye in opts.eye.eyes() {
            let request = view.request(eye, opts.spp, opts.seed, 0);
            stats = stats + view.trace(&renderer, &request, &mut image, opts.general).map_err(|e| e.to_string())?;
            let stem = dir.join(format!("{eye}_{frame:03}"));
            write_exr(&stem.with_extension("exr"), &image).map_err(|e| e.to_string())?;
            write_png_preview(&stem.with_extension("png"), &image, opts.exposure).map_err(|e| e.to_string())?;
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    if stats.non_finite > 0 {
        eprintln!("warning: {} samples were not finite and were dropped", stats.non_finite);
    }
    Ok(format!(
        "wrote {jobs} image{} ({}x{}, {} spp) to {} in {secs:.2} s ({:.2} Mrays/s)",
        if jobs == 1 { "" } else { "s" },
        opts.input.res.width(),
        opts.input.res.height(),
        opts.spp,
        dir.display(),
        stats.rays as f64 / secs / 1e6
    ))
}
