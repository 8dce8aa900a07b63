//! Mesh module: every kind of malformed input gives its own error variant, and the message
//! names the file, the line and the offending value. Ends with a fuzz-ish test: mutated files
//! never panic a reader.

use std::fs;
use std::path::{Path, PathBuf};

use lop_sim::mesh::{read_gmsh, read_mesh, read_tetgen, read_vtk, MeshReadError, TetMesh};

// ---------------------------------------------------------------------------------------------
// helpers

/// A scratch directory, removed when dropped (unique per process, so concurrent runs of the
/// suite don't clash).
struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;

    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

fn scratch(name: &str) -> Scratch {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("lop-sim-mesh-err-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    Scratch(dir)
}

/// The unit cube, nodes numbered from 1 (node n = corner n-1, corner = x + 2y + 4z).
/// Node n sits on line n + 1.
const NODE1: &str = "8 3 0 0
1 0 0 0
2 1 0 0
3 0 1 0
4 1 1 0
5 0 0 1
6 1 0 1
7 0 1 1
8 1 1 1
";

/// Five positively oriented tetrahedra; tetrahedron k sits on line k + 1.
const ELE1: &str = "5 4 0
1 1 2 4 6
2 3 1 4 7
3 1 5 6 7
4 8 4 6 7
5 4 1 6 7
";

/// Writes `name.node` / `name.ele` (and `.bnd` if given) and returns the base path.
fn tetgen(dir: &Path, node: &str, ele: &str, bnd: Option<&str>) -> PathBuf {
    let base = dir.join("m");
    fs::write(dir.join("m.node"), node).unwrap();
    fs::write(dir.join("m.ele"), ele).unwrap();
    if let Some(bnd) = bnd {
        fs::write(dir.join("m.bnd"), bnd).unwrap();
    }
    base
}

/// Reads a TetGen mesh made of the given texts in a fresh directory.
fn read_tg(name: &str, node: &str, ele: &str, bnd: Option<&str>) -> (Scratch, MeshReadError) {
    let dir = scratch(name);
    let base = tetgen(&dir, node, ele, bnd);
    let err = read_tetgen(&base).expect_err("the mesh should be rejected");
    (dir, err)
}

fn write(dir: &Path, name: &str, text: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    fs::write(&path, text).unwrap();
    path
}

/// Asserts the message contains every needle, and prints it for the test log.
fn says(err: &MeshReadError, needles: &[&str]) {
    let msg = err.to_string();
    println!("{msg}");
    for needle in needles {
        assert!(msg.contains(needle), "{needle:?} missing from: {msg}");
    }
}

fn cube_nodes() -> Vec<[f64; 3]> {
    (0..8)
        .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
        .collect()
}

/// The 0-based tetrahedra of `ELE1`.
fn cube_tets() -> Vec<[u32; 4]> {
    vec![
        [0, 1, 3, 5],
        [2, 0, 3, 6],
        [0, 4, 5, 6],
        [7, 3, 5, 6],
        [3, 0, 5, 6],
    ]
}

fn replace_line(text: &str, line: usize, with: &str) -> String {
    text.lines()
        .enumerate()
        .map(|(i, l)| if i + 1 == line { with } else { l })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}

// ---------------------------------------------------------------------------------------------
// TetGen: indices and numbering

#[test]
fn the_fixture_texts_are_valid() {
    let dir = scratch("valid");
    let base = tetgen(&dir, NODE1, ELE1, Some("1\n8\n"));
    let mesh = read_tetgen(&base).unwrap();
    assert_eq!(mesh.tets, cube_tets());
    assert_eq!(mesh.fixed, vec![7]);
}

#[test]
fn ele_index_out_of_range() {
    let (dir, err) = read_tg("oor", NODE1, &replace_line(ELE1, 4, "3 1 5 6 905"), None);
    match &err {
        MeshReadError::IndexOutOfRange {
            path,
            line,
            index,
            count,
            first_index,
            node_file,
        } => {
            assert_eq!(path, &dir.join("m.ele"));
            assert_eq!(*line, Some(4));
            assert_eq!((*index, *count, *first_index), (905, 8, 1));
            assert_eq!(node_file, &dir.join("m.node"));
        }
        other => panic!("unexpected {other:?}"),
    }
    assert_eq!(
        err.to_string(),
        format!(
            "{}:4: node index 905 out of range (m.node has 8 nodes, numbered from 1)",
            dir.join("m.ele").display()
        )
    );
    assert_eq!(err.line(), Some(4));
    assert_eq!(err.path(), dir.join("m.ele"));
}

#[test]
fn zero_based_node_file_with_one_based_ele() {
    let node0: String = NODE1
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                l.to_owned()
            } else {
                l.replacen(&i.to_string(), &(i - 1).to_string(), 1)
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    // Tetrahedron 4 (line 5) is the first to use node 8.
    let (_, err) = read_tg("base01", &node0, ELE1, None);
    assert!(matches!(
        err,
        MeshReadError::IndexOutOfRange {
            line: Some(5),
            index: 8,
            count: 8,
            first_index: 0,
            ..
        }
    ));
    says(&err, &["m.ele:5:", "node index 8", "numbered from 0"]);
}

#[test]
fn one_based_node_file_with_zero_based_ele() {
    let ele0 = "5 4 0\n0 0 1 3 5\n1 2 0 3 6\n2 0 4 5 6\n3 7 3 5 6\n4 3 0 5 6\n";
    let (_, err) = read_tg("base10", NODE1, ele0, None);
    assert!(matches!(
        err,
        MeshReadError::IndexOutOfRange {
            line: Some(2),
            index: 0,
            first_index: 1,
            ..
        }
    ));
    says(&err, &["m.ele:2:", "node index 0", "numbered from 1"]);
}

#[test]
fn node_numbers_must_start_at_0_or_1_and_be_consecutive() {
    let (_, err) = read_tg("first2", &replace_line(NODE1, 2, "2 0 0 0"), ELE1, None);
    assert!(matches!(err, MeshReadError::Parse { line: 2, .. }));
    says(&err, &["m.node:2:", "numbered 0 or 1", "`2`"]);

    let (_, err) = read_tg("gap", &replace_line(NODE1, 5, "5 1 1 0"), ELE1, None);
    assert!(matches!(err, MeshReadError::Parse { line: 5, .. }));
    says(&err, &["m.node:5:", "point number 4", "`5`"]);
}

#[test]
fn face_file_index_out_of_range() {
    let dir = scratch("face");
    let base = tetgen(&dir, NODE1, ELE1, None);
    write(&dir, "m.face", "2 0\n1 1 2 4\n2 1 2 9\n");
    let err = read_tetgen(&base).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::IndexOutOfRange {
            line: Some(3),
            index: 9,
            ..
        }
    ));
    says(&err, &["m.face:3:", "node index 9"]);
}

