//! Cage validation: every way a cage can be unusable is refused with what is wrong and where,
//! in a stated order, and points not strictly inside are refused by the binding.

use super::*;

#[test]
fn inward_winding_is_rejected_with_the_volume() {
    let mut cage = irregular_box();
    for t in &mut cage.triangles {
        t.swap(1, 2);
    }
    let e = err(&cage);
    let CageError::InwardWinding { volume } = e else {
        panic!("{e:?}")
    };
    let expected = -(1.1 * 1.3 * 0.6);
    assert!((volume - expected).abs() <= 1e-12, "{volume}");
    let msg = e.to_string();
    assert!(
        msg.contains("inward") && msg.contains(&format!("{volume:e}")),
        "{msg}"
    );
}

#[test]
fn a_missing_triangle_leaves_the_cage_open() {
    let mut cage = irregular_box();
    let removed = cage.triangles.remove(5);
    let e = err(&cage);
    let CageError::OpenEdge { edge, triangle } = e else {
        panic!("{e:?}")
    };
    // The open edge is one of the removed triangle's, run the other way by its neighbour.
    let edges: Vec<[usize; 2]> = (0..3).map(|k| [removed[(k + 1) % 3], removed[k]]).collect();
    assert!(edges.contains(&edge), "{edge:?} not in {edges:?}");
    let t = cage.triangles[triangle];
    assert!(t.contains(&edge[0]) && t.contains(&edge[1]));
    let msg = e.to_string();
    assert!(
        msg.contains("not closed")
            && msg.contains(&format!("vertex {} to vertex {}", edge[0], edge[1]))
            && msg.contains(&format!("triangle {triangle}")),
        "{msg}"
    );
}

#[test]
fn a_third_triangle_on_an_edge_is_non_manifold() {
    // A fin: a new triangle on the edge of triangle 0, to a new apex vertex (its other two
    // edges are open, but the non-manifold edge is reported first).
    let mut cage = irregular_box();
    let [a, b, _] = cage.triangles[0];
    cage.vertices.push([2.0, 2.0, 2.0]);
    cage.triangles.push([b, a, 8]);
    let e = err(&cage);
    let CageError::NonManifoldEdge { edge, triangles } = &e else {
        panic!("{e:?}")
    };
    assert_eq!(*edge, [a.min(b), a.max(b)]);
    assert_eq!(triangles.len(), 3);
    assert!(triangles.contains(&0) && triangles.contains(&12));
    let msg = e.to_string();
    assert!(
        msg.contains(&format!("vertex {} and vertex {}", edge[0], edge[1]))
            && msg.contains("3 triangles")
            && msg.contains("12"),
        "{msg}"
    );
}

#[test]
fn a_flipped_triangle_is_inconsistent_winding() {
    let mut cage = octahedron();
    cage.triangles[3].swap(0, 1);
    let e = err(&cage);
    let CageError::InconsistentWinding { edge, triangles } = e else {
        panic!("{e:?}")
    };
    assert!(triangles.contains(&3));
    assert!(cage.triangles[3].contains(&edge[0]) && cage.triangles[3].contains(&edge[1]));
    let msg = e.to_string();
    assert!(
        msg.contains("inconsistently")
            && msg.contains(&format!("triangles {} and {}", triangles[0], triangles[1])),
        "{msg}"
    );
}

#[test]
fn zero_area_triangles_are_degenerate() {
    // A repeated vertex.
    let mut cage = irregular_box();
    let [a, b, _] = cage.triangles[4];
    cage.triangles[4] = [a, b, a];
    let e = err(&cage);
    assert_eq!(
        e,
        CageError::DegenerateTriangle {
            triangle: 4,
            vertices: [a, b, a],
            area: 0.0
        }
    );
    let msg = e.to_string();
    assert!(
        msg.contains("triangle 4") && msg.contains("degenerate"),
        "{msg}"
    );

    // Three collinear vertices: move a corner of triangle 0 onto the line of the other two.
    let mut cage = irregular_box();
    let [a, b, c] = cage.triangles[0];
    cage.vertices[c] = add(
        cage.vertices[a],
        scale(sub(cage.vertices[b], cage.vertices[a]), 0.5),
    );
    let e = err(&cage);
    let CageError::DegenerateTriangle {
        triangle,
        vertices,
        area,
    } = e
    else {
        panic!("{e:?}")
    };
    assert!(vertices.contains(&c) && area.abs() < 1e-15 && cage.triangles[triangle] == vertices);
}

#[test]
fn index_out_of_range_is_named() {
    let mut cage = irregular_box();
    cage.triangles[7][1] = 99;
    let e = err(&cage);
    assert_eq!(
        e,
        CageError::IndexOutOfRange {
            triangle: 7,
            index: 99,
            vertex_count: 8
        }
    );
    let msg = e.to_string();
    assert!(
        msg.contains("triangle 7") && msg.contains("vertex 99") && msg.contains("8 vertices"),
        "{msg}"
    );
}

