use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Real-time stereoscopic path tracing with spatiotemporal sample reprojection.
#[derive(Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Path trace frames of a scene and write linear HDR EXR files and PNG previews.
    Render {
        /// A built-in scene name (see `stereotrace scenes`), a manifest (*.toml) or a scene folder.
        #[arg(long, default_value = "cornell")]
        scene: String,
        /// Number of frames of the camera path to render.
        #[arg(long, default_value_t = 1)]
        frames: u32,
        /// First frame to render.
        #[arg(long, default_value_t = 0)]
        first_frame: u32,
        /// Samples per pixel.
        #[arg(long, default_value_t = 16)]
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
        /// Exposure multiplier for the PNG previews.
        #[arg(long, default_value_t = 1.0)]
        exposure: f32,
        /// Use the general integrator instead of the one specialised for the scene's effects.
        #[arg(long)]
        general: bool,
    },
    /// List the built-in scenes (triangle counts, effects), or describe the given scenes.
    Scenes {
        /// Scenes to load and describe: built-in names, manifests (*.toml) or scene folders.
        specs: Vec<String>,
    },
}

fn main() -> ExitCode {
    if let Err(message) = stereotrace::cpu::check_cpu() {
        eprintln!("error: {message}");
        return ExitCode::FAILURE;
    }
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render { scene, frames, first_frame, spp, res, eye, out, eye_separation, seed, exposure, general } => {
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
            };
            stereotrace::commands::render::run(&opts).map(|summary| println!("{summary}"))
        }
        Command::Scenes { specs } => {
            stereotrace::scene::command::run(&specs, &mut std::io::stdout().lock()).map_err(|e| e.to_string())
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
