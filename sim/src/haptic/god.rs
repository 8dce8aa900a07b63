//! The god-object (thesis §5.2.1): a proxy of the tool tip that stays on the tissue surface while
//! the device penetrates, and the force law between the two (§5.2.2).
//!
//! The tool tip is a sphere of radius `r`; the proxy is that sphere's centre. Each tick the
//! proxy moves *from where it was* towards the device, Zilles–Salisbury style:
//!
//! 1. constraints: every triangle within `r` of the proxy that the device is pushing into gives a
//!    plane through the proxy (normal from the closest point to the proxy's centre);
//! 2. target: the device position projected onto the active planes — one plane: the projection,
//!    two: the crease line, three: stay;
//! 3. the sphere is swept from the proxy to the target against the surface (plane, edge and
//!    corner contacts, `sweep`); at the first contact it stops there and that contact becomes a
//!    plane; repeat (at most three planes).
//!
//! Because the proxy is never teleported to the closest surface point, a device moving fast
//! through a thin part cannot pull it out the far side: the force keeps pointing back out of the
//! face it went in through (tested at 0.5 m/s into a 1 cm slab).
//!
//! A proxy that *starts* with the device inside a body (the loop started, or started again,
//! while the hand held the stylus in the tissue) starts on the surface closest to the device,
//! in contact, so that surface is felt from the first tick (ramped in by the safety).
//!
//! The surface deforms between frames. While in contact the proxy is anchored to the material
//! point it rests on (triangle + barycentric weights, plus its offset from that point), so a new
//! frame carries the proxy along with the tissue; then it is pushed out of any triangle that
//! moved into it.
//!
//! **Picking** (§5.2.3): with the grab button pressed while touching, the anchor becomes a grip:
//! the proxy is glued to the grabbed material point, the hand feels the spring between it and
//! the device in every direction (it pulls too), and the deformation process pulls that point
//! of the tissue towards the device with the opposite force. Releasing the button lets go.
//!
//! Everything is allocation-free after [`GodObject::new`].

use glam::DVec3;

use super::surface::{Closest, SurfaceSet};
use super::sweep::{crease, sweep};
use crate::contact::{off_triangle, ForceLaw};
use crate::vec3::v;

/// Gap kept between the proxy sphere and a surface it rests on, m: keeps the next sweep from
/// starting in contact because of rounding.
const SKIN: f64 = 1e-7;
/// How far the proxy may be from its anchor triangle and still rest on it, m.
const STICK: f64 = 2e-5;
/// A rest point from the deformation process ([`GodObject::rest_at`]) is taken only with the
/// sphere's centre at least this many radii outside the anchor's triangle. A resting sphere's
/// centre is one radius out; points on the surface itself came with frames of a tissue behind
/// the wall clock (the two-handed scene's grabbed liver stepping late on a slow machine,
/// 2026-12-07: 9 µm and 0.43 mm *behind* the triangle, against 2.0 mm outside for the rest).
/// Moved there, the proxy's centre lies behind the surface, where faces are one-sided: the
/// anchor is dropped and the tool falls through the tissue with no force. The deformation
/// process no longer makes such points (it starts each patch from the proxy put back on its
/// own surface, [`crate::interaction::ToolAnchor::patch_proxy`]); this stays as the haptic
/// loop's own guard against a frame that would drop the tool through.
const REST_CLEARANCE: f64 = 0.5;
/// Most planes that constrain the proxy at once.
const MAX_PLANES: usize = 3;
/// Sweeps per tick (each adds a plane or ends the motion).
const MAX_ITERATIONS: usize = 6;

/// A material point of the surface: where the proxy rests or what it holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Anchor {
    /// Body index.
    pub body: usize,
    /// Global triangle index (in the [`SurfaceSet`]).
    pub triangle: usize,
    /// Barycentric weights of the point on the triangle.
    pub bary: [f64; 3],
    /// Proxy centre minus the point, m (length `r` while resting on a face).
    pub offset: [f64; 3],
}