// ---------------------------------------------------------------------------------------------
// TetGen: geometry

#[test]
fn duplicate_tet() {
    let ele = format!("6 4 0\n{}6 7 6 1 4\n", &ELE1[6..]);
    let (_, err) = read_tg("dup", NODE1, &ele, None);
    assert!(matches!(
        err,
        MeshReadError::DuplicateTet {
            line: Some(7),
            tet: 6,
            first_line: Some(6),
            first_tet: 5,
            ..
        }
    ));
    says(
        &err,
        &["m.ele:7:", "tetrahedron 6", "tetrahedron 5 (line 6)"],
    );
}

#[test]
fn degenerate_tet() {
    let ele = format!("6 4 0\n{}6 1 2 3 4\n", &ELE1[6..]);
    let (_, err) = read_tg("flat", NODE1, &ele, None);
    assert!(matches!(
        err,
        MeshReadError::DegenerateTet {
            line: Some(7),
            tet: 6,
            nodes: [1, 2, 3, 4],
            ..
        }
    ));
    says(
        &err,
        &["m.ele:7:", "tetrahedron 6", "nodes 1 2 3 4", "degenerate"],
    );

    // A repeated node is degenerate too.
    let (_, err) = read_tg("repeat", NODE1, &replace_line(ELE1, 3, "2 3 1 3 7"), None);
    assert!(
        matches!(err, MeshReadError::DegenerateTet { line: Some(3), volume, .. } if volume == 0.0)
    );
}

#[test]
fn degenerate_threshold_is_relative_to_size() {
    for scale in [1.0, 1e-3, 1e3] {
        let tet = |h: f64| {
            let nodes = vec![
                [0.0, 0.0, 0.0],
                [scale, 0.0, 0.0],
                [0.0, scale, 0.0],
                [0.0, 0.0, h * scale],
            ];
            TetMesh::from_parts(nodes, vec![[0, 1, 2, 3]], vec![], "flat".into())
        };
        // 6V = h scale³ against 1e-12 (√2 scale)³ ≈ 2.8e-12 scale³.
        assert!(matches!(
            tet(1e-12),
            Err(MeshReadError::DegenerateTet { .. })
        ));
        assert!(tet(1e-11).is_ok());
    }
}

#[test]
fn mixed_orientation_reports_the_minority() {
    // Tetrahedron 3 flipped.
    let (_, err) = read_tg("inv", NODE1, &replace_line(ELE1, 4, "3 5 1 6 7"), None);
    match &err {
        MeshReadError::InvertedTet {
            line,
            tet,
            nodes,
            volume,
            inverted,
            total,
            ..
        } => {
            assert_eq!((*line, *tet, *nodes), (Some(4), 3, [5, 1, 6, 7]));
            assert!((volume + 1.0 / 6.0).abs() < 1e-15);
            assert_eq!((*inverted, *total), (1, 5));
        }
        other => panic!("unexpected {other:?}"),
    }
    says(
        &err,
        &["m.ele:4:", "tetrahedron 3", "inverted", "4 of the 5"],
    );

    // All flipped but tetrahedron 2: now tetrahedron 2 is the odd one out.
    let mut ele = String::from("5 4 0\n");
    for (k, line) in ELE1.lines().skip(1).enumerate() {
        let f: Vec<&str> = line.split_whitespace().collect();
        if k == 1 {
            ele += &format!("{line}\n");
        } else {
            ele += &format!("{} {} {} {} {}\n", f[0], f[2], f[1], f[3], f[4]);
        }
    }
    let (_, err) = read_tg("inv2", NODE1, &ele, None);
    assert!(matches!(
        err,
        MeshReadError::InvertedTet { line: Some(3), tet: 2, inverted: 1, volume, .. } if volume > 0.0
    ));
}

