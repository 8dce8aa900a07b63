//! The test block of `lop-bench haptics`: 40 × 40 × 20 mm (x, y ∈ [−20, 20] mm, z ∈ [0, 20] mm),
//! bottom face clamped, meshed by gmsh with element size `h_c` within [`FINE_RADIUS`] of the
//! contact point (the top face's centre) and graded to [`COARSE_SIZE`] away from it.
//!
//! The `.geo` is written by the bench and the `.msh` cached beside it under
//! `target/lop-bench/meshes/`; a cached mesh is reused only while its `.geo` is byte for byte
//! the one this code writes (so changing the grading here regenerates it). The mesh is read
//! with lop-sim's own Gmsh reader, as a user's mesh would be.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context, Result};
use lop_sim::mesh::{read_gmsh, TetMesh};

/// Half the block's width (x and y), m.
pub const HALF_WIDTH: f64 = 0.020;
/// The block's height (z of the top face), m.
pub const HEIGHT: f64 = 0.020;
/// The contact point: the top face's centre, m.
pub const CONTACT: [f64; 3] = [0.0, 0.0, HEIGHT];
/// The top face's outward normal: the tool presses along `−z`.
pub const NORMAL: [f64; 3] = [0.0, 0.0, 1.0];
/// Element size far from the contact, m.
pub const COARSE_SIZE: f64 = 0.004;
/// Radius around the contact point meshed at the fine size, m: covers the contact patch up to
/// 0.4 mm indentation with a 3 mm sphere (the intersection radius √(2Rd) is 1.5 mm).
pub const FINE_RADIUS: f64 = 0.002;
/// Growth of the element size with the distance beyond [`FINE_RADIUS`] (m per m): each element
/// at most 1.2 times its inner neighbour, the usual bound on size growth in a finite-element
/// mesh. Decision, measured with the static reference at 0.3 mm: with a growth of 0.5 (1.5
/// per element) the far field, not the contact, dominated the coarse meshes' error (0.8 mm:
/// 16.58 mN, against 15.06 mN at 0.2) and even the 0.1 mm "converged" mesh was 3 % stiff
/// (14.05 against 13.64 mN). The finest pressed mesh (0.2 mm) has about 32k tetrahedra, the
/// 0.1 mm reference about 130k.
pub const GRADING: f64 = 0.2;

/// A graded block mesh and what was measured on it.
#[derive(Debug, Clone)]
pub struct Block {
    /// The element size asked of gmsh at the contact, m.
    pub size: f64,
    /// The mesh, bottom face fixed.
    pub mesh: TetMesh,
    /// Mean length of the tetrahedra's edges whose midpoint lies within 0.5 mm of the contact
    /// point, m: the size the tool actually meets.
    pub edge_at_contact: f64,
}

impl Block {
    /// `"0.8 mm"` and the like.
    pub fn label(&self) -> String {
        format!("{} mm", size_mm(self.size))
    }
}

/// `0.0008` → `"0.8"`.
pub fn size_mm(size: f64) -> String {
    let mm = size * 1e3;
    format!("{}", (mm * 1000.0).round() / 1000.0)
}

/// The gmsh input for a block with element size `size` (m) at the contact.
pub fn geo(size: f64) -> String {
    let dist_max = FINE_RADIUS + (COARSE_SIZE - size) / GRADING;
    format!(
        "// lop-bench haptics: the 40 x 40 x 20 mm test block, {h} mm at the top face's centre.\n\
         // Written by bench/src/haptics/block.rs; edit the code, not this file.\n\
         SetFactory(\"OpenCASCADE\");\n\
         Box(1) = {{{x0}, {x0}, 0, {w}, {w}, {z}}};\n\
         // The contact point, embedded in the top face so that a node sits exactly under the tool.\n\
         Point(100) = {{0, 0, {z}}};\n\
         top() = Surface In BoundingBox{{{b0}, {b0}, {zlo}, {b1}, {b1}, {zhi}}};\n\
         Point{{100}} In Surface{{top(0)}};\n\
         Field[1] = Distance;\n\
         Field[1].PointsList = {{100}};\n\
         Field[2] = Threshold;\n\
         Field[2].InField = 1;\n\
         Field[2].SizeMin = {size:e};\n\
         Field[2].SizeMax = {COARSE_SIZE:e};\n\
         Field[2].DistMin = {FINE_RADIUS:e};\n\
         Field[2].DistMax = {dist_max:e};\n\
         Background Field = 2;\n\
         Mesh.MeshSizeExtendFromBoundary = 0;\n\
         Mesh.MeshSizeFromPoints = 0;\n\
         Mesh.MeshSizeFromCurvature = 0;\n\
         Mesh.Optimize = 1;\n",
        h = size_mm(size),
        x0 = -HALF_WIDTH,
        w = 2.0 * HALF_WIDTH,
        z = HEIGHT,
        b0 = -HALF_WIDTH - 1e-3,
        b1 = HALF_WIDTH + 1e-3,
        zlo = HEIGHT - 1e-7,
        zhi = HEIGHT + 1e-7,
    )
}