/// The god-object after a tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GodState {
    /// Proxy (tool sphere centre), m.
    pub proxy: [f64; 3],
    /// Where the proxy rests or what it holds; `None` in free space.
    pub anchor: Option<Anchor>,
    /// Holding tissue (grab button).
    pub grabbing: bool,
    /// `|proxy − device|` while in contact or grabbing, m.
    pub depth: f64,
    /// Unit direction of the force on the hand (device → proxy), zero without contact.
    pub direction: [f64; 3],
}

/// The proxy of the tool tip.
#[derive(Debug, Clone)]
pub struct GodObject {
    radius: f64,
    proxy: DVec3,
    started: bool,
    anchor: Option<Anchor>,
    grab: Option<Anchor>,
    planes: [DVec3; MAX_PLANES],
    nplanes: usize,
    candidates: Vec<u32>,
}

/// [`off_triangle`] against triangle `tri` of `set`.
fn off_set_triangle(set: &SurfaceSet, tri: usize, p: DVec3) -> ([f64; 3], DVec3) {
    let [a, b, c] = set.corners_v(tri);
    off_triangle(p, a, b, c)
}

impl GodObject {
    /// A proxy for a tip of `radius` m over a surface set of `triangles` triangles.
    pub fn new(radius: f64, triangles: usize) -> GodObject {
        GodObject {
            radius,
            proxy: DVec3::ZERO,
            started: false,
            anchor: None,
            grab: None,
            planes: [DVec3::ZERO; MAX_PLANES],
            nplanes: 0,
            candidates: Vec::with_capacity(triangles),
        }
    }

    /// Tip radius, m.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The proxy, m.
    pub fn proxy(&self) -> [f64; 3] {
        self.proxy.to_array()
    }

    /// Forgets the surface: the next update puts the proxy on the device, or on the surface if
    /// the device is inside a body.
    pub fn reset(&mut self) {
        self.started = false;
        self.anchor = None;
        self.grab = None;
    }

    /// Takes over the proxy of `old`, a god-object over the surfaces before a cut changed
    /// them: the proxy stays where it was, free (no anchor, no grab: a grab does not survive a
    /// cut), and the next update moves it from there towards the device against the new
    /// surfaces. Where the cut took the tissue under it, it sinks into the wound as the hand
    /// pushes; where the tissue is still there it rests on it. The force is continuous across
    /// the change: the tool spring's stretch is the same before and after.
    pub fn keep_proxy_of(&mut self, old: &GodObject) {
        self.proxy = old.proxy;
        self.started = old.started;
        self.anchor = None;
        self.grab = None;
    }

    /// Moves an anchored proxy with the tissue after the surface's positions changed.
    pub fn follow_surface(&mut self, set: &SurfaceSet) {
        if let Some(a) = self.grab.or(self.anchor) {
            if a.triangle < set.triangles().len() {
                self.proxy = set.point_on_v(a.triangle, a.bary) + v(a.offset);
            }
        }
    }

    /// Puts a resting proxy where the deformation process balanced the tool's contact patch
    /// on body `body` (see [`crate::patch`]): the sphere touches the tissue there and the tool
    /// spring holds what the patch pushes, so the hand feels what the tissue receives. Keeps
    /// the anchor's material point (its offset follows). Ignored while grabbing, off contact,
    /// on another body or with a non-finite point, and where `set` puts the point less than
    /// half a radius outside the anchor's triangle ([`REST_CLEARANCE`]).
    pub fn rest_at(&mut self, set: &SurfaceSet, body: usize, proxy: [f64; 3]) {
        let p = v(proxy);
        if self.grab.is_some() || !p.is_finite() {
            return;
        }
        let r = self.radius;
        if let Some(a) = &mut self.anchor {
            if a.body == body && a.triangle < set.triangles().len() {
                let (_, offset) = off_set_triangle(set, a.triangle, p);
                if offset.dot(set.normal_of_v(a.triangle)) < REST_CLEARANCE * r {
                    return;
                }
                self.proxy = p;
                a.offset = (p - set.point_on_v(a.triangle, a.bary)).to_array();
            }
        }
    }

