//! `lop-record`: attach to a running lopd read-only and write its frames as a VTK series
//! (`.vtu` per frame plus a `.pvd` index) that ParaView opens. Each frame is written with the
//! topology it belongs to: after a cut (a new topology) the pieces hold the cut meshes; the
//! frames that arrive while the new topology is read are skipped.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::Parser;
use lop_client::vtk::PvdSeries;
use lop_client::Attachment;

#[derive(Parser)]
#[command(
    name = "lop-record",
    version,
    about = "Record lopd frames as a VTK series (.pvd + .vtu)"
)]
struct Args {
    /// Service prefix of the daemon.
    #[arg(long, default_value = "lop")]
    prefix: String,
    /// Output directory (created).
    #[arg(long)]
    out: PathBuf,
    /// Stop after this many frames.
    #[arg(long, conflicts_with = "seconds")]
    frames: Option<usize>,
    /// Stop after this many seconds.
    #[arg(long)]
    seconds: Option<f64>,
    /// How long to wait for the daemon, s.
    #[arg(long, default_value_t = 10.0)]
    wait: f64,
}

fn main() -> Result<()> {
    let args = Args::parse();
    if args.frames.is_none() && args.seconds.is_none() {
        bail!("give --frames N or --seconds S");
    }
    if let Some(s) = args.seconds {
        if !(s > 0.0 && s.is_finite()) {
            bail!("--seconds {s}: must be a positive number");
        }
    }
    let wait = Duration::from_secs_f64(args.wait.max(0.0));
    let mut lop = Attachment::open(&args.prefix, wait).context("attaching to lopd")?;
    let mut topology_id = lop.wait_topology(wait)?.header.topology_id;
    let mut series = PvdSeries::new(&args.out, "frame")
        .with_context(|| format!("creating {}", args.out.display()))?;
    let start = Instant::now();
    let limit = args.seconds.map(Duration::from_secs_f64);
    loop {
        if args.frames.is_some_and(|n| series.len() >= n)
            || limit.is_some_and(|l| start.elapsed() >= l)
        {
            break;
        }
        let frames = lop.frames()?;
        // `wait_topology` above: there is one.
        let topology = lop.topology().context("the topology")?;
        if topology.header.topology_id != topology_id {
            topology_id = topology.header.topology_id;
            println!(
                "topology {topology_id:#x} (after a cut): {} triangles, {} tetrahedra",
                topology.header.triangle_count, topology.header.tet_count
            );
        }
        for frame in frames {
            if args.frames.is_some_and(|n| series.len() >= n) {
                break;
            }
            series.add(topology, &frame)?;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let pvd = series.finish()?;
    println!(
        "wrote {} frames; open {} in ParaView",
        series.len(),
        pvd.display()
    );
    Ok(())
}
