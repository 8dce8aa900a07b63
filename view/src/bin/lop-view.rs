//! `lop-view`: serves the web viewer of a running `lopd` (read-only; control through
//! `PREFIX/control`). Prints its URL on the first line of stdout.

use clap::Parser;

#[derive(Parser)]
#[command(
    name = "lop-view",
    version,
    about = "Web viewer of a running lopd (WebGL, read-only)"
)]
struct Cli {
    /// Service prefix of the daemon to show.
    #[arg(long, default_value = lop_client::SERVICE_PREFIX_DEFAULT)]
    prefix: String,
    /// Address and port to listen on (loopback by default; port 0 picks a free one).
    #[arg(long, default_value = lop_view::BIND_DEFAULT)]
    bind: String,
    /// Frames per second sent to each browser at most.
    #[arg(long, default_value_t = lop_view::FPS_DEFAULT)]
    fps: f64,
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    if lop_client::ServiceNames::new(&cli.prefix).is_err() || cli.fps.is_nan() || cli.fps <= 0.0 {
        eprintln!(
            "lop-view: error: bad --prefix {:?} or --fps {} (must be positive)",
            cli.prefix, cli.fps
        );
        return std::process::ExitCode::from(2);
    }
    let listener = match lop_view::bind(&cli.bind) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("lop-view: error: {e:#}");
            return std::process::ExitCode::from(2);
        }
    };
    let addr = listener
        .local_addr()
        .map(|a| a.to_string())
        .unwrap_or(cli.bind.clone());
    println!("lop-view: http://{addr}/ (prefix {:?})", cli.prefix);
    let opts = lop_view::ViewOptions {
        prefix: cli.prefix,
        fps: cli.fps,
    };
    match lop_view::serve(listener, opts) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("lop-view: error: {e:#}");
            std::process::ExitCode::from(1)
        }
    }
}
