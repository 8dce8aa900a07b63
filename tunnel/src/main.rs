//! `lop-tunnel`: the scene on other hosts, over iceoryx2's Zenoh link tunnel (the crates
//! `iceoryx2-link`, `iceoryx2-link-tunnel` and `iceoryx2-integrations-zenoh-link-carrier`, at
//! lop's iceoryx2 version). `lopd run --remote` runs it on the rig (in the export domain the
//! relay fills, never in the rig's own) and `lopd remote attach` runs it on a far host; see
//! `daemon/src/remote.rs` and `docs/deploy.md`.
//!
//! Why lop builds its own program from those crates instead of running iceoryx2's
//! `iox2-link-tunnel-zenoh`: that program runs a whole round of *discovery* (listing every
//! local service, which reads and parses each service's static config, about 3 ms here) before
//! every *propagation*, on every wake. Woken for each frame, the rig's side then spent 39 % of a
//! core at 120 frames/s, and a frame waited behind the discovery of the last: far frames were
//! 39–52 ms old at p99 against about 1 ms for a local client (`docs/benchmarks.md`). Here a
//! wake (a frame the relay announced, a sample Zenoh delivered) propagates at once, and
//! discovery runs on its own interval (`--poll`, 100 ms by default), in the quiet after a
//! propagation (see `Rounds`): a service that appears is bridged within two intervals, a frame
//! crosses within one propagation.
//!
//! A wake is waited on with the listener's own `timed_wait`, not a wait set: iceoryx2 0.10's
//! event can lose a wake-up for a wait set, which left far frames waiting up to 90 ms for the
//! next interval (see [`SEVERAL_WAKES_FALLBACK`]).
//!
//! The command line is iceoryx2's tunnel program's (`--zenoh-config`, `--allow`, `--poll`,
//! `--reactive`, `--listener`), so `[remote] tunnel` may name either; `--poll` is the discovery
//! interval here. `--version` ends with the iceoryx2 version, which lopd checks.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use clap::{CommandFactory, FromArgMatches, Parser};
use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::*;
use iceoryx2_integrations_zenoh_link_carrier::ZenohCarrier;
use iceoryx2_link::Link;
use iceoryx2_link_backend::AllowList;
use iceoryx2_link_tunnel::Tunnel;

/// The discovery interval when `--poll` is not given, ms.
const DEFAULT_DISCOVERY_MS: u64 = 100;

#[derive(Parser, Debug)]
#[command(
    name = "lop-tunnel",
    about = "Carries iceoryx2 services to other hosts over Zenoh: a wake propagates at once, \
             discovery runs on its own interval."
)]
struct Cli {
    /// A Zenoh configuration file (JSON5); Zenoh's defaults without one.
    #[arg(short = 'z', long, value_name = "PATH")]
    zenoh_config: Option<PathBuf>,
    /// Bridge only the services whose names match this pattern ('*' any run of characters,
    /// '?' one); repeatable. Every service without one.
    #[arg(short = 'a', long = "allow", value_name = "SERVICE")]
    allow: Vec<String>,
    /// How often discovery runs (new services bridged, gone ones closed), ms.
    #[arg(long, value_name = "MS", default_value_t = DEFAULT_DISCOVERY_MS)]
    poll: u64,
    /// Propagate as soon as Zenoh delivers samples (the far side).
    #[arg(long)]
    reactive: bool,
    /// Propagate whenever this iceoryx2 event service fires (the rig side: the frame-ready
    /// event); repeatable.
    #[arg(long, value_name = "EVENT_SERVICE")]
    listener: Vec<String>,
}

fn main() {
    if let Err(e) = run() {
        eprintln!("lop-tunnel: {e:#}");
        std::process::exit(1);
    }
}

