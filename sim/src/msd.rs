//! Mass-spring-damper model (thesis §4.1, eq. 4.2): springs on tetrahedron edges, lumped nodal
//! masses, viscous damping per node, fixed nodes, gravity and external nodal loads.
//!
//! Integration here is symplectic (semi-implicit) Euler with automatic sub-stepping: a body
//! advances by its configured `dt`, split into as many equal sub-steps as the explicit stability
//! bound requires, so a scene's thesis time step (often far above that bound for light, stiff
//! meshes) never makes the body explode. The remaining integrators of thesis ch. 3 extend this
//! type in the deformation-models work.
//!
//! Stability bound used: for symplectic Euler on `M ẍ = −K x − γ ẋ`, a sub-step `h` is stable
//! when `h ω_max < 2` and `h γ/m < 2`. `ω_max² ≤ max_i 4 Σ_j k_ij / m_i` (Gershgorin on
//! `M⁻¹K`, each spring contributing at most `2k` to a row in any direction, twice over), and we
//! keep a safety factor of 2 below both limits.
//!
//! The tool's penalty spring is far stiffer than the tissue's springs on light nodes (300 N/m on
//! milligram nodes), so it is not part of that bound: its normal component is integrated
//! implicitly (linearised backward Euler along the contact normal, per node), which is stable for
//! any stiffness, while everything else stays explicit.

use crate::contact::{add, closest_on_surface, dot, norm, scale, sub, SurfaceHit};
use crate::mesh::TetMesh;
use crate::model::{BlowUp, ContactReport, ToolContact, RUNAWAY_SPEED};

/// Parameters of a mass-spring body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MsdParameters {
    /// Spring stiffness, N/m (every edge the same, as in the thesis).
    pub stiffness: f64,
    /// How nodal masses are found.
    pub mass: NodeMass,
    /// Viscous damping γ per node, N·s/m (eq. 4.2).
    pub damping: f64,
    /// Time step the body advances by per step, s.
    pub dt: f64,
}

/// Nodal masses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NodeMass {
    /// Lumped from density (kg/m³): each tetrahedron gives a quarter of its mass to each node.
    Density(f64),
    /// Every node has this mass, kg (thesis ch. 3).
    PerNode(f64),
}

#[derive(Debug, Clone, Copy)]
struct Spring {
    a: u32,
    b: u32,
    rest: f64,
}

/// A mass-spring body.
#[derive(Debug, Clone)]
pub struct MassSpring {
    params: MsdParameters,
    springs: Vec<Spring>,
    mass: Vec<f64>,
    /// 0 for fixed nodes, so the integrator never moves them.
    inv_mass: Vec<f64>,
    rest: Vec<[f64; 3]>,
    x: Vec<[f64; 3]>,
    v: Vec<[f64; 3]>,
    /// Scratch: filled by `accumulate_forces`, read by the integrator.
    force: Vec<[f64; 3]>,
    substeps: usize,
}

impl MassSpring {
    /// Builds the model on `mesh` (rest shape = the mesh's nodes; fixed = `mesh.fixed`).
    pub fn new(mesh: &TetMesh, params: MsdParameters) -> MassSpring {
        let n = mesh.nodes.len();
        let mut mass = vec![0.0; n];
        match params.mass {
            NodeMass::PerNode(m) => mass.iter_mut().for_each(|x| *x = m),
            NodeMass::Density(rho) => {
                for (i, t) in mesh.tets.iter().enumerate() {
                    let share = rho * mesh.tet_volume(i) / 4.0;
                    for &k in t {
                        mass[k as usize] += share;
                    }
                }
            }
        }
        let mut inv_mass: Vec<f64> = mass
            .iter()
            .map(|&m| if m > 0.0 { 1.0 / m } else { 0.0 })
            .collect();
        for &f in &mesh.fixed {
            inv_mass[f as usize] = 0.0;
        }
        let springs: Vec<Spring> = mesh
            .edges()
            .into_iter()
            .map(|[a, b]| Spring {
                a,
                b,
                rest: norm(sub(mesh.nodes[b as usize], mesh.nodes[a as usize])),
            })
            .collect();
        let substeps = stable_substeps(&params, &springs, &inv_mass);
        MassSpring {
            params,
            springs,
            mass,
            inv_mass,
            rest: mesh.nodes.clone(),
            x: mesh.nodes.clone(),
            v: vec![[0.0; 3]; n],
            force: vec![[0.0; 3]; n],
            substeps,
        }
    }

