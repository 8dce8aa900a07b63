//! `lopd mesh tetrahedralize`: a triangle surface (a segmented organ as STL, OBJ, PLY or VTK)
//! filled with tetrahedra of the size asked for, checked on the way in and on the way out.
//!
//! 1. Read the surface ([`lop_sim::mesh::read_surface`]).
//! 2. Optionally close small holes ([`close_holes`]), then check it ([`check_surface`]) in the
//!    file's own units, so a defect's coordinates can be looked up in the file. A surface with
//!    a hole, a non-manifold edge or vertex, an inconsistent winding, a degenerate triangle or
//!    a self-intersection is refused with the triangles at fault — unless `--repair` is given:
//!    then fTetWild meshes it inside an envelope of 1e-3 of its bounding box diagonal and the
//!    boundary of that mesh becomes the surface (checked like the input: closed and manifold
//!    nearly always; otherwise fTetWild runs once more at another size, then it is refused). One
//!    wound inward throughout is flipped, with a note. Then it is scaled to metres (`--units`).
//! 3. Fill it with the mesher ([`crate::mesher`]): `--tets N` starts from the edge of a
//!    regular tetrahedron that tiles the volume N times, `L = (6√2·V/N)^(1/3)`, and rescales L
//!    by `(made/N)^(1/3)` until the count is within ±20 % and the smallest dihedral angle is at
//!    least 10° ([`TRIES`] meshings at most; the best one is kept and a miss is said). gmsh's
//!    and fTetWild's results first lose their boundary slivers ([`crate::mesher::peel`]: a flat
//!    tetrahedron with its four corners on the boundary and two faces on it, which their
//!    optimisers cannot move since the surface vertices stay on the surface); each meshing
//!    line says how many were peeled and their volume.
//! 4. Read the result back with lop's own reader, which refuses inverted, degenerate or
//!    duplicate tetrahedra and extracts the boundary; check its volume against the surface's
//!    (TetGen: exactly; the others re-mesh the surface and may differ by the chords) and how
//!    far its boundary vertices are from the input surface; report the shape of the
//!    tetrahedra (dihedral angles); write `PREFIX.node/.ele/.face/.bnd`.
//!
//! # Which mesher, and why
//!
//! Measured on three built surfaces (a 20 cm two-lobed liver of 5,120 triangles, an ellipsoid
//! and a kidney-like bean of 1,280) and on defective copies of the liver (crossing triangles,
//! holes); figures in `docs/benchmarks.md`, "Meshing":
//!
//! - **gmsh** is the default for a surface that passes the checks: it re-meshes the surface at
//!   the target size, so the count follows the size (19 of 20 runs from 2k to 20k within
//!   ±20 %, in 1–4 meshings of about a second each) and its optimiser leaves the smallest
//!   dihedral at 10–13°. The one miss, the kidney at 5,000, was a 3.1° sliver lying on the
//!   boundary through 4 meshings; peeled off, that mesh's smallest dihedral is 12.1°.
//! - **fTetWild** gives the best shapes (smallest dihedral 13–19° on the ellipsoid) and does
//!   not mind defects, but it keeps the input's detail within its envelope, so the 5,120-
//!   triangle liver gives 6–7k tetrahedra whatever the size asked, and one meshing takes
//!   10–30 s. So it repairs (`--repair`: its boundary, loosely optimised, becomes the
//!   surface), and gmsh then sizes the repaired surface (2k–20k within ±20 % and ≥ 11° on the
//!   liver with crossing triangles and with holes); `--mesher ftetwild` uses it alone.
//! - **TetGen** keeps the input's triangles (split, never moved) and fills exactly their
//!   volume, but cannot make a small mesh of a fine surface: asked for 2,000 it makes 12.5k
//!   (ellipsoid) to 55k (liver with a lobe) tetrahedra whatever the `-a`, with slivers of
//!   3–4.6°. It stays for `--mesher tetgen` and is chosen when a TetGen-only switch is given
//!   (`--quality`, `--max-volume`, `--keep-surface`).
//!
//! gmsh alone cannot mesh a defective surface ("No elements in volume 1" on the liver with a
//! lobe). A defective surface is refused unless `--repair` is given, rather than repaired by
//! default: the repaired mesh is not the segmentation (a hole is patched, crossing sheets are
//! merged), and the user should see that said and accept it.

