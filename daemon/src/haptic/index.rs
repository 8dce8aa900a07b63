//! The haptic loop's view of the surfaces: the contact index of the newest topology (built off
//! the RT thread, handed over through a lock-free ring, handed back to be freed there) and the
//! newest frame's positions, as the [`ContactSurfaces`] the haptic pipeline renders against.
//!
//! The index (adjacency, hierarchies, the god-object's buffers) is sized by the topology, so a
//! helper thread subscribes to the topology, builds the index for each new one and pushes it
//! to the RT thread; the RT thread swaps it in and pushes the old one back to be freed on the
//! helper thread. The RT thread never frees an index: if the return ring is full it keeps the
//! retired index and retries on a later tick, taking no newer index meanwhile
//! ([`IndexSlot::take_newest`]). A new frame only refreshes positions (copied from shared
//! memory, no allocation), and only of the bodies the tool can reach.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use lop_ipc::services::{self, Role};
use lop_ipc::*;
use lop_sim::haptic::{ContactSurfaces, GodObject, LocalModel, SurfaceSet};

/// A body's positions are copied into the contact index once the device or the god-object is
/// this close to its bounds, m: well beyond what the tool covers between frames.
const REACH: f64 = 0.02;

/// A frame as the loop holds it: copied out of shared memory by the frame thread.
pub(crate) type FrameSample = super::FrameCopy;

/// A value that changes whenever body `bf`'s positions may have changed between two frames:
/// its last step's wall time (to the nanosecond), kinetic energy, top speed, bounds and model
/// switches, mixed. A body that did not step carries them unchanged (the deformation process
/// only updates them when it steps); two different steps giving all of them identical to the
/// bit is not a case worth a copy of every node on each tick.
fn body_stamp(bf: &BodyFrame) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut mix = |x: u64| {
        h ^= x;
        h = h.wrapping_mul(0x0100_0000_01b3).rotate_left(23);
    };
    mix(u64::from(bf.step_ns));
    mix(u64::from(bf.kinetic_energy.to_bits()) << 32 | u64::from(bf.max_speed.to_bits()));
    for k in 0..3 {
        mix(u64::from(bf.aabb_min[k].to_bits()) << 32 | u64::from(bf.aabb_max[k].to_bits()));
    }
    mix(u64::from(bf.switches) << 32 | u64::from(bf.resets) << 8 | u64::from(bf.model));
    h
}

/// The local model a frame carries for the patch it balanced for tool `tool` (its index in
/// the scene's tool list): the body and the model; `None` when the frame has none for it.
pub fn frame_local(h: &FrameHeader, tool: usize) -> Option<(usize, LocalModel)> {
    let c = h.contact(tool)?;
    if c.local != 1 || c.body == NO_CONTACT {
        return None;
    }
    let k = &c.stiffness;
    Some((
        c.body as usize,
        LocalModel {
            device: c.device,
            force: c.force,
            stiffness: [[k[0], k[1], k[2]], [k[3], k[4], k[5]], [k[6], k[7], k[8]]],
            drift: c.drift,
            horizon: c.horizon,
        },
    ))
}

/// What a frame carries for one tool's press (the inverse of [`frame_local`]): the contact
/// patch's body and balanced proxy, and its local model when there is one.
pub fn contact_frame(body: u32, proxy: [f64; 3], local: Option<&LocalModel>) -> ContactFrame {
    let mut c = ContactFrame {
        body,
        proxy,
        ..ContactFrame::default()
    };
    if let Some(m) = local {
        c.force = m.force;
        c.device = m.device;
        for (dst, row) in c.stiffness.chunks_exact_mut(3).zip(&m.stiffness) {
            dst.copy_from_slice(row);
        }
        c.drift = m.drift;
        c.horizon = m.horizon;
        c.local = 1;
    }
    c
}

/// The contact index of one topology: every body's surface, shared by the tools (a body's
/// positions are copied in once per frame whichever tool reaches it first), and each tool's
/// god-object over it.
pub(crate) struct ContactIndex {
    pub(crate) topology_id: u64,
    set: SurfaceSet,
    /// Per tool.
    tools: Vec<ToolGod>,
    /// Counts the refreshes that copied positions in: a tool whose god-object followed an
    /// older count follows the surface again.
    version: u64,
}

