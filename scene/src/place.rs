//! A body's mesh placed in the scene: read, transformed by the body's `scale`, `rotate_deg` and
//! `translate`, and its fixed nodes gathered (the mesh's `.bnd`, `fixed_nodes`, and the nodes
//! each `[[body.fix]]` selector picks in scene coordinates).

use anyhow::{bail, Context, Result};
use lop_config::{selector_toml, Scene};
use lop_sim::mesh::{bounds, read_mesh, TetMesh};

/// Body `index` of `scene`: its mesh read, placed in the scene and with every fixed node
/// (sorted, unique).
///
/// # Errors
/// The mesh does not read; a `fixed_nodes` entry names no node; a `[[body.fix]]` selector picks
/// no node (the message names `body[i].fix[j]`, the selector and the body's bounds).
pub fn place_body(scene: &Scene, index: usize) -> Result<TetMesh> {
    let spec = &scene.bodies[index];
    let mut mesh = read_mesh(&spec.mesh)
        .with_context(|| format!("body {:?} of scene {}", spec.name, scene.path.display()))?;
    for p in mesh.nodes.iter_mut() {
        *p = spec.transform_point(*p);
    }
    for &f in &spec.fixed_nodes {
        if f as usize >= mesh.nodes.len() {
            bail!(
                "{}: body {:?}: fixed_nodes has {f}, but the mesh has {} nodes",
                scene.path.display(),
                spec.name,
                mesh.nodes.len()
            );
        }
        mesh.fixed.push(f);
    }
    for (j, f) in spec.fix.iter().enumerate() {
        let picked = f.select(&mesh.nodes, &mesh.surface);
        if picked.is_empty() {
            let (lo, hi) = bounds(&mesh.nodes);
            bail!(
                "{}: body[{index}].fix[{j}] = {} (body {:?}): picks no node; the body spans \
                 [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}] m in scene coordinates (after \
                 its scale, rotate_deg and translate)",
                scene.path.display(),
                selector_toml(f),
                spec.name,
                lo[0],
                lo[1],
                lo[2],
                hi[0],
                hi[1],
                hi[2]
            );
        }
        mesh.fixed.extend(picked);
    }
    mesh.fixed.sort_unstable();
    mesh.fixed.dedup();
    Ok(mesh)
}

/// Places every body of `scene` (see [`place_body`]) without building models: the cheap check
/// that a scene's meshes read and its selectors pick nodes, for `lopd run` before it starts its
/// processes and for `lopd scene new`.
pub fn place_bodies(scene: &Scene) -> Result<Vec<TetMesh>> {
    (0..scene.bodies.len())
        .map(|i| place_body(scene, i))
        .collect()
}