/// The cache folder of the generated meshes: `target/lop-bench/meshes` under the workspace.
pub fn cache_dir() -> PathBuf {
    crate::models::workspace_root().join("target/lop-bench/meshes")
}

/// The block with element size `size` (m) at the contact: from the cache, or generated with
/// gmsh into it first.
///
/// # Errors
/// gmsh missing or failing (the message says how to install it), or the mesh not reading.
pub fn block(size: f64, cache: &Path) -> Result<Block> {
    std::fs::create_dir_all(cache).with_context(|| format!("creating {}", cache.display()))?;
    let stem = format!("block-{}mm", size_mm(size));
    let geo_path = cache.join(format!("{stem}.geo"));
    let msh_path = cache.join(format!("{stem}.msh"));
    let text = geo(size);
    let cached =
        msh_path.exists() && std::fs::read_to_string(&geo_path).is_ok_and(|old| old == text);
    if !cached {
        // Under names of this call's own first (the process id and a counter: two tests of
        // one process share the id), renamed into place after: two runs or two tests
        // generating the same block at once never read a half-written file, nor rename each
        // other's.
        static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let own = format!("{stem}.{}-{call}", std::process::id());
        let tmp_geo = cache.join(format!("{own}.geo.tmp"));
        let tmp_msh = cache.join(format!("{own}.msh.tmp"));
        std::fs::write(&tmp_geo, &text)
            .with_context(|| format!("writing {}", tmp_geo.display()))?;
        run_gmsh(&tmp_geo, &tmp_msh)?;
        std::fs::rename(&tmp_msh, &msh_path)
            .with_context(|| format!("writing {}", msh_path.display()))?;
        std::fs::rename(&tmp_geo, &geo_path)
            .with_context(|| format!("writing {}", geo_path.display()))?;
    }
    let mut mesh = read_gmsh(&msh_path)?;
    mesh.fixed = mesh
        .nodes
        .iter()
        .enumerate()
        .filter(|(_, p)| p[2].abs() < 1e-9)
        .map(|(i, _)| i as u32)
        .collect();
    if mesh.fixed.is_empty() {
        bail!("{}: no node on the bottom face", msh_path.display());
    }
    let edge_at_contact = edge_near(&mesh, CONTACT, 5e-4);
    Ok(Block {
        size,
        mesh,
        edge_at_contact,
    })
}

/// gmsh's version string (`"4.8.4"`), if gmsh is installed.
pub fn gmsh_version() -> Option<String> {
    let out = Command::new("gmsh").arg("--version").output().ok()?;
    // gmsh prints its version on stderr.
    let text = String::from_utf8_lossy(&out.stderr).trim().to_string()
        + String::from_utf8_lossy(&out.stdout).trim();
    (!text.is_empty()).then_some(text)
}

fn run_gmsh(geo: &Path, msh: &Path) -> Result<()> {
    let out = Command::new("gmsh")
        .arg("-3")
        .arg(geo)
        .arg("-format")
        .arg("msh41")
        .arg("-o")
        .arg(msh)
        .output()
        .context("running gmsh (install it with `scripts/setup.sh` or `apt-get install gmsh`)")?;
    if !out.status.success() {
        let _ = std::fs::remove_file(msh);
        bail!(
            "gmsh failed on {} ({}):\n{}",
            geo.display(),
            out.status,
            String::from_utf8_lossy(&out.stdout)
                .lines()
                .chain(String::from_utf8_lossy(&out.stderr).lines())
                .filter(|l| l.contains("Error"))
                .collect::<Vec<_>>()
                .join("\n")
        );
    }
    Ok(())
}

/// Mean length of the edges whose midpoint lies within `radius` of `point`, m (NaN if none).
pub fn edge_near(mesh: &TetMesh, point: [f64; 3], radius: f64) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for [a, b] in mesh.edges() {
        let (p, q) = (mesh.nodes[a as usize], mesh.nodes[b as usize]);
        let mid = [0, 1, 2].map(|c| 0.5 * (p[c] + q[c]) - point[c]);
        if mid.iter().map(|m| m * m).sum::<f64>() <= radius * radius {
            sum += (0..3).map(|c| (p[c] - q[c]).powi(2)).sum::<f64>().sqrt();
            count += 1;
        }
    }
    sum / count as f64
}
