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
        Command::Scenes { specs } => stereotrace::scene::command::run(&specs, &mut std::io::stdout().lock()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