use std::path::PathBuf;
use std::time::Instant;

use lop_sim::mesh::{
    check_surface, close_holes, read_surface, write_tetgen, DefectKind, HoleClosing, MeshReadError,
    SurfaceMesh, SurfaceReport, TetMesh,
};

use crate::mesher::peel::{peel_boundary_slivers, Peeled};
use crate::mesher::shape::{surface_distance, Dihedrals, SurfaceDistance};
use crate::mesher::tetgen::TetgenSwitches;
use crate::mesher::{self, Mesher, MesherError};

mod summary;

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

/// The size asked for when none is (`--tets`, `--edge`, `--max-volume`) and the mesher is
/// gmsh or fTetWild: under [`REAL_TIME_TETS`] with room for the ±20 % of `--tets`.
pub const DEFAULT_TETS: usize = 2000;

/// `--tets N` is met when the mesh has N ± this fraction tetrahedra (issue 28's target).
pub const TETS_TOLERANCE: f64 = 0.2;

/// The smallest dihedral angle asked of a mesh, degrees (issue 28's target: no slivers).
pub const MIN_DIHEDRAL: f64 = 10.0;

/// At most this many meshings to hit `--tets N`.
const TRIES: usize = 4;

/// `--repair` patches gaps, not missing sides: a surface whose holes, fanned shut, would make
/// more than this share of the closed surface's area is refused before any mesher runs. A
/// segmentation's gaps are a few per cent at most (the built liver with holes 0.3 %, the
/// test ellipsoid with two holes of 5–6 edges 3.8 %); a bowl, half an organ or an open sheet
/// is a third or more, and fTetWild given one either finds no inside or, now and then, wraps
/// a thin shell around the sheet and meshes that.
pub const MAX_OPEN_SHARE: f64 = 0.10;

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

/// How big a mesh to make.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Size {
    /// About this many tetrahedra (±20 %).
    Tets(usize),
    /// Tetrahedra of about this edge length, metres (TetGen: `-a` of a regular tetrahedron).
    Edge(f64),
    /// TetGen `-a`: largest tetrahedron volume, m³.
    MaxVolume(f64),
    /// Nothing asked: [`DEFAULT_TETS`] for gmsh and fTetWild, TetGen's own sizing.
    Auto,
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
    /// The mesher; `None`: TetGen if a TetGen-only switch is given, else gmsh.
    pub mesher: Option<Mesher>,
    /// How big.
    pub size: Size,
    /// Radius-edge ratio bound (TetGen `-q`), > 1; TetGen only (1.4 when not given).
    pub quality: Option<f64>,
    /// Close holes of at most this many edges before the check.
    pub close_holes: Option<usize>,
    /// Keep the surface exactly as given (TetGen `-Y`); TetGen only.
    pub keep_surface: bool,
    /// Repair a surface that fails the checks with fTetWild instead of refusing it.
    pub repair: bool,
}

impl TetrahedralizeOptions {
    /// The mesher that fills the surface.
    pub fn mesher(&self) -> Mesher {
        self.mesher.unwrap_or(
            if self.quality.is_some()
                || self.keep_surface
                || matches!(self.size, Size::MaxVolume(_))
            {
                Mesher::Tetgen
            } else {
                Mesher::Gmsh
            },
        )
    }
}

