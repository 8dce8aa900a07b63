//! `lop-bench`: benchmarks of the lop pipeline. One module per subcommand (`latency`, `models`,
//! `lop`, `interaction`, `haptics`, `soak`, …); shared helpers in `stats` (the one quantile
//! definition), `table` (percentile rows, aligned tables, notes), `plot` (SVG charts),
//! `pipeline` (spawning `lopd` with a guard), `scenes` (a scene copied with more tools) and
//! `cyclictest` (the machine's own wake-up latency, as a yardstick).

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cyclictest;
mod haptics;
mod interaction;
mod latency;
mod lop;
mod models;
mod organs;
#[cfg(feature = "parry")]
mod parry;
mod pipeline;
mod plot;
mod remote;
mod scenes;
mod soak;
mod stats;
mod table;
mod timings;

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
    /// The organs a lab brings, live: the shipped liver and organs meshed from built surfaces
    /// at 2k-20k tetrahedra, at 1 and 2 threads: period, real-time factor, frame interval and
    /// age in contact, device → tissue (table, SVG, JSON).
    Organs(organs::OrgansArgs),
    /// Levels of precision, the thesis' §6.3–6.4: time per iteration per body with and without
    /// the GC cage, the cage's speed-up over FEM, and its approximation error (CSV + SVG plots).
    Lop(lop::LopArgs),
    /// Tool interaction, the thesis' §6.3.4: haptic tick compute (god-object + force), collision
    /// detection per step, heat step per body (table, CSV, SVG).
    Interaction(interaction::InteractionArgs),
    /// Haptics: the force lop renders when a 3 mm tool presses a clamped block (three gmsh
    /// meshes) and the liver, against a static FE contact reference and Hertz; the stability of
    /// the closed loop with the simulated hand; a bimanual pinch with two simulated hands
    /// (tables, CSV, SVG, PASS/FAIL).
    Haptics(haptics::HapticsArgs),
    /// Soak: the whole pipeline for N minutes under randomised faults (deformation process
    /// killed and stopped, NaN and out-of-workspace samples, control hammered, viewers coming
    /// and going, a recording written); every safety invariant checked, PASS/FAIL, soak.json.
    Soak(soak::SoakArgs),
    /// Micro-timings, printed: collision detection on the organs, the GC cage deformation.
    Timings(timings::TimingsArgs),
    /// Organ collision and tool queries: ours against parry3d-f64 (time, allocations, answers).
    #[cfg(feature = "parry")]
    Collide(parry::CollideArgs),
    /// A far-side frame reader for `latency --remote` (run by it, in the far domain).
    #[command(hide = true)]
    RemoteReader(remote::ReaderArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    pipeline::install_stop_handler();
    let result = match cli.command {
        Command::Latency(a) => latency::run(a),
        Command::Models(a) => models::run(a),
        Command::Organs(a) => organs::run(a),
        Command::Lop(a) => lop::run(a),
        Command::Interaction(a) => interaction::run(a),
        Command::Haptics(a) => haptics::run(a),
        Command::Soak(a) => soak::run(a),
        Command::Timings(a) => timings::run(a),
        #[cfg(feature = "parry")]
        Command::Collide(a) => parry::run(a),
        Command::RemoteReader(a) => remote::reader(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("lop-bench: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
