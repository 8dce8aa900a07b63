//! Mesh and surface readers against the committed corpus: no panic, bounded memory, and every
//! refusal names the file and says where.
//!
//! The corpus is `tests/corpus/mesh/` (read with `read_mesh`: TetGen `.node`/`.ele`/`.face`/
//! `.bnd`, Gmsh 1, 2.2 and 4.1, legacy VTK ASCII and binary, VTK XML) and
//! `tests/corpus/surface/` (read with `read_surface`: STL ASCII and binary, OBJ, PLY ASCII and
//! binary). It holds valid files and known-nasty ones: headers claiming 10¹² records
//! (`huge-*`), NaN coordinates, truncation, invalid UTF-8, a BOM with CRLF, very long lines,
//! deep XML nesting. Each seed is read as it is, then [`ROUNDS`] deterministic mutations of it
//! (`lop_test_support::fuzz`; `LOP_FUZZ_ROUNDS` runs more, `LOP_FUZZ_LOG` prints each
//! refusal). A TetGen seed is mutated alone, its siblings of the same stem (`cube.node` with
//! `cube.ele`, ...) copied beside it unchanged.
//!
//! For every read:
//! - a success satisfies what a mesh promises (indices in range, finite coordinates, positive
//!   volumes);
//! - a refusal names the file it is about, and says the line or the byte offset unless it is
//!   about the whole file (no tetrahedra, an unsupported format, too many nodes, a file that is
//!   missing);
//! - the largest single allocation stays under 4 MiB plus 64 bytes per input byte: memory
//!   follows what the file holds, never what its header claims.
//!
//! `huge_headers_are_refused_before_allocating` checks the `huge-*` seeds on their own: each is
//! refused, the message names the file, the line or byte and the claimed count, and nothing
//! near the claim is allocated (the `mesh_vtk_bounded` test of the VTK readers, for all).
//! What keeps memory bounded: the text readers reserve at most 65,536 records ahead whatever
//! the header says (TetGen, `.bnd`, Gmsh 4.1 node tags and PLY no more than the file's size
//! could hold: under 64 KiB here) and fail at the end of the file; the binary readers compare
//! a count with the bytes left before reading.

use std::fs;
use std::path::{Path, PathBuf};

use lop_sim::mesh::{read_mesh, read_surface, MeshReadError, SurfaceMesh, TetMesh};
use lop_test_support::alloc::largest_on_this_thread;
use lop_test_support::fuzz::{self, Rng, Seed};

// The counting allocator (`Counting::armed_threads`) is installed once for this
// test binary, in `main.rs`.

/// Mutations per seed (about 6,000 reads in all, about a second in the dev profile).
const ROUNDS: usize = 100;

/// The format's own words, for the mutator.
const DICTIONARY: &[&[u8]] = &[
    b"$Nodes",
    b"$EndNodes",
    b"$Elements",
    b"$EndElements",
    b"$MeshFormat",
    b"$ENDNOD",
    b"$ELM",
    b"POINTS",
    b"CELLS",
    b"CELL_TYPES",
    b"OFFSETS",
    b"CONNECTIVITY",
    b"double",
    b"vtktypeint64",
    b"BINARY",
    b"</DataArray>",
    b"format=\"binary\"",
    b"NumberOfPoints=\"",
    b"endsolid",
    b"facet normal",
    b"end_header",
    b"element vertex",
    b"property list uint int",
    b"f -1 -2 -3",
    b"10",
    b"4",
];

fn corpus_dir(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/corpus")
        .join(name)
}

/// A fresh scratch directory for this process.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("lop-sim-corpus-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

fn is_tetgen(name: &str) -> bool {
    [".node", ".ele", ".face", ".bnd"]
        .iter()
        .any(|e| name.ends_with(e))
}

fn stem(name: &str) -> &str {
    name.rsplit_once('.').map_or(name, |(s, _)| s)
}

/// Writes `bytes` as `seed` in `dir` (with its TetGen siblings from the corpus beside it) and
/// returns the path to read.
fn stage(dir: &Path, seeds: &[Seed], seed: &Seed, bytes: &[u8]) -> PathBuf {
    let _ = fs::remove_dir_all(dir);
    fs::create_dir_all(dir).unwrap();
    if is_tetgen(&seed.name) {
        for s in seeds
            .iter()
            .filter(|s| is_tetgen(&s.name) && stem(&s.name) == stem(&seed.name))
        {
            fs::write(dir.join(&s.name), &s.bytes).unwrap();
        }
    }
    let path = dir.join(&seed.name);
    fs::write(&path, bytes).unwrap();
    path
}

/// The allocation a reader may make for an input of `len` bytes.
fn allowed(len: usize) -> u64 {
    (4 << 20) + 64 * len as u64
}

fn check_mesh(mesh: &TetMesh) {
    let n = mesh.nodes.len() as u32;
    assert!(!mesh.tets.is_empty());
    for (i, t) in mesh.tets.iter().enumerate() {
        assert!(t.iter().all(|&v| v < n));
        assert!(mesh.tet_volume(i) > 0.0);
    }
    assert!(mesh.surface.iter().flatten().all(|&v| v < n));
    assert!(mesh.fixed.iter().all(|&v| v < n));
    assert!(mesh.nodes.iter().flatten().all(|v| v.is_finite()));
}

fn check_surface(s: &SurfaceMesh) {
    let n = s.vertices.len() as u32;
    assert!(s.triangles.iter().flatten().all(|&v| v < n));
    assert!(s.vertices.iter().flatten().all(|v| v.is_finite()));
}

