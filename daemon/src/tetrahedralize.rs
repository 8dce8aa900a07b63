//! `lopd mesh tetrahedralize`: a closed triangle surface (a segmented organ as STL, OBJ or PLY)
//! filled with tetrahedra by TetGen, checked on the way in and on the way out.
//!
//! 1. Read the surface ([`lop_sim::mesh::read_surface`]).
//! 2. Optionally close small holes ([`close_holes`]), then check it ([`check_surface`]) in the
//!    file's own units, so a defect's coordinates can be looked up in the file: a surface with
//!    a hole, a non-manifold edge or vertex, an inconsistent winding, a degenerate triangle or a
//!    self-intersection is refused with the triangles at fault; one wound inward throughout is
//!    flipped, with a note. Then it is scaled to metres (`--units`).
//! 3. Write it as a TetGen `.smesh` in a temporary directory and run the `tetgen` program there
//!    (a separate program, never linked: TetGen is AGPL; Debian package `tetgen`, installed by
//!    `scripts/setup.sh`) with `-p` (fill the surface), `-q` (radius-edge bound) and `-a`
//!    (largest volume) when a size is given.
//! 4. Read the result back with lop's own reader, which refuses inverted, degenerate or
//!    duplicate tetrahedra and extracts the boundary; check the tetrahedra fill exactly the
//!    surface's volume; report quality; write `PREFIX.node/.ele/.face/.bnd`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use lop_sim::mesh::{
    check_surface, close_holes, read_surface, read_tetgen, write_tetgen, HoleClosing,
    MeshReadError, SurfaceMesh, SurfaceReport, TetMesh,
};

/// Length units of a surface file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Units {
    /// Millimetres (most segmentation tools and CT/MRI exports).
    Mm,
    /// Centimetres.
    Cm,
    /// Metres (lop's unit).
    M,
}

/// Above this many tetrahedra `tetrahedralize` warns that a touched body will not step in real
/// time at 1 ms on the project's 2-core machine (`lopd simulate` of the poke: the 1,706-tet
/// `abdomen` liver steps in 0.6–0.8 ms in contact; generated ellipsoids of 2,785 and 8,155
/// tetrahedra with slivers down to 1.7–2.7° in about 2.2 and 10 ms).
const REAL_TIME_TETS: usize = 2500;

impl Units {
    /// As written on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Units::Mm => "mm",
            Units::Cm => "cm",
            Units::M => "m",
        }
    }

    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            Units::Mm => 1e-3,
            Units::Cm => 1e-2,
            Units::M => 1.0,
        }
    }
}

/// What to build.
#[derive(Debug, Clone)]
pub struct TetrahedralizeOptions {
    /// The surface file.
    pub surface: PathBuf,
    /// Output base path: `PREFIX.node`, `.ele`, `.face`, `.bnd`.
    pub out: PathBuf,
    /// The surface's units; the output is in metres.
    pub units: Units,
    /// Largest tetrahedron volume, m³ (TetGen `-a`); `None`: sized by the surface's triangles.
    pub max_volume: Option<f64>,
    /// Radius-edge ratio bound (TetGen `-q`), > 1 (TetGen's own default is 2).
    pub quality: f64,
    /// Close holes of at most this many edges before the check.
    pub close_holes: Option<usize>,
    /// Keep the surface exactly as given (TetGen `-Y`: no points added on it).
    pub keep_surface: bool,
}

/// What was built.
#[derive(Debug)]
pub struct Tetrahedralized {
    /// The volume mesh, in metres, as written.
    pub mesh: TetMesh,
    /// The surface check (after closing holes, before flipping; in the file's units).
    pub report: SurfaceReport,
    /// Holes closed or left open, if asked to close them.
    pub holes: Option<HoleClosing>,
    /// The surface was wound inward and was flipped.
    pub flipped: bool,
    /// The TetGen command's switches.
    pub switches: String,
    /// Smallest and largest dihedral angle of the tetrahedra, degrees.
    pub dihedral: (f64, f64),
}

