//! `[remote]` of the daemon config: the scene carried to other hosts over Zenoh by iceoryx2's
//! link tunnel (`lopd run --remote`, the `lop-tunnel` program).

use std::path::{Path, PathBuf};

use crate::check::Check;
use crate::error::ConfigError;
use crate::source::KeyPath;

/// The tunnel program when `[remote] tunnel` is missing: lop's build of iceoryx2's Zenoh link
/// tunnel (the workspace's `lop-tunnel`), looked for beside `lopd` and then on `PATH`.
pub const DEFAULT_TUNNEL: &str = "lop-tunnel";

/// The Zenoh endpoint a rig listens on when `[remote]` names none: every interface, Zenoh's
/// own port. Only the renderer-facing services cross, read-only (`docs/deploy.md`).
pub const DEFAULT_LISTEN: &str = "tcp/0.0.0.0:7447";

/// How this side joins the Zenoh network.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ZenohMode {
    /// Peer to peer: listens on `listen`, connects to `connect`.
    Peer,
    /// Client of a Zenoh router (`zenohd`) named in `connect`; listens on nothing.
    Client,
}

impl ZenohMode {
    /// `peer` or `client`.
    pub fn parse(name: &str) -> Option<ZenohMode> {
        match name {
            "peer" => Some(ZenohMode::Peer),
            "client" => Some(ZenohMode::Client),
            _ => None,
        }
    }

    /// The name Zenoh's configuration uses.
    pub fn as_str(self) -> &'static str {
        match self {
            ZenohMode::Peer => "peer",
            ZenohMode::Client => "client",
        }
    }
}

/// `[remote]`: where the tunnel listens or connects and which program it is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RemoteConfig {
    /// `[remote] enabled = true` runs the tunnel with every `lopd run` (as `--remote` does).
    pub enabled: bool,
    /// Peer or client of a router.
    pub mode: ZenohMode,
    /// Zenoh endpoints this side listens on (peer mode), e.g. `tcp/0.0.0.0:7447`.
    pub listen: Vec<String>,
    /// Zenoh endpoints this side connects to: peers, or the router in client mode.
    pub connect: Vec<String>,
    /// The tunnel program: a name looked for beside `lopd` and then on `PATH`, or a path
    /// (relative to the config file).
    pub tunnel: PathBuf,
    /// A Zenoh configuration file given to the tunnel as is (relative to the config file); when
    /// set, `mode`, `listen` and `connect` are not used.
    pub zenoh_config: Option<PathBuf>,
    /// Zenoh's multicast scouting (finding peers on the LAN without naming them). Default off:
    /// a rig is found only where it is named.
    pub multicast_scouting: bool,
    /// The most frames a second sent to other hosts (`[remote] frame_rate_hz`, 1..=1000, or 0
    /// for every frame). Default [`DEFAULT_REMOTE_FRAME_RATE_HZ`]: a frame is the bodies' every
    /// node (20 bytes each), and at the tissue's 1 kHz a 2,000-node scene is 40 MB/s per far
    /// host; a renderer draws at 60–120 Hz.
    pub frame_rate_hz: u32,
    /// Which renderer-facing services cross (`[remote] services`): any of [`REMOTE_SERVICES`],
    /// default all. `scene` (topology, frames, frame-ready) is always among them.
    pub services: Vec<String>,
}

/// Command-line replacements of `[remote]` keys (`lopd remote`, `lopd run --remote-listen`);
/// empty or `None`: the key as configured.
#[derive(Debug, Clone, Default)]
pub struct RemoteOverrides {
    /// `--listen`.
    pub listen: Vec<String>,
    /// `--connect`.
    pub connect: Vec<String>,
    /// `--mode`.
    pub mode: Option<String>,
    /// `--tunnel`.
    pub tunnel: Option<PathBuf>,
    /// `--zenoh-config`.
    pub zenoh_config: Option<PathBuf>,
}

const BAD_MODE: &str = "use \"peer\" or \"client\" (a client of a Zenoh router named in connect)";
const CLIENT_WITHOUT_ROUTER: &str =
    "a client needs the router's endpoint in connect, e.g. tcp/10.0.0.2:7447";