/// One tool's god-object over the shared surfaces and what it last followed.
struct ToolGod {
    god: GodObject,
    /// Its proxy was taken over from the index of the topology before (a cut): the first
    /// frame does not reset it.
    carried: bool,
    /// The pipeline has not been told of the topology change yet.
    glide_due: bool,
    /// Sequence of the newest frame this tool saw.
    frame_sequence: Option<u64>,
    /// [`ContactIndex::version`] the god-object last followed.
    followed: u64,
}

impl ContactIndex {
    /// Builds the index of a topology (allocates; off the RT thread). `None` if the topology is
    /// not this contract's.
    fn build(h: &TopologyHeader, indices: &[u32], radii: &[f64]) -> Option<ContactIndex> {
        if h.contract_version != CONTRACT_VERSION {
            return None;
        }
        let tri_count = (h.triangle_count as usize).min(indices.len() / 3);
        let triangles: Vec<[u32; 3]> = indices[..tri_count * 3]
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let bodies = (h.body_count as usize).min(MAX_BODIES);
        let mut slices = Vec::with_capacity(bodies);
        for b in &h.bodies[..bodies] {
            let start = (b.triangle_offset as usize).min(tri_count);
            let end = (start + b.triangle_count as usize).min(tri_count);
            slices.push(&triangles[start..end]);
        }
        let set = SurfaceSet::new(h.node_count as usize, &slices);
        let tools = radii
            .iter()
            .map(|&r| ToolGod {
                god: GodObject::new(r, set.triangles().len()),
                carried: false,
                glide_due: false,
                frame_sequence: None,
                followed: 0,
            })
            .collect();
        Some(ContactIndex {
            topology_id: h.topology_id,
            set,
            tools,
            version: 0,
        })
    }

    /// Takes over each tool's proxy from `old`, the index of the topology before a cut
    /// ([`GodObject::keep_proxy_of`]): the proxy stays where the hand left it and moves on
    /// against the new surfaces, so the force does not jump when the topology changes.
    /// Allocation-free (on the RT thread, as the new index is swapped in).
    pub(crate) fn carry_from(&mut self, old: &ContactIndex) {
        if old.topology_id == self.topology_id {
            return;
        }
        for (t, o) in self.tools.iter_mut().zip(&old.tools) {
            t.god.keep_proxy_of(&o.god);
            t.carried = true;
            t.glide_due = true;
        }
    }

    /// Brings the index up to date with `frame` for the bodies tool `tool` can reach this
    /// tick: their positions are copied in (a few µs for an organ, so only bodies whose frame
    /// bounds are within [`REACH`] of the device or the god-object are, and only once per
    /// frame whichever tool asks first), the others are left out of the queries until they
    /// come within reach. The tool's god-object is carried along with the tissue, and rests
    /// where the frame balanced the tool's contact patch. False when the frame does not fit
    /// this index (another contract or node count) or the tool has no god-object here: then
    /// nothing is touched (and a stale frame ramps the force down anyway). A frame of a newer
    /// topology with the same nodes (a cut) leaves the surfaces as they are and is not an
    /// error: its index is on its way.
    fn refresh(&mut self, frame: &FrameSample, device: Option<[f64; 3]>, tool: usize) -> bool {
        let fh = frame.user_header();
        let nodes = frame.payload();
        if fh.contract_version != CONTRACT_VERSION
            || nodes.len() != self.set.node_count()
            || tool >= self.tools.len()
        {
            return false;
        }
        if fh.topology_id != self.topology_id {
            // A frame of the next topology (a cut) before its index is built: the god-object
            // goes on against this one's last surface for those few milliseconds rather than
            // let go of the hand (its force would drop by the safety's step in one tick).
            return true;
        }
        let t = &mut self.tools[tool];
        let first = t.frame_sequence.is_none();
        let new_frame = t.frame_sequence != Some(fh.sequence);
        t.frame_sequence = Some(fh.sequence);
        let proxy = t.god.proxy();
        let points = [device.unwrap_or(proxy), proxy];
        let count = (fh.body_count as usize).min(MAX_BODIES);
        let bounds = |b: usize| match fh.bodies.get(b) {
            Some(bf) if b < count => (bf.aabb_min.map(|c| c as f64), bf.aabb_max.map(|c| c as f64)),
            _ => ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        };
        // A body that did not step since the last frame keeps its positions: at 1 kHz frames
        // only the touched body changes in most, and its neighbours are not copied again.
        let stamp = |b: usize| match fh.bodies.get(b) {
            Some(bf) if b < count => body_stamp(bf),
            _ => fh.sequence,
        };
        if self
            .set
            .refresh_reachable(stamp, &points, REACH, bounds, |i| {
                nodes[i].position.map(|c| c as f64)
            })
        {
            self.version += 1;
        }
        // Positions copied since this god-object last followed them (by this tool's refresh
        // or another's): follow.
        let t = &mut self.tools[tool];
        let moved = t.followed != self.version;
        t.followed = self.version;
        if first && !t.carried {
            t.god.reset();
        } else if new_frame || moved {
            t.god.follow_surface(&self.set);
            // The press balanced as a contact patch: rest the proxy where the tissue put it.
            if let Some(c) = fh.contact(tool).filter(|_| new_frame) {
                let b = c.body as usize;
                if c.body != NO_CONTACT && b < count {
                    t.god.rest_at(&self.set, b, c.proxy);
                }
            }
        }
        true
    }
}

