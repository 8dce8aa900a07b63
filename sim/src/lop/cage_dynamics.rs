//! The cage's dynamics, one per [`CageDynamics`] variant, each with its own constructor and
//! step: the reduced implicit model in cage-vertex displacements ([`CageDynamics::Projected`]
//! and [`CageDynamics::Galerkin`], which differ only in the stiffness they project) and the
//! thesis' mass-spring system on the cage vertices ([`CageDynamics::MassSpring`]). [`CageModel`]
//! (`cage_model.rs`) owns one and maps the body's loads to it and its cage back to the nodes.
//!
//! [`CageDynamics`]: super::CageDynamics
//! [`CageDynamics::Projected`]: super::CageDynamics::Projected
//! [`CageDynamics::Galerkin`]: super::CageDynamics::Galerkin
//! [`CageDynamics::MassSpring`]: super::CageDynamics::MassSpring
//! [`CageModel`]: super::CageModel

use crate::solve::dense::spd_solve_in_place;
use nalgebra::{Cholesky, DMatrix, DMatrixView, DVector, DVectorViewMut, Dyn};

use crate::gc::{Cage, GcBinding};
use crate::interaction::{BlowUp, ContactReport, ContactSpring, Touch};
use crate::mesh::TetMesh;
use crate::msd::{Integrator, MassSpring, MsdParameters, NodeMass};
use crate::patch::{self, PatchSolve, ToolPatch};
use crate::vec3::{add, dot, scale};

use super::cage_model::{CageModelError, Damping, PreciseOperators};
use super::compliance::matched_stiffness;
use super::kernel::gemv_acc;

/// Cage dynamics state: [`Reduced`] for the projected and Galerkin cages, a mass-spring
/// system for the thesis' one.
#[derive(Debug, Clone)]
pub(super) enum Dynamics {
    Projected(Box<Reduced>),
    MassSpring(Box<MassSpring>),
}

/// The reduced (Galerkin) model in cage-vertex displacements `q` (3V).
///
/// Implicit scheme of eq. 4.20 on `M_r q̈ + D_r q̇ + K_r q = f_r`, in increment form like the FEM
/// (`K̃ d = f_r − K_r q + (M_r/Δt − D_r/2) q̇`), with everything that does not change folded
/// into dense matrices at set-up: `d = A⁻¹f_r − P q + Q q̇`.
#[derive(Debug, Clone)]
pub(super) struct Reduced {
    /// `A⁻¹ = K̃⁻¹`, column-major 3V × 3V.
    pub(super) a_inv: Vec<f64>,
    /// `[−A⁻¹K_r | A⁻¹(M_r/Δt − D_r/2)]`, column-major 3V × 6V: the step's response to the
    /// state.
    pub(super) response: Vec<f64>,
    /// `A⁻¹ Gᵀ M 1_a` for gravity along axis `a`, column-major 3V × 3.
    pub(super) gravity: Vec<f64>,
    /// `[q; q̇]`.
    pub(super) state: Vec<f64>,
    /// Static correction `A⁻¹(K_r q* − f_g)` added to every increment after a hand-over, so
    /// that the shape `q*` the cage took over under gravity `g` is its equilibrium (it would
    /// otherwise drift to its own, slightly different one). `None` until the first step after
    /// a hand-over computes it; zero from rest.
    pub(super) correction: Vec<f64>,
    /// The correction from rest: zero, or the prestressed equilibrium's (see
    /// [`CageModel::from_precise_under`](super::CageModel::from_precise_under)).
    pub(super) rest_correction: Vec<f64>,
    pub(super) correction_due: bool,
    /// The step's increment `d`, scratch.
    pub(super) d: Vec<f64>,
    /// `A = K̃_r`, column-major 3V × 3V, for steps with contact springs.
    pub(super) a: Vec<f64>,
    /// Scratch for contact springs: `A + Σ k c cᵀ` and its Cholesky factor (in place), one
    /// spring's `c = Gᵀ (w ⊗ n)`, and the right-hand side.
    pub(super) sys: Vec<f64>,
    pub(super) c: Vec<f64>,
    pub(super) rhs: Vec<f64>,
    /// The tool's `c`, kept to report the force it left.
    pub(super) c_tool: Vec<f64>,
    /// The tool's contact patch (`patch_correct`), in the cage's 3V unknowns.
    pub(super) patch: PatchSolve,
}

