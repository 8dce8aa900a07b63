//! Writing frames as a VTK time series that ParaView opens: one XML unstructured grid (`.vtu`,
//! ASCII) per frame with the tetrahedra, node temperatures and a body id per cell (and the
//! render surfaces as a second piece), and a `.pvd` collection indexing them by simulated time.

use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::{Frame, Topology};

/// Writes one frame as `.vtu`: a piece with the tetrahedra over the frame's nodes and, when the
/// scene has render surfaces, a second piece with their triangles over the render vertices
/// (placed by their weights, temperatures blended the same way). Cell array `part` tells them
/// apart in ParaView (0: tetrahedra, 1: render surface; `Threshold` on it shows either).
pub fn write_vtu(path: &Path, topology: &Topology, frame: &Frame) -> std::io::Result<()> {
    let mut s = String::with_capacity(64 * (frame.nodes.len() + topology.tets.len()) + 1024);
    s += "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n";
    let points: Vec<([f32; 3], f32)> = frame
        .nodes
        .iter()
        .map(|p| (p.position, p.temperature))
        .collect();
    let bodies: Vec<usize> = topology
        .bodies()
        .iter()
        .enumerate()
        .flat_map(|(b, body)| std::iter::repeat_n(b, body.tet_count as usize))
        .collect();
    let cells: Vec<&[u32]> = topology.tets.iter().map(|t| &t[..]).collect();
    piece(&mut s, &points, &cells, &bodies, 0, 10);
    if !topology.render_vertices.is_empty() {
        let points: Vec<([f32; 3], f32)> = topology
            .render_vertices
            .iter()
            .map(|v| {
                let [t] = v.blend(&frame.nodes, |s| [s.temperature]);
                (v.blend(&frame.nodes, |s| s.position), t)
            })
            .collect();
        let bodies: Vec<usize> = topology
            .bodies()
            .iter()
            .enumerate()
            .flat_map(|(b, body)| std::iter::repeat_n(b, body.render_triangle_count as usize))
            .collect();
        let cells: Vec<&[u32]> = topology.render_triangles.iter().map(|t| &t[..]).collect();
        piece(&mut s, &points, &cells, &bodies, 1, 5);
    }
    s += "</UnstructuredGrid>\n</VTKFile>\n";
    std::fs::write(path, s)
}

/// One `<Piece>`: points with their temperatures, cells of one VTK type with their body and
/// `part`.
fn piece(
    s: &mut String,
    points: &[([f32; 3], f32)],
    cells: &[&[u32]],
    bodies: &[usize],
    part: u8,
    vtk_type: u8,
) {
    let (n, e) = (points.len(), cells.len());
    let _ = writeln!(s, "<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{e}\">");
    *s += "<PointData Scalars=\"temperature\">\n<DataArray type=\"Float32\" Name=\"temperature\" format=\"ascii\">\n";
    for (_, t) in points {
        let _ = writeln!(s, "{t}");
    }
    *s += "</DataArray>\n</PointData>\n<CellData Scalars=\"body\">\n<DataArray type=\"Int32\" Name=\"body\" format=\"ascii\">\n";
    for b in bodies {
        let _ = writeln!(s, "{b}");
    }
    *s += "</DataArray>\n<DataArray type=\"UInt8\" Name=\"part\" format=\"ascii\">\n";
    for _ in 0..e {
        let _ = writeln!(s, "{part}");
    }
    *s += "</DataArray>\n</CellData>\n<Points>\n<DataArray type=\"Float32\" Name=\"Points\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    for (p, _) in points {
        let _ = writeln!(s, "{} {} {}", p[0], p[1], p[2]);
    }
    *s += "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
    for c in cells {
        let line: Vec<String> = c.iter().map(u32::to_string).collect();
        let _ = writeln!(s, "{}", line.join(" "));
    }
    *s += "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
    let mut offset = 0;
    for c in cells {
        offset += c.len();
        let _ = writeln!(s, "{offset}");
    }
    *s += "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
    for _ in 0..e {
        let _ = writeln!(s, "{vtk_type}");
    }
    *s += "</DataArray>\n</Cells>\n</Piece>\n";
}

/// Collects written frames and writes the `.pvd` index.
pub struct PvdSeries {
    dir: PathBuf,
    stem: String,
    entries: Vec<(f64, String)>,
}

impl PvdSeries {
    /// A series of files `DIR/STEM_NNNNNN.vtu` indexed by `DIR/STEM.pvd`.
    pub fn new(dir: &Path, stem: &str) -> std::io::Result<PvdSeries> {
        std::fs::create_dir_all(dir)?;
        Ok(PvdSeries {
            dir: dir.to_path_buf(),
            stem: stem.to_string(),
            entries: Vec::new(),
        })
    }

    /// Writes one frame and remembers it for the index.
    pub fn add(&mut self, topology: &Topology, frame: &Frame) -> std::io::Result<PathBuf> {
        let file = format!("{}_{:06}.vtu", self.stem, self.entries.len());
        let path = self.dir.join(&file);
        write_vtu(&path, topology, frame)?;
        self.entries.push((frame.header.sim_time, file));
        Ok(path)
    }

    /// Frames written.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True if no frame was written.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Writes `STEM.pvd`; returns its path.
    pub fn finish(&self) -> std::io::Result<PathBuf> {
        let path = self.dir.join(format!("{}.pvd", self.stem));
        let mut f = std::io::BufWriter::new(std::fs::File::create(&path)?);
        writeln!(f, "<?xml version=\"1.0\"?>")?;
        writeln!(
            f,
            "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">"
        )?;
        writeln!(f, "<Collection>")?;
        for (t, file) in &self.entries {
            writeln!(
                f,
                "<DataSet timestep=\"{t}\" group=\"\" part=\"0\" file=\"{file}\"/>"
            )?;
        }
        writeln!(f, "</Collection>\n</VTKFile>")?;
        f.flush()?;
        Ok(path)
    }
}