/// Why it failed.
#[derive(Debug, thiserror::Error)]
pub enum TetrahedralizeError {
    /// The surface file does not read.
    #[error("{0}")]
    Surface(#[from] MeshReadError),
    /// The surface has defects.
    #[error("{path}: the surface cannot be tetrahedralised: {report}{hint}")]
    Defects {
        /// The surface file.
        path: PathBuf,
        /// The check's findings.
        report: Box<SurfaceReport>,
        /// What to try.
        hint: String,
    },
    /// An option is out of range.
    #[error("{0}")]
    BadOption(String),
    /// No `tetgen` program.
    #[error(
        "tetgen not found ({tried}): install it with `bash scripts/setup.sh` (Debian package \
         tetgen), or point LOP_TETGEN at the program"
    )]
    TetgenMissing {
        /// Where it was looked for.
        tried: String,
    },
    /// TetGen ran and failed.
    #[error("`{command}` failed ({status}); its last output:\n{tail}")]
    TetgenFailed {
        /// The command line.
        command: String,
        /// Exit status.
        status: String,
        /// The last lines of its output.
        tail: String,
    },
    /// TetGen's result does not read or does not fill the surface.
    #[error("TetGen's result is not a valid mesh: {0}")]
    BadResult(String),
    /// Reading or writing files.
    #[error("{0}")]
    Io(String),
}

impl TetrahedralizeError {
    /// Whether the user's input is at fault (exit code 2) rather than the machine (1).
    pub fn is_bad_input(&self) -> bool {
        matches!(
            self,
            TetrahedralizeError::Surface(_)
                | TetrahedralizeError::Defects { .. }
                | TetrahedralizeError::BadOption(_)
        )
    }
}

/// A length with an optional unit: `8mm`, `0.8cm`, `0.008m` or `0.008` (metres).
pub fn parse_length(text: &str) -> Result<f64, String> {
    parse_with_units(text, &[("mm", 1e-3), ("cm", 1e-2), ("m", 1.0)], "length")
}

/// A volume with an optional unit: `500mm3`, `0.5cm3`, `5e-7m3` or `5e-7` (cubic metres).
pub fn parse_volume(text: &str) -> Result<f64, String> {
    parse_with_units(text, &[("mm3", 1e-9), ("cm3", 1e-6), ("m3", 1.0)], "volume")
}

fn parse_with_units(text: &str, units: &[(&str, f64)], what: &str) -> Result<f64, String> {
    let t = text.trim();
    let (number, factor) = units
        .iter()
        .find_map(|(u, f)| t.strip_suffix(u).map(|n| (n.trim(), *f)))
        .unwrap_or((t, 1.0));
    match number.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v * factor),
        _ => Err(format!(
            "{text:?}: a {what} must be a positive number, optionally followed by {} \
             (none: {})",
            units.iter().map(|u| u.0).collect::<Vec<_>>().join(", "),
            units.last().map(|u| u.0).unwrap_or_default()
        )),
    }
}

/// TetGen `-a` for a target edge length `l`: the volume of a regular tetrahedron of edge `l`,
/// `l³ / (6√2)`.
pub fn volume_for_edge(l: f64) -> f64 {
    l * l * l / (6.0 * std::f64::consts::SQRT_2)
}

/// The `tetgen` program: `$LOP_TETGEN`, else `tetgen` on `PATH`, else `/usr/bin/tetgen`.
fn find_tetgen() -> Result<PathBuf, TetrahedralizeError> {
    let mut tried = Vec::new();
    if let Some(p) = std::env::var_os("LOP_TETGEN").filter(|p| !p.is_empty()) {
        let p = PathBuf::from(p);
        if p.is_file() {
            return Ok(p);
        }
        return Err(TetrahedralizeError::TetgenMissing {
            tried: format!("LOP_TETGEN={}", p.display()),
        });
    }
    if let Some(path) = std::env::var_os("PATH") {
        for dir in std::env::split_paths(&path) {
            let p = dir.join("tetgen");
            if p.is_file() {
                return Ok(p);
            }
        }
        tried.push("tetgen on PATH".to_owned());
    }
    let usr = PathBuf::from("/usr/bin/tetgen");
    if usr.is_file() {
        return Ok(usr);
    }
    tried.push(usr.display().to_string());
    Err(TetrahedralizeError::TetgenMissing {
        tried: tried.join(", "),
    })
}