fn run() -> Result<()> {
    // "lop-tunnel 0.1.0 iceoryx2 0.10.0": the last word is what lopd checks.
    let version: &'static str = Box::leak(
        format!(
            "{} iceoryx2 {}",
            env!("CARGO_PKG_VERSION"),
            lop_ipc::ICEORYX2_VERSION
        )
        .into_boxed_str(),
    );
    let cli = match Cli::from_arg_matches(&Cli::command().version(version).get_matches()) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    if cli.poll == 0 {
        anyhow::bail!("--poll 0: the discovery interval must be at least 1 ms");
    }
    iceoryx2_log::set_log_level_from_env_or(iceoryx2_log::LogLevel::Warn);
    // Zenoh's own log when RUST_LOG asks for it (e.g. RUST_LOG=zenoh=debug): why a link, a TLS
    // handshake or a router connection does not come up.
    zenoh::try_init_log_from_env();

    // The domain: `config/iceoryx2.toml` under the working directory (lopd writes it), else
    // iceoryx2's defaults, as for every iceoryx2 program.
    let config = iceoryx2::config::Config::global_config();
    let zenoh = match &cli.zenoh_config {
        Some(path) => zenoh::Config::from_file(path)
            .map_err(|e| anyhow!("the Zenoh config {}: {e}", path.display()))?,
        None => zenoh::Config::default(),
    };
    let node = NodeBuilder::new()
        .config(config)
        .create::<ipc::Service>()
        .map_err(|e| anyhow!("the tunnel's iceoryx2 node: {e:?}"))?;
    let carrier = ZenohCarrier::create(zenoh).map_err(|e| anyhow!("the Zenoh session: {e:?}"))?;
    let mut link = Link::new(node, Tunnel::new(carrier, config));
    if !cli.allow.is_empty() {
        let allow = AllowList::new(&cli.allow);
        link = link.with_filter(move |name: &ServiceName| allow.admits(name.as_str()));
    }

    let carrier_wake = if cli.reactive {
        Some(
            link.listener()
                .map_err(|e| anyhow!("the tunnel's wake listener: {e:?}"))?,
        )
    } else {
        None
    };
    let mut events: Vec<Listener<ipc::Service>> = Vec::with_capacity(cli.listener.len());
    for name in &cli.listener {
        let service_name =
            ServiceName::new(name).map_err(|e| anyhow!("--listener {name:?}: {e:?}"))?;
        let service = link
            .node()
            .service_builder(&service_name)
            .event()
            .open_or_create()
            .map_err(|e| anyhow!("--listener {name:?}: the event service: {e:?}"))?;
        events.push(
            service
                .listener_builder()
                .create()
                .map_err(|e| anyhow!("--listener {name:?}: a listener: {e:?}"))?,
        );
    }

    eprintln!(
        "lop-tunnel: bridging {} over Zenoh; discovery every {} ms, propagation on {}",
        if cli.allow.is_empty() {
            "every service".to_string()
        } else {
            cli.allow.join(", ")
        },
        cli.poll,
        match (cli.reactive, events.len()) {
            (true, 0) => "Zenoh's deliveries".to_string(),
            (false, 0) => "the interval only".to_string(),
            (true, n) => format!("Zenoh's deliveries and {n} event(s)"),
            (false, n) => format!("{n} event(s)"),
        }
    );

    let mut rounds = Rounds {
        every: Duration::from_millis(cli.poll),
        discovered: None,
        failures: 0,
    };
    // The first wake is waited on with the listener's own `timed_wait`; any others are drained
    // after it, at least every `SEVERAL_WAKES_FALLBACK`. A discovery that is due waits for the
    // next wake, so that it runs in the quiet after a propagation (see [`Rounds`]).
    let sources: Vec<&dyn WakeSource> = carrier_wake
        .iter()
        .map(|l| l as &dyn WakeSource)
        .chain(events.iter().map(|l| l as &dyn WakeSource))
        .collect();
    loop {
        let timeout = match sources.len() {
            0 => rounds.until_discovery(),
            1 => rounds.until_discovery_overdue(),
            _ => rounds.until_discovery_overdue().min(SEVERAL_WAKES_FALLBACK),
        };
        let woke = match sources.first() {
            Some(first) => first.wait(timeout),
            // A signal ends the sleep early; it is seen just below.
            None => {
                let _ = link.node().wait(timeout);
                Ok(0)
            }
        };
        let drained: u64 = sources.iter().skip(1).map(|other| other.drain()).sum();
        if link.node().wait(Duration::ZERO).is_err() {
            return Ok(()); // SIGINT or SIGTERM, which also interrupts the wait
        }
        let woke = woke? + drained > 0;
        rounds.propagate(&mut link);
        if rounds.discovery_due(woke || sources.is_empty()) {
            // Let the rest of a burst (a frame's tool states, its event) cross first.
            let tries = if sources.is_empty() { 0 } else { QUIET_TRIES };
            for _ in 0..tries {
                std::thread::sleep(QUIET);
                if sources.iter().map(|s| s.drain()).sum::<u64>() == 0 {
                    break;
                }
                rounds.propagate(&mut link);
            }
            rounds.discover(&mut link);
            rounds.propagate(&mut link);
        }
    }
}

