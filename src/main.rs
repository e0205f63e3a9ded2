use std::process::ExitCode;

use clap::Parser;

/// Real-time stereoscopic path tracing with spatiotemporal sample reprojection.
#[derive(Parser)]
#[command(version, about)]
struct Cli {}

fn main() -> ExitCode {
    if let Err(message) = stereotrace::cpu::check_cpu() {
        eprintln!("error: {message}");
        return ExitCode::FAILURE;
    }
    let _cli = Cli::parse();
    ExitCode::SUCCESS
}
