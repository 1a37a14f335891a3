//! `fabric`: generate fabric volumes, path-trace references, bake hybrid models and
//! render them. Run `fabric --help` for the commands.

#[allow(dead_code)] // used by the rendering commands as they land
mod args;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "fabric", version, about = "Hybrid micro-appearance fabrics: generate, reference, bake, render.")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the version.
    Version,
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Version => {
            println!("fabric {}", env!("CARGO_PKG_VERSION"));
            Ok::<(), anyhow::Error>(())
        }
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