#[test]
fn non_finite_coordinates() {
    for (token, shown) in [("nan", "NaN"), ("inf", "inf"), ("-1e999", "-inf")] {
        let node = replace_line(NODE1, 4, &format!("3 0 {token} 0"));
        let (_, err) = read_tg(&format!("nan-{token}"), &node, ELE1, None);
        match &err {
            MeshReadError::NonFiniteCoordinate {
                line, node, value, ..
            } => {
                assert_eq!((*line, *node), (Some(4), 3));
                assert!(!value.is_finite());
            }
            other => panic!("unexpected {other:?}"),
        }
        says(&err, &["m.node:4:", shown, "node 3", "not finite"]);
    }
}

#[test]
fn declared_counts_must_match() {
    let cases = [
        (
            "node9",
            replace_line(NODE1, 1, "9 3 0 0"),
            ELE1.to_owned(),
            "m.node:1:",
            9,
            8,
        ),
        (
            "node7",
            replace_line(NODE1, 1, "7 3 0 0"),
            ELE1.to_owned(),
            "m.node:1:",
            7,
            8,
        ),
        (
            "ele6",
            NODE1.to_owned(),
            replace_line(ELE1, 1, "6 4 0"),
            "m.ele:1:",
            6,
            5,
        ),
        (
            "ele4",
            NODE1.to_owned(),
            replace_line(ELE1, 1, "4 4 0"),
            "m.ele:1:",
            4,
            5,
        ),
    ];
    for (name, node, ele, at, d, f) in cases {
        let (_, err) = read_tg(name, &node, &ele, None);
        match &err {
            MeshReadError::CountMismatch {
                line,
                declared,
                found,
                ..
            } => {
                assert_eq!((*line, *declared, *found), (1, d, f), "{name}");
            }
            other => panic!("{name}: unexpected {other:?}"),
        }
        says(&err, &[at, &format!("declares {d}"), &format!("has {f}")]);
    }
}

#[test]
fn garbage_tokens_and_wrong_field_counts() {
    let (_, err) = read_tg("garbage", &replace_line(NODE1, 4, "3 0 1x 0"), ELE1, None);
    assert!(matches!(&err, MeshReadError::Parse { line: 4, found, .. } if found == "`1x`"));
    says(&err, &["m.node:4:", "y coordinate of point 3", "`1x`"]);

    let (_, err) = read_tg(
        "garbage-ele",
        NODE1,
        &replace_line(ELE1, 3, "2 3 one 4 7"),
        None,
    );
    assert!(matches!(err, MeshReadError::Parse { line: 3, .. }));
    says(&err, &["m.ele:3:", "node 2 of tetrahedron 2", "`one`"]);

    let (_, err) = read_tg("short", NODE1, &replace_line(ELE1, 6, "5 4 1 6"), None);
    assert!(matches!(err, MeshReadError::Parse { line: 6, .. }));
    says(&err, &["m.ele:6:", "5 fields", "`5 4 1 6`"]);

    let (_, err) = read_tg("long", &replace_line(NODE1, 9, "8 1 1 1 0"), ELE1, None);
    says(&err, &["m.node:9:", "4 fields", "5 fields"]);

    let (_, err) = read_tg("dim2", &replace_line(NODE1, 1, "8 2 0 0"), ELE1, None);
    says(&err, &["m.node:1:", "dimension 3", "`2`"]);

    let (_, err) = read_tg("npt", NODE1, &replace_line(ELE1, 1, "5 6 0"), None);
    says(&err, &["m.ele:1:", "4 or 10", "`6`"]);
}

#[test]
fn missing_ele_is_an_io_error() {
    let dir = scratch("noele");
    write(&dir, "m.node", NODE1);
    let err = read_mesh(&dir.join("m.node")).unwrap_err();
    match &err {
        MeshReadError::Io { path, source } => {
            assert_eq!(path, &dir.join("m.ele"));
            assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
        }
        other => panic!("unexpected {other:?}"),
    }
    says(&err, &["m.ele", "cannot read"]);
}

