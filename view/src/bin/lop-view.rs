//! `lop-view`: serves the web viewer of a running `lopd` (control through `PREFIX/control`,
//! for whoever holds the control token). Prints its URL, token included, on the first line of
//! stdout.

use clap::Parser;

#[derive(Parser)]
#[command(
    name = "lop-view",
    version,
    about = "Web viewer of a running lopd (WebGL; control panel for the holder of the printed URL)",
    after_help = "Access: a WebSocket from a page of another origin is refused (HTTP 403); one \
without an Origin header (not a browser) is accepted. Control requests must carry the run's \
token, which the printed URL holds (http://127.0.0.1:8733/#token=...); without it a connection \
is read-only. The token is generated per run (128 bits) on a loopback bind, or given with \
--token / LOP_VIEW_TOKEN; bound to any other address, control is off unless a token is given."
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
    /// Control token (16+ characters of A-Z a-z 0-9 . _ ~ -), instead of a generated one; also
    /// read from LOP_VIEW_TOKEN (preferred: the command line is visible to other users). Needed
    /// for any control on a non-loopback bind.
    #[arg(long)]
    token: Option<String>,
    /// Another origin allowed to open the WebSocket (e.g. http://rig.local:8733 when the page
    /// is reached by that name); repeatable.
    #[arg(long = "allow-origin", value_name = "URL")]
    allow_origin: Vec<String>,
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
    if let Some(bad) = cli
        .allow_origin
        .iter()
        .find(|o| !(o.starts_with("http://") || o.starts_with("https://")))
    {
        eprintln!("lop-view: error: --allow-origin {bad:?}: not an http:// or https:// origin");
        return std::process::ExitCode::from(2);
    }
    let listener = match lop_view::bind(&cli.bind) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("lop-view: error: {e:#}");
            return std::process::ExitCode::from(2);
        }
    };
    let local = match listener.local_addr() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("lop-view: error: address of --bind {}: {e}", cli.bind);
            return std::process::ExitCode::from(1);
        }
    };
    let given = cli.token.clone().or_else(|| {
        std::env::var(lop_view::access::TOKEN_ENV)
            .ok()
            .filter(|t| !t.is_empty())
    });
    let token = match lop_view::access::control_token(local, given.as_deref()) {
        Ok(t) => t,
        Err(e) => {
            eprintln!(
                "lop-view: error: --token / {}: {e}",
                lop_view::access::TOKEN_ENV
            );
            return std::process::ExitCode::from(2);
        }
    };
    let url = lop_view::access::url(local, token.as_deref());
    let note = match &token {
        Some(_) => "control with this URL; without its token a page is read-only",
        None => {
            "read-only: bound beyond loopback; control needs --token or LOP_VIEW_TOKEN \
             (lopd run: --view-token)"
        }
    };
    println!("lop-view: {url} (prefix {:?}; {note})", cli.prefix);
    let opts = lop_view::ViewOptions {
        prefix: cli.prefix,
        fps: cli.fps,
        token,
        allow_origins: cli.allow_origin,
    };
    match lop_view::serve(listener, opts) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("lop-view: error: {e:#}");
            std::process::ExitCode::from(1)
        }
    }
}