    /// Node positions, m.
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.x
    }
    /// Node velocities, m/s.
    pub fn velocities(&self) -> &[[f64; 3]] {
        &self.v
    }
    /// Nodal masses, kg.
    pub fn masses(&self) -> &[f64] {
        &self.mass
    }
    /// The body's time step, s.
    pub fn dt(&self) -> f64 {
        self.params.dt
    }
    /// Sub-steps per step that the stability bound requires.
    pub fn substeps(&self) -> usize {
        self.substeps
    }
    /// Springs (edges).
    pub fn spring_count(&self) -> usize {
        self.springs.len()
    }

    /// Kinetic energy, J.
    pub fn kinetic_energy(&self) -> f64 {
        self.v
            .iter()
            .zip(&self.mass)
            .map(|(v, m)| 0.5 * m * dot(*v, *v))
            .sum()
    }

    /// Largest nodal speed, m/s.
    pub fn max_speed(&self) -> f64 {
        self.v.iter().map(|v| norm(*v)).fold(0.0, f64::max)
    }

    /// Back to the rest shape, at rest.
    pub fn reset(&mut self) {
        self.x.copy_from_slice(&self.rest);
        self.v.iter_mut().for_each(|v| *v = [0.0; 3]);
    }

    /// Advances by `dt` under `gravity` (m/s²) and the nodal loads `external` (N, one per node).
    /// On a blow-up the body is reset to rest and the cause returned; nothing non-finite ever
    /// stays in the state. Allocation-free.
    pub fn step(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
        contact: Option<&ToolContact<'_>>,
    ) -> Result<ContactReport, BlowUp> {
        let h = self.params.dt / self.substeps as f64;
        let mut report = ContactReport::default();
        for _ in 0..self.substeps {
            self.accumulate_forces(gravity, external);
            if let Some(c) = contact {
                report = self.apply_contact(c, h);
            }
            for i in 0..self.x.len() {
                let w = self.inv_mass[i];
                if w == 0.0 {
                    continue;
                }
                let f = sub(self.force[i], scale(self.v[i], self.params.damping));
                self.v[i] = add(self.v[i], scale(f, h * w));
                self.x[i] = add(self.x[i], scale(self.v[i], h));
            }
        }
        self.check().map(|()| report)
    }

    /// Adds the tool's penalty force on the closest candidate triangle, spread to its nodes by
    /// the barycentric weights of the contact point, and makes its normal part implicit for the
    /// sub-step `h`: with `K = w² dF/dd` the node's stiffness along the normal `n`, the normal
    /// force `f_n` (damping included) becomes `(f_n − h K v_n) / (1 + h² K / m)`, the backward-
    /// Euler value, so the stiff tool cannot destabilise the explicit step.
    fn apply_contact(&mut self, c: &ToolContact<'_>, h: f64) -> ContactReport {
        let mut best: Option<(u32, SurfaceHit)> = None;
        for &t in c.candidates {
            let Some(tri) = c.surface.get(t as usize) else {
                continue;
            };
            if let Some(hit) =
                closest_on_surface(self.x.as_slice(), std::slice::from_ref(tri), c.tool.center)
            {
                if best.is_none_or(|(_, b)| hit.distance < b.distance) {
                    best = Some((t, hit));
                }
            }
        }
        let Some((t, hit)) = best else {
            return ContactReport::default();
        };
        let depth = c.tool.depth(&hit);
        if depth <= 0.0 {
            return ContactReport::default();
        }
        let on_tissue = scale(c.tool.force_on_tool(&hit), -1.0);
        let stiffness = c.tool.max_stiffness(depth);
        let n = hit.normal;
        let tri = c.surface[t as usize];
        for k in 0..3 {
            let i = tri[k] as usize;
            let wgt = hit.barycentric[k];
            self.force[i] = add(self.force[i], scale(on_tissue, wgt));
            let inv_m = self.inv_mass[i];
            if inv_m == 0.0 {
                continue;
            }
            let kn = stiffness * wgt * wgt;
            let f_n = dot(sub(self.force[i], scale(self.v[i], self.params.damping)), n);
            let v_n = dot(self.v[i], n);
            let implicit = (f_n - h * kn * v_n) / (1.0 + h * h * kn * inv_m);
            self.force[i] = add(self.force[i], scale(n, implicit - f_n));
        }
        ContactReport {
            force_on_tissue: on_tissue,
            depth,
        }
    }

    fn accumulate_forces(&mut self, gravity: [f64; 3], external: &[[f64; 3]]) {
        for (i, f) in self.force.iter_mut().enumerate() {
            let ext = external.get(i).copied().unwrap_or([0.0; 3]);
            *f = add(scale(gravity, self.mass[i]), ext);
        }
        let k = self.params.stiffness;
        for s in &self.springs {
            let (a, b) = (s.a as usize, s.b as usize);
            let d = sub(self.x[b], self.x[a]);
            let len = norm(d);
            if len <= 0.0 {
                continue;
            }
            // Hooke's law along the spring (eq. 4.1).
            let f = scale(d, k * (len - s.rest) / len);
            self.force[a] = add(self.force[a], f);
            self.force[b] = sub(self.force[b], f);
        }
    }

    fn check(&mut self) -> Result<(), BlowUp> {
        let mut cause = None;
        for (x, v) in self.x.iter().zip(&self.v) {
            if !(x.iter().chain(v.iter()).all(|c| c.is_finite())) {
                cause = Some(BlowUp::NonFinite);
                break;
            }
            if dot(*v, *v) > RUNAWAY_SPEED * RUNAWAY_SPEED {
                cause = Some(BlowUp::Runaway);
                break;
            }
        }
        match cause {
            Some(c) => {
                self.reset();
                Err(c)
            }
            None => Ok(()),
        }
    }
}

fn stable_substeps(params: &MsdParameters, springs: &[Spring], inv_mass: &[f64]) -> usize {
    let mut ksum = vec![0.0; inv_mass.len()];
    for s in springs {
        ksum[s.a as usize] += params.stiffness;
        ksum[s.b as usize] += params.stiffness;
    }
    let mut h_max = f64::INFINITY;
    for (k, w) in ksum.iter().zip(inv_mass) {
        if *w == 0.0 {
            continue;
        }
        let omega = (4.0 * k * w).sqrt();
        if omega > 0.0 {
            h_max = h_max.min(1.0 / omega); // safety factor 2 below 2/ω
        }
        if params.damping > 0.0 {
            h_max = h_max.min(1.0 / (params.damping * w)); // 2 below 2m/γ
        }
    }
    if !h_max.is_finite() || !(params.dt > 0.0) {
        return 1;
    }
    ((params.dt / h_max).ceil() as usize).clamp(1, 100_000)
}