/// Runs the whole job (see the [module docs](self)).
pub fn run(opts: &TetrahedralizeOptions) -> Result<Tetrahedralized, TetrahedralizeError> {
    if !(opts.quality > 1.0 && opts.quality.is_finite()) {
        return Err(TetrahedralizeError::BadOption(format!(
            "--quality {}: the radius-edge ratio bound must be a number > 1 (TetGen cannot \
             reach 1 or less; 1.2-2 is usual)",
            opts.quality
        )));
    }
    let tetgen = find_tetgen()?;

    // 1-2. The surface, checked in its own units (so that the coordinates a defect names are
    // the file's), then scaled to metres.
    let mut surface = read_surface(&opts.surface)?;
    let holes = opts.close_holes.map(|n| close_holes(&mut surface, n));
    let report = check_surface(&surface);
    if !report.is_ok() {
        let open = report.count(lop_sim::mesh::DefectKind::OpenEdge) > 0;
        let hint = match (open, opts.close_holes) {
            (true, None) => "\n(small holes can be closed with --close-holes MAX_EDGES)".to_owned(),
            (true, Some(n)) => format!(
                "\n(--close-holes {n} closed {} hole(s); holes of {:?} edges are left)",
                holes.as_ref().map_or(0, |h| h.closed.len()),
                holes
                    .as_ref()
                    .map(|h| h.left_open.clone())
                    .unwrap_or_default()
            ),
            _ => String::new(),
        };
        return Err(TetrahedralizeError::Defects {
            path: opts.surface.clone(),
            report: Box::new(report),
            hint,
        });
    }
    let flipped = report.inverted;
    if flipped {
        surface.flip();
    }
    surface.scale(opts.units.metres());

    // 3. TetGen in a scratch directory.
    let work =
        scratch_dir().map_err(|e| TetrahedralizeError::Io(format!("temporary directory: {e}")))?;
    let result = run_tetgen(&tetgen, &surface, opts, &work);
    let _ = std::fs::remove_dir_all(&work);
    let (mut mesh, switches) = result?;

    // 4. Fills the surface exactly; quality; write.
    let tets: f64 = (0..mesh.tets.len()).map(|i| mesh.tet_volume(i)).sum();
    let enclosed = surface.signed_volume();
    if (tets - enclosed).abs() > 1e-6 * enclosed.abs() {
        return Err(TetrahedralizeError::BadResult(format!(
            "the tetrahedra fill {tets:e} m^3 but the surface encloses {enclosed:e} m^3"
        )));
    }
    mesh.source = opts.surface.clone();
    let dihedral = dihedral_range(&mesh);
    if let Some(dir) = opts.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| TetrahedralizeError::Io(format!("{}: {e}", dir.display())))?;
    }
    write_tetgen(&mesh, &opts.out)
        .map_err(|e| TetrahedralizeError::Io(format!("writing {}: {e}", opts.out.display())))?;
    Ok(Tetrahedralized {
        mesh,
        report,
        holes,
        flipped,
        switches,
        dihedral,
    })
}