impl Reduced {
    pub(super) fn q(&self) -> &[f64] {
        &self.state[..self.d.len()]
    }
}

/// What every cage dynamics is built from: the body and its projection onto the cage.
pub(super) struct CageBasis<'a> {
    /// The body (rest shape, fixed nodes).
    pub mesh: &'a TetMesh,
    /// Nodes that never move (fixed, or held by the precise model).
    pub held: &'a [bool],
    /// `G = ∂x/∂q` at rest (3N × 3V), zero rows on held nodes.
    pub jacobian: &'a DMatrix<f64>,
    /// `M G`.
    pub mg: &'a DMatrix<f64>,
    /// `M_r = Gᵀ M G`, and its Cholesky factor.
    pub m_r: &'a DMatrix<f64>,
    pub fit: &'a Cholesky<f64, Dyn>,
}

/// A step's loads as the cage dynamics receive them.
pub(super) struct StepLoads<'a> {
    /// Gravity, m/s².
    pub gravity: [f64; 3],
    /// Nodal loads, N (missing entries count as zero).
    pub external: &'a [[f64; 3]],
    /// The tool on the current shape, if it touches.
    pub touch: Option<&'a Touch>,
    /// Organ-to-organ contact springs.
    pub springs: &'a [ContactSpring],
    /// Whether any external load or the tool's `touch` acts.
    pub has_loads: bool,
    /// The god-object's press as a contact patch (projected dynamics; `touch` is then `None`).
    pub patch: Option<ToolPatch<'a>>,
}

impl Reduced {
    /// `CageDynamics::Projected`: the reduced model with the stiffness matched to the body's
    /// compliance (about the prestressed equilibrium if `ops` has one).
    pub(super) fn projected(
        basis: &CageBasis<'_>,
        ops: &PreciseOperators<'_>,
        dt: f64,
    ) -> Result<Reduced, CageModelError> {
        Reduced::new(basis, ops, dt, true)
    }

    /// `CageDynamics::Galerkin`: the reduced model with the projected stiffness `GᵀKG`.
    pub(super) fn galerkin(
        basis: &CageBasis<'_>,
        ops: &PreciseOperators<'_>,
        dt: f64,
    ) -> Result<Reduced, CageModelError> {
        Reduced::new(basis, ops, dt, false)
    }

