//! Fill-reducing orderings of the free nodes, for the sparse Cholesky factor of `system.rs`.
//!
//! Two candidates; `System::new` factorises symbolically with each and keeps the one whose
//! factor stores fewer non-zeros (a symbolic analysis costs a few milliseconds even at 100k
//! tetrahedra, far less than one numeric factorisation):
//!
//! - **Approximate minimum degree** (faer's AMD on the node graph). Greedy and local: the best
//!   on small meshes, but on a large 3D mesh its fill grows faster than nested dissection's.
//! - **Geometric nested dissection.** faer has no METIS, but the nodes have coordinates, and a
//!   tetrahedral mesh's graph is local in space, so recursive coordinate bisection finds good
//!   separators: split the node set at the median coordinate along its longest extent; the
//!   separator is the nodes of one half that have a graph neighbour in the other (the smaller
//!   of the two such layers); removing it disconnects the halves. Number the first half, then
//!   the second, then the separator, recursively, down to leaves of at most
//!   [`LEAF_NODES`] nodes, which AMD orders. The separators, eliminated last, are where the
//!   fill concentrates: on an `n`-node 3D grid it is `O(n^{4/3})` against AMD's observed
//!   faster growth (the classic result of George 1973 for 2D, Lipton–Rose–Tarjan in 3D).
//!
//! The orderings are on nodes; `system.rs` gives each node three consecutive DOFs.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::amd;
use faer::sparse::SymbolicSparseColMatRef;

/// Nested dissection stops splitting at this many nodes and orders the rest by AMD.
pub(crate) const LEAF_NODES: usize = 64;

/// A node graph in compressed form: the neighbours of node `i` are
/// `idx[ptr[i]..ptr[i + 1]]` (both directions, sorted, no self loops).
pub(crate) struct Graph<'a> {
    pub ptr: &'a [u32],
    pub idx: &'a [u32],
}

impl Graph<'_> {
    fn n(&self) -> usize {
        self.ptr.len() - 1
    }

    fn neighbours(&self, i: u32) -> &[u32] {
        &self.idx[self.ptr[i as usize] as usize..self.ptr[i as usize + 1] as usize]
    }
}

/// AMD on the whole graph: `perm[new] = old`.
pub(crate) fn minimum_degree(graph: &Graph<'_>) -> Result<Vec<u32>, faer::sparse::FaerError> {
    let n = graph.n();
    let mut perm = vec![0u32; n];
    let mut perm_inv = vec![0u32; n];
    if n > 0 {
        let g = SymbolicSparseColMatRef::new_checked(n, n, graph.ptr, None, graph.idx);
        let mut mem = MemBuffer::try_new(amd::order_scratch::<u32>(n, graph.idx.len()))?;
        amd::order(
            &mut perm,
            &mut perm_inv,
            g,
            amd::Control::default(),
            MemStack::new(&mut mem),
        )?;
    }
    Ok(perm)
}

/// Geometric nested dissection (module docs): `perm[new] = old`. `coords[i]` is node `i`'s
/// position.
pub(crate) fn nested_dissection(
    graph: &Graph<'_>,
    coords: &[[f64; 3]],
) -> Result<Vec<u32>, faer::sparse::FaerError> {
    let n = graph.n();
    assert_eq!(coords.len(), n, "one coordinate per node");
    let mut d = Dissection {
        graph,
        coords,
        stamp: vec![0; n],
        next_stamp: 1,
        local: vec![u32::MAX; n],
        keys: Vec::new(),
    };
    let mut perm: Vec<u32> = (0..n as u32).collect();
    // An explicit stack of node ranges still to dissect (depth is only ~log n, but this keeps
    // the borrow of `perm` simple).
    let mut todo = vec![(0usize, n)];
    while let Some((start, end)) = todo.pop() {
        match d.split(&mut perm[start..end]) {
            Some((a, b)) => {
                todo.push((start, start + a));
                todo.push((start + a, start + a + b));
            }
            None => d.order_leaf(&mut perm[start..end])?,
        }
    }
    Ok(perm)
}

/// Scratch of [`nested_dissection`].
struct Dissection<'a, 'g> {
    graph: &'a Graph<'g>,
    coords: &'a [[f64; 3]],
    /// Per node: which half it was last put in (a fresh value per half, so never cleared).
    stamp: Vec<u32>,
    next_stamp: u32,
    /// Per node: its index within the leaf being ordered (`u32::MAX` outside it).
    local: Vec<u32>,
    keys: Vec<f64>,
}