/// The newest index and frame as the pipeline's surfaces for one tick.
pub(crate) struct LiveSurfaces<'a> {
    pub(crate) index: Option<&'a mut ContactIndex>,
    pub(crate) frame: Option<&'a FrameSample>,
    /// Render with the frame's local model.
    pub(crate) local_model: bool,
    /// The loop's tool: its index in the scene's tool list, which picks its contact in a
    /// frame.
    pub(crate) tool: usize,
    /// When the tick woke, ns (the local model's age is counted from its step's tool read).
    pub(crate) wake_ns: u64,
}

impl ContactSurfaces for LiveSurfaces<'_> {
    fn refresh(&mut self, tip: Option<[f64; 3]>) -> bool {
        match (self.index.as_deref_mut(), self.frame) {
            (Some(ix), Some(frame)) => ix.refresh(frame, tip, self.tool),
            _ => false,
        }
    }

    fn god_object(&mut self) -> Option<(&mut GodObject, &mut SurfaceSet)> {
        let tool = self.tool;
        let ix = self.index.as_deref_mut()?;
        let t = ix.tools.get_mut(tool)?;
        Some((&mut t.god, &mut ix.set))
    }

    fn topology_changed(&mut self) -> bool {
        let tool = self.tool;
        self.index
            .as_deref_mut()
            .and_then(|ix| ix.tools.get_mut(tool))
            .is_some_and(|t| std::mem::take(&mut t.glide_due))
    }

    fn local_model(&self) -> Option<(usize, LocalModel, f64)> {
        let frame = self.frame.filter(|_| self.local_model)?;
        let h = frame.user_header();
        let (body, model) = frame_local(h, self.tool)?;
        let elapsed = self.wake_ns.saturating_sub(h.tool_read_ns) as f64 * 1e-9;
        Some((body, model, elapsed))
    }
}

/// The RT thread's end of an index handover: the index in use and, while the return ring is
/// full, the one it retired. Generic so the handover can be tested on its own.
pub struct IndexSlot<T> {
    current: Option<Box<T>>,
    retired: Option<Box<T>>,
}

impl<T> Default for IndexSlot<T> {
    fn default() -> Self {
        IndexSlot {
            current: None,
            retired: None,
        }
    }
}

impl<T> IndexSlot<T> {
    /// The index in use.
    pub fn current(&mut self) -> Option<&mut T> {
        self.current.as_deref_mut()
    }

    /// Whether an index is in use.
    pub fn is_ready(&self) -> bool {
        self.current.is_some()
    }

    /// Takes the newest index from `rx` and hands every one it replaces back through `back`.
    /// Never frees: a retired index the full `back` ring cannot take is kept and pushed again
    /// on the next call, and no newer index is taken until it is gone. Allocation-free.
    pub fn take_newest(
        &mut self,
        rx: &mut rtrb::Consumer<Box<T>>,
        back: &mut rtrb::Producer<Box<T>>,
    ) {
        self.take_newest_carrying(rx, back, |_, _| {});
    }

