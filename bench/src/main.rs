//! `lop-bench`: benchmarks of the lop pipeline. One module per subcommand; shared helpers in
//! `table` (percentile rows, table printing), `pipeline` (spawning `lopd` with a guard) and
//! `cyclictest` (the machine's own wake-up latency, as a yardstick).

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cyclictest;
mod latency;
mod models;
mod pipeline;
mod plot;
mod table;

#[derive(Parser)]
#[command(name = "lop-bench", version, about = "lop benchmarks")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// End-to-end latency of the real pipeline (`lopd run` with the mock device): haptic jitter,
    /// tick compute, frame age, tool → deform and deform → client latency.
    Latency(latency::LatencyArgs),
    /// Deformation models: time per step on the shipped meshes, scaling with mesh size, and the
    /// thesis' chapter-3 integrator study (CSV + SVG plots).
    Models(models::ModelsArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    pipeline::install_stop_handler();
    let result = match cli.command {
        Command::Latency(a) => latency::run(a),
        Command::Models(a) => models::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("lop-bench: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