#[test]
fn empty_files() {
    let (_, err) = read_tg("empty-node", "", ELE1, None);
    assert!(matches!(&err, MeshReadError::Parse { line: 1, found, .. } if found == "end of file"));
    says(&err, &["m.node:1:", "end of file"]);

    let (_, err) = read_tg("comments-only", "# nothing\n\n# here\n", ELE1, None);
    assert!(matches!(err, MeshReadError::Parse { line: 3, .. }));

    let (_, err) = read_tg("empty-ele", NODE1, "", None);
    says(&err, &["m.ele:1:", "end of file"]);

    let (_, err) = read_tg("zero-tets", NODE1, "0 4 0\n", None);
    assert!(matches!(err, MeshReadError::NoTets { .. }));
    says(&err, &["m.ele", "no tetrahedra"]);

    let dir = scratch("empty-other");
    let err = read_gmsh(&write(&dir, "e.msh", "")).unwrap_err();
    assert!(matches!(err, MeshReadError::Parse { line: 1, .. }));
    says(&err, &["e.msh:1:", "$MeshFormat", "end of file"]);
    let err = read_vtk(&write(&dir, "e.vtk", "")).unwrap_err();
    assert!(matches!(err, MeshReadError::Parse { line: 1, .. }));
    says(&err, &["e.vtk:1:", "end of file"]);
}

#[test]
fn not_utf8() {
    let dir = scratch("utf8");
    let mut node = NODE1.as_bytes().to_vec();
    node.splice(22..22, [0xff, 0xfe]); // inside line 3
    let base = tetgen(&dir, "", ELE1, None);
    fs::write(dir.join("m.node"), &node).unwrap();
    let err = read_tetgen(&base).unwrap_err();
    assert!(matches!(err, MeshReadError::Parse { line: 3, .. }));
    says(&err, &["m.node:3:", "UTF-8", "0xff"]);
}

// ---------------------------------------------------------------------------------------------
// Boundary files

#[test]
fn boundary_index_out_of_range() {
    let (_, err) = read_tg("bnd9", NODE1, ELE1, Some("# fixed\n2\n1\n9\n"));
    assert!(matches!(
        err,
        MeshReadError::BadBoundary {
            line: Some(4),
            index: 9,
            count: 8,
            first_index: 1,
            ..
        }
    ));
    says(
        &err,
        &[
            "m.bnd:4:",
            "boundary node 9 out of range (m.node has 8 nodes, numbered from 1)",
        ],
    );

    let (_, err) = read_tg("bnd0", NODE1, ELE1, Some("1\n0\n"));
    assert!(matches!(err, MeshReadError::BadBoundary { index: 0, .. }));
}

#[test]
fn boundary_count_and_garbage() {
    let (_, err) = read_tg("bndcount", NODE1, ELE1, Some("3\n1\n2\n"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 1,
            what: "boundary nodes",
            declared: 3,
            found: 2,
            ..
        }
    ));
    says(&err, &["m.bnd:1:", "3 boundary nodes", "has 2"]);

    let (_, err) = read_tg("bndextra", NODE1, ELE1, Some("1\n1\n2\n"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            declared: 1,
            found: 2,
            ..
        }
    ));

    let (_, err) = read_tg("bndgarbage", NODE1, ELE1, Some("2\n1\nfoo\n"));
    assert!(matches!(err, MeshReadError::Parse { line: 3, .. }));
    says(&err, &["m.bnd:3:", "`foo`"]);

    let (_, err) = read_tg("bndtwo", NODE1, ELE1, Some("2\n1 2\n"));
    says(&err, &["m.bnd:2:", "1 field (one node number)", "2 fields"]);

    let (_, err) = read_tg("bndempty", NODE1, ELE1, Some("# nothing\n"));
    says(&err, &["m.bnd:1:", "number of fixed nodes", "end of file"]);
}

// ---------------------------------------------------------------------------------------------
// Gmsh

const MSH22: &str = "$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
8
1 0 0 0
2 1 0 0
3 0 1 0
4 1 1 0
5 0 0 1
6 1 0 1
7 0 1 1
8 1 1 1
$EndNodes
$Elements
6
1 2 2 0 1 1 2 4
2 4 2 0 1 1 2 4 6
3 4 2 0 1 3 1 4 7
4 4 2 0 1 1 5 6 7
5 4 2 0 1 8 4 6 7
6 4 2 0 1 4 1 6 7
$EndElements
";

/// The same cube in format 4.1, with a triangle block to skip.
const MSH41: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$Nodes
2 8 1 8
2 1 0 4
1
2
3
4
0 0 0
1 0 0
0 1 0
1 1 0
3 1 0 4
5
6
7
8
0 0 1
1 0 1
0 1 1
1 1 1
$EndNodes
$Elements
2 6 1 6
2 1 2 1
1 1 2 4
3 1 4 5
2 1 2 4 6
3 3 1 4 7
4 1 5 6 7
5 8 4 6 7
6 4 1 6 7
$EndElements
";

fn read_msh(name: &str, text: impl AsRef<[u8]>) -> (Scratch, MeshReadError) {
    let dir = scratch(name);
    let path = write(&dir, "m.msh", text);
    (
        dir,
        read_gmsh(&path).expect_err("the mesh should be rejected"),
    )
}

#[test]
fn gmsh_fixture_is_valid() {
    let dir = scratch("msh-valid");
    let mesh = read_mesh(&write(&dir, "m.msh", MSH22)).unwrap();
    assert_eq!(mesh.tets, cube_tets());
}

