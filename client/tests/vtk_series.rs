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