impl RemoteConfig {
    /// This configuration with `o`'s replacements, checked by the rules of the file's keys; the
    /// reason names the flag and its value.
    pub fn with_overrides(mut self, o: &RemoteOverrides) -> Result<RemoteConfig, String> {
        for (flag, list) in [("--listen", &o.listen), ("--connect", &o.connect)] {
            for e in list {
                check_zenoh_endpoint(e).map_err(|why| format!("{flag} {e:?}: {why}"))?;
            }
        }
        if !o.listen.is_empty() {
            self.listen = o.listen.clone();
        }
        if !o.connect.is_empty() {
            self.connect = o.connect.clone();
        }
        if let Some(m) = &o.mode {
            self.mode = ZenohMode::parse(m).ok_or_else(|| format!("--mode {m:?}: {BAD_MODE}"))?;
            if self.mode == ZenohMode::Client {
                self.listen.clear();
            }
        }
        if self.mode == ZenohMode::Client && self.connect.is_empty() {
            return Err(format!("--mode client: {CLIENT_WITHOUT_ROUTER}"));
        }
        if let Some(t) = &o.tunnel {
            self.tunnel = t.clone();
        }
        if let Some(z) = &o.zenoh_config {
            if !z.is_file() {
                return Err(format!("--zenoh-config {}: no such file", z.display()));
            }
            self.zenoh_config = Some(z.clone());
        }
        Ok(self)
    }
}

/// The groups of renderer-facing services `[remote] services` may name: `scene`
/// (`PREFIX/scene/topology`, `PREFIX/scene/frame`, `PREFIX/scene/frame/ready`), `tool`
/// (`PREFIX/tool`, tool states for drawing), `telemetry` (`PREFIX/telemetry/haptic`). Nothing
/// else can cross: not the device, the control service or the daemon's tool blackboard.
pub const REMOTE_SERVICES: [&str; 3] = ["scene", "tool", "telemetry"];

/// `[remote] frame_rate_hz` when missing.
pub const DEFAULT_REMOTE_FRAME_RATE_HZ: u32 = 120;

impl Default for RemoteConfig {
    fn default() -> Self {
        RemoteConfig {
            enabled: false,
            mode: ZenohMode::Peer,
            listen: vec![DEFAULT_LISTEN.to_string()],
            connect: Vec::new(),
            tunnel: PathBuf::from(DEFAULT_TUNNEL),
            zenoh_config: None,
            multicast_scouting: false,
            frame_rate_hz: DEFAULT_REMOTE_FRAME_RATE_HZ,
            services: REMOTE_SERVICES.iter().map(|s| s.to_string()).collect(),
        }
    }
}

/// The transports a Zenoh locator may name here, and whether the address is `host:port`.
const PROTOCOLS: [(&str, bool); 6] = [
    ("tcp", true),
    ("udp", true),
    ("tls", true),
    ("quic", true),
    ("ws", true),
    ("unixsock-stream", false),
];

/// Checks one Zenoh endpoint, `PROTOCOL/ADDRESS` (e.g. `tcp/192.168.1.20:7447`,
/// `tcp/[::1]:7447`, `unixsock-stream//tmp/lop.sock`); the reason when it is not one.
pub fn check_zenoh_endpoint(endpoint: &str) -> Result<(), String> {
    let Some((proto, addr)) = endpoint.split_once('/') else {
        return Err("a Zenoh endpoint is PROTOCOL/ADDRESS, e.g. tcp/192.168.1.20:7447".into());
    };
    let Some(&(_, host_port)) = PROTOCOLS.iter().find(|(p, _)| *p == proto) else {
        let known: Vec<&str> = PROTOCOLS.iter().map(|(p, _)| *p).collect();
        return Err(format!(
            "unknown transport {proto:?}: use one of {}",
            known.join(", ")
        ));
    };
    // Zenoh's own suffixes (`#iface=eth0`, `?…`) are passed through; the address comes first.
    let addr = addr.split(['#', '?']).next().unwrap_or("");
    if !host_port {
        return if addr.is_empty() {
            Err(format!("{proto} needs a path after {proto}/"))
        } else {
            Ok(())
        };
    }
    let Some((host, port)) = addr.rsplit_once(':') else {
        return Err(format!("{addr:?} has no port: write HOST:PORT"));
    };
    if host.is_empty() {
        return Err(format!("{addr:?} has no host: write HOST:PORT"));
    }
    match port.parse::<u16>() {
        Ok(p) if p > 0 => Ok(()),
        _ => Err(format!("port {port:?} is not a number in 1..=65535")),
    }
}

#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawRemote {
    pub enabled: Option<bool>,
    pub mode: Option<String>,
    pub listen: Option<Vec<String>>,
    pub connect: Option<Vec<String>>,
    pub tunnel: Option<PathBuf>,
    pub zenoh_config: Option<PathBuf>,
    pub multicast_scouting: Option<bool>,
    pub frame_rate_hz: Option<u32>,
    pub services: Option<Vec<String>>,
}

