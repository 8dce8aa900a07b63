//! A client for the remote system test (`tests/tests/remote.rs`), run on the far side of the
//! Zenoh tunnel: its iceoryx2 domain is the one its working directory's
//! `config/iceoryx2.toml` names, as for any client there.
//!
//! - `read PREFIX FRAMES TIMEOUT_S`: prints `topology ID NODES`, then `frame SEQUENCE
//!   TOPOLOGY_ID LATENCY_NS` for every frame its own subscriber receives, in arrival order
//!   (latency: receipt against the frame's `publish_ns`, one machine's monotonic clock), then
//!   `service NAME` for every service of the domain, and `done`.
//! - `inject PREFIX SECONDS`: publishes frames with topology id [`INJECTED_TOPOLOGY`] into the
//!   domain's `PREFIX/scene/frame` and notifies `PREFIX/scene/frame/ready`, 1 kHz, for SECONDS.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use lop_ipc::services::{self, Role};
use lop_ipc::types::{FrameHeader, NodeSample};
use lop_ipc::{clock, ServiceNames, CONTRACT_VERSION};

/// The topology id of injected frames: no scene load has it.
const INJECTED_TOPOLOGY: u64 = 0xBAD0_BAD0_BAD0_BAD0;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        ["read", prefix, frames, timeout] => read(
            prefix,
            frames.parse().expect("FRAMES"),
            Duration::from_secs_f64(timeout.parse().expect("TIMEOUT_S")),
        ),
        ["inject", prefix, seconds] => inject(
            prefix,
            Duration::from_secs_f64(seconds.parse().expect("SECONDS")),
        ),
        _ => Err(
            "usage: lop-remote-probe read PREFIX FRAMES TIMEOUT_S | inject PREFIX SECONDS".into(),
        ),
    };
    if let Err(e) = result {
        eprintln!("lop-remote-probe: {e}");
        std::process::exit(1);
    }
}

fn read(prefix: &str, frames: usize, timeout: Duration) -> Result<(), String> {
    let names = ServiceNames::new(prefix).map_err(|e| e.to_string())?;
    let node = services::node("lop-remote-probe").map_err(|e| e.to_string())?;
    let topology = services::open_retry(&names.topology, timeout, || {
        services::topology_service(&node, &names, Role::Client)?
            .subscriber_builder()
            .create()
            .map_err(|e| lop_ipc::limits::subscriber_create_error(&names.topology, e))
    })
    .map_err(|e| e.to_string())?;
    let frame_sub = services::open_retry(&names.frame, timeout, || {
        services::frame_service(&node, &names, Role::Client)?
            .subscriber_builder()
            .buffer_size(services::FRAME_BUFFER)
            .create()
            .map_err(|e| lop_ipc::limits::subscriber_create_error(&names.frame, e))
    })
    .map_err(|e| e.to_string())?;
    let start = Instant::now();
    let topology_id = loop {
        if let Ok(Some(s)) = topology.receive() {
            let h = s.user_header();
            if h.contract_version != CONTRACT_VERSION {
                return Err(format!("contract version {}", h.contract_version));
            }
            println!("topology {:#x} {}", h.topology_id, h.node_count);
            break h.topology_id;
        }
        if start.elapsed() > timeout {
            return Err(format!("no topology in {timeout:?}"));
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    let mut got = 0;
    while got < frames {
        match frame_sub.receive() {
            Ok(Some(s)) => {
                let h = s.user_header();
                let latency = clock::monotonic_ns() as i64 - h.publish_ns as i64;
                println!("frame {} {:#x} {latency}", h.sequence, h.topology_id);
                if h.topology_id == topology_id {
                    got += 1;
                }
            }
            Ok(None) => std::thread::sleep(Duration::from_micros(200)),
            Err(e) => return Err(format!("receive: {e:?}")),
        }
        if start.elapsed() > timeout {
            return Err(format!("{got} of {frames} frames in {timeout:?}"));
        }
    }
    let _ = ipc::Service::list(Config::global_config(), |details| {
        println!("service {}", details.static_details.name().as_str());
        CallbackProgression::Continue
    });
    println!("done");
    Ok(())
}

fn inject(prefix: &str, seconds: Duration) -> Result<(), String> {
    let names = ServiceNames::new(prefix).map_err(|e| e.to_string())?;
    let node = services::node("lop-remote-probe-inject").map_err(|e| e.to_string())?;
    let publisher = services::open_retry(&names.frame, Duration::from_secs(30), || {
        services::frame_service(&node, &names, Role::Owner)?
            .publisher_builder()
            .initial_max_slice_len(64)
            .create()
            .map_err(|e| lop_ipc::services::IpcError::Iceoryx {
                what: "create publisher for",
                service: names.frame.clone(),
                reason: format!("{e:?}"),
            })
    })
    .map_err(|e| e.to_string())?;
    let ready = services::frame_ready_service(&node, &names)
        .map_err(|e| e.to_string())?
        .notifier_builder()
        .create()
        .map_err(|e| format!("{e:?}"))?;
    let start = Instant::now();
    let mut sent = 0u64;
    while start.elapsed() < seconds {
        let mut sample = publisher
            .loan_slice_uninit(64)
            .map_err(|e| format!("{e:?}"))?;
        // SAFETY: a frame header is plain numbers (`repr(C)`, shared with C readers), for which
        // all-zero bytes are a valid value.
        let mut header: FrameHeader = unsafe { std::mem::zeroed() };
        header.contract_version = CONTRACT_VERSION;
        header.topology_id = INJECTED_TOPOLOGY;
        header.sequence = u64::MAX - sent;
        header.node_count = 64;
        header.publish_ns = clock::monotonic_ns();
        *sample.user_header_mut() = header;
        let _ = sample.write_from_fn(|_| NodeSample::default()).send();
        let _ = ready.notify();
        sent += 1;
        std::thread::sleep(Duration::from_millis(1));
    }
    println!("injected {sent}");
    Ok(())
}