    /// One tick: the device is at `device` (m) and the grab button is `grab`. Allocation-free.
    pub fn update(&mut self, set: &mut SurfaceSet, device: [f64; 3], grab: bool) -> GodState {
        let device = v(device);
        if !device.is_finite() {
            // Broken sample: nothing to render; keep the proxy where it was.
            return self.state(device, false);
        }
        if !self.started {
            self.started = true;
            self.proxy = device;
            self.anchor = None;
            self.grab = None;
            self.start_on_surface(set, device);
        }
        // Picking.
        if let Some(g) = self.grab {
            if grab && g.triangle < set.triangles().len() {
                self.proxy = set.point_on_v(g.triangle, g.bary) + v(g.offset);
                return self.state(device, true);
            }
            self.grab = None;
        }
        if grab {
            if let Some(a) = self.anchor {
                self.grab = Some(a);
                return self.state(device, true);
            }
        }

        // An anchored proxy moved with its material point (`follow_surface`), exactly where
        // the deformation process puts it when it applies the hand's force to the tissue;
        // pushing it out of the faces around a dimple that force made would make the two
        // disagree (and the load hop between faces every frame). A free proxy the surface
        // moved into is pushed out.
        if self.anchor.is_none() {
            self.depenetrate(set);
        }
        self.gather_planes(set, device);
        for _ in 0..MAX_ITERATIONS {
            let target = self.project(device);
            let d = target - self.proxy;
            if d.length() < 1e-12 {
                break;
            }
            match self.sweep(set, d) {
                Some((s, n)) => {
                    self.proxy = self.proxy + d * s + n * SKIN;
                    if self.nplanes == MAX_PLANES || self.has_plane(n) {
                        break;
                    }
                    self.planes[self.nplanes] = n;
                    self.nplanes += 1;
                }
                None => {
                    self.proxy = target;
                    break;
                }
            }
        }
        // Contact: the proxy rests on the surface and the device is behind it. The anchor stays
        // on its triangle while the proxy still rests on it (within `STICK`): a proxy held by
        // two faces at once (in a dimple its push has made) would otherwise hand the anchor
        // back and forth between them, and the tissue's load with it, every frame.
        let previous = self.anchor.take();
        let r = self.radius;
        let pushing = |offset: DVec3| (device - self.proxy).dot(offset) < 0.0;
        if let Some(prev) = previous {
            if prev.triangle < set.triangles().len() {
                let (w, offset) = off_set_triangle(set, prev.triangle, self.proxy);
                let outside = offset.dot(set.normal_of_v(prev.triangle)) > 0.0;
                if outside && offset.length() <= r + STICK && pushing(offset) {
                    self.anchor = Some(Anchor {
                        bary: w,
                        offset: offset.to_array(),
                        ..prev
                    });
                    return self.state(device, false);
                }
            }
        }
        if let Some(c) = set.closest(self.proxy.to_array(), r + 4.0 * SKIN) {
            let offset = self.proxy - v(c.hit.point);
            if !c.hit.inside && pushing(offset) && (device - self.proxy).length() > 0.0 {
                self.anchor = Some(Anchor {
                    body: c.body,
                    triangle: c.hit.triangle,
                    bary: c.hit.barycentric,
                    offset: offset.to_array(),
                });
            }
        }
        self.state(device, false)
    }