/// What a repair did.
#[derive(Debug, Clone)]
pub struct Repair {
    /// The repaired surface (the boundary of fTetWild's mesh): vertices, triangles.
    pub vertices: usize,
    /// Triangles of the repaired surface.
    pub triangles: usize,
    /// Enclosed volume before (holes closed by a fan for the measure only) and after, m³.
    pub volume: (f64, f64),
    /// Seconds fTetWild took.
    pub seconds: f64,
    /// The share of the closed surface's area its holes were (see [`MAX_OPEN_SHARE`]).
    pub open_share: f64,
}

/// One meshing of the search for `--tets N`.
#[derive(Debug, Clone, Copy)]
pub struct Attempt {
    /// Target edge length, metres (`None`: TetGen's own sizing or `-a`).
    pub edge: Option<f64>,
    /// Tetrahedra made.
    pub tets: usize,
    /// Smallest dihedral angle, degrees (after peeling).
    pub min_dihedral: f64,
    /// Boundary slivers peeled off the mesher's result ([`crate::mesher::peel`]).
    pub peeled: Peeled,
    /// Seconds the mesher took.
    pub seconds: f64,
}

/// What was built.
#[derive(Debug)]
pub struct Tetrahedralized {
    /// The volume mesh, in metres, as written.
    pub mesh: TetMesh,
    /// The input surface in metres, wound outward, as written beside the mesh for drawing
    /// ([`render_surface_path`]).
    pub render: PathBuf,
    /// The mesher.
    pub mesher: Mesher,
    /// The surface check (after closing holes, before flipping; in the file's units).
    pub report: SurfaceReport,
    /// Holes closed or left open, if asked to close them.
    pub holes: Option<HoleClosing>,
    /// The surface failed the checks and was repaired.
    pub repair: Option<Repair>,
    /// The surface was wound inward and was flipped.
    pub flipped: bool,
    /// TetGen's switches, when TetGen meshed.
    pub switches: Option<String>,
    /// The tetrahedra asked for (`--tets`, or the default).
    pub asked: Option<usize>,
    /// Every meshing, the kept one marked by [`Tetrahedralized::kept`].
    pub attempts: Vec<Attempt>,
    /// Index of the kept attempt.
    pub kept: usize,
    /// The shape of the tetrahedra.
    pub dihedrals: Dihedrals,
    /// Boundary vertices' distance from the input surface, metres.
    pub distance: SurfaceDistance,
    /// The largest distance allowed, metres.
    pub tolerance: f64,
    /// Volume of the tetrahedra and enclosed by the (possibly repaired) surface, m³.
    pub volume: (f64, f64),
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
    /// `--repair` could not make a closed surface of it.
    #[error("{path}: the surface cannot be repaired: {reason}\nits defects: {report}")]
    Unrepairable {
        /// The surface file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
        /// The check's findings.
        report: Box<SurfaceReport>,
    },
    /// An option is out of range.
    #[error("{0}")]
    BadOption(String),
    /// A mesher is missing or failed.
    #[error("{0}")]
    Mesher(#[from] MesherError),
    /// The result does not fill the surface.
    #[error("the {mesher} mesh does not fit the surface: {reason}")]
    BadResult {
        /// The mesher.
        mesher: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// Writing the result.
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
                | TetrahedralizeError::Unrepairable { .. }
                | TetrahedralizeError::BadOption(_)
        )
    }
}

/// TetGen `-a` for a target edge length `l`: the volume of a regular tetrahedron of edge `l`,
/// `l³ / (6√2)`.
pub fn volume_for_edge(l: f64) -> f64 {
    l * l * l / (6.0 * std::f64::consts::SQRT_2)
}

/// The edge of the regular tetrahedron that tiles `volume` `n` times.
pub fn edge_for_tets(volume: f64, n: usize) -> f64 {
    (6.0 * std::f64::consts::SQRT_2 * volume / n.max(1) as f64).cbrt()
}