    /// [`IndexSlot::take_newest`], with `carry(new, old)` called as each newer value replaces
    /// the current one (what the new one takes over from the old). Allocation-free if `carry`
    /// is.
    pub fn take_newest_carrying(
        &mut self,
        rx: &mut rtrb::Consumer<Box<T>>,
        back: &mut rtrb::Producer<Box<T>>,
        mut carry: impl FnMut(&mut T, &T),
    ) {
        loop {
            if let Some(old) = self.retired.take() {
                if let Err(rtrb::PushError::Full(old)) = back.push(old) {
                    self.retired = Some(old);
                    return;
                }
            }
            match rx.pop() {
                Ok(mut ix) => {
                    if let Some(old) = &self.current {
                        carry(&mut ix, old);
                    }
                    self.retired = self.current.replace(ix);
                }
                Err(_) => return,
            }
        }
    }
}

/// The thread that builds contact indices for the RT thread, and frees the ones it retires.
pub(crate) struct IndexFeed {
    pub(crate) rx: rtrb::Consumer<Box<ContactIndex>>,
    pub(crate) back: rtrb::Producer<Box<ContactIndex>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl IndexFeed {
    /// Starts the thread building the indices of every topology, with a god-object of each of
    /// `radii` (one per tool).
    pub(crate) fn start(names: &ServiceNames, radii: Vec<f64>) -> Result<IndexFeed> {
        let (mut tx, rx) = rtrb::RingBuffer::<Box<ContactIndex>>::new(2);
        let (back, mut retired) = rtrb::RingBuffer::<Box<ContactIndex>>::new(8);
        let stop = Arc::new(AtomicBool::new(false));
        let names = names.clone();
        let flag = stop.clone();
        let (ready_tx, ready_rx) = std::sync::mpsc::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("lop-haptic-index".into())
            .spawn(move || {
                let mut run = || -> Result<()> {
                    let node = services::node("lopd-haptic-index")?;
                    let topologies = services::topology_service(&node, &names, Role::Owner)?
                        .subscriber_builder()
                        .create()
                        .context("topology subscriber")?;
                    let _ = ready_tx.send(());
                    // An index the RT thread has not made room for yet: pushed again before a
                    // newer topology replaces it.
                    let mut pending: Option<Box<ContactIndex>> = None;
                    while !flag.load(Ordering::Relaxed) {
                        while let Ok(Some(t)) = topologies.receive() {
                            if let Some(ix) =
                                ContactIndex::build(t.user_header(), t.payload(), &radii)
                            {
                                pending = Some(Box::new(ix));
                            }
                        }
                        if let Some(ix) = pending.take() {
                            if let Err(rtrb::PushError::Full(ix)) = tx.push(ix) {
                                pending = Some(ix);
                            }
                        }
                        while let Ok(old) = retired.pop() {
                            drop(old);
                        }
                        std::thread::sleep(Duration::from_millis(2));
                    }
                    Ok(())
                };
                if let Err(e) = run() {
                    tracing::warn!("haptic contact index thread stopped: {e:#}");
                }
            })?;
        // Subscribed before the loop starts, so a topology published right after is not missed
        // (the deformation process also re-offers its topology to late subscribers).
        let _ = ready_rx.recv_timeout(Duration::from_secs(2));
        Ok(IndexFeed {
            rx,
            back,
            stop,
            thread: Some(thread),
        })
    }
}

impl Drop for IndexFeed {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_return_ring_keeps_the_retired_index() {
        let (mut tx, mut rx) = rtrb::RingBuffer::<Box<u32>>::new(4);
        let (mut back, mut freed) = rtrb::RingBuffer::<Box<u32>>::new(1);
        let mut slot = IndexSlot::default();
        tx.push(Box::new(1)).unwrap();
        slot.take_newest(&mut rx, &mut back);
        assert_eq!(slot.current().copied(), Some(1));
        // Fill the return ring, then offer two newer indices.
        back.push(Box::new(0)).unwrap();
        tx.push(Box::new(2)).unwrap();
        tx.push(Box::new(3)).unwrap();
        slot.take_newest(&mut rx, &mut back);
        // 2 replaced 1; 1 could not go back, so 3 waits.
        assert_eq!(slot.current().copied(), Some(2));
        slot.take_newest(&mut rx, &mut back);
        assert_eq!(slot.current().copied(), Some(2));
        // Room again: 1 goes back, 3 comes in, 2 goes back once there is room.
        assert_eq!(*freed.pop().unwrap(), 0);
        slot.take_newest(&mut rx, &mut back);
        assert_eq!(slot.current().copied(), Some(3));
        assert_eq!(*freed.pop().unwrap(), 1);
        slot.take_newest(&mut rx, &mut back);
        assert_eq!(*freed.pop().unwrap(), 2);
    }
}
