//! The frames, received off the RT thread.
//!
//! A frame lives in the deformation process's shared memory, and an iceoryx2 subscriber maps a
//! publisher's data segment on its first receive from it. That segment holds every sample the
//! service may have in flight, about 100 frames. With the haptic process's memory locked, the
//! mapping populates all of it at once: 24–28 ms for a 20k-tetrahedron organ. Done by the RT
//! thread, that was one stalled tick, and 19–26 missed deadlines, each time a deformation
//! process started. So a thread of its own, the frame thread, subscribes to the frames. It
//! sleeps on the `PREFIX/scene/frame/ready` event that the deformation process notifies after
//! each frame (it also wakes every millisecond, for a publisher that does not notify). It
//! copies the newest frame into a buffer of its own and hands it to the RT thread through a
//! lock-free ring. The RT thread takes the newest ([`super::IndexSlot`], as for the contact
//! index) and hands the one it replaces back, to be filled again. The thread takes the
//! mapping's cost and every allocation (a buffer is sized for a frame's nodes once, then
//! reused); the RT thread only swaps a pointer.
//!
//! Where the loop is pinned, the frame thread runs on the same core at a lower `SCHED_FIFO`
//! priority (when permitted). That core idles between ticks, so the thread wakes as soon as a
//! frame is announced, and the loop's higher priority takes the core back for every tick. The
//! copy (tens of µs for a 20k-tetrahedron organ) costs a frame at most the wait for the next
//! tick. When the device's own servo thread runs the tick (OpenHaptics), at a priority that is
//! the vendor's, the frame thread runs unpinned at the default policy instead.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use lop_ipc::services::{self, Role};
use lop_ipc::*;

use crate::rt;

/// How long the thread sleeps on the event before it looks for frames (and its stop flag)
/// anyway.
const POLL: Duration = Duration::from_millis(1);

/// Buffers the thread keeps for reuse beyond those in flight.
const SPARE: usize = 2;

/// A frame copied out of shared memory.
#[derive(Debug, Clone, Default)]
pub struct FrameCopy {
    header: FrameHeader,
    nodes: Vec<NodeSample>,
}

impl FrameCopy {
    /// The frame's header.
    pub fn user_header(&self) -> &FrameHeader {
        &self.header
    }

    /// The frame's nodes.
    pub fn payload(&self) -> &[NodeSample] {
        &self.nodes
    }

    /// Overwrites this copy with `header` and `nodes` (reusing its buffer).
    fn fill(&mut self, header: &FrameHeader, nodes: &[NodeSample]) {
        self.header = *header;
        self.nodes.clear();
        self.nodes.extend_from_slice(nodes);
    }
}

/// Where the frame thread runs.
#[derive(Debug, Clone, Copy, Default)]
pub struct FramePlacement {
    /// The haptic loop's core.
    pub core: Option<usize>,
    /// `SCHED_FIFO` priority, below the loop's (0: the default policy).
    pub priority: u8,
}

/// The frame thread and its rings to the RT thread.
pub(crate) struct FrameFeed {
    pub(crate) rx: rtrb::Consumer<Box<FrameCopy>>,
    pub(crate) back: rtrb::Producer<Box<FrameCopy>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl FrameFeed {
    /// Starts the thread; returns once it is subscribed (or after two seconds).
    pub(crate) fn start(names: &ServiceNames, placement: FramePlacement) -> Result<FrameFeed> {
        let (mut tx, rx) = rtrb::RingBuffer::<Box<FrameCopy>>::new(2);
        let (back, mut returned) = rtrb::RingBuffer::<Box<FrameCopy>>::new(8);
        let stop = Arc::new(AtomicBool::new(false));
        let names = names.clone();
        let flag = stop.clone();
        let (ready_tx, ready_rx) = std::sync::mpsc::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("lop-haptic-frames".into())
            .spawn(move || {
                // Each is optional, as for the loop, which already says what it lacks.
                if let Some(core) = placement.core {
                    if let Err(e) = rt::pin_to_core(core) {
                        tracing::debug!("haptic frame thread not pinned: {e}");
                    }
                }
                if placement.priority > 0 {
                    if let Err(e) = rt::set_fifo(placement.priority) {
                        tracing::debug!("haptic frame thread without SCHED_FIFO: {e}");
                    }
                }
                let mut run = || -> Result<()> {
                    let node = services::node("lopd-haptic-frames")?;
                    let frames = services::frame_service(&node, &names, Role::Owner)?
                        .subscriber_builder()
                        .buffer_size(2)
                        .create()
                        .context("frame subscriber")?;
                    let listener = match services::frame_ready_service(&node, &names)
                        .map_err(anyhow::Error::from)
                        .and_then(|s| Ok(s.listener_builder().create()?))
                    {
                        Ok(l) => Some(l),
                        Err(e) => {
                            tracing::warn!(
                                "frame-ready event unavailable ({e:#}): frames are polled every \
                                 {} ms",
                                POLL.as_millis()
                            );
                            None
                        }
                    };
                    let _ = ready_tx.send(());
                    let mut spare: Vec<Box<FrameCopy>> = Vec::new();
                    // A copy the RT thread has not made room for: replaced by newer frames
                    // until it goes.
                    let mut pending: Option<Box<FrameCopy>> = None;
                    while !flag.load(Ordering::Relaxed) {
                        match &listener {
                            Some(l) => {
                                let _ = l.timed_wait(|_| {}, POLL);
                            }
                            None => std::thread::sleep(POLL),
                        }
                        let mut newest = None;
                        while let Ok(Some(s)) = frames.receive() {
                            newest = Some(s);
                        }
                        while let Ok(old) = returned.pop() {
                            spare.push(old);
                        }
                        if let Some(s) = newest {
                            let mut copy =
                                pending.take().or_else(|| spare.pop()).unwrap_or_default();
                            copy.fill(s.user_header(), s.payload());
                            pending = Some(copy);
                        }
                        if let Some(copy) = pending.take() {
                            if let Err(rtrb::PushError::Full(copy)) = tx.push(copy) {
                                pending = Some(copy);
                            }
                        }
                        spare.truncate(SPARE);
                    }
                    Ok(())
                };
                if let Err(e) = run() {
                    tracing::warn!("haptic frame thread stopped: {e:#}");
                }
            })?;
        let _ = ready_rx.recv_timeout(Duration::from_secs(2));
        Ok(FrameFeed {
            rx,
            back,
            stop,
            thread: Some(thread),
        })
    }
}

impl Drop for FrameFeed {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