fn scratch_dir() -> std::io::Result<PathBuf> {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or_default();
    let dir = std::env::temp_dir().join(format!("lopd-tetgen-{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    Ok(dir)
}

/// Writes `work/surface.smesh`, runs TetGen on it, reads `work/surface.1.*` back.
fn run_tetgen(
    tetgen: &Path,
    surface: &SurfaceMesh,
    opts: &TetrahedralizeOptions,
    work: &Path,
) -> Result<(TetMesh, String), TetrahedralizeError> {
    let smesh = work.join("surface.smesh");
    std::fs::write(&smesh, smesh_text(surface))
        .map_err(|e| TetrahedralizeError::Io(format!("{}: {e}", smesh.display())))?;
    let mut switches = format!("-pq{}", opts.quality);
    if let Some(v) = opts.max_volume {
        write!(switches, "a{v:e}").ok();
    }
    if opts.keep_surface {
        switches.push('Y');
    }
    let out = Command::new(tetgen)
        .arg(&switches)
        .arg("surface.smesh")
        .current_dir(work)
        .output()
        .map_err(|e| TetrahedralizeError::Io(format!("running {}: {e}", tetgen.display())))?;
    let command = format!("{} {switches} surface.smesh", tetgen.display());
    let output = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let base = work.join("surface.1");
    if !out.status.success() || !work.join("surface.1.ele").is_file() {
        let lines: Vec<&str> = output.lines().filter(|l| !l.trim().is_empty()).collect();
        let tail = lines[lines.len().saturating_sub(12)..].join("\n");
        return Err(TetrahedralizeError::TetgenFailed {
            command,
            status: out.status.to_string(),
            tail,
        });
    }
    let mesh = read_tetgen(&base).map_err(|e| TetrahedralizeError::BadResult(e.to_string()))?;
    Ok((mesh, switches))
}

/// A TetGen `.smesh`: the surface's vertices (numbered from 1) and triangles, no holes, no
/// regions. Coordinates as Rust prints them, which read back bit for bit.
fn smesh_text(s: &SurfaceMesh) -> String {
    let mut t = String::new();
    writeln!(t, "# lopd mesh tetrahedralize: surface in metres").ok();
    writeln!(t, "{} 3 0 0", s.vertices.len()).ok();
    for (i, [x, y, z]) in s.vertices.iter().enumerate() {
        writeln!(t, "{} {x:?} {y:?} {z:?}", i + 1).ok();
    }
    writeln!(t, "{} 0", s.triangles.len()).ok();
    for [a, b, c] in &s.triangles {
        writeln!(t, "3 {} {} {}", a + 1, b + 1, c + 1).ok();
    }
    t.push_str("0\n0\n");
    t
}

/// Smallest and largest dihedral angle over all tetrahedra, degrees.
fn dihedral_range(mesh: &TetMesh) -> (f64, f64) {
    use glam::DVec3;
    let mut lo = f64::INFINITY;
    let mut hi = 0.0f64;
    for t in &mesh.tets {
        let p = t.map(|i| DVec3::from_array(mesh.nodes[i as usize]));
        for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
            let others: Vec<usize> = (0..4).filter(|&k| k != i && k != j).collect();
            let e = (p[j] - p[i]).normalize_or_zero();
            let u = p[others[0]] - p[i];
            let v = p[others[1]] - p[i];
            let (u, v) = (u - e * u.dot(e), v - e * v.dot(e));
            let c = (u.dot(v) / (u.length() * v.length())).clamp(-1.0, 1.0);
            let a = c.acos().to_degrees();
            lo = lo.min(a);
            hi = hi.max(a);
        }
    }
    (lo, hi)
}

impl Tetrahedralized {
    /// A human summary: the surface, what was done to it, TetGen's switches, the mesh.
    pub fn summary(&self, opts: &TetrahedralizeOptions) -> String {
        let mut s = String::new();
        writeln!(s, "surface {}: {}", opts.surface.display(), self.report).ok();
        if let Some(h) = &self.holes {
            writeln!(
                s,
                "holes closed: {} (edges {:?}); left open: {:?}",
                h.closed.len(),
                h.closed,
                h.left_open
            )
            .ok();
        }
        if self.flipped {
            writeln!(
                s,
                "note: the surface was wound inward throughout (negative volume); every \
                 triangle was flipped"
            )
            .ok();
        }
        writeln!(
            s,
            "tetgen {} surface.smesh  (the surface scaled from {} to m by {})",
            self.switches,
            opts.units.name(),
            opts.units.metres()
        )
        .ok();
        writeln!(s, "{}", self.mesh.info()).ok();
        writeln!(
            s,
            "dihedral angles:   {:.1} .. {:.1} degrees",
            self.dihedral.0, self.dihedral.1
        )
        .ok();
        if self.mesh.tets.len() > REAL_TIME_TETS {
            writeln!(
                s,
                "warning: {} tetrahedra. A touched body steps its FEM every millisecond; on a \
                 2-core machine the shipped liver (1,706 tetrahedra) takes about 0.7 ms in \
                 contact, a generated mesh of 2,800 about 2 ms and one of 8,000 about 10 ms, so \
                 the tissue would lag the hand. Keep a body under about {REAL_TIME_TETS} \
                 tetrahedra (a larger --edge) unless the machine is faster",
                self.mesh.tets.len()
            )
            .ok();
        }
        write!(
            s,
            "wrote {}.node, .ele, .face, .bnd (no fixed nodes: fix them in the scene, e.g. with \
             [[body.fix]])",
            opts.out.display()
        )
        .ok();
        s
    }
}