#[test]
fn gmsh41_fixture_is_valid_and_checks_block_counts() {
    let dir = scratch("msh41-valid");
    let mesh = read_mesh(&write(&dir, "m.msh", MSH41)).unwrap();
    assert_eq!(mesh.tets, cube_tets());

    // Block of 4 nodes declared as 5: it runs into the coordinates' count.
    let (_, err) = read_msh("msh41-block", replace_line(MSH41, 6, "2 1 0 5"));
    says(&err, &["m.msh:"]);
    // Header total disagrees with the blocks.
    let (_, err) = read_msh("msh41-total", replace_line(MSH41, 5, "2 9 1 8"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 5,
            declared: 9,
            found: 8,
            ..
        }
    ));
    let (_, err) = read_msh("msh41-elements", replace_line(MSH41, 26, "2 7 1 6"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 26,
            declared: 7,
            found: 6,
            ..
        }
    ));
    let (_, err) = read_msh("msh41-param", replace_line(MSH41, 11, "0 0 0 0.5"));
    says(&err, &["m.msh:11:", "3 fields", "4 fields"]);
}

#[test]
fn gmsh_unknown_node_tag() {
    let (_, err) = read_msh("msh-tag", replace_line(MSH22, 20, "4 4 2 0 1 1 5 6 70"));
    assert!(matches!(
        err,
        MeshReadError::UnknownNodeTag {
            line: 20,
            tag: 70,
            ..
        }
    ));
    says(&err, &["m.msh:20:", "node tag 70", "$Nodes"]);
}

#[test]
fn gmsh_counts() {
    let (_, err) = read_msh("msh-more", replace_line(MSH22, 5, "9"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 5,
            declared: 9,
            found: 8,
            ..
        }
    ));
    says(&err, &["m.msh:5:", "declares 9 nodes", "has 8"]);

    let (_, err) = read_msh("msh-fewer", replace_line(MSH22, 16, "5"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 16,
            declared: 5,
            found: 6,
            ..
        }
    ));

    let truncated: String = MSH22.lines().take(19).map(|l| format!("{l}\n")).collect();
    let (_, err) = read_msh("msh-trunc", truncated);
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            declared: 6,
            found: 3,
            ..
        }
    ));
}

#[test]
fn gmsh_garbage_and_structure() {
    let (_, err) = read_msh("msh-garbage", replace_line(MSH22, 8, "3 0 1,5 0"));
    assert!(matches!(err, MeshReadError::Parse { line: 8, .. }));
    says(&err, &["m.msh:8:", "y coordinate of node 3", "`1,5`"]);

    let (_, err) = read_msh("msh-dup", replace_line(MSH22, 8, "2 0 1 0"));
    says(&err, &["m.msh:8:", "tag 2 again (first on line 7)"]);

    let (_, err) = read_msh("msh-nan", replace_line(MSH22, 8, "3 0 NaN 0"));
    assert!(matches!(
        err,
        MeshReadError::NonFiniteCoordinate {
            line: Some(8),
            node: 3,
            ..
        }
    ));

    let (_, err) = read_msh("msh-tetfields", replace_line(MSH22, 19, "3 4 2 0 1 3 1 4"));
    says(&err, &["m.msh:19:", "9 fields"]);

    let (_, err) = read_msh("msh-noend", MSH22.replace("$EndElements\n", ""));
    says(&err, &["`$EndElements`", "end of file"]);

    let (_, err) = read_msh("msh-v1", "$NOD\n1\n1 0 0 0\n$ENDNOD\n");
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
}

#[test]
fn gmsh_unsupported_versions_and_binary() {
    let (_, err) = read_msh("msh-40", MSH22.replace("2.2 0 8", "4 0 8"));
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(&err, &["m.msh", "Gmsh format 4", "re-export"]);

    let mut binary = b"$MeshFormat\n4.1 1 8\n".to_vec();
    binary.extend_from_slice(&1i32.to_le_bytes());
    binary.extend_from_slice(b"\n$EndMeshFormat\n$Nodes\n");
    binary.extend_from_slice(&[0xff, 0x00, 0x80, 0xc3, 0x28, 0x0a]);
    let (_, err) = read_msh("msh-binary", binary);
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(&err, &["m.msh", "binary"]);

    // A binary flag with an all-ASCII payload is caught too.
    let (_, err) = read_msh("msh-binary2", MSH22.replace("2.2 0 8", "2.2 1 8"));
    says(&err, &["binary"]);
}

#[test]
fn gmsh_without_tetrahedra() {
    let text: String = MSH22
        .lines()
        .enumerate()
        .filter(|&(i, _)| !(18..=22).contains(&(i + 1)))
        .map(|(_, l)| format!("{l}\n"))
        .collect::<String>()
        .replace("$Elements\n6\n", "$Elements\n1\n");
    let (_, err) = read_msh("msh-notets", text);
    assert!(matches!(err, MeshReadError::NoTets { skipped: 1, .. }));
    says(
        &err,
        &["m.msh", "no tetrahedra", "1 elements of other types"],
    );
}

