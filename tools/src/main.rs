//! `fabric`: generate fabric volumes, path-trace references, bake hybrid models and
//! render them. Run `fabric --help` for the commands.

mod args;
mod cmd;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "fabric", version, about = "Hybrid micro-appearance fabrics: generate, reference, bake, render.")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the Vulkan devices and which one would be chosen.
    Devices(cmd::devices::DevicesArgs),
    /// Path-trace the input fabric volume (the reference renderer) and print paths/s.
    Reference(cmd::reference::ReferenceArgs),
    /// Compare image A with reference B: relative RMSE, mean differences, FLIP.
    Diff(cmd::diff::DiffArgs),
    /// Render with the Vulkan renderer (a base mesh for now) and print the GPU frame time.
    Render(cmd::render::RenderArgs),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Devices(a) => cmd::devices::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::Reference(a) => cmd::reference::run(a),
        Command::Diff(a) => cmd::diff::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
