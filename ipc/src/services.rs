//! Service names, their quality of service, and helpers to create or open them.
//!
//! | service                  | pattern         | payload                         | written by        |
//! |--------------------------|-----------------|---------------------------------|-------------------|
//! | `PREFIX/tool`            | publish–subscribe | [`ToolState`]                 | haptic (1 kHz)    |
//! | `PREFIX/tool/latest`     | blackboard, a key per tool | [`ToolState`]        | haptic RT thread  |
//! | `PREFIX/scene/topology`  | publish–subscribe | `[u32]` + [`TopologyHeader`]  | deform (per load) |
//! | `PREFIX/scene/frame`     | publish–subscribe | `[NodeSample]` + [`FrameHeader`] | deform (per step) |
//! | `PREFIX/telemetry/haptic`| publish–subscribe | [`HapticTelemetry`]           | haptic (~4 Hz)    |
//!
//! Rules for clients (viewers, recorders, third-party renderers):
//! - The daemon creates every service and fixes its QoS. A client calls `open`, and retries
//!   while the daemon is starting (see [`open_retry`]).
//! - Subscribers map the publisher's memory read-only: a client cannot corrupt what the daemon
//!   and other clients see.
//! - Every publish–subscribe service has safe overflow on: a slow or frozen client loses the
//!   oldest samples, it never stalls a publisher.
//! - The blackboard `PREFIX/tool/latest` is mapped read-write by readers and is reserved for the
//!   daemon's own processes. Clients use `PREFIX/tool`.

use std::time::{Duration, Instant};

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

use crate::types::*;

/// Service prefix when none is given.
pub const SERVICE_PREFIX_DEFAULT: &str = "lop";

/// Most subscribers one publish–subscribe service accepts (viewers, recorders, the daemon).
pub const MAX_SUBSCRIBERS: usize = 16;
/// Samples a tool-state subscriber may have queued: 64 ms at 1 kHz.
pub const TOOL_BUFFER: usize = 64;
/// Frames a frame subscriber may have queued.
pub const FRAME_BUFFER: usize = 4;
/// Telemetry samples a subscriber may have queued.
pub const TELEMETRY_BUFFER: usize = 16;

/// The key of the tool blackboard's entry holding the newest state of tool `tool` (its index
/// in the scene's tool list, `ToolState::tool`): the index itself. The blackboard has an entry
/// for each of `0..MAX_TOOLS`; a key beyond names none, and opening its entry fails.
pub const fn tool_latest_key(tool: usize) -> u32 {
    tool as u32
}

/// The full service names for one prefix.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServiceNames {
    /// The prefix itself.
    pub prefix: String,
    /// `PREFIX/tool`.
    pub tool: String,
    /// `PREFIX/tool/latest`.
    pub tool_latest: String,
    /// `PREFIX/scene/topology`.
    pub topology: String,
    /// `PREFIX/scene/frame`.
    pub frame: String,
    /// `PREFIX/scene/frame/ready`: an event the deformation process notifies after each frame.
    pub frame_ready: String,
    /// `PREFIX/telemetry/haptic`.
    pub haptic_telemetry: String,
}

impl ServiceNames {
    /// Names under `prefix`. A prefix is non-empty and uses `[A-Za-z0-9_-]` and `/` only.
    pub fn new(prefix: &str) -> Result<ServiceNames, IpcError> {
        let ok = !prefix.is_empty()
            && !prefix.starts_with('/')
            && !prefix.ends_with('/')
            && prefix
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '/');
        if !ok {
            return Err(IpcError::BadPrefix(prefix.to_string()));
        }
        Ok(ServiceNames {
            prefix: prefix.to_string(),
            tool: format!("{prefix}/tool"),
            tool_latest: format!("{prefix}/tool/latest"),
            topology: format!("{prefix}/scene/topology"),
            frame: format!("{prefix}/scene/frame"),
            frame_ready: format!("{prefix}/scene/frame/ready"),
            haptic_telemetry: format!("{prefix}/telemetry/haptic"),
        })
    }

    /// Every service name, for listing and clean-up checks.
    pub fn all(&self) -> [&str; 6] {
        [
            &self.tool,
            &self.tool_latest,
            &self.topology,
            &self.frame,
            &self.frame_ready,
            &self.haptic_telemetry,
        ]
    }
}