fn check_options(opts: &TetrahedralizeOptions) -> Result<Mesher, TetrahedralizeError> {
    let mesher = opts.mesher();
    let bad = |m: String| Err(TetrahedralizeError::BadOption(m));
    if let Some(q) = opts.quality {
        if !(q > 1.0 && q.is_finite()) {
            return bad(format!(
                "--quality {q}: the radius-edge ratio bound must be a number > 1 (TetGen cannot \
                 reach 1 or less; 1.2-2 is usual)"
            ));
        }
    }
    if mesher != Mesher::Tetgen {
        let tetgen_only = [
            (opts.quality.is_some(), "--quality"),
            (opts.keep_surface, "--keep-surface"),
            (matches!(opts.size, Size::MaxVolume(_)), "--max-volume"),
        ];
        if let Some((_, flag)) = tetgen_only.iter().find(|(given, _)| *given) {
            return bad(format!(
                "{flag} is a TetGen switch, but --mesher is {}: use --tets or --edge, or \
                 --mesher tetgen",
                mesher.name()
            ));
        }
    }
    if opts.size == Size::Tets(0) {
        return bad("--tets 0: ask for at least one tetrahedron".to_owned());
    }
    if opts.repair && opts.keep_surface {
        return bad(
            "--repair replaces the surface by a repaired one; it cannot be kept as given \
             (--keep-surface)"
                .to_owned(),
        );
    }
    // The programs before the work, so a missing one is said at once.
    match mesher {
        Mesher::Gmsh => drop(mesher::find_program(
            "gmsh",
            "LOP_GMSH",
            "Debian package gmsh",
        )?),
        Mesher::Tetgen => drop(mesher::find_program(
            "tetgen",
            "LOP_TETGEN",
            "Debian package tetgen",
        )?),
        Mesher::Ftetwild => drop(mesher::ftetwild::find_python()?),
    }
    Ok(mesher)
}

/// Where the mesh written to base path `out` keeps its render surface: `out.render.obj`.
/// `lopd scene new` finds it there.
pub fn render_surface_path(out: &std::path::Path) -> PathBuf {
    let mut name = out.as_os_str().to_owned();
    name.push(".render.obj");
    PathBuf::from(name)
}

