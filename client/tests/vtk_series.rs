//! The VTK series `lop-record` writes: one `.vtu` per frame whose points, tetrahedra, body ids
//! and temperatures are the frame's, and a `.pvd` index in frame order with simulated times.

use lop_client::vtk::PvdSeries;
use lop_client::{Frame, FrameHeader, NodeSample, Topology, TopologyHeader};

fn numbers_in(xml: &str, name: &str) -> Vec<f64> {
    let start = xml.find(&format!("Name=\"{name}\"")).expect(name);
    let open = xml[start..].find('>').unwrap() + start + 1;
    let close = xml[open..].find("</DataArray>").unwrap() + open;
    xml[open..close]
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect()
}

#[test]
fn series_round_trips_geometry_and_index() {
    let mut header = TopologyHeader {
        body_count: 2,
        topology_id: 7,
        node_count: 5,
        triangle_count: 0,
        tet_count: 2,
        ..Default::default()
    };
    header.bodies[0].set_name("a");
    header.bodies[0].tet_count = 1;
    header.bodies[1].set_name("b");
    header.bodies[1].tet_count = 1;
    let topology = Topology {
        header,
        triangles: vec![],
        tets: vec![[0, 1, 2, 3], [1, 2, 3, 4]],
        render_triangles: vec![],
        render_vertices: vec![],
    };
    let dir = std::env::temp_dir().join(format!("lop-vtk-{}", std::process::id()));
    let mut series = PvdSeries::new(&dir, "frame").unwrap();
    for k in 0..3 {
        let nodes = (0..5)
            .map(|i| NodeSample {
                position: [i as f32 * 0.5, k as f32, 0.25],
                temperature: 37.0 + k as f32,
                flags: 0,
            })
            .collect();
        let frame = Frame {
            header: FrameHeader {
                topology_id: 7,
                sim_time: 0.01 * k as f64,
                node_count: 5,
                ..Default::default()
            },
            nodes,
            received_ns: 0,
        };
        series.add(&topology, &frame).unwrap();
    }
    let pvd = std::fs::read_to_string(series.finish().unwrap()).unwrap();
    let files: Vec<&str> = pvd
        .lines()
        .filter_map(|l| l.split("file=\"").nth(1))
        .map(|r| r.trim_end_matches("\"/>"))
        .collect();
    assert_eq!(
        files,
        ["frame_000000.vtu", "frame_000001.vtu", "frame_000002.vtu"]
    );
    assert!(pvd.contains("timestep=\"0.02\""));

    let vtu = std::fs::read_to_string(dir.join("frame_000002.vtu")).unwrap();
    assert!(vtu.contains("NumberOfPoints=\"5\" NumberOfCells=\"2\""));
    let points = numbers_in(&vtu, "Points");
    assert_eq!(points.len(), 15);
    assert_eq!(&points[6..9], [1.0, 2.0, 0.25]);
    assert_eq!(
        numbers_in(&vtu, "connectivity"),
        [0., 1., 2., 3., 1., 2., 3., 4.]
    );
    assert_eq!(numbers_in(&vtu, "offsets"), [4., 8.]);
    assert_eq!(numbers_in(&vtu, "types"), [10., 10.]);
    assert_eq!(numbers_in(&vtu, "body"), [0., 1.]);
    assert_eq!(numbers_in(&vtu, "temperature"), [39.0; 5]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A scene with a render surface gets a second piece: its triangles over the render vertices,
/// each placed and coloured by its weights on the frame's nodes.
#[test]
fn render_surface_is_a_second_piece_placed_by_its_weights() {
    use lop_client::RenderVertex;
    let mut header = TopologyHeader {
        body_count: 1,
        topology_id: 9,
        node_count: 4,
        tet_count: 1,
        render_triangle_count: 1,
        render_vertex_count: 3,
        ..Default::default()
    };
    header.bodies[0].set_name("a");
    header.bodies[0].tet_count = 1;
    header.bodies[0].render_vertex_count = 3;
    header.bodies[0].render_triangle_count = 1;
    let vertex = |nodes: [u32; 4], weights: [f32; 4]| RenderVertex { nodes, weights };
    let topology = Topology {
        header,
        triangles: vec![],
        tets: vec![[0, 1, 2, 3]],
        render_triangles: vec![[0, 1, 2]],
        render_vertices: vec![
            vertex([0, 1, 2, 3], [1.0, 0.0, 0.0, 0.0]),
            vertex([0, 1, 2, 3], [0.5, 0.5, 0.0, 0.0]),
            // Just outside the tetrahedron: one weight negative.
            vertex([0, 1, 2, 3], [-0.25, 0.25, 0.5, 0.5]),
        ],
    };
    let nodes = [
        [0.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [0.0, 2.0, 0.0],
        [0.0, 0.0, 2.0],
    ]
    .iter()
    .enumerate()
    .map(|(i, &position)| NodeSample {
        position,
        temperature: 37.0 + i as f32,
        flags: 0,
    })
    .collect();
    let frame = Frame {
        header: FrameHeader {
            topology_id: 9,
            node_count: 4,
            ..Default::default()
        },
        nodes,
        received_ns: 0,
    };
    assert_eq!(
        topology.render_positions(&frame),
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1.0, 1.0]]
    );
    let dir = std::env::temp_dir().join(format!("lop-vtk-render-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("f.vtu");
    lop_client::vtk::write_vtu(&path, &topology, &frame).unwrap();
    let vtu = std::fs::read_to_string(&path).unwrap();
    let pieces: Vec<&str> = vtu.split("<Piece").skip(1).collect();
    assert_eq!(pieces.len(), 2);
    assert!(pieces[0].contains("NumberOfPoints=\"4\" NumberOfCells=\"1\""));
    assert_eq!(numbers_in(pieces[0], "part"), [0.0]);
    let render = pieces[1];
    assert!(render.contains("NumberOfPoints=\"3\" NumberOfCells=\"1\""));
    assert_eq!(
        numbers_in(render, "Points"),
        [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.5, 1.0, 1.0]
    );
    assert_eq!(numbers_in(render, "connectivity"), [0., 1., 2.]);
    assert_eq!(numbers_in(render, "types"), [5.]);
    assert_eq!(numbers_in(render, "part"), [1.]);
    assert_eq!(numbers_in(render, "body"), [0.]);
    // 37 + (−0.25·0 + 0.25·1 + 0.5·2 + 0.5·3) = 39.75
    assert_eq!(numbers_in(render, "temperature"), [37.0, 37.5, 39.75]);
    std::fs::remove_dir_all(&dir).unwrap();
}