    /// The reduced model: `K_r = GᵀKG` (or, `matched_to_body`, the stiffness matched to the
    /// body's compliance), mass and damping projected, everything constant folded into dense
    /// matrices.
    fn new(
        basis: &CageBasis<'_>,
        ops: &PreciseOperators<'_>,
        dt: f64,
        matched_to_body: bool,
    ) -> Result<Reduced, CageModelError> {
        let CageBasis {
            mesh,
            held,
            jacobian,
            mg,
            m_r,
            fit,
        } = *basis;
        let n = mesh.nodes.len();
        let m = jacobian.ncols();
        // K G, column by column, through the precise model.
        let mut kg = DMatrix::zeros(3 * n, m);
        let mut u = vec![[0.0; 3]; n];
        for c in 0..m {
            let col = jacobian.column(c);
            for k in 0..n {
                u[k] = [col[3 * k], col[3 * k + 1], col[3 * k + 2]];
            }
            let f = (ops.stiffness)(&u);
            let mut out = kg.column_mut(c);
            for k in 0..n {
                if held[k] {
                    continue;
                }
                for b in 0..3 {
                    out[3 * k + b] = f[k][b];
                }
            }
        }
        let mut k_r = jacobian.transpose() * kg;
        k_r = (&k_r + k_r.transpose()) * 0.5;
        // The static correction a cage starting from rest carries: zero about the rest
        // shape; about a prestressed equilibrium `q_g`, `A⁻¹(K_r q_g − Gᵀ M g)`, which
        // makes `q_g` the cage's equilibrium under that gravity.
        let mut rest_load: Option<DVector<f64>> = None;
        if matched_to_body {
            let mut matched = None;
            if let Some(pre) = &ops.prestress {
                matched = matched_stiffness(mesh, held, pre.tangent, mg, m_r, 1e-6)?;
                if let Some(k_t) = &matched {
                    // q_g: the mass-weighted fit of the equilibrium.
                    let mut mu = DVector::zeros(3 * n);
                    for k in (0..n).filter(|&k| !held[k]) {
                        for b in 0..3 {
                            mu[3 * k + b] = ops.masses[k] * pre.displacement[k][b];
                        }
                    }
                    let q_g = fit.solve(&(jacobian.transpose() * mu));
                    let mut f_g = DVector::zeros(m);
                    for c in 0..m {
                        let col = mg.column(c);
                        f_g[c] = (0..n)
                            .map(|k| (0..3).map(|a| col[3 * k + a] * pre.gravity[a]).sum::<f64>())
                            .sum::<f64>();
                    }
                    rest_load = Some(k_t * q_g - f_g);
                }
            }
            if matched.is_none() {
                matched = matched_stiffness(mesh, held, ops.stiffness, mg, m_r, 1e-9)?;
            }
            if let Some(matched) = matched {
                k_r = matched;
            }
        }
        let d_r = match ops.damping {
            Damping::MassProportional(alpha) => m_r * alpha,
            Damping::PerNode(gamma) => jacobian.transpose() * jacobian * gamma,
        };
        let a = m_r / (dt * dt) + &d_r / (2.0 * dt) + &k_r;
        let a_dense = a.as_slice().to_vec();
        let a_inv = Cholesky::new(a).ok_or(CageModelError::Singular)?.inverse();
        let p = &a_inv * &k_r;
        let q_mat = &a_inv * (m_r / dt - &d_r * 0.5);
        let mut response = (-p).as_slice().to_vec();
        response.extend_from_slice(q_mat.as_slice());
        // Gᵀ M 1_a: the generalised gravity load per unit acceleration along axis a.
        let mut g1 = DMatrix::zeros(m, 3);
        for a in 0..3 {
            for c in 0..m {
                let col = mg.column(c);
                g1[(c, a)] = (0..n).map(|k| col[3 * k + a]).sum::<f64>();
            }
        }
        let gravity = &a_inv * g1;
        let rest_correction = match rest_load {
            Some(b) => (&a_inv * b).as_slice().to_vec(),
            None => vec![0.0; m],
        };
        Ok(Reduced {
            a_inv: a_inv.as_slice().to_vec(),
            response,
            gravity: gravity.as_slice().to_vec(),
            state: vec![0.0; 2 * m],
            correction: rest_correction.clone(),
            rest_correction,
            correction_due: false,
            d: vec![0.0; m],
            a: a_dense,
            sys: vec![0.0; m * m],
            c: vec![0.0; m],
            rhs: vec![0.0; m],
            c_tool: vec![0.0; m],
            patch: PatchSolve::new(m),
        })
    }