impl Dissection<'_, '_> {
    /// Splits `nodes` in place into `[first half | second half | separator]` and returns the
    /// lengths of the halves, or `None` if it is small enough to be a leaf (or cannot be
    /// split).
    fn split(&mut self, nodes: &mut [u32]) -> Option<(usize, usize)> {
        if nodes.len() <= LEAF_NODES {
            return None;
        }
        // Longest extent of the bounding box.
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for &v in nodes.iter() {
            let p = self.coords[v as usize];
            for c in 0..3 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        let axis = (0..3)
            .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
            .expect("three axes");
        // Median coordinate; the first half is strictly below it (nodes on a grid plane share
        // a coordinate and stay together), or at most it if nothing is below.
        self.keys.clear();
        self.keys
            .extend(nodes.iter().map(|&v| self.coords[v as usize][axis]));
        let mid = self.keys.len() / 2;
        let (_, &mut median, _) = self.keys.select_nth_unstable_by(mid, f64::total_cmp);
        let below = |x: f64| x < median;
        let at_most = |x: f64| x <= median;
        let count = |f: &dyn Fn(f64) -> bool| self.keys.iter().filter(|&&x| f(x)).count();
        let n_below = count(&below);
        let n_at_most = count(&at_most);
        // Whichever rule splits closer to the middle (and leaves both halves non-empty).
        let half = nodes.len() / 2;
        let use_below = n_below > 0
            && (n_at_most == nodes.len() || n_below.abs_diff(half) <= n_at_most.abs_diff(half));
        if !use_below && (n_at_most == 0 || n_at_most == nodes.len()) {
            return None;
        }
        let (s1, s2) = (self.next_stamp, self.next_stamp + 1);
        self.next_stamp += 2;
        for &v in nodes.iter() {
            let x = self.coords[v as usize][axis];
            let first = if use_below { x < median } else { x <= median };
            self.stamp[v as usize] = if first { s1 } else { s2 };
        }
        // Boundary layers: nodes of each half with a neighbour in the other.
        let touches = |v: u32, other: u32, stamp: &[u32]| {
            self.graph
                .neighbours(v)
                .iter()
                .any(|&w| stamp[w as usize] == other)
        };
        let (mut layer1, mut layer2) = (0usize, 0usize);
        for &v in nodes.iter() {
            if self.stamp[v as usize] == s1 {
                layer1 += touches(v, s2, &self.stamp) as usize;
            } else {
                layer2 += touches(v, s1, &self.stamp) as usize;
            }
        }
        // The separator is the smaller layer; it moves to the end, the halves keep their
        // nodes' relative order.
        let (sep_side, other) = if layer1 <= layer2 { (s1, s2) } else { (s2, s1) };
        let s_sep = self.next_stamp;
        self.next_stamp += 1;
        for k in 0..nodes.len() {
            let v = nodes[k];
            // Re-stamping a node of `sep_side` leaves the other half's stamps, which the
            // test reads, as they were.
            if self.stamp[v as usize] == sep_side && touches(v, other, &self.stamp) {
                self.stamp[v as usize] = s_sep;
            }
        }
        let rank = |v: u32, stamp: &[u32]| match stamp[v as usize] {
            s if s == s1 => 0u8,
            s if s == s2 => 1,
            _ => 2,
        };
        let stamp = &self.stamp;
        nodes.sort_by_key(|&v| rank(v, stamp));
        let a = nodes.iter().filter(|&&v| stamp[v as usize] == s1).count();
        let b = nodes.iter().filter(|&&v| stamp[v as usize] == s2).count();
        Some((a, b))
    }

    /// Orders a leaf in place by AMD on its induced subgraph.
    fn order_leaf(&mut self, nodes: &mut [u32]) -> Result<(), faer::sparse::FaerError> {
        let n = nodes.len();
        if n < 3 {
            return Ok(());
        }
        for (k, &v) in nodes.iter().enumerate() {
            self.local[v as usize] = k as u32;
        }
        let mut ptr = Vec::with_capacity(n + 1);
        let mut idx = Vec::new();
        ptr.push(0u32);
        for &v in nodes.iter() {
            let start = idx.len();
            idx.extend(
                self.graph
                    .neighbours(v)
                    .iter()
                    .map(|&w| self.local[w as usize])
                    .filter(|&l| l != u32::MAX),
            );
            idx[start..].sort_unstable();
            ptr.push(idx.len() as u32);
        }
        for &v in nodes.iter() {
            self.local[v as usize] = u32::MAX;
        }
        let perm = minimum_degree(&Graph {
            ptr: &ptr,
            idx: &idx,
        })?;
        let original: Vec<u32> = nodes.to_vec();
        for (k, &p) in perm.iter().enumerate() {
            nodes[k] = original[p as usize];
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The node graph and coordinates of an `n × n × n` grid of points (6-neighbour edges plus
    /// one diagonal per cell, like the Kuhn split's long diagonal).
    fn grid(n: usize) -> (Vec<u32>, Vec<u32>, Vec<[f64; 3]>) {
        let id = |i: usize, j: usize, k: usize| (i + n * (j + n * k)) as u32;
        let mut adj = vec![Vec::new(); n * n * n];
        let mut coords = vec![[0.0; 3]; n * n * n];
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let a = id(i, j, k);
                    coords[a as usize] = [i as f64, j as f64, k as f64];
                    let mut link = |b: u32| {
                        adj[a as usize].push(b);
                        adj[b as usize].push(a);
                    };
                    if i + 1 < n {
                        link(id(i + 1, j, k));
                    }
                    if j + 1 < n {
                        link(id(i, j + 1, k));
                    }
                    if k + 1 < n {
                        link(id(i, j, k + 1));
                    }
                    if i + 1 < n && j + 1 < n && k + 1 < n {
                        link(id(i + 1, j + 1, k + 1));
                    }
                }
            }
        }
        let mut ptr = vec![0u32];
        let mut idx = Vec::new();
        for mut list in adj {
            list.sort_unstable();
            idx.extend(list);
            ptr.push(idx.len() as u32);
        }
        (ptr, idx, coords)
    }

    fn is_permutation(perm: &[u32]) -> bool {
        let mut seen = vec![false; perm.len()];
        perm.iter()
            .all(|&p| (p as usize) < perm.len() && !std::mem::replace(&mut seen[p as usize], true))
    }

    #[test]
    fn nested_dissection_is_a_permutation() {
        for n in [1, 2, 5, 9, 12] {
            let (ptr, idx, coords) = grid(n);
            let g = Graph {
                ptr: &ptr,
                idx: &idx,
            };
            let perm = nested_dissection(&g, &coords).unwrap();
            assert_eq!(perm.len(), n * n * n);
            assert!(is_permutation(&perm), "n = {n}");
        }
    }

    #[test]
    fn coincident_points_make_a_leaf() {
        // Nothing to split along: the whole set is one leaf, ordered by AMD.
        let (ptr, idx, coords) = grid(5);
        let flat = vec![[0.0; 3]; coords.len()];
        let g = Graph {
            ptr: &ptr,
            idx: &idx,
        };
        let perm = nested_dissection(&g, &flat).unwrap();
        assert!(is_permutation(&perm));
    }

    #[test]
    fn the_top_separator_is_numbered_last_and_separates() {
        // The last-numbered nodes of a 12³ grid are the top separator: one grid plane of 144
        // nodes. Without them the graph falls into two pieces, each numbered contiguously.
        let n = 12;
        let (ptr, idx, coords) = grid(n);
        let g = Graph {
            ptr: &ptr,
            idx: &idx,
        };
        let perm = nested_dissection(&g, &coords).unwrap();
        let total = n * n * n;
        let sep = &perm[total - n * n..];
        let axis = (0..3)
            .find(|&a| {
                sep.iter()
                    .all(|&v| coords[v as usize][a] == coords[sep[0] as usize][a])
            })
            .expect("the separator is a grid plane");
        assert!(axis < 3);
        // Components of the rest, by flood fill; `label[v]` = component, separator = MAX.
        let mut label = vec![usize::MAX - 1; total];
        for &v in sep {
            label[v as usize] = usize::MAX;
        }
        let mut components = 0;
        for start in 0..total {
            if label[start] != usize::MAX - 1 {
                continue;
            }
            let mut stack = vec![start as u32];
            label[start] = components;
            while let Some(v) = stack.pop() {
                for &w in g.neighbours(v) {
                    if label[w as usize] == usize::MAX - 1 {
                        label[w as usize] = components;
                        stack.push(w);
                    }
                }
            }
            components += 1;
        }
        assert_eq!(components, 2);
        // Numbered contiguously: the component changes once along the order.
        let order: Vec<usize> = perm[..total - n * n]
            .iter()
            .map(|&v| label[v as usize])
            .collect();
        let changes = order.windows(2).filter(|w| w[0] != w[1]).count();
        assert_eq!(changes, 1, "the halves interleave");
    }
}
