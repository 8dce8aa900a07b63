//! Paths to the workspace's shipped files, fresh temporary directories, small meshes.

use std::path::PathBuf;

/// The workspace's root directory.
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("test-support sits in the workspace root")
        .to_path_buf()
}

/// A shipped mesh's base path (`assets/meshes/NAME`, without extension).
pub fn mesh_path(name: &str) -> PathBuf {
    workspace_root().join("assets/meshes").join(name)
}

/// The directory of the shipped meshes.
pub fn meshes_dir() -> PathBuf {
    workspace_root().join("assets/meshes")
}

/// A shipped scene (`config/scenes/NAME.toml`).
pub fn scene_path(name: &str) -> PathBuf {
    workspace_root()
        .join("config/scenes")
        .join(name)
        .with_extension("toml")
}

/// The default scene (`abdomen`) with two tools, written into `dir` (its paths made absolute):
/// its `[tool]` becomes the first `[[tool]]`, "left"; a second, "right", the same tool whose
/// device maps 30 mm further along x (the liver's front there is 3 mm lower, so the default
/// poke goes about 9 mm in), playing the same poke. Returns the file's path.
pub fn two_tool_abdomen(dir: &std::path::Path) -> PathBuf {
    let root = workspace_root();
    let text = std::fs::read_to_string(scene_path("abdomen")).expect("the abdomen scene");
    assert!(text.contains("\n[tool]\n") && text.contains("\n[workspace]\n"));
    let poke = root.join("config/scripts/abdomen-poke.toml");
    let text = text
        .replace("\"../../assets/", &format!("\"{}/assets/", root.display()))
        .replace(
            "\"../scripts/",
            &format!("\"{}/config/scripts/", root.display()),
        )
        .replace("\n[tool]\n", "\n[[tool]]\nname = \"left\"\n")
        .replace(
            "\n[workspace]\n",
            &format!(
                "\n[[tool]]\nname = \"right\"\nradius = 0.003\nstiffness = 300.0\n\
                 mock_script = \"{}\"\n\
                 workspace = {{ scale = 2.0, offset = [0.012, 0.048, -0.005] }}\n\
                 \n[workspace]\n",
                poke.display()
            ),
        );
    let path = dir.join("abdomen-two-tools.toml");
    std::fs::write(&path, text).expect("writing the two-tool scene");
    path
}

/// An empty directory `TMP/TAG-PID` (removed first if a previous run left it behind). The
/// process id keeps parallel runs of the same test binary apart.
pub fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir)
        .unwrap_or_else(|e| panic!("cannot create {}: {e}", dir.display()));
    dir
}

/// Corners of the cube `[0, size]³`; corner `i` is at `(i & 1, i >> 1 & 1, i >> 2 & 1) · size`.
pub fn cube_corners(size: f64) -> Vec<[f64; 3]> {
    (0..8)
        .map(|i| {
            [
                (i & 1) as f64 * size,
                ((i >> 1) & 1) as f64 * size,
                ((i >> 2) & 1) as f64 * size,
            ]
        })
        .collect()
}

/// The unit sphere as a closed, outward-wound triangle surface: an icosahedron whose faces are
/// split in four `level` times, every new vertex pushed out onto the sphere.
pub fn icosphere(level: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    let unit = |p: [f64; 3]| {
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        p.map(|c| c / l)
    };
    let mut x: Vec<[f64; 3]> = [
        [-1., g, 0.],
        [1., g, 0.],
        [-1., -g, 0.],
        [1., -g, 0.],
        [0., -1., g],
        [0., 1., g],
        [0., -1., -g],
        [0., 1., -g],
        [g, 0., -1.],
        [g, 0., 1.],
        [-g, 0., -1.],
        [-g, 0., 1.],
    ]
    .map(unit)
    .to_vec();
    let mut t: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(4 * t.len());
        for &[a, b, c] in &t {
            let mut m = |i: u32, j: u32| {
                *mid.entry((i.min(j), i.max(j))).or_insert_with(|| {
                    let (p, q) = (x[i as usize], x[j as usize]);
                    x.push(unit([0, 1, 2].map(|k| (p[k] + q[k]) / 2.0)));
                    (x.len() - 1) as u32
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        t = next;
    }
    (x, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_paths_exist() {
        assert!(mesh_path("liver").with_extension("node").is_file());
        assert!(meshes_dir().is_dir());
        assert!(scene_path("organs").is_file());
    }

    #[test]
    fn temp_dir_is_fresh() {
        let d = temp_dir("lop-test-support-fixtures");
        std::fs::write(d.join("x"), "x").unwrap();
        let d = temp_dir("lop-test-support-fixtures");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn cube_corners_are_the_unit_cube_scaled() {
        let c = cube_corners(2.0);
        assert_eq!(c.len(), 8);
        assert_eq!(c[0], [0.0; 3]);
        assert_eq!(c[5], [2.0, 0.0, 2.0]);
        assert_eq!(c[7], [2.0; 3]);
    }
}