/// Runs the whole job (see the [module docs](self)).
pub fn run(opts: &TetrahedralizeOptions) -> Result<Tetrahedralized, TetrahedralizeError> {
    let mesher = check_options(opts)?;

    // 1-2. The surface, checked in its own units (so that the coordinates a defect names are
    // the file's), then scaled to metres.
    let mut surface = read_surface(&opts.surface)?;
    let holes = opts.close_holes.map(|n| close_holes(&mut surface, n));
    let report = check_surface(&surface);
    let mut input = surface.clone();
    input.scale(opts.units.metres());
    let mut flipped = false;
    let mut repair = None;
    if !report.is_ok() {
        if !opts.repair {
            return Err(defects(opts, report, holes.as_ref()));
        }
        let share = open_share(&input);
        if share > MAX_OPEN_SHARE {
            return Err(TetrahedralizeError::Unrepairable {
                path: opts.surface.clone(),
                reason: format!(
                    "its holes are {:.0} % of the surface they would close (at most {:.0} % \
                     can be patched): it is open, not a closed organ with gaps",
                    share * 100.0,
                    MAX_OPEN_SHARE * 100.0
                ),
                report: Box::new(report),
            });
        }
        if mesher != Mesher::Ftetwild {
            let (repaired, done) = repair_surface(opts, &input, &report, share)?;
            surface = repaired;
            repair = Some(done);
        } else {
            surface = input.clone();
        }
    } else {
        flipped = report.inverted;
        if flipped {
            surface.flip();
        }
        surface.scale(opts.units.metres());
    }
    let enclosed = surface.signed_volume().abs();

    // 3. Mesh, searching the size for --tets.
    let asked = match opts.size {
        Size::Tets(n) => Some(n),
        Size::Auto if mesher != Mesher::Tetgen => Some(DEFAULT_TETS),
        _ => None,
    };
    let switches = (mesher == Mesher::Tetgen).then(|| TetgenSwitches {
        quality: opts.quality.unwrap_or(1.4),
        max_volume: None,
        keep_surface: opts.keep_surface,
    });
    let mut attempts: Vec<Attempt> = Vec::new();
    let mut best: Option<(TetMesh, Dihedrals, usize)> = None;
    let mut edge = match (opts.size, asked) {
        (Size::Edge(l), _) => Some(l),
        (_, Some(n)) => Some(edge_for_tets(enclosed, n)),
        _ => None,
    };
    let tries = if asked.is_some() { TRIES } else { 1 };
    for _ in 0..tries {
        let started = Instant::now();
        let mut mesh = match mesher {
            Mesher::Gmsh => mesher::gmsh::mesh(&surface, edge.unwrap_or(f64::NAN))?,
            Mesher::Ftetwild => mesher::ftetwild::mesh(
                &surface,
                edge.unwrap_or(f64::NAN),
                mesher::ftetwild::EPSILON,
            )?,
            Mesher::Tetgen => {
                let mut s = switches.expect("TetGen's switches");
                s.max_volume = match opts.size {
                    Size::MaxVolume(v) => Some(v),
                    _ => edge.map(volume_for_edge),
                };
                mesher::tetgen::mesh(&surface, &s)?
            }
        };
        let seconds = started.elapsed().as_secs_f64();
        // gmsh and fTetWild make their own boundary, within the tolerance of the input: a flat
        // tetrahedron lying on it goes. TetGen's boundary is the input's triangles, kept.
        let peeled = match mesher {
            Mesher::Tetgen => Peeled::default(),
            _ => peel_boundary_slivers(&mut mesh, MIN_DIHEDRAL),
        };
        let dihedrals = Dihedrals::of(&mesh);
        attempts.push(Attempt {
            edge,
            tets: mesh.tets.len(),
            min_dihedral: dihedrals.min,
            peeled,
            seconds,
        });
        let i = attempts.len() - 1;
        let met = |a: &Attempt| {
            let count = asked.is_none_or(|n| within(a.tets, n));
            (count, a.min_dihedral >= MIN_DIHEDRAL)
        };
        let better = best.as_ref().is_none_or(|(_, _, k)| {
            let (a, b) = (&attempts[i], &attempts[*k]);
            let key = |x: &Attempt| {
                let (c, d) = met(x);
                let miss = asked.map_or(0.0, |n| (x.tets as f64 / n as f64).ln().abs());
                (c && d, c, -miss, x.min_dihedral)
            };
            key(a).partial_cmp(&key(b)) == Some(std::cmp::Ordering::Greater)
        });
        let (count_ok, shape_ok) = met(&attempts[i]);
        if better {
            best = Some((mesh, dihedrals, i));
        }
        if count_ok && shape_ok {
            break;
        }
        let (Some(n), Some(l)) = (asked, edge) else {
            break;
        };
        // Rescale by the count; a mesh of the right count with a sliver is meshed again at a
        // nudged size (the optimiser's result depends on where the points fall).
        let ratio = attempts[i].tets as f64 / n as f64;
        edge = Some(if count_ok { l * 0.97 } else { l * ratio.cbrt() });
    }
    let (mut mesh, dihedrals, kept) = best.expect("at least one meshing");

    // 4. Fits the surface; write.
    let volume: f64 = (0..mesh.tets.len()).map(|i| mesh.tet_volume(i)).sum();
    let name = mesher_name(mesher);
    if mesher == Mesher::Tetgen && (volume - enclosed).abs() > 1e-6 * enclosed {
        return Err(TetrahedralizeError::BadResult {
            mesher: name,
            reason: format!(
                "the tetrahedra fill {volume:e} m^3 but the surface encloses {enclosed:e} m^3"
            ),
        });
    }
    // Against the input with its holes fanned shut; the vertices nearest to a fan are counted
    // apart: across a hole fTetWild's patch is its own guess, as far from the fan as the hole
    // is curved.
    let mut reference = input.clone();
    let patches_from = reference.triangles.len();
    if report.count(DefectKind::OpenEdge) > 0 {
        close_holes(&mut reference, usize::MAX);
    }
    let distance = surface_distance(&mesh, &reference, patches_from);
    let tolerance = tolerance(&input, mesher, repair.is_some() || !report.is_ok());
    if distance.max > tolerance {
        return Err(TetrahedralizeError::BadResult {
            mesher: name,
            reason: format!(
                "a boundary vertex is {:.3} mm from the input surface, more than the {:.3} mm \
                 allowed",
                distance.max * 1e3,
                tolerance * 1e3
            ),
        });
    }
    mesh.source = opts.surface.clone();
    if let Some(dir) = opts.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| TetrahedralizeError::Io(format!("{}: {e}", dir.display())))?;
    }
    write_tetgen(&mesh, &opts.out)
        .map_err(|e| TetrahedralizeError::Io(format!("writing {}: {e}", opts.out.display())))?;
    // The surface as it came (in metres, outward), to draw the organ as segmented: the mesher
    // smooths and coarsens, and a repaired surface's defects never show at a renderer's scale.
    let render = render_surface_path(&opts.out);
    if input.signed_volume() < 0.0 {
        input.flip();
    }
    input
        .write_obj(&render)
        .map_err(|e| TetrahedralizeError::Io(format!("writing {}: {e}", render.display())))?;
    Ok(Tetrahedralized {
        render,
        mesh,
        mesher,
        report,
        holes,
        repair,
        flipped,
        switches: switches.map(|mut s| {
            s.max_volume = match opts.size {
                Size::MaxVolume(v) => Some(v),
                _ => attempts[kept].edge.map(volume_for_edge),
            };
            s.text()
        }),
        asked,
        attempts,
        kept,
        dihedrals,
        distance,
        tolerance,
        volume: (volume, enclosed),
    })
}