#[test]
fn gmsh_boundary_unknown_tag() {
    let dir = scratch("msh-bnd");
    let path = write(&dir, "m.msh", MSH22);
    write(&dir, "m.bnd", "2\n1\n42\n");
    let err = read_mesh(&path).unwrap_err();
    assert!(
        matches!(&err, MeshReadError::UnknownNodeTag { path, line: 3, tag: 42, .. } if path == &dir.join("m.bnd"))
    );
    says(&err, &["m.bnd:3:", "node tag 42", "m.msh"]);
}

// ---------------------------------------------------------------------------------------------
// VTK

const VTK: &str = "# vtk DataFile Version 3.0
cube
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 8 double
0 0 0
1 0 0
0 1 0
1 1 0
0 0 1
1 0 1
0 1 1
1 1 1
CELLS 5 25
4 0 1 3 5
4 2 0 3 6
4 0 4 5 6
4 7 3 5 6
4 3 0 5 6
CELL_TYPES 5
10
10
10
10
10
";

fn read_vtk_text(name: &str, text: impl AsRef<[u8]>) -> (Scratch, MeshReadError) {
    let dir = scratch(name);
    let path = write(&dir, "m.vtk", text);
    (
        dir,
        read_vtk(&path).expect_err("the mesh should be rejected"),
    )
}

#[test]
fn vtk_fixture_is_valid() {
    let dir = scratch("vtk-valid");
    let mesh = read_mesh(&write(&dir, "m.vtk", VTK)).unwrap();
    assert_eq!(mesh.tets, cube_tets());
}

#[test]
fn vtk_errors() {
    let (_, err) = read_vtk_text("vtk-oor", replace_line(VTK, 17, "4 7 3 5 8"));
    assert!(matches!(
        err,
        MeshReadError::IndexOutOfRange {
            line: Some(17),
            index: 8,
            count: 8,
            first_index: 0,
            ..
        }
    ));
    says(
        &err,
        &[
            "m.vtk:17:",
            "node index 8",
            "m.vtk has 8 nodes, numbered from 0",
        ],
    );

    let (_, err) = read_vtk_text("vtk-points", replace_line(VTK, 5, "POINTS 9 double"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            line: 5,
            what: "points",
            declared: 9,
            found: 8,
            ..
        }
    ));
    says(&err, &["m.vtk:5:", "declares 9 points", "has 8"]);

    let (_, err) = read_vtk_text("vtk-points7", replace_line(VTK, 5, "POINTS 7 double"));
    assert!(matches!(
        err,
        MeshReadError::CountMismatch {
            declared: 7,
            found: 8,
            ..
        }
    ));

    let (_, err) = read_vtk_text("vtk-types", replace_line(VTK, 20, "CELL_TYPES 4"));
    assert!(matches!(err, MeshReadError::CountMismatch { line: 20, .. }));

    let (_, err) = read_vtk_text("vtk-nan", replace_line(VTK, 8, "0 nan 0"));
    assert!(matches!(
        err,
        MeshReadError::NonFiniteCoordinate {
            line: Some(8),
            node: 2,
            ..
        }
    ));
    says(&err, &["m.vtk:8:", "NaN", "node 2"]);

    let (_, err) = read_vtk_text("vtk-garbage", replace_line(VTK, 8, "0 one 0"));
    assert!(matches!(err, MeshReadError::Parse { line: 8, .. }));
    says(&err, &["m.vtk:8:", "y coordinate of point 2", "`one`"]);

    let (_, err) = read_vtk_text("vtk-tri", replace_line(VTK, 16, "3 7 3 5"));
    says(&err, &["m.vtk"]);

    let (_, err) = read_vtk_text("vtk-poly", VTK.replace("UNSTRUCTURED_GRID", "POLYDATA"));
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));

    let (_, err) = read_vtk_text("vtk-binary", VTK.replace("ASCII", "BINARY"));
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(&err, &["binary"]);

    let (_, err) = read_vtk_text(
        "vtk-header",
        VTK.replace("# vtk DataFile", "# vtx DataFile"),
    );
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));

    let types: String = VTK.lines().take(19).map(|l| format!("{l}\n")).collect();
    let (_, err) = read_vtk_text("vtk-notypes", types);
    says(&err, &["CELL_TYPES", "end of file"]);

    let dir = scratch("vtk-bnd");
    let path = write(&dir, "m.vtk", VTK);
    write(&dir, "m.bnd", "1\n8\n");
    let err = read_mesh(&path).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::BadBoundary {
            line: Some(2),
            index: 8,
            first_index: 0,
            ..
        }
    ));
    says(&err, &["m.bnd:2:", "boundary node 8"]);
}

// ---------------------------------------------------------------------------------------------
// from_parts and surfaces