/// With several wakes (both `--reactive` and `--listener`, or several `--listener`s; lopd
/// never gives more than one), the first is waited on and the others are looked at least this
/// often.
///
/// Why not a wait set over them all: iceoryx2 0.10's event can lose a wake-up for a wait set.
/// A notification that lands between a listener's reset of the event's state and its emptying
/// of the socket has its byte read with the state left "notified"; later notifications then
/// write nothing, and a wait set, which waits on the socket, sleeps until something else drains
/// the listener. Measured on the far side of `lop-bench latency --remote` (2026-12-07, 2-core
/// machine), the tunnel's wait set lost Zenoh's wakes this way every few hundred ms, for 25–90
/// ms each time, ending at the discovery interval: far frames p99 32 ms. A listener's own
/// `timed_wait` does not lose them: it resets a "notified" state without waiting on the socket.
const SEVERAL_WAKES_FALLBACK: Duration = Duration::from_millis(2);

/// How long the link must have been quiet (no wake) before a due discovery runs, and how many
/// times that is tried before it runs anyway.
const QUIET: Duration = Duration::from_micros(300);
const QUIET_TRIES: usize = 8;

/// Propagation on every wake; discovery on its interval, in the quiet after a propagation.
///
/// A discovery lists every service of the domain (it reads each one's static config: 1.6 ms
/// at the median here, p99 6.9 ms, up to 20 ms) and the link cannot propagate meanwhile: the
/// two need the link mutably, and the listing is iceoryx2's, inside `Link::discover`. Run when
/// its interval fell due, as it first was, it landed on the frames' path every 100 ms on each
/// side: far frames p99 2.7–3.4 ms with discovery every second, against 3.8–14.7 ms with it
/// every 100 ms (`lop-bench latency --remote`, 2026-12-07, 1 to 16 far viewers). So a discovery
/// that is due waits for the next wake (the relay sends a frame's round with one wake; Zenoh
/// delivers one's samples together), propagates what it brought and what follows within
/// [`QUIET`], and then runs in the gap before the next frame (8 ms at the relay's 120 frames
/// a second). With no wake for a whole further interval, the link is idle and it runs then.
struct Rounds {
    every: Duration,
    discovered: Option<Instant>,
    failures: u64,
}

impl Rounds {
    /// The time left until the next discovery is due.
    fn until_discovery(&self) -> Duration {
        self.discovered
            .map_or(Duration::ZERO, |t| self.every.saturating_sub(t.elapsed()))
    }

    /// The time left until a due discovery runs without a wake: one interval after it fell due.
    fn until_discovery_overdue(&self) -> Duration {
        self.discovered.map_or(Duration::ZERO, |t| {
            (self.every * 2).saturating_sub(t.elapsed())
        })
    }

    /// Whether a discovery should run now: due and just after a propagation a wake asked for,
    /// or overdue by a whole interval (the link is idle). The first one runs at once.
    fn discovery_due(&self, after_wake: bool) -> bool {
        match self.discovered {
            None => true,
            Some(t) => {
                let since = t.elapsed();
                (after_wake && since >= self.every) || since >= self.every * 2
            }
        }
    }

