//! The topology a cut publishes (`Topology::after_cuts`): the same nodes, the cut body's new
//! surface and tetrahedra, its render surface dropped, every other body's kept as loaded.

use lop_config::load_scene;
use lop_scene::{load, RENDER_VERTEX_WORDS};

#[test]
fn a_cut_topology_keeps_the_nodes_and_the_uncut_bodies() {
    let loaded = load(load_scene(&lop_config::resolve_scene("abdomen").unwrap()).unwrap()).unwrap();
    let (mut world, topology) = (loaded.world, loaded.topology);
    // Nothing cut yet: the same topology as loaded.
    assert_eq!(topology.after_cuts(&world), topology);

    // The liver loses the tetrahedra around its first surface triangle's nodes.
    let liver = &world.bodies[0];
    let around: Vec<u32> = liver.mesh.surface[0].to_vec();
    let remove: Vec<bool> = liver
        .mesh
        .tets
        .iter()
        .map(|t| t.iter().any(|k| around.contains(k)))
        .collect();
    let report = world.cut_body(0, &remove).expect("the cut lands");
    let cut = topology.after_cuts(&world);
    assert_eq!(cut.node_count, topology.node_count);
    let (old, new) = (&topology.bodies[0], &cut.bodies[0]);
    assert_eq!(new.node_offset, old.node_offset);
    assert_eq!(new.tet_count, old.tet_count - report.removed_tets);
    assert_eq!(new.triangle_count, world.bodies[0].mesh.surface.len());
    assert_eq!((new.render_triangle_count, new.render_vertex_count), (0, 0));
    assert!(
        old.render_triangle_count > 0,
        "the shipped liver has a render surface"
    );
    // The liver's triangles, as global nodes.
    let tris =
        &cut.indices[3 * new.triangle_offset..3 * (new.triangle_offset + new.triangle_count)];
    let expect: Vec<u32> = world.bodies[0]
        .mesh
        .surface
        .iter()
        .flatten()
        .map(|&k| k + new.node_offset as u32)
        .collect();
    assert_eq!(tris, &expect[..]);
    // Every other body: the same triangles, tetrahedra and render surface, moved.
    let tri_at = |t: &lop_scene::Topology, b: &lop_scene::BodyTopology| {
        t.indices[3 * b.triangle_offset..3 * (b.triangle_offset + b.triangle_count)].to_vec()
    };
    let render_at = |t: &lop_scene::Topology, b: &lop_scene::BodyTopology| {
        let tets_end = 3 * t.triangle_count + 4 * t.tet_count;
        let tris: Vec<u32> = t.indices[tets_end + 3 * b.render_triangle_offset
            ..tets_end + 3 * (b.render_triangle_offset + b.render_triangle_count)]
            .iter()
            .map(|&k| k - b.render_vertex_offset as u32)
            .collect();
        let v0 =
            tets_end + 3 * t.render_triangle_count + RENDER_VERTEX_WORDS * b.render_vertex_offset;
        let verts = t.indices[v0..v0 + RENDER_VERTEX_WORDS * b.render_vertex_count].to_vec();
        (tris, verts)
    };
    for (old, new) in topology.bodies.iter().zip(&cut.bodies).skip(1) {
        assert_eq!(tri_at(&topology, old), tri_at(&cut, new), "{}", old.name);
        assert_eq!(new.tet_count, old.tet_count, "{}", old.name);
        assert_eq!(
            render_at(&topology, old),
            render_at(&cut, new),
            "{}",
            old.name
        );
    }
}