fn mesher_name(m: Mesher) -> &'static str {
    match m {
        Mesher::Gmsh => "gmsh",
        Mesher::Ftetwild => "fTetWild",
        Mesher::Tetgen => "TetGen",
    }
}

/// `made` is within ±[`TETS_TOLERANCE`] of `asked`.
pub fn within(made: usize, asked: usize) -> bool {
    (made as f64 - asked as f64).abs() <= TETS_TOLERANCE * asked as f64
}

/// The largest distance of a boundary vertex from the input surface: TetGen and gmsh put
/// their boundary vertices on the input triangles (1e-4 of the bounding box diagonal: TetGen
/// treats nearly coplanar neighbours as one facet and puts points on it 7e-6 of the diagonal
/// off the 5,120-triangle liver's triangles); fTetWild within its envelope, [`mesher::ftetwild::EPSILON`] of the diagonal
/// (twice that, as gmsh then re-meshes the repaired surface, whose vertices are within it).
fn tolerance(input: &SurfaceMesh, mesher: Mesher, repaired: bool) -> f64 {
    let [x, y, z] = lop_sim::mesh::extents(&input.vertices);
    let diagonal = (x * x + y * y + z * z).sqrt();
    if repaired || mesher == Mesher::Ftetwild {
        2.0 * mesher::ftetwild::EPSILON * diagonal
    } else {
        1e-4 * diagonal
    }
}

fn defects(
    opts: &TetrahedralizeOptions,
    report: SurfaceReport,
    holes: Option<&HoleClosing>,
) -> TetrahedralizeError {
    let open = report.count(DefectKind::OpenEdge) > 0;
    let mut hint = match (open, opts.close_holes) {
        (true, None) => "\n(small holes can be closed with --close-holes MAX_EDGES)".to_owned(),
        (true, Some(n)) => format!(
            "\n(--close-holes {n} closed {} hole(s); holes of {:?} edges are left)",
            holes.map_or(0, |h| h.closed.len()),
            holes.map(|h| h.left_open.clone()).unwrap_or_default()
        ),
        _ => String::new(),
    };
    hint.push_str(
        "\n(--repair meshes it anyway with fTetWild, inside an envelope of 1e-3 of its size: \
         crossing triangles are merged, holes patched, and what was done is reported)",
    );
    TetrahedralizeError::Defects {
        path: opts.surface.clone(),
        report: Box::new(report),
        hint,
    }
}