    /// One step of the reduced model: `d = A⁻¹f_r − P q + Q q̇` (plus gravity and the static
    /// correction), with the tool's push and the contact springs solved implicitly when they
    /// act; then `q += d`, `q̇ = d/Δt`. `load_r` is scratch (3N → 3V), `x` the current positions.
    /// Returns what the tool did if it was resolved implicitly. Allocation-free.
    pub(super) fn step(
        &mut self,
        loads: &StepLoads<'_>,
        dt: f64,
        x: &[[f64; 3]],
        jacobian_t: &DMatrix<f64>,
        load_r: &mut DVector<f64>,
    ) -> Option<ContactReport> {
        let r = self;
        let (gravity, external, springs) = (loads.gravity, loads.external, loads.springs);
        let touch = loads.touch;
        let n = x.len();
        let mut report = None;
        // The tool's push along its normal joins the implicit solve (linearised like a
        // contact spring: `F + k'·(depth change)`), as in the precise models: a cage
        // as soft as its body would ring or blow up under an explicit 300 N/m tool.
        let implicit_tool = touch.and_then(Touch::as_spring);
        let explicit_touch = if implicit_tool.is_some() { None } else { touch };
        // f_r = Gᵀ f over the loaded nodes only (gravity is folded in at set-up).
        if loads.has_loads {
            load_r.fill(0.0);
            let jt = jacobian_t;
            let mut add_load = |k: usize, f: [f64; 3]| {
                for (b, fb) in f.iter().enumerate() {
                    if *fb != 0.0 {
                        load_r.axpy(*fb, &jt.column(3 * k + b), 1.0);
                    }
                }
            };
            each_load(external, n, explicit_touch, &mut add_load);
        }
        r.d.fill(0.0);
        if loads.has_loads {
            gemv_acc(&r.a_inv, load_r.as_slice(), &mut r.d);
        }
        if r.correction_due {
            // A⁻¹(K_r q* − f_g) = −(response_q · q*) − A⁻¹ f_g.
            let m = r.d.len();
            r.correction.fill(0.0);
            gemv_acc(&r.response[..m * m], &r.state[..m], &mut r.correction);
            gemv_acc(&r.gravity, &gravity, &mut r.correction);
            r.correction.iter_mut().for_each(|c| *c = -*c);
            r.correction_due = false;
        }
        gemv_acc(&r.gravity, &gravity, &mut r.d);
        gemv_acc(&r.response, &r.state, &mut r.d);
        r.d.iter_mut().zip(&r.correction).for_each(|(d, c)| *d += c);
        let mut factored = false;
        if implicit_tool.is_some() || springs.iter().any(|sp| sp.touch(x).is_some()) {
            let resolved = resolve_springs(r, jacobian_t, x, springs, implicit_tool.as_ref());
            factored = resolved.is_some();
            if let (Some(t), Some(gap), Some(orig)) = (&implicit_tool, resolved.flatten(), touch) {
                // The force the step applied and the depth it left.
                let g = gap.max(0.0);
                report = Some(ContactReport {
                    force_on_tissue: scale(t.normal, t.stiffness * g),
                    depth: (orig.depth - (t.depth - gap)).max(0.0),
                    proxy: None,
                    response: None,
                });
            }
        }
        if let Some(p) = &loads.patch {
            report = Some(patch_correct(r, p, x, jacobian_t, factored));
        }
        let m = r.d.len();
        let (q, qd) = r.state.split_at_mut(m);
        for ((q, qd), d) in q.iter_mut().zip(qd).zip(&r.d) {
            *q += d;
            *qd = d / dt;
        }
        report
    }
}

/// One step of the thesis' mass-spring cage: every load (and each pushing contact spring's
/// force at the start of the step) goes to the cage vertices by the node's φ weights,
/// explicitly; then the cage's own step. `cage_loads` is scratch (one per cage vertex).
pub(super) fn step_mass_spring(
    msd: &mut MassSpring,
    loads: &StepLoads<'_>,
    binding: &GcBinding,
    x: &[[f64; 3]],
    cage_loads: &mut [[f64; 3]],
) -> Result<(), BlowUp> {
    let (external, springs) = (loads.external, loads.springs);
    let n = x.len();
    // Each load goes to the cage vertices by the node's φ weights (thesis §6.3.4.1).
    cage_loads.iter_mut().for_each(|f| *f = [0.0; 3]);
    if loads.has_loads {
        let mut add_load = |k: usize, f: [f64; 3]| {
            for (i, load) in cage_loads.iter_mut().enumerate() {
                let w = binding.phi(k, i);
                *load = add(*load, scale(f, w));
            }
        };
        each_load(external, n, loads.touch, &mut add_load);
    }
    for sp in springs {
        if let Some(t) = sp.touch(x) {
            for (j, &node) in t.tri.iter().enumerate() {
                let f = scale(t.on_tissue, t.weights[j]);
                for (i, load) in cage_loads.iter_mut().enumerate() {
                    *load = add(*load, scale(f, binding.phi(node as usize, i)));
                }
            }
        }
    }
    msd.step(loads.gravity, cage_loads, None)?;
    Ok(())
}