pub(crate) fn remote_config(
    c: &Check,
    raw: RawRemote,
    config_path: &Path,
) -> Result<RemoteConfig, ConfigError> {
    let k = KeyPath::top("remote");
    let d = RemoteConfig::default();
    let relative = |p: PathBuf| {
        if p.is_relative() {
            config_path.parent().unwrap_or(Path::new(".")).join(p)
        } else {
            p
        }
    };
    let mode = match raw.mode.as_deref() {
        None => ZenohMode::Peer,
        Some(name) => ZenohMode::parse(name)
            .ok_or_else(|| c.invalid(&k.key("mode"), format!("{name:?}"), BAD_MODE))?,
    };
    let endpoints = |key: &str, list: Vec<String>| -> Result<Vec<String>, ConfigError> {
        for (i, e) in list.iter().enumerate() {
            check_zenoh_endpoint(e)
                .map_err(|why| c.invalid(&k.key(key).index(i), format!("{e:?}"), why))?;
        }
        Ok(list)
    };
    let listen = match mode {
        ZenohMode::Peer => endpoints("listen", raw.listen.unwrap_or(d.listen))?,
        ZenohMode::Client => {
            if let Some(l) = raw.listen.filter(|l| !l.is_empty()) {
                return Err(c.invalid(
                    &k.key("listen"),
                    format!("{l:?}"),
                    "a client of a router listens on nothing: leave listen out, or use mode = \"peer\"",
                ));
            }
            Vec::new()
        }
    };
    let connect = endpoints("connect", raw.connect.unwrap_or_default())?;
    if mode == ZenohMode::Client && connect.is_empty() {
        return Err(c.invalid(&k.key("connect"), "[]", CLIENT_WITHOUT_ROUTER));
    }
    let tunnel = match raw.tunnel {
        Some(t) if t.as_os_str().is_empty() => {
            let why = format!("leave tunnel out for {DEFAULT_TUNNEL} beside lopd or on PATH");
            return Err(c.invalid(&k.key("tunnel"), "\"\"", why));
        }
        // A bare name is looked for beside lopd, then on PATH; anything with a slash is a path.
        Some(t) if t.components().count() > 1 => relative(t),
        Some(t) => t,
        None => d.tunnel,
    };
    let zenoh_config = match raw.zenoh_config {
        Some(p) => {
            let p = relative(p);
            if !p.is_file() {
                return Err(c.invalid(
                    &k.key("zenoh_config"),
                    format!("{:?}", p.display().to_string()),
                    "no such Zenoh configuration file",
                ));
            }
            Some(p)
        }
        None => None,
    };
    let frame_rate_hz = raw.frame_rate_hz.unwrap_or(d.frame_rate_hz);
    if frame_rate_hz > 1000 {
        return Err(c.invalid(
            &k.key("frame_rate_hz"),
            frame_rate_hz,
            "at most 1000 frames a second (the tissue's own rate), or 0 for every frame",
        ));
    }
    let services = raw.services.unwrap_or(d.services);
    for (i, name) in services.iter().enumerate() {
        if !REMOTE_SERVICES.contains(&name.as_str()) {
            return Err(c.invalid(
                &k.key("services").index(i),
                format!("{name:?}"),
                format!(
                    "services are any of {}: the device, control and the daemon's tool \
                     blackboard never cross",
                    REMOTE_SERVICES.join(", ")
                ),
            ));
        }
    }
    if !services.iter().any(|s| s == "scene") {
        return Err(c.invalid(
            &k.key("services"),
            format!("{services:?}"),
            "the scene (topology and frames) always crosses: add \"scene\"",
        ));
    }
    Ok(RemoteConfig {
        services,
        frame_rate_hz,
        enabled: raw.enabled.unwrap_or(false),
        mode,
        listen,
        connect,
        tunnel,
        zenoh_config,
        multicast_scouting: raw.multicast_scouting.unwrap_or(false),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_are_checked_by_transport_host_and_port() {
        for ok in [
            "tcp/127.0.0.1:7447",
            "tcp/[::1]:7447",
            "udp/rig.local:7447",
            "tcp/0.0.0.0:7447#iface=eth0",
            "unixsock-stream//tmp/lop.sock",
        ] {
            assert_eq!(check_zenoh_endpoint(ok), Ok(()), "{ok}");
        }
        for (bad, why) in [
            ("127.0.0.1:7447", "PROTOCOL/ADDRESS"),
            ("http/127.0.0.1:80", "unknown transport \"http\""),
            ("tcp/127.0.0.1", "has no port"),
            ("tcp/:7447", "has no host"),
            ("tcp/127.0.0.1:99999", "port \"99999\""),
            ("tcp/127.0.0.1:0", "port \"0\""),
        ] {
            let e = check_zenoh_endpoint(bad).unwrap_err();
            assert!(e.contains(why), "{bad}: {e}");
        }
    }
}
