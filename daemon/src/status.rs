//! The one-line live status of `lopd run`: haptic rate, jitter p99, frame age, deformation step
//! time and each body's model, read from the services like any other client.

use iceoryx2::prelude::*;
use lop_ipc::services::{self, Role};
use lop_ipc::*;

/// Attaches to telemetry, frames and topology, and formats what it last saw.
pub struct StatusMonitor {
    node: Node<ipc::Service>,
    names: ServiceNames,
    telemetry: Option<services::TelemetrySubscriber>,
    frames: Option<services::FrameSubscriber>,
    topologies: Option<services::TopologySubscriber>,
    last_telemetry: Option<HapticTelemetry>,
    last_frame: Option<FrameHeader>,
    last_frame_seen_ns: u64,
    topology: Option<TopologyHeader>,
}

impl StatusMonitor {
    /// A monitor for the services under `names`.
    pub fn new(names: &ServiceNames) -> anyhow::Result<StatusMonitor> {
        Ok(StatusMonitor {
            node: services::node("lopd-status")?,
            names: names.clone(),
            telemetry: None,
            frames: None,
            topologies: None,
            last_telemetry: None,
            last_frame: None,
            last_frame_seen_ns: 0,
            topology: None,
        })
    }

    /// Opens missing subscriptions and takes everything new.
    pub fn poll(&mut self) {
        if self.telemetry.is_none() {
            self.telemetry = services::telemetry_service(&self.node, &self.names, Role::Client)
                .ok()
                .and_then(|s| s.subscriber_builder().create().ok());
        }
        if self.frames.is_none() {
            self.frames = services::frame_service(&self.node, &self.names, Role::Client)
                .ok()
                .and_then(|s| s.subscriber_builder().buffer_size(1).create().ok());
        }
        if self.topologies.is_none() {
            self.topologies = services::topology_service(&self.node, &self.names, Role::Client)
                .ok()
                .and_then(|s| s.subscriber_builder().create().ok());
        }
        if let Some(sub) = &self.telemetry {
            while let Ok(Some(s)) = sub.receive() {
                self.last_telemetry = Some(*s);
            }
        }
        if let Some(sub) = &self.frames {
            while let Ok(Some(s)) = sub.receive() {
                self.last_frame = Some(*s.user_header());
                self.last_frame_seen_ns = clock::monotonic_ns();
            }
        }
        if let Some(sub) = &self.topologies {
            while let Ok(Some(s)) = sub.receive() {
                self.topology = Some(*s.user_header());
            }
        }
    }

    /// Drops every subscription (before the daemon's processes stop, so nothing keeps the
    /// services alive).
    pub fn detach(&mut self) {
        self.telemetry = None;
        self.frames = None;
        self.topologies = None;
    }

    /// The status line.
    pub fn line(&self, deform_restarts: u32) -> String {
        let mut s = String::new();
        match &self.last_telemetry {
            Some(t) => {
                s += &format!(
                    "haptic {:6.1} Hz  jitter p99 {:>5}  tick p99 {:>5}  frame age {:>6}  force {:.2} N",
                    t.rate_hz,
                    fmt_ns(t.window_jitter.p99),
                    fmt_ns(t.window_compute.p99),
                    if t.window_frame_age.count > 0 {
                        fmt_ns(t.window_frame_age.p50)
                    } else {
                        "stale".to_string()
                    },
                    t.force_norm
                );
                if t.rt_flags & RT_FLAG_FIFO == 0 {
                    s += " (no RT prio)";
                }
            }
            None => s += "haptic: waiting",
        }
        let now = clock::monotonic_ns();
        match (&self.last_frame, &self.topology) {
            (Some(f), Some(topo))
                if now.saturating_sub(self.last_frame_seen_ns) < 1_000_000_000 =>
            {
                s += &format!(" | deform step {:>6} |", fmt_ns(f.step_ns));
                for (b, bf) in topo
                    .bodies
                    .iter()
                    .zip(f.bodies.iter())
                    .take(f.body_count as usize)
                {
                    let model = BodyModel::from_u8(bf.model).map_or("?", |m| m.as_str());
                    let mark = if bf.state == BODY_STATE_ACTIVE {
                        "*"
                    } else {
                        ""
                    };
                    s += &format!(" {} {model}{mark}", b.name_str());
                    // A body in motion: the period it steps at and whether it keeps real time.
                    if bf.state == BODY_STATE_ACTIVE && bf.period_us > 0 {
                        s += &format!(" {}", fmt_period(bf.period_us));
                        if bf.real_time_factor > 0.0 {
                            s += &format!(" x{:.2}", bf.real_time_factor);
                        }
                    }
                }
            }
            _ => s += " | deform: waiting",
        }
        if deform_restarts > 0 {
            s += &format!(" | deform restarts {deform_restarts}");
        }
        s
    }

    /// The newest telemetry seen.
    pub fn telemetry(&self) -> Option<&HapticTelemetry> {
        self.last_telemetry.as_ref()
    }
}

/// A duration in ns, human-sized.
pub fn fmt_ns(ns: u64) -> String {
    if ns >= 1_000_000_000 {
        format!("{:.2} s", ns as f64 * 1e-9)
    } else if ns >= 1_000_000 {
        format!("{:.1} ms", ns as f64 * 1e-6)
    } else if ns >= 1_000 {
        format!("{:.0} µs", ns as f64 * 1e-3)
    } else {
        format!("{ns} ns")
    }
}

/// A step period in µs as the status line shows it: `1ms`, `2.5ms`.
fn fmt_period(us: u32) -> String {
    let ms = f64::from(us) * 1e-3;
    if (ms - ms.round()).abs() < 1e-6 {
        format!("{}ms", ms.round())
    } else {
        format!("{ms:.1}ms")
    }
}

#[cfg(test)]
mod tests {
    use super::fmt_period;

    #[test]
    fn periods_read_in_milliseconds() {
        assert_eq!(fmt_period(1000), "1ms");
        assert_eq!(fmt_period(10_000), "10ms");
        assert_eq!(fmt_period(2500), "2.5ms");
    }
}