/// `CageDynamics::MassSpring`: a mass-spring system on the cage's vertices, every pair of
/// them a spring, the cage's volume times `density` shared equally by the vertices.
pub(super) fn mass_spring_cage(
    mesh: &TetMesh,
    cage: &Cage,
    binding: &GcBinding,
    stiffness: f64,
    density: f64,
    damping: f64,
    dt: f64,
) -> MassSpring {
    let nv = cage.vertices.len();
    let volume = cage_volume(cage);
    let node_mass = density * volume / nv as f64;
    // Every pair of cage vertices is a spring: a cage's triangle edges alone are a
    // shell that folds flat at no cost; the complete graph holds its volume.
    let mut springs = Vec::new();
    for a in 0..nv as u32 {
        for b in a + 1..nv as u32 {
            springs.push([a, b]);
        }
    }
    // A cage vertex is fixed when it carries the largest weight of some fixed node.
    let mut fixed = Vec::new();
    for &f in &mesh.fixed {
        let k = f as usize;
        let best = (0..nv)
            .max_by(|&i, &j| binding.phi(k, i).total_cmp(&binding.phi(k, j)))
            .unwrap_or(0) as u32;
        fixed.push(best);
    }
    fixed.sort_unstable();
    fixed.dedup();
    MassSpring::from_springs(
        cage.vertices.clone(),
        &springs,
        &fixed,
        MsdParameters {
            stiffness,
            mass: NodeMass::PerNode(node_mass),
            damping,
            dt,
            integrator: Integrator::ImplicitEuler,
        },
    )
}

/// Adds the contact springs (and the tool, in the same spring form) to the reduced step: with
/// `d₀` (in `r.d`) the increment without them, the increment with them solves
/// `(A + Σ k c cᵀ) d = A d₀ + Σ c k g`, `g` each spring's gap at the start of the step and
/// `c = Gᵀ (w ⊗ n)`; i.e. `d = d₀ + Δ` with `(A + Σ k c cᵀ) Δ = Σ c k (g − cᵀ d₀)`.
/// Allocation-free; leaves `d₀` and returns `None` if the matrix cannot be factorised
/// (non-finite input). Otherwise `r.sys` holds the Cholesky factor of `A + Σ k c cᵀ` (lower
/// triangle) and the result is the tool's gap at the end of the step (`g − cᵀ d`), if it was
/// given.
fn resolve_springs(
    r: &mut Reduced,
    jacobian_t: &DMatrix<f64>,
    x: &[[f64; 3]],
    springs: &[ContactSpring],
    tool: Option<&Touch>,
) -> Option<Option<f64>> {
    let m = r.d.len();
    r.sys.copy_from_slice(&r.a);
    r.rhs.fill(0.0);
    let touches = tool
        .copied()
        .into_iter()
        .chain(springs.iter().filter_map(|sp| sp.touch(x)));
    for (i, t) in touches.enumerate() {
        r.c.fill(0.0);
        for (p, &node) in t.tri.iter().enumerate() {
            if t.weights[p] == 0.0 {
                continue;
            }
            for b in 0..3 {
                let s = t.weights[p] * t.normal[b];
                if s != 0.0 {
                    let col = jacobian_t.column(3 * node as usize + b);
                    r.c.iter_mut()
                        .zip(col.iter())
                        .for_each(|(c, g)| *c += s * g);
                }
            }
        }
        if i == 0 && tool.is_some() {
            r.c_tool.copy_from_slice(&r.c);
        }
        let gap = t.depth - r.c.iter().zip(&r.d).map(|(c, d)| c * d).sum::<f64>();
        for j in 0..m {
            r.rhs[j] += t.stiffness * gap * r.c[j];
            let kc = t.stiffness * r.c[j];
            if kc != 0.0 {
                for i in 0..m {
                    r.sys[j * m + i] += kc * r.c[i];
                }
            }
        }
    }
    if !spd_solve_in_place(&mut r.sys, m, &mut r.rhs) {
        return None;
    }
    r.d.iter_mut()
        .zip(&r.rhs)
        .for_each(|(d, delta)| *d += delta);
    Some(tool.map(|t| t.depth - r.c_tool.iter().zip(&r.d).map(|(c, d)| c * d).sum::<f64>()))
}