    /// A proxy that starts with the device inside a body (the haptic loop started, or started
    /// again after a crash or a stop, with the stylus held in the tissue) starts on the surface:
    /// at the surface point closest to the device, one radius outside, resting there. The
    /// force then renders that surface from the first tick (the safety ramps it in from zero)
    /// and eases off as the stylus comes out. Started where the device is instead, the proxy
    /// would feel nothing inside and pass out through the one-sided faces; as the stylus left,
    /// the first face it met from outside would be felt all at once.
    ///
    /// Inside means behind the closest point's surface ([`SurfaceSet::behind`]), among the
    /// bodies whose box holds the device. With the grab button held, that surface point is
    /// grabbed at once, as on any touch made with the button held (a grab needs contact and the
    /// button, not a press of it). Allocation-free.
    fn start_on_surface(&mut self, set: &mut SurfaceSet, device: DVec3) {
        let p = device.to_array();
        let mut best: Option<Closest> = None;
        for b in 0..set.bodies() {
            if !set.near_body(b, p, 0.0) {
                continue;
            }
            if let Some(c) = set.closest_in_body(b, p, f64::INFINITY) {
                if set.behind(p, &c) && best.is_none_or(|bc| c.hit.distance < bc.hit.distance) {
                    best = Some(c);
                }
            }
        }
        let Some(c) = best else {
            return;
        };
        let q = v(c.hit.point);
        let out = if c.hit.distance > 1e-12 {
            (q - device) * (1.0 / c.hit.distance)
        } else {
            v(c.hit.normal)
        };
        if !out.is_finite() || out == DVec3::ZERO {
            return;
        }
        self.proxy = q + out * (self.radius + SKIN);
        self.anchor = Some(Anchor {
            body: c.body,
            triangle: c.hit.triangle,
            bary: c.hit.barycentric,
            offset: (self.proxy - q).to_array(),
        });
    }

    fn state(&self, device: DVec3, grabbing: bool) -> GodState {
        let anchor = if grabbing { self.grab } else { self.anchor };
        let gap = self.proxy - device;
        let depth = gap.length();
        let touching = anchor.is_some() && depth > 0.0 && depth.is_finite();
        GodState {
            proxy: self.proxy.to_array(),
            anchor,
            grabbing,
            depth: if touching { depth } else { 0.0 },
            direction: if touching {
                (gap * (1.0 / depth)).to_array()
            } else {
                [0.0; 3]
            },
        }
    }

    /// Pushes the proxy out of triangles that moved into it (the surface deforms between
    /// frames). A proxy whose centre ended up behind the surface is left alone: it passes out
    /// freely (faces are one-sided) rather than being thrown through the tissue.
    fn depenetrate(&mut self, set: &mut SurfaceSet) {
        let r = self.radius;
        for _ in 0..3 {
            let Some(c) = set.closest(self.proxy.to_array(), r) else {
                return;
            };
            if c.hit.inside || c.hit.distance >= r {
                return;
            }
            let point = v(c.hit.point);
            let out = if c.hit.distance > 1e-12 {
                (self.proxy - point) * (1.0 / c.hit.distance)
            } else {
                v(c.hit.normal)
            };
            self.proxy = point + out * (r + SKIN);
        }
    }

    fn has_plane(&self, n: DVec3) -> bool {
        self.planes[..self.nplanes]
            .iter()
            .any(|p| p.dot(n) > 0.9999)
    }

    /// The planes of the surface the proxy rests on that the device pushes into.
    fn gather_planes(&mut self, set: &mut SurfaceSet, device: DVec3) {
        self.nplanes = 0;
        let r = self.radius;
        let reach = r + 4.0 * SKIN;
        let p = self.proxy;
        self.candidates.clear();
        let cands = &mut self.candidates;
        set.triangles_near_v(p, reach, |t| {
            if cands.len() < cands.capacity() {
                cands.push(t as u32);
            }
        });
        let goal = device - p;
        for i in 0..self.candidates.len() {
            let t = self.candidates[i] as usize;
            let (_, off) = off_set_triangle(set, t, p);
            let l = off.length();
            if !(l > 1e-12) || l > reach || off.dot(set.normal_of_v(t)) < 0.0 {
                continue;
            }
            let n = off * (1.0 / l);
            if goal.dot(n) < 0.0 && !self.has_plane(n) && self.nplanes < MAX_PLANES {
                self.planes[self.nplanes] = n;
                self.nplanes += 1;
            }
        }
    }