#[test]
fn from_parts_errors_have_no_lines() {
    let mut tets = cube_tets();
    tets[2][1] = 8;
    let err = TetMesh::from_parts(cube_nodes(), tets, vec![], "gen".into()).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::IndexOutOfRange {
            line: None,
            index: 8,
            count: 8,
            first_index: 0,
            ..
        }
    ));
    assert_eq!(
        err.to_string(),
        "gen: node index 8 out of range (gen has 8 nodes, numbered from 0)"
    );

    let err = TetMesh::from_parts(cube_nodes(), cube_tets(), vec![8], "".into()).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::BadBoundary {
            line: None,
            index: 8,
            ..
        }
    ));
    assert_eq!(
        err.to_string(),
        "(in-memory mesh): boundary node 8 out of range (the mesh has 8 nodes, numbered from 0)"
    );

    let mut nodes = cube_nodes();
    nodes[5][2] = f64::NAN;
    let err = TetMesh::from_parts(nodes, cube_tets(), vec![], "gen".into()).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::NonFiniteCoordinate {
            line: None,
            node: 5,
            ..
        }
    ));

    let err = TetMesh::from_parts(cube_nodes(), vec![], vec![], "gen".into()).unwrap_err();
    assert!(matches!(err, MeshReadError::NoTets { skipped: 0, .. }));

    let mut tets = cube_tets();
    tets.push([6, 5, 0, 3]);
    let err = TetMesh::from_parts(cube_nodes(), tets, vec![], "gen".into()).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::DuplicateTet {
            line: None,
            tet: 5,
            first_tet: 4,
            ..
        }
    ));
    says(
        &err,
        &["gen: tetrahedron 5 uses the same four nodes as tetrahedron 4"],
    );

    let mut tets = cube_tets();
    tets[1].swap(0, 1);
    let err = TetMesh::from_parts(cube_nodes(), tets, vec![], "gen".into()).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::InvertedTet {
            line: None,
            tet: 1,
            ..
        }
    ));
}

/// Triangle (0, 1, 2) in the plane z = 0 and apexes above and below it.
fn fan(apexes: &[[f64; 3]]) -> Result<TetMesh, MeshReadError> {
    let mut nodes = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let mut tets = Vec::new();
    for (k, &apex) in apexes.iter().enumerate() {
        nodes.push(apex);
        let apex_index = 3 + k as u32;
        // Orient positively by hand: the apex above the plane needs (0, 1, 2, apex).
        tets.push(if apex[2] > 0.0 {
            [0, 1, 2, apex_index]
        } else {
            [0, 2, 1, apex_index]
        });
    }
    TetMesh::from_parts(nodes, tets, vec![], "fan".into())
}

#[test]
fn two_tets_sharing_a_face_are_fine() {
    let mesh = fan(&[[0.2, 0.2, 1.0], [0.2, 0.2, -1.0]]).unwrap();
    assert_eq!(mesh.surface.len(), 6);
}

#[test]
fn overlapping_tets() {
    let err = fan(&[[0.2, 0.2, 1.0], [0.3, 0.3, 2.0]]).unwrap_err();
    assert!(matches!(
        err,
        MeshReadError::OverlappingTets {
            tet: 1,
            other_tet: 0,
            face: [0, 2, 1],
            ..
        }
    ));
    says(
        &err,
        &[
            "fan: tetrahedron 1",
            "face 0 2 1",
            "tetrahedron 0",
            "overlap",
        ],
    );
}

#[test]
fn non_manifold_face() {
    let err = fan(&[[0.2, 0.2, 1.0], [0.2, 0.2, -1.0], [0.3, 0.3, 2.0]]).unwrap_err();
    assert!(matches!(err, MeshReadError::NonManifoldFace { tet: 2, .. }));
    says(&err, &["fan: tetrahedron 2", "third", "not a manifold"]);
}

#[test]
fn non_manifold_in_a_file_names_the_line() {
    let node = "6 3\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0.2 0.2 1\n4 0.2 0.2 -1\n5 0.3 0.3 2\n";
    let ele = "3 4\n0 0 1 2 3\n1 0 2 1 4\n2 0 1 2 5\n";
    let (_, err) = read_tg("nonmanifold", node, ele, None);
    assert!(matches!(
        err,
        MeshReadError::NonManifoldFace {
            line: Some(4),
            tet: 2,
            ..
        }
    ));
    says(&err, &["m.ele:4:", "tetrahedron 2"]);
}

// ---------------------------------------------------------------------------------------------
// dispatch

#[test]
fn read_mesh_dispatch_errors() {
    let dir = scratch("dispatch");
    let err = read_mesh(&dir.join("nothing")).unwrap_err();
    assert!(
        matches!(&err, MeshReadError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
    );
    says(&err, &["nothing", "nothing.node"]);

    let err = read_mesh(&write(&dir, "liver.obj", "v 0 0 0\n")).unwrap_err();
    assert!(matches!(err, MeshReadError::UnsupportedFormat { .. }));
    says(&err, &["liver.obj", "TetGen", ".msh", ".vtk"]);

    let err = read_mesh(&dir.join("gone.msh")).unwrap_err();
    assert!(matches!(err, MeshReadError::Io { .. }));
}

// ---------------------------------------------------------------------------------------------
// fuzz-ish: mutated inputs never panic

/// xorshift64*: deterministic, dependency-free.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const TOKENS: [&str; 16] = [
    "",
    "0",
    "-1",
    "1",
    "8",
    "9",
    "4",
    "10",
    "nan",
    "-inf",
    "1e999",
    "x",
    "$EndNodes",
    "99999999999999999999",
    "1.5",
    "\u{feff}",
];