/// The tool's contact patch (see [`crate::patch`]) on the reduced step: with `d` (in `r.d`) the
/// increment without it, a point's position after the step is linearised as `x + G d` (`G` the
/// cage's Jacobian at rest, as the contact springs take it), so its gap is linear in the
/// points' forces through the step's compliance: `w = q + (Cᵀ K̃⁻¹ C + Nᵀ N / k) λ`, with
/// `c_j = Gᵀ (n_j` spread over the point's nodes with their weights`)` and `K̃⁻¹` the step's
/// compliance: `A⁻¹` (`a_inv`), or, when contact springs were resolved this step (`factored`), the factor
/// of `A + Σ k c cᵀ` they left in `r.sys`, so the patch's forces meet the springs' stiffness
/// as one linear system would. (Right after a hand-over the displayed `x` carries the fading
/// offset, whose fade over the step, at most `residual · dt / blend`, the prediction leaves
/// out.) Adds `K̃⁻¹ C λ` to `d`; a patch that cannot be solved
/// (non-finite data) applies no force. Allocation-free once the columns have grown to the
/// largest patch.
fn patch_correct(
    r: &mut Reduced,
    patch: &ToolPatch<'_>,
    x: &[[f64; 3]],
    jacobian_t: &DMatrix<f64>,
    factored: bool,
) -> ContactReport {
    // The cage resolves presses only: a grabbed body runs its precise model (`crate::grasp`).
    let presses = crate::patch::ToolPatch {
        holds: &[],
        ..*patch
    };
    let Some(patch) = PatchSolve::limit(&presses) else {
        return ContactReport::default();
    };
    let Reduced {
        a_inv,
        d,
        sys,
        rhs,
        patch: solve,
        ..
    } = r;
    let (a_inv, sys): (&[f64], &[f64]) = (a_inv, sys);
    let m = d.len();
    let dofs = jacobian_t.ncols();
    // Node k's three columns of `Gᵀ`, if it is a node of the body.
    let node_cols = |k: u32| Some(3 * k as usize).filter(|&c| c + 2 < dofs);
    solve.begin(&patch, |k| match (x.get(k as usize), node_cols(k)) {
        (Some(&xk), Some(c)) => {
            let mut p = xk;
            for (b, pb) in p.iter_mut().enumerate() {
                let g = jacobian_t.column(c + b);
                *pb += g.iter().zip(d.iter()).map(|(g, d)| g * d).sum::<f64>();
            }
            p
        }
        _ => [f64::NAN; 3],
    });
    let points = patch.points;
    let column = |j: usize, out: &mut [f64]| {
        let p = &points[j];
        for (&k, &w) in p.nodes.iter().zip(&p.weights) {
            let Some(c) = node_cols(k).filter(|_| w != 0.0) else {
                continue;
            };
            for b in 0..3 {
                let s = w * p.normal[b];
                if s != 0.0 {
                    let g = jacobian_t.column(c + b);
                    out.iter_mut().zip(g.iter()).for_each(|(o, g)| *o += s * g);
                }
            }
        }
    };
    solve.matrix_by_columns(points.len(), column, 1.0, |b, _| {
        for col in b.chunks_exact_mut(m) {
            if factored {
                let l = DMatrixView::from_slice(sys, m, m);
                let mut z = DVectorViewMut::from_slice(col, m);
                l.solve_lower_triangular_mut(&mut z);
                l.tr_solve_lower_triangular_mut(&mut z);
            } else {
                rhs.fill(0.0);
                gemv_acc(a_inv, col, &mut rhs[..]);
                col.copy_from_slice(&rhs[..]);
            }
        }
    });
    if !(solve.solve(&patch) && solve.correction_by_solves(1.0)) {
        return ContactReport::default();
    }
    d.iter_mut()
        .zip(&solve.correction)
        .for_each(|(d, c)| *d += c);
    patch::report(&patch, &mut solve.lcp, 0)
}

/// Calls `add` with every non-zero nodal load: the first `n` of `external`, then the tool's
/// force spread on the touched triangle's nodes by its barycentric weights.
fn each_load(
    external: &[[f64; 3]],
    n: usize,
    touch: Option<&Touch>,
    add: &mut impl FnMut(usize, [f64; 3]),
) {
    for (k, f) in external.iter().enumerate().take(n) {
        if *f != [0.0; 3] {
            add(k, *f);
        }
    }
    if let Some(t) = touch {
        for (j, &node) in t.tri.iter().enumerate() {
            add(node as usize, scale(t.on_tissue, t.weights[j]));
        }
    }
}

/// Volume enclosed by an outward cage (divergence theorem).
fn cage_volume(c: &Cage) -> f64 {
    c.triangles
        .iter()
        .map(|t| {
            let (a, b, d) = (c.vertices[t[0]], c.vertices[t[1]], c.vertices[t[2]]);
            dot(a, crate::vec3::cross(b, d)) / 6.0
        })
        .sum()
}