    fn discover<S: Service, B: iceoryx2_link_backend::Backend<S>>(
        &mut self,
        link: &mut Link<S, B>,
    ) {
        self.discovered = Some(Instant::now());
        if let Err(e) = link.discover() {
            report(&mut self.failures, "discovery", &e);
        }
    }

    fn propagate<S: Service, B: iceoryx2_link_backend::Backend<S>>(
        &mut self,
        link: &mut Link<S, B>,
    ) {
        if let Err(e) = link.propagate() {
            report(&mut self.failures, "propagation", &e);
        }
    }
}

/// A wake of the tunnel: an iceoryx2 listener of any service variant.
trait WakeSource {
    /// Waits for a notification at most `timeout` and consumes what is pending; the number of
    /// notifications (0: the wait timed out).
    fn wait(&self, timeout: Duration) -> Result<u64>;
    /// Consumes the pending notifications, so a wake is not seen twice; their number.
    fn drain(&self) -> u64;
}

/// The shortest timeout given to a listener's `timed_wait`; a shorter wait only looks.
///
/// iceoryx2 0.10's event waits on a socket with `SO_RCVTIMEO` set to the timeout, in whole
/// microseconds, and a timeout of zero there means *no* timeout: `timed_wait(Duration::ZERO)`
/// blocks until the next notification. The tunnel's first wait had a zero timeout (discovery
/// due at once). On a far host whose tunnel received the rig's offers before its wake was
/// attached, no notification ever came: the tunnel slept for good after its first round and
/// imported nothing (`lopd remote attach` then showed nothing, in about half of the attaches
/// tried by hand on 2026-12-07, with the far side started seconds after the rig).
const SHORTEST_WAIT: Duration = Duration::from_millis(1);

impl<S: Service> WakeSource for Listener<S> {
    fn wait(&self, timeout: Duration) -> Result<u64> {
        if timeout < SHORTEST_WAIT {
            return self
                .try_wait(|_| {})
                .map_err(|e| anyhow!("looking for a wake: {e:?}"));
        }
        self.timed_wait(|_| {}, timeout)
            .map_err(|e| anyhow!("waiting for a wake: {e:?}"))
    }

    fn drain(&self) -> u64 {
        self.try_wait(|_| {}).unwrap_or(0)
    }
}

/// Logs the first failures of a kind and then every thousandth: a far host that went away
/// fails every round until discovery closes its bridges.
fn report(failures: &mut u64, what: &str, e: &dyn std::fmt::Debug) {
    *failures += 1;
    if *failures <= 10 || failures.is_multiple_of(1000) {
        eprintln!("lop-tunnel: {what} failed ({} so far): {e:?}", *failures);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Waits on a listener nobody notifies, in a thread of its own: `Some` with the result if
    /// the wait came back at all (within a minute; it returns at once or after `timeout`).
    fn wait_alone(timeout: Duration) -> Option<Result<u64>> {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let node = NodeBuilder::new()
                .create::<local::Service>()
                .expect("a local node");
            let name = format!("lop-tunnel-test/wake/{}", std::process::id());
            let service = node
                .service_builder(&ServiceName::new(&name).expect("a service name"))
                .event()
                .open_or_create()
                .expect("an event service");
            let listener = service.listener_builder().create().expect("a listener");
            let _ = tx.send(WakeSource::wait(&listener, timeout));
        });
        rx.recv_timeout(Duration::from_secs(60)).ok()
    }

    #[test]
    fn a_zero_or_sub_microsecond_timeout_looks_without_blocking() {
        // Passed on to iceoryx2 0.10's `timed_wait`, both block until a notification comes.
        for timeout in [Duration::ZERO, Duration::from_nanos(500)] {
            match wait_alone(timeout) {
                Some(Ok(n)) => assert_eq!(n, 0, "{timeout:?}"),
                Some(Err(e)) => panic!("{timeout:?}: {e:#}"),
                None => panic!("a wait of {timeout:?} did not come back"),
            }
        }
    }

    #[test]
    fn a_timeout_is_a_timeout() {
        assert!(matches!(wait_alone(Duration::from_millis(20)), Some(Ok(0))));
    }
}
