//! Part 2b of `lop-bench models`: the fill-reducing orderings the FEM system can use, compared
//! on the shipped meshes and the scaling boxes. For each mesh and each ordering (AMD, geometric
//! nested dissection), a corotational body is built with that ordering forced
//! (`Fem::with_ordering`) and its single-precision factor of `K̃` at rest — the corotational
//! preconditioner — is timed: the numeric factorisation (median of a few) and one pair of
//! triangular solves (median of many). "chosen" is what `Fem::new` picks: the smaller factor.

use std::time::Instant;

use anyhow::{anyhow, Result};
use lop_sim::fem::{Fem, FemMode, FemParameters, NodeOrdering};
use lop_sim::mesh::TetMesh;
use serde::Serialize;

use super::summarize;
use crate::pipeline;
use crate::table::{table, Align};

/// One ordering on one mesh.
#[derive(Debug, Clone, Serialize)]
pub struct OrderingCost {
    /// Stored non-zeros of the Cholesky factor.
    pub factor_nnz: usize,
    /// Numeric factorisation (single precision), median, ms.
    pub factor_ms: f64,
    /// One forward and backward substitution (single precision), median, ms.
    pub solve_ms: f64,
}

/// Both orderings on one mesh.
#[derive(Debug, Clone, Serialize)]
pub struct OrderingRow {
    pub mesh: String,
    pub tets: usize,
    pub dofs: usize,
    pub amd: OrderingCost,
    pub nested_dissection: OrderingCost,
    /// What `Fem::new` chooses: "amd" or "nested-dissection".
    pub chosen: String,
}

/// Times both orderings on `mesh` with material `params`; `quick` takes fewer samples.
pub fn compare(
    name: &str,
    mesh: &TetMesh,
    params: FemParameters,
    quick: bool,
) -> Result<OrderingRow> {
    let params = FemParameters {
        mode: FemMode::Corotational,
        ..params
    };
    let (factors, solves) = if quick { (1, 3) } else { (3, 20) };
    let cost = |ordering| -> Result<(OrderingCost, usize)> {
        let mut fem = Fem::with_ordering(mesh, params, ordering)
            .map_err(|e| anyhow!("FEM on {name}: {e}"))?;
        let mut ns = Vec::new();
        for _ in 0..factors {
            let t = Instant::now();
            if !fem.refactorize_at_rest() {
                return Err(anyhow!("FEM on {name}: the factorisation failed"));
            }
            ns.push(t.elapsed().as_nanos() as u64);
            if pipeline::interrupted() {
                return Err(anyhow!("interrupted"));
            }
        }
        let factor_ms = summarize(&mut ns).0 / 1e3;
        let n = fem.dofs();
        let rhs: Vec<f64> = (0..n).map(|k| ((k % 7) as f64 - 3.0) * 1e-3).collect();
        let mut x = rhs.clone();
        ns.clear();
        for _ in 0..solves {
            x.copy_from_slice(&rhs);
            let t = Instant::now();
            fem.solve_with_factor(&mut x);
            ns.push(t.elapsed().as_nanos() as u64);
        }
        let solve_ms = summarize(&mut ns).0 / 1e3;
        Ok((
            OrderingCost {
                factor_nnz: fem.solver_info().1,
                factor_ms,
                solve_ms,
            },
            n,
        ))
    };
    let (amd, dofs) = cost(NodeOrdering::Amd)?;
    let (nested_dissection, _) = cost(NodeOrdering::NestedDissection)?;
    let chosen = Fem::new(mesh, params)
        .map_err(|e| anyhow!("FEM on {name}: {e}"))?
        .ordering();
    Ok(OrderingRow {
        mesh: name.into(),
        tets: mesh.tets.len(),
        dofs,
        amd,
        nested_dissection,
        chosen: match chosen {
            NodeOrdering::NestedDissection => "nested-dissection".into(),
            _ => "amd".into(),
        },
    })
}

pub fn render(rows: &[OrderingRow]) -> String {
    let mut s = String::from(
        "Part 2b: fill-reducing orderings of the FEM system (single-precision factor of K~ at \
         rest, the corotational preconditioner; AMD vs geometric nested dissection)\n",
    );
    let cells: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.mesh.clone(),
                r.tets.to_string(),
                r.dofs.to_string(),
                format!("{:.3}", r.amd.factor_nnz as f64 / 1e6),
                format!("{:.3}", r.nested_dissection.factor_nnz as f64 / 1e6),
                format!("{:.2}", r.amd.factor_ms),
                format!("{:.2}", r.nested_dissection.factor_ms),
                format!("{:.3}", r.amd.solve_ms),
                format!("{:.3}", r.nested_dissection.solve_ms),
                r.chosen.clone(),
            ]
        })
        .collect();
    s += &table(
        &[
            ("mesh", Align::Left),
            ("tets", Align::Right),
            ("dofs", Align::Right),
            ("nnz(L) M AMD", Align::Right),
            ("ND", Align::Right),
            ("factor ms AMD", Align::Right),
            ("ND", Align::Right),
            ("solve ms AMD", Align::Right),
            ("ND", Align::Right),
            ("chosen", Align::Left),
        ],
        &cells,
    );
    s
}