    /// The device projected onto the active planes (all through the proxy).
    fn project(&self, device: DVec3) -> DVec3 {
        let g = device - self.proxy;
        match self.nplanes {
            0 => device,
            1 => {
                let n = self.planes[0];
                let gn = g.dot(n);
                if gn >= 0.0 {
                    device
                } else {
                    device - n * gn
                }
            }
            2 => {
                // Leave a plane if moving along the other one's projection leaves it.
                for k in 0..2 {
                    let (n, m) = (self.planes[k], self.planes[1 - k]);
                    let t = g - n * g.dot(n).min(0.0);
                    if t.dot(m) >= 0.0 {
                        return self.proxy + t;
                    }
                }
                let u = crease(self.planes[0], self.planes[1]);
                self.proxy + u * g.dot(u)
            }
            _ => self.proxy,
        }
    }

    /// The first contact of the proxy sphere moving by `d`: fraction and contact normal.
    fn sweep(&mut self, set: &mut SurfaceSet, d: DVec3) -> Option<(f64, DVec3)> {
        let r = self.radius + 2.0 * SKIN;
        let p = self.proxy;
        // Every triangle the swept sphere can meet lies within the sphere around the sweep.
        let centre = p + d * 0.5;
        let bound = d.length() * 0.5 + r;
        self.candidates.clear();
        let cands = &mut self.candidates;
        set.triangles_near_v(centre, bound, |t| {
            if cands.len() < cands.capacity() {
                cands.push(t as u32);
            }
        });
        let len = d.length();
        let mut best: Option<(f64, DVec3)> = None;
        for &t in &self.candidates {
            let corners = set.corners_v(t as usize);
            // Faces are one-sided: a proxy whose centre is behind a face's plane (it went
            // through the tissue while the surface lagged the hand) passes out through it.
            let [a, b, c] = corners;
            if (p - a).dot((b - a).cross(c - a)) < 0.0 {
                continue;
            }
            if let Some((s, normal)) = sweep(p, d, self.radius, corners) {
                // Sliding along a plane already in contact is not an impact.
                if d.dot(normal) > -1e-9 * len {
                    continue;
                }
                if best.is_none_or(|(bs, _)| s < bs) {
                    best = Some((s, normal));
                }
            }
        }
        best
    }
}

/// The force law between proxy and device: magnitude at depth `d` (m), N.
pub fn law_magnitude(law: ForceLaw, stiffness: f64, d: f64) -> f64 {
    if !(d > 0.0) {
        return 0.0;
    }
    match law {
        ForceLaw::Linear => stiffness * d,
        ForceLaw::Quadratic => stiffness * d * d,
    }
}

/// The force on the hand for a god-object state: the law along device → proxy, plus damping
/// `−b (v · u) u` on the device velocity `v` (m/s) along that direction. While pressing (not
/// grabbing) the damped force never pulls the hand into the tissue. Finite for finite input;
/// zero without contact. The caller clamps to the device's limits.
pub fn hand_force(
    state: &GodState,
    law: ForceLaw,
    stiffness: f64,
    damping: f64,
    velocity: [f64; 3],
) -> [f64; 3] {
    if state.anchor.is_none() || !(state.depth > 0.0) {
        return [0.0; 3];
    }
    let u = state.direction;
    let mut f = law_magnitude(law, stiffness, state.depth);
    if damping > 0.0 && velocity.iter().all(|c| c.is_finite()) {
        f -= damping * v(velocity).dot(v(u));
    }
    if !state.grabbing {
        f = f.max(0.0);
    }
    let out = v(u) * f;
    if out.is_finite() {
        out.to_array()
    } else {
        [0.0; 3]
    }
}