/// What can go wrong creating or opening lop's services.
#[derive(Debug, thiserror::Error)]
pub enum IpcError {
    /// The prefix has characters a service name cannot hold.
    #[error("service prefix {0:?} is invalid: use letters, digits, '_', '-' and inner '/'")]
    BadPrefix(String),
    /// iceoryx2 refused; the message names the service and iceoryx2's reason.
    #[error("{what} {service:?}: {reason}")]
    Iceoryx {
        /// What was attempted (e.g. "create publisher for").
        what: &'static str,
        /// The service name.
        service: String,
        /// iceoryx2's error, formatted.
        reason: String,
    },
    /// The service is at its capacity for this kind of port (set by the daemon when it created
    /// the service); retrying does not help until another client leaves.
    #[error("{service:?} refused a new {port}: it already has its maximum of {limit} {port}s ({constant}); close another client first")]
    Full {
        /// The service name.
        service: String,
        /// "subscriber", "client".
        port: &'static str,
        /// The capacity.
        limit: usize,
        /// The contract constant that sets it.
        constant: &'static str,
    },
    /// The service did not appear within the retry time.
    #[error(
        "service {service:?} did not appear within {waited:?}: is lopd running with this prefix?"
    )]
    NotAvailable {
        /// The service name.
        service: String,
        /// How long we retried.
        waited: Duration,
    },
}

fn ice<E: core::fmt::Debug>(what: &'static str, service: &str) -> impl FnOnce(E) -> IpcError {
    let service = service.to_string();
    move |e| IpcError::Iceoryx {
        what,
        service,
        reason: format!("{e:?}"),
    }
}

fn service_name(name: &str) -> Result<ServiceName, IpcError> {
    ServiceName::new(name).map_err(ice("invalid service name", name))
}

/// A node for one of lop's processes or clients. Signal handling is left to the caller (the
/// daemon installs its own handlers so that every exit path writes zero force first).
pub fn node(name: &str) -> Result<Node<ipc::Service>, IpcError> {
    // iceoryx2 warns on stderr that no config file exists; lop uses the defaults on purpose.
    set_log_level(LogLevel::Error);
    let node_name = NodeName::new(name).map_err(ice("invalid node name", name))?;
    NodeBuilder::new()
        .name(&node_name)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(ice("create node", name))
}

/// A node like [`node`], in the iceoryx2 domain `config` describes instead of the process's
/// global one (`lopd remote serve` publishes the scene for the tunnel in a domain of its own).
pub fn node_in(
    name: &str,
    config: &iceoryx2::config::Config,
) -> Result<Node<ipc::Service>, IpcError> {
    set_log_level(LogLevel::Error);
    let node_name = NodeName::new(name).map_err(ice("invalid node name", name))?;
    NodeBuilder::new()
        .name(&node_name)
        .config(config)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(ice("create node", name))
}

/// Removes what crashed lop processes left behind (through `node`), so a restart never fails on
/// stale resources. Returns how many dead nodes were cleaned.
pub fn cleanup_dead_nodes(node: &Node<ipc::Service>) -> u64 {
    node.try_cleanup_dead_nodes().cleanups
}

/// Names of the services that currently exist under `prefix` (any pattern).
pub fn list_services(prefix: &str) -> Vec<String> {
    let mut found = Vec::new();
    let want = format!("{prefix}/");
    let _ = ipc::Service::list(iceoryx2::config::Config::global_config(), |details| {
        let name = details.static_details.name().as_str();
        if name.starts_with(&want) {
            found.push(name.to_string());
        }
        CallbackProgression::Continue
    });
    found.sort();
    found
}

/// Retries `f` until it succeeds or `timeout` passes.
pub fn open_retry<T>(
    service: &str,
    timeout: Duration,
    mut f: impl FnMut() -> Result<T, IpcError>,
) -> Result<T, IpcError> {
    let start = Instant::now();
    loop {
        match f() {
            Ok(v) => return Ok(v),
            Err(e @ IpcError::Full { .. }) => return Err(e),
            Err(e) if start.elapsed() >= timeout => {
                return Err(match e {
                    IpcError::Iceoryx { .. } => IpcError::NotAvailable {
                        service: service.to_string(),
                        waited: timeout,
                    },
                    other => other,
                })
            }
            Err(_) => std::thread::sleep(Duration::from_millis(20)),
        }
    }
}

/// Tool state publish–subscribe service.
pub type ToolService = PubSubFactory<ipc::Service, ToolState, ()>;
/// Frame service.
pub type FrameService = PubSubFactory<ipc::Service, [NodeSample], FrameHeader>;
/// Topology service.
pub type TopologyService = PubSubFactory<ipc::Service, [u32], TopologyHeader>;
/// Haptic telemetry service.
pub type TelemetryService = PubSubFactory<ipc::Service, HapticTelemetry, ()>;

/// Tool state publisher type.
pub type ToolPublisher = Publisher<ipc::Service, ToolState, ()>;
/// Tool state subscriber type.
pub type ToolSubscriber = Subscriber<ipc::Service, ToolState, ()>;
/// Frame publisher type.
pub type FramePublisher = Publisher<ipc::Service, [NodeSample], FrameHeader>;
/// Frame subscriber type.
pub type FrameSubscriber = Subscriber<ipc::Service, [NodeSample], FrameHeader>;
/// Topology publisher type.
pub type TopologyPublisher = Publisher<ipc::Service, [u32], TopologyHeader>;
/// Topology subscriber type.
pub type TopologySubscriber = Subscriber<ipc::Service, [u32], TopologyHeader>;
/// Telemetry publisher type.
pub type TelemetryPublisher = Publisher<ipc::Service, HapticTelemetry, ()>;
/// Telemetry subscriber type.
pub type TelemetrySubscriber = Subscriber<ipc::Service, HapticTelemetry, ()>;

