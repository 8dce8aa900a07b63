//! Turning raw parts into a valid [`TetMesh`]: range and finiteness checks, degenerate,
//! duplicate and inverted tetrahedra, orientation normalisation, surface extraction.

use std::path::PathBuf;

use super::quality::{edge_lengths2, volume6};
use super::{surface, MeshReadError, TetMesh};

/// A tetrahedron is degenerate when `|6V| <= DEGENERATE_TOL * (longest edge)^3`.
pub(crate) const DEGENERATE_TOL: f64 = 1e-12;

/// How the file numbers its nodes, to name them in messages.
#[derive(Debug, Clone)]
pub(crate) enum NodeLabels {
    /// Node `i` is number `first + i` (TetGen, VTK, in-memory meshes).
    Offset(i64),
    /// Node `i` has tag `tags[i]` (Gmsh).
    Tags(Vec<i64>),
}

/// Where the tetrahedra came from, to name them in messages.
#[derive(Debug, Clone)]
pub(crate) struct Origin {
    /// The file holding the tetrahedra (`.ele` for TetGen).
    pub tet_file: PathBuf,
    /// 1-based line of each tetrahedron; empty for in-memory meshes.
    pub tet_lines: Vec<usize>,
    /// Number of each tetrahedron in its file; empty means "its 0-based index".
    pub tet_labels: Vec<i64>,
    pub node_labels: NodeLabels,
}

impl Origin {
    /// The origin of a mesh built in memory: no lines, 0-based numbers.
    pub fn in_memory(source: PathBuf) -> Self {
        Self {
            tet_file: source,
            tet_lines: Vec::new(),
            tet_labels: Vec::new(),
            node_labels: NodeLabels::Offset(0),
        }
    }

    pub fn line(&self, tet: usize) -> Option<usize> {
        self.tet_lines.get(tet).copied()
    }

    pub fn tet_label(&self, tet: usize) -> i64 {
        self.tet_labels
            .get(tet)
            .copied()
            .unwrap_or_else(|| i64::try_from(tet).unwrap_or(i64::MAX))
    }

    pub fn node_label(&self, node: u32) -> i64 {
        match &self.node_labels {
            NodeLabels::Offset(first) => first.saturating_add(i64::from(node)),
            NodeLabels::Tags(tags) => tags.get(node as usize).copied().unwrap_or(-1),
        }
    }

    pub fn face_labels(&self, face: [u32; 3]) -> [i64; 3] {
        face.map(|n| self.node_label(n))
    }

    fn first_index(&self) -> i64 {
        match self.node_labels {
            NodeLabels::Offset(first) => first,
            NodeLabels::Tags(_) => 0,
        }
    }
}

/// Validates raw parts and builds the mesh. Readers check indices with file-specific messages
/// first; the checks here repeat them generically so that `from_parts` is just as safe.
pub(crate) fn build(
    nodes: Vec<[f64; 3]>,
    mut tets: Vec<[u32; 4]>,
    mut fixed: Vec<u32>,
    source: PathBuf,
    origin: &Origin,
) -> Result<TetMesh, MeshReadError> {
    if u32::try_from(nodes.len()).is_err() {
        return Err(MeshReadError::TooManyNodes {
            path: source,
            count: nodes.len(),
        });
    }
    for (i, p) in nodes.iter().enumerate() {
        if let Some(&value) = p.iter().find(|v| !v.is_finite()) {
            return Err(MeshReadError::NonFiniteCoordinate {
                path: source,
                line: None,
                node: origin.node_label(i as u32),
                value,
            });
        }
    }
    if tets.is_empty() {
        return Err(MeshReadError::NoTets {
            path: origin.tet_file.clone(),
            skipped: 0,
        });
    }
    let count = nodes.len();
    let point = |i: u32| nodes[i as usize];
    for (t, tet) in tets.iter().enumerate() {
        if let Some(&bad) = tet.iter().find(|&&i| i as usize >= count) {
            return Err(MeshReadError::IndexOutOfRange {
                path: origin.tet_file.clone(),
                line: origin.line(t),
                index: origin.first_index().saturating_add(i64::from(bad)),
                count,
                first_index: origin.first_index(),
                node_file: source,
            });
        }
    }
    if let Some(&bad) = fixed.iter().find(|&&i| i as usize >= count) {
        return Err(MeshReadError::BadBoundary {
            path: source.clone(),
            line: None,
            index: origin.first_index().saturating_add(i64::from(bad)),
            count,
            first_index: origin.first_index(),
            node_file: source,
        });
    }

    // Degenerate tetrahedra, orientation census.
    let mut volumes6 = Vec::with_capacity(tets.len());
    for (t, tet) in tets.iter().enumerate() {
        let p = tet.map(point);
        let v6 = volume6(&p);
        let longest = edge_lengths2(&p).into_iter().fold(0.0, f64::max).sqrt();
        if !v6.is_finite() || v6.abs() <= DEGENERATE_TOL * longest * longest * longest {
            return Err(MeshReadError::DegenerateTet {
                path: origin.tet_file.clone(),
                line: origin.line(t),
                tet: origin.tet_label(t),
                nodes: tet.map(|n| origin.node_label(n)),
                volume: v6 / 6.0,
                longest_edge: longest,
            });
        }
        volumes6.push(v6);
    }

    // Duplicates: sort the node sets; report the earliest tetrahedron that repeats another.
    let mut keys: Vec<([u32; 4], usize)> = tets
        .iter()
        .enumerate()
        .map(|(t, tet)| {
            let mut key = *tet;
            key.sort_unstable();
            (key, t)
        })
        .collect();
    keys.sort_unstable();
    let duplicate = keys
        .chunk_by(|a, b| a.0 == b.0)
        .filter_map(|group| match group {
            [(_, first), (_, second), ..] => Some((*second, *first)),
            _ => None,
        })
        .min();
    drop(keys);
    if let Some((t, first)) = duplicate {
        return Err(MeshReadError::DuplicateTet {
            path: origin.tet_file.clone(),
            line: origin.line(t),
            tet: origin.tet_label(t),
            first_line: origin.line(first),
            first_tet: origin.tet_label(first),
        });
    }

    let negative = volumes6.iter().filter(|&&v| v < 0.0).count();
    let positive = volumes6.len() - negative;
    if negative > 0 && positive > 0 {
        // The minority is inverted; on a tie, the negative ones.
        let minority_negative = negative <= positive;
        let inverted = negative.min(positive);
        let t = volumes6
            .iter()
            .position(|&v| (v < 0.0) == minority_negative)
            .unwrap_or(0);
        return Err(MeshReadError::InvertedTet {
            path: origin.tet_file.clone(),
            line: origin.line(t),
            tet: origin.tet_label(t),
            nodes: tets[t].map(|n| origin.node_label(n)),
            volume: volumes6[t] / 6.0,
            inverted,
            total: tets.len(),
        });
    }
    if negative > 0 {
        // Consistently negative (the other convention): swap two corners of every tetrahedron.
        for tet in &mut tets {
            tet.swap(1, 2);
        }
    }

    let surface = surface::extract(&tets, origin)?;
    fixed.sort_unstable();
    fixed.dedup();
    Ok(TetMesh {
        nodes,
        tets,
        surface,
        fixed,
        source,
    })
}