fn mutate(rng: &mut Rng, text: &[u8]) -> Vec<u8> {
    let mut out = text.to_vec();
    for _ in 0..1 + rng.below(2) * rng.below(3) {
        match rng.below(6) {
            0 => {
                let at = rng.below(out.len() + 1);
                out.truncate(at);
            }
            1 => {
                // Replace a whitespace-separated token.
                let s = String::from_utf8_lossy(&out).into_owned();
                let tokens: Vec<&str> = s.split_inclusive(char::is_whitespace).collect();
                if tokens.is_empty() {
                    continue;
                }
                let k = rng.below(tokens.len());
                let with = TOKENS[rng.below(TOKENS.len())];
                let mut joined = String::new();
                for (i, t) in tokens.iter().enumerate() {
                    if i == k {
                        joined.push_str(with);
                        joined.push_str(&t[t.trim_end().len()..]);
                    } else {
                        joined.push_str(t);
                    }
                }
                out = joined.into_bytes();
            }
            2 => {
                // Delete or duplicate a line.
                let s = String::from_utf8_lossy(&out).into_owned();
                let mut lines: Vec<&str> = s.lines().collect();
                if lines.is_empty() {
                    continue;
                }
                let k = rng.below(lines.len());
                if rng.below(2) == 0 {
                    lines.remove(k);
                } else {
                    lines.insert(k, lines[k]);
                }
                out = (lines.join("\n") + "\n").into_bytes();
            }
            3 => {
                if !out.is_empty() {
                    let k = rng.below(out.len());
                    out[k] = b" 0123456789.-e\n#$x"[rng.below(18)];
                }
            }
            4 => {
                let k = rng.below(out.len() + 1);
                out.insert(k, (rng.next() & 0xff) as u8);
            }
            _ => {
                // Swap two digits somewhere: changes indices and counts plausibly.
                let digits: Vec<usize> = (0..out.len())
                    .filter(|&i| out[i].is_ascii_digit())
                    .collect();
                if digits.len() >= 2 {
                    let a = digits[rng.below(digits.len())];
                    let b = digits[rng.below(digits.len())];
                    out.swap(a, b);
                }
            }
        }
    }
    out
}

/// Checks what a successful read promises.
fn check_ok(mesh: &TetMesh) {
    let n = mesh.nodes.len() as u32;
    assert!(!mesh.tets.is_empty());
    for (i, t) in mesh.tets.iter().enumerate() {
        assert!(t.iter().all(|&v| v < n));
        assert!(mesh.tet_volume(i) > 0.0);
    }
    assert!(mesh.surface.iter().flatten().all(|&v| v < n));
    assert!(mesh.fixed.windows(2).all(|w| w[0] < w[1]));
    assert!(mesh.fixed.iter().all(|&v| v < n));
    assert!(mesh.nodes.iter().flatten().all(|v| v.is_finite()));
    let info = mesh.info();
    assert!(info.volume > 0.0 && info.quality_min > 0.0 && info.quality_mean <= 1.0 + 1e-12);
}

#[test]
fn mutated_files_never_panic() {
    let dir = scratch("fuzz");
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut outcomes = [0usize; 2];
    for round in 0..600 {
        let which = round % 5;
        let result = match which {
            0 | 1 => {
                let (node, ele) = if which == 0 {
                    (mutate(&mut rng, NODE1.as_bytes()), ELE1.as_bytes().to_vec())
                } else {
                    (NODE1.as_bytes().to_vec(), mutate(&mut rng, ELE1.as_bytes()))
                };
                fs::write(dir.join("f.node"), node).unwrap();
                fs::write(dir.join("f.ele"), ele).unwrap();
                let bnd = mutate(&mut rng, b"2\n1\n8\n");
                fs::write(dir.join("f.bnd"), bnd).unwrap();
                read_mesh(&dir.join("f"))
            }
            2 => {
                let path = write(&dir, "f.msh", mutate(&mut rng, MSH22.as_bytes()));
                read_mesh(&path)
            }
            3 => {
                let path = write(&dir, "g.msh", mutate(&mut rng, MSH41.as_bytes()));
                read_mesh(&path)
            }
            _ => {
                let path = write(&dir, "f.vtk", mutate(&mut rng, VTK.as_bytes()));
                read_mesh(&path)
            }
        };
        match result {
            Ok(mesh) => {
                check_ok(&mesh);
                outcomes[0] += 1;
            }
            Err(err) => {
                let msg = err.to_string();
                if std::env::var_os("LOP_MESH_FUZZ_LOG").is_some() {
                    eprintln!("{msg}");
                }
                assert!(
                    msg.contains(dir.to_str().unwrap()),
                    "message does not name the file: {msg}"
                );
                outcomes[1] += 1;
            }
        }
    }
    // The mutations must exercise both paths.
    println!("ok: {}, errors: {}", outcomes[0], outcomes[1]);
    assert!(outcomes[0] >= 20 && outcomes[1] >= 300, "{outcomes:?}");
}