/// Checks a refusal of `path` (read from `dir`): it names a file in `dir`, and a line or a byte
/// unless it is about the whole file.
fn check_refusal(err: &MeshReadError, dir: &Path, what: &str) {
    let msg = err.to_string();
    if fuzz::log() {
        eprintln!("{msg}");
    }
    assert!(
        msg.contains(dir.to_str().unwrap()),
        "{what}: the message does not name the file: {msg}"
    );
    let whole_file = matches!(
        err,
        MeshReadError::Io { .. }
            | MeshReadError::UnsupportedFormat { .. }
            | MeshReadError::NoTets { .. }
            | MeshReadError::TooManyNodes { .. }
    );
    // Errors found while building the mesh from a binary file have no line; they name the
    // tetrahedron or node by its number instead.
    let built = matches!(
        err,
        MeshReadError::DuplicateTet { .. }
            | MeshReadError::DegenerateTet { .. }
            | MeshReadError::InvertedTet { .. }
            | MeshReadError::OverlappingTets { .. }
            | MeshReadError::NonManifoldFace { .. }
            | MeshReadError::IndexOutOfRange { .. }
            | MeshReadError::NonFiniteCoordinate { .. }
    );
    assert!(
        err.line().is_some() || err.offset().is_some() || whole_file || built,
        "{what}: the message says no line or byte: {msg}"
    );
}

/// Reads every seed of corpus `name` and its mutations with `read`; returns (successes,
/// refusals).
fn run_corpus<T>(
    name: &str,
    state: u64,
    read: impl Fn(&Path) -> Result<T, MeshReadError>,
    check: impl Fn(&T),
) -> [usize; 2] {
    let seeds = fuzz::corpus(&corpus_dir(name));
    let root = scratch(name);
    let rounds = fuzz::rounds(ROUNDS);
    let mut outcomes = [0; 2];
    for seed in &seeds {
        let mut rng = Rng::for_seed(state, &seed.name);
        let dir = root.join(stem(&seed.name));
        // The siblings once; each round rewrites only the seed's file.
        let path = stage(&dir, &seeds, seed, &seed.bytes);
        for round in 0..=rounds {
            let bytes = if round == 0 {
                seed.bytes.clone()
            } else {
                fuzz::mutate(&mut rng, &seed.bytes, DICTIONARY)
            };
            let what = format!("{} round {round}", seed.name);
            fs::write(&path, &bytes).unwrap();
            let (result, largest) = largest_on_this_thread(|| read(&path));
            assert!(
                largest <= allowed(bytes.len()),
                "{what}: an allocation of {largest} bytes for a {}-byte file",
                bytes.len()
            );
            match result {
                Ok(value) => {
                    check(&value);
                    outcomes[0] += 1;
                }
                Err(err) => {
                    check_refusal(&err, &dir, &what);
                    outcomes[1] += 1;
                }
            }
        }
    }
    let _ = fs::remove_dir_all(&root);
    println!(
        "{name}: {} seeds, ok: {}, refused: {}",
        seeds.len(),
        outcomes[0],
        outcomes[1]
    );
    outcomes
}

#[test]
fn mesh_corpus_and_its_mutations_never_panic() {
    let [ok, refused] = run_corpus("mesh", 0x9e37_79b9_7f4a_7c15, read_mesh, check_mesh);
    // The mutations must exercise both paths.
    assert!(ok >= 50 && refused >= 500, "ok {ok}, refused {refused}");
}

#[test]
fn surface_corpus_and_its_mutations_never_panic() {
    let [ok, refused] = run_corpus(
        "surface",
        0x2545_f491_4f6c_dd1d,
        read_surface,
        check_surface,
    );
    assert!(ok >= 20 && refused >= 100, "ok {ok}, refused {refused}");
}

/// The claims of the `huge-*` seeds, as their messages must quote them (10¹² points are
/// 3·10¹² coordinates to the binary VTK reader).
const CLAIMS: &[&str] = &["1000000000000", "3000000000000", "4294967295"];

#[test]
fn huge_headers_are_refused_before_allocating() {
    let mut checked = 0;
    for corpus in ["mesh", "surface"] {
        let seeds = fuzz::corpus(&corpus_dir(corpus));
        let root = scratch(&format!("huge-{corpus}"));
        for seed in seeds.iter().filter(|s| s.name.starts_with("huge-")) {
            let dir = root.join(stem(&seed.name));
            let path = stage(&dir, &seeds, seed, &seed.bytes);
            let (result, largest) = largest_on_this_thread(|| {
                if corpus == "mesh" {
                    read_mesh(&path).map(|_| ())
                } else {
                    read_surface(&path).map(|_| ())
                }
            });
            let err = result.expect_err(&seed.name);
            let msg = err.to_string();
            println!("{msg} (largest allocation {largest} bytes)");
            check_refusal(&err, &dir, &seed.name);
            assert!(
                err.line().is_some() || err.offset().is_some(),
                "{}: no line or byte: {msg}",
                seed.name
            );
            assert!(
                CLAIMS.iter().any(|c| msg.contains(c)),
                "{}: the claimed count is not quoted: {msg}",
                seed.name
            );
            // Every reader reserves no more records than the file could hold.
            let limit = 64 << 10;
            assert!(
                largest < limit,
                "{}: an allocation of {largest} bytes",
                seed.name
            );
            checked += 1;
        }
        let _ = fs::remove_dir_all(&root);
    }
    assert!(checked >= 20, "only {checked} huge-* seeds");
}