/// Whether the caller creates the service (daemon) or only opens it (client).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The daemon: opens the service if it exists (a restarted process), else creates it with
    /// the contract's QoS.
    Owner,
    /// A client: opens an existing service only.
    Client,
}

macro_rules! pubsub {
    ($fn_name:ident, $ty:ty, $payload:ty, $header:ty, $field:ident, $buffer:expr, $history:expr, $publishers:expr) => {
        /// Opens (client) or opens-or-creates (owner) the service with the contract's QoS.
        pub fn $fn_name(
            node: &Node<ipc::Service>,
            names: &ServiceNames,
            role: Role,
        ) -> Result<$ty, IpcError> {
            let name = &names.$field;
            let builder = node
                .service_builder(&service_name(name)?)
                .publish_subscribe::<$payload>()
                .user_header::<$header>();
            match role {
                Role::Owner => builder
                    .enable_safe_overflow(true)
                    .history_size($history)
                    .subscriber_max_buffer_size($buffer)
                    .subscriber_max_borrowed_samples(2)
                    .max_subscribers(MAX_SUBSCRIBERS)
                    .max_publishers($publishers)
                    .open_or_create()
                    .map_err(ice("create service", name)),
                Role::Client => builder.open().map_err(ice("open service", name)),
            }
        }
    };
}

pubsub!(
    tool_service,
    ToolService,
    ToolState,
    (),
    tool,
    TOOL_BUFFER,
    1,
    2
);
pubsub!(
    frame_service,
    FrameService,
    [NodeSample],
    FrameHeader,
    frame,
    FRAME_BUFFER,
    1,
    2
);
pubsub!(
    topology_service,
    TopologyService,
    [u32],
    TopologyHeader,
    topology,
    1,
    1,
    2
);
pubsub!(
    telemetry_service,
    TelemetryService,
    HapticTelemetry,
    (),
    haptic_telemetry,
    TELEMETRY_BUFFER,
    1,
    2
);

/// The frame-ready event service.
pub type FrameReadyService = iceoryx2::service::port_factory::event::PortFactory<ipc::Service>;

/// Listeners the frame-ready event allows: the haptic process's frame thread, with room for a
/// restarted one and two clients.
pub const FRAME_READY_LISTENERS: usize = 4;

/// Opens or creates `PREFIX/scene/frame/ready`: the deformation process notifies it right after
/// publishing each frame, so a reader can sleep until a frame is there instead of polling.
/// Both sides open-or-create with the same settings, whichever starts first.
pub fn frame_ready_service(
    node: &Node<ipc::Service>,
    names: &ServiceNames,
) -> Result<FrameReadyService, IpcError> {
    let name = &names.frame_ready;
    node.service_builder(&service_name(name)?)
        .event()
        .max_listeners(FRAME_READY_LISTENERS)
        .max_notifiers(2)
        .open_or_create()
        .map_err(ice("open or create event service", name))
}

/// The blackboard holding the newest state of each tool (one entry per tool, keyed by
/// [`tool_latest_key`]), for the daemon's processes only.
pub type ToolBoard = iceoryx2::service::port_factory::blackboard::PortFactory<ipc::Service, u32>;

/// Creates (haptic process) the tool blackboard with an entry per tool, keys `0..MAX_TOOLS`
/// ([`tool_latest_key`]), or opens it if a previous haptic process left it open through a
/// reader. The iceoryx2 blackboard sizes itself by the entries added here (it has no entry
/// limit to set); `max_readers` counts reader ports, and one reader reads every entry.
pub fn tool_board_owner(
    node: &Node<ipc::Service>,
    names: &ServiceNames,
) -> Result<ToolBoard, IpcError> {
    let name = &names.tool_latest;
    let sn = service_name(name)?;
    let creator = (0..MAX_TOOLS).fold(
        node.service_builder(&sn)
            .blackboard_creator::<u32>()
            .max_readers(4),
        |creator, tool| {
            creator.add::<ToolState>(
                tool_latest_key(tool),
                ToolState {
                    tool: tool as u32,
                    ..ToolState::default()
                },
            )
        },
    );
    match creator.create() {
        Ok(board) => Ok(board),
        Err(_) => node
            .service_builder(&sn)
            .blackboard_opener::<u32>()
            .open()
            .map_err(ice("open blackboard", name)),
    }
}

/// Opens the tool blackboard (deformation process).
pub fn tool_board_reader(
    node: &Node<ipc::Service>,
    names: &ServiceNames,
) -> Result<ToolBoard, IpcError> {
    let name = &names.tool_latest;
    node.service_builder(&service_name(name)?)
        .blackboard_opener::<u32>()
        .open()
        .map_err(ice("open blackboard", name))
}