#[test]
fn non_finite_vertex_is_named() {
    let mut cage = octahedron();
    cage.vertices[4][1] = f64::NAN;
    let e = err(&cage);
    let CageError::NonFiniteVertex { vertex, position } = e else {
        panic!("{e:?}")
    };
    assert_eq!(vertex, 4);
    assert!(position[1].is_nan());
    let msg = e.to_string();
    assert!(msg.contains("vertex 4") && msg.contains("NaN"), "{msg}");

    let mut cage = octahedron();
    cage.vertices[2][0] = f64::INFINITY;
    assert!(matches!(
        err(&cage),
        CageError::NonFiniteVertex { vertex: 2, .. }
    ));
}

#[test]
fn unused_vertex_and_too_few_elements() {
    let mut cage = irregular_box();
    cage.vertices.push([0.0, 0.0, 0.0]);
    let e = err(&cage);
    assert_eq!(e, CageError::UnusedVertex { vertex: 8 });
    assert!(e.to_string().contains("vertex 8"));

    let e = GreenCoordinates::new(&[[0.0; 3]; 3], &[]).unwrap_err();
    assert_eq!(e, CageError::TooFewVertices { count: 3 });
    assert!(e.to_string().contains("3 vertices"));
    let cage = irregular_box();
    let e = GreenCoordinates::new(&cage.vertices, &cage.triangles[..3]).unwrap_err();
    assert_eq!(e, CageError::TooFewTriangles { count: 3 });
}

/// Element checks come before the volume: an inward cage with a NaN vertex reports the NaN,
/// an inward cage with a hole reports the hole.
#[test]
fn validation_order() {
    let mut cage = irregular_box();
    for t in &mut cage.triangles {
        t.swap(1, 2);
    }
    let mut nan = cage.clone();
    nan.vertices[3][2] = f64::NAN;
    assert!(matches!(
        err(&nan),
        CageError::NonFiniteVertex { vertex: 3, .. }
    ));
    let mut open = cage.clone();
    open.triangles.pop();
    assert!(matches!(err(&open), CageError::OpenEdge { .. }));
    let mut bad = cage;
    bad.triangles[0][0] = 8;
    assert!(matches!(
        err(&bad),
        CageError::IndexOutOfRange {
            triangle: 0,
            index: 8,
            ..
        }
    ));
}

#[test]
fn bind_rejects_points_not_strictly_inside() {
    let cage = irregular_box(); // [-0.35, 0.75] × [-0.25, 1.05] × [-0.15, 0.45]
    let gc = gc_of(&cage);
    let inside = [0.1, 0.2, 0.1];

    let outside = [0.9, 0.2, 0.1];
    let e = gc.bind(&[inside, inside, outside]).unwrap_err();
    let CageError::PointNotInside {
        point,
        position,
        phi_sum,
    } = e
    else {
        panic!("{e:?}")
    };
    assert_eq!((point, position), (2, outside));
    assert!(phi_sum.abs() < 1e-12, "Σφ outside = {phi_sum}");
    let msg = e.to_string();
    assert!(
        msg.contains("point 2")
            && msg.contains("(0.9, 0.2, 0.1)")
            && msg.contains("not strictly inside"),
        "{msg}"
    );

    // Just outside a face (1e-12 beyond x = 0.75): Σφ = 0.
    let e = gc.bind(&[inside, [0.75 + 1e-12, 0.3, 0.05]]).unwrap_err();
    let CageError::PointNotInside {
        point: 1, phi_sum, ..
    } = e
    else {
        panic!("{e:?}")
    };
    assert!(phi_sum.abs() < 1e-9, "Σφ just outside = {phi_sum}");

    // Exactly on a face the solid angle of that face is ±2π by the sign of a rounded zero:
    // the point is either rejected or gets the limit of the coordinates from inside, which
    // reproduce it.
    let on_face = [0.75, 0.3, 0.05];
    match gc.bind(&[on_face]) {
        Err(CageError::PointNotInside { point: 0, .. }) => {}
        Err(e) => panic!("{e:?}"),
        Ok(_) => assert!(dist(gc.deform(on_face, &cage.vertices), on_face) < 1e-12),
    }

    // At a vertex and a non-finite point: non-finite coordinates, reported as NaN.
    for (k, p) in [cage.vertices[0], [f64::NAN, 0.0, 0.0]]
        .into_iter()
        .enumerate()
    {
        let e = gc.bind(&[inside, p]).unwrap_err();
        assert!(
            matches!(e, CageError::PointNotInside { point: 1, .. }),
            "{k}: {e:?}"
        );
    }
}
