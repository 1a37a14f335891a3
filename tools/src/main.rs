//! `fabric`: generate fabric volumes, path-trace references, bake hybrid models and
//! render them. Run `fabric --help` for the commands.

mod args;
mod cmd;
mod progress;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "fabric", version, about = "Hybrid micro-appearance fabrics: generate, reference, bake, render.")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The main job on a built-in default: generate a twill, bake it, draw it against the
    /// reference on the GPU; prints bake time, model size, error and frame time into out/.
    Demo(cmd::demo::DemoArgs),
    /// Run time against error: per preset bake and render figures, sweeps as CSVs and plots, summary.md.
    Bench(cmd::bench::BenchArgs),
    /// Generate a procedural fabric volume (woven or felt) as a fabric directory.
    #[command(name = "gen")]
    Gen(cmd::generate::GenArgs),
    /// Show what a fabric directory, a .vol file or a hybrid model (.hyb) holds.
    Inspect(cmd::inspect::InspectArgs),
    /// Path-trace the input fabric volume (the reference renderer) and print paths/s.
    Reference(cmd::reference::ReferenceArgs),
    /// Compare image A with reference B: relative RMSE, mean differences, FLIP.
    Diff(cmd::diff::DiffArgs),
    /// List the Vulkan devices and which one would be chosen.
    Devices(cmd::devices::DevicesArgs),
    /// Render a hybrid model (GPU, or --backend cpu) or a base mesh; print the frame time.
    Render(cmd::render::RenderArgs),
    /// Open the GPU renderer in a window: orbit camera, live light and exposure.
    View(cmd::view::ViewArgs),
    /// Extract the hybrid geometry (h0, h, normal/tangent maps, flyaways) from a fabric volume.
    Geometry(cmd::geometry::GeometryArgs),
    /// Bake a fabric volume into a hybrid model (fitted BRDFs) and measure it on held-out views.
    Bake(cmd::bake::BakeArgs),
    /// Rebuild a model's mip chain (coarse levels, flyaways with alpha) from its level 0.
    Prefilter(cmd::prefilter::PrefilterCmdArgs),
}

/// Restores the default SIGPIPE action so that `fabric inspect … | head` ends quietly
/// instead of panicking in `println!` (Rust ignores SIGPIPE by default).
fn restore_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in main, before any thread exists; SIG_DFL is a valid action.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> std::process::ExitCode {
    restore_sigpipe();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(a) => cmd::demo::run(a),
        Command::Bench(a) => cmd::bench::run(a),
        Command::Gen(a) => cmd::generate::run(a),
        Command::Inspect(a) => cmd::inspect::run(a),
        Command::Reference(a) => cmd::reference::run(a),
        Command::Diff(a) => cmd::diff::run(a),
        Command::Devices(a) => cmd::devices::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::View(a) => cmd::view::run(a),
        Command::Geometry(a) => cmd::geometry::run(a),
        Command::Bake(a) => cmd::bake::run(a),
        Command::Prefilter(a) => cmd::prefilter::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The error and its causes, as `{:#}` prints them, less each cause whose text the
/// message so far already holds (a `thiserror` variant that quotes its source, e.g.
/// "geometry: {0}", would otherwise say it twice).
fn error_chain(e: &anyhow::Error) -> String {
    let mut text = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !text.contains(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}