/// The share of the closed surface's area that fanning every hole of `surface` shut adds
/// (0 for a closed surface).
fn open_share(surface: &SurfaceMesh) -> f64 {
    let mut closed = surface.clone();
    close_holes(&mut closed, usize::MAX);
    let all = closed.area();
    if all > 0.0 {
        (all - surface.area()) / all
    } else {
        0.0
    }
}

/// fTetWild's mesh of a defective surface (metres), and its boundary as the new surface.
fn repair_surface(
    opts: &TetrahedralizeOptions,
    input: &SurfaceMesh,
    report: &SurfaceReport,
    open_share: f64,
) -> Result<(SurfaceMesh, Repair), TetrahedralizeError> {
    let unrepairable = |reason: String| TetrahedralizeError::Unrepairable {
        path: opts.surface.clone(),
        reason,
        report: Box::new(report.clone()),
    };
    let [x, y, z] = lop_sim::mesh::extents(&input.vertices);
    let diagonal = (x * x + y * y + z * z).sqrt();
    if diagonal.is_nan() || diagonal <= 0.0 {
        return Err(unrepairable("it has no extent".to_owned()));
    }
    // Fine enough to keep the shape (fTetWild's own default is diagonal / 20): the sizing
    // mesher then sets the size. fTetWild's boundary is closed and manifold nearly always;
    // when not (two tetrahedra meeting at an edge only), again at other sizes. fTetWild is not
    // deterministic: on CI the first two sizes both left a non-manifold edge once in a few
    // dozen runs of the same ellipsoid, so there are three.
    let started = Instant::now();
    let mut repaired = SurfaceMesh::default();
    let mut check = None;
    for divisions in [40.0, 30.0, 50.0] {
        repaired = match mesher::ftetwild::boundary(
            input,
            diagonal / divisions,
            mesher::ftetwild::EPSILON,
        ) {
            Ok(s) => s,
            Err(MesherError::BadResult { reason, .. }) => return Err(unrepairable(reason)),
            Err(MesherError::Failed { tail, .. }) => {
                return Err(unrepairable(format!("fTetWild failed: {tail}")))
            }
            Err(e) => return Err(e.into()),
        };
        if repaired.triangles.is_empty() {
            return Err(unrepairable(
                "fTetWild found no inside: the surface does not enclose a volume (an open \
                 sheet?)"
                    .to_owned(),
            ));
        }
        let c = check_surface(&repaired);
        let ok = c.is_ok();
        check = Some(c);
        if ok {
            break;
        }
    }
    let seconds = started.elapsed().as_secs_f64();
    if let Some(check) = check.filter(|c| !c.is_ok()) {
        return Err(unrepairable(format!(
            "fTetWild's mesh has a boundary that fails the checks too: {check}"
        )));
    }
    // The volume before: the input with every hole fanned shut, for the measure only.
    let mut closed = input.clone();
    close_holes(&mut closed, usize::MAX);
    let before = closed.signed_volume().abs();
    let after = repaired.signed_volume().abs();
    if after < 1e-3 * before {
        return Err(unrepairable(format!(
            "fTetWild found almost no inside ({after:e} m^3 of {before:e} m^3): the surface \
             does not enclose a volume (an open sheet?)"
        )));
    }
    Ok((
        repaired.clone(),
        Repair {
            vertices: repaired.vertices.len(),
            triangles: repaired.triangles.len(),
            volume: (before, after),
            seconds,
            open_share,
        },
    ))
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
