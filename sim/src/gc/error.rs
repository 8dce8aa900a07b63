//! [`CageError`]: everything that can be wrong with a cage, or with a point bound to it.

/// Why a cage was rejected by [`GreenCoordinates::new`], or a point by
/// [`GreenCoordinates::bind`].
///
/// Vertex and triangle numbers are 0-based indices into the slices given to
/// [`GreenCoordinates::new`]; point numbers are 0-based indices into the slice given to
/// [`GreenCoordinates::bind`]. Coordinates are in the caller's length unit (metres by the
/// crate's convention).
///
/// [`GreenCoordinates::new`]: super::GreenCoordinates::new
/// [`GreenCoordinates::bind`]: super::GreenCoordinates::bind
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CageError {
    /// Fewer than 4 vertices: no closed triangle surface can be built from them.
    #[error("the cage has {count} vertices, but a closed cage needs at least 4 (a tetrahedron)")]
    TooFewVertices {
        /// The number of vertices given.
        count: usize,
    },

    /// Fewer than 4 triangles: no closed triangle surface has fewer.
    #[error("the cage has {count} triangles, but a closed cage needs at least 4 (a tetrahedron)")]
    TooFewTriangles {
        /// The number of triangles given.
        count: usize,
    },

    /// A triangle refers to a vertex that does not exist.
    #[error(
        "triangle {triangle} refers to vertex {index}, but the cage has only {vertex_count} \
         vertices (numbered from 0)"
    )]
    IndexOutOfRange {
        /// The triangle at fault.
        triangle: usize,
        /// The offending vertex index.
        index: usize,
        /// The number of cage vertices.
        vertex_count: usize,
    },

    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate: {}", show(.position))]
    NonFiniteVertex {
        /// The vertex at fault.
        vertex: usize,
        /// Its coordinates as given.
        position: [f64; 3],
    },

    /// A triangle has (numerically) zero area — a repeated vertex or three collinear ones — so
    /// it has no normal.
    #[error(
        "triangle {triangle} (vertices {}, {}, {}) is degenerate: its area is {area:e}, too \
         small for its edge lengths to define a normal (a repeated vertex or three collinear \
         vertices)",
        .vertices[0], .vertices[1], .vertices[2]
    )]
    DegenerateTriangle {
        /// The triangle at fault.
        triangle: usize,
        /// Its three vertex indices.
        vertices: [usize; 3],
        /// Its area (square length units).
        area: f64,
    },

    /// An edge belongs to one triangle only: the surface has a hole there.
    #[error(
        "the cage is not closed: the edge from vertex {} to vertex {} belongs only to triangle \
         {triangle} (every edge of a closed cage is shared by exactly two triangles)",
        .edge[0], .edge[1]
    )]
    OpenEdge {
        /// The edge's two vertices, in the order the triangle traverses them.
        edge: [usize; 2],
        /// The one triangle that uses it.
        triangle: usize,
    },

    /// An edge belongs to more than two triangles.
    #[error(
        "the cage is not a manifold surface: the edge between vertex {} and vertex {} is \
         shared by {} triangles ({}), but every edge must be shared by exactly two",
        .edge[0], .edge[1], .triangles.len(), list(.triangles)
    )]
    NonManifoldEdge {
        /// The edge's two vertices, smaller index first.
        edge: [usize; 2],
        /// All triangles that use it, in increasing order.
        triangles: Vec<usize>,
    },

    /// Two triangles sharing an edge traverse it in the same direction, so one of them is
    /// wound the other way round from its neighbour.
    #[error(
        "triangles {} and {} are wound inconsistently: both run along the edge from vertex {} \
         to vertex {} in the same direction (neighbouring triangles must traverse their shared \
         edge in opposite directions)",
        .triangles[0], .triangles[1], .edge[0], .edge[1]
    )]
    InconsistentWinding {
        /// The edge, in the direction both triangles traverse it.
        edge: [usize; 2],
        /// The two triangles, in increasing order.
        triangles: [usize; 2],
    },

    /// A vertex is used by no triangle (it would get no coordinate).
    #[error("vertex {vertex} is not used by any triangle; remove it from the cage")]
    UnusedVertex {
        /// The vertex at fault.
        vertex: usize,
    },

    /// The closed surface encloses a negative volume: its triangles run clockwise seen from
    /// outside, so every normal points into the cage.
    #[error(
        "the cage is wound inward: its signed volume is {volume:e} (negative); list every \
         triangle's vertices counter-clockwise as seen from outside the cage (e.g. swap the \
         last two indices of every triangle)"
    )]
    InwardWinding {
        /// The signed enclosed volume (cubic length units), < 0.
        volume: f64,
    },

    /// The closed surface encloses (numerically) no volume, e.g. a flattened cage.
    #[error(
        "the cage encloses no volume (signed volume {volume:e}, negligible for its size): it \
         is flat, so no point can be inside it"
    )]
    NoVolume {
        /// The signed enclosed volume (cubic length units).
        volume: f64,
    },

    /// A point given to [`GreenCoordinates::bind`](super::GreenCoordinates::bind) is not
    /// strictly inside the cage: its vertex coordinates do not sum to 1 (they sum to 0
    /// outside), or some coordinate is not finite (a point on an edge or vertex of the cage, or
    /// a non-finite point).
    #[error(
        "point {point} at {} is not strictly inside the cage: its vertex coordinates sum to \
         {phi_sum} instead of 1; enlarge the cage (e.g. more padding) so that it encloses every \
         point with a margin",
        show(.position)
    )]
    PointNotInside {
        /// The point at fault.
        point: usize,
        /// Its coordinates as given.
        position: [f64; 3],
        /// The sum of its vertex coordinates φ (NaN if a coordinate is not finite).
        phi_sum: f64,
    },
}

/// `(x, y, z)`.
fn show(p: &[f64; 3]) -> String {
    format!("({}, {}, {})", p[0], p[1], p[2])
}

/// `a, b, c`.
fn list(v: &[usize]) -> String {
    v.iter()
        .map(|i| i.to_string())
        .collect::<Vec<_>>()
        .join(", ")
}
