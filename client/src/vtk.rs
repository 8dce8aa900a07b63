//! Writing frames as a VTK time series that ParaView opens: one XML unstructured grid (`.vtu`,
//! ASCII) per frame with the tetrahedra, node temperatures and a body id per cell, and a `.pvd`
//! collection indexing them by simulated time.

use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::{Frame, Topology};

/// Writes one frame as `.vtu`.
pub fn write_vtu(path: &Path, topology: &Topology, frame: &Frame) -> std::io::Result<()> {
    let n = frame.nodes.len();
    let e = topology.tets.len();
    let mut s = String::with_capacity(64 * (n + e) + 1024);
    s += "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n";
    let _ = writeln!(s, "<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{e}\">");
    s += "<PointData Scalars=\"temperature\">\n<DataArray type=\"Float32\" Name=\"temperature\" format=\"ascii\">\n";
    for p in &frame.nodes {
        let _ = writeln!(s, "{}", p.temperature);
    }
    s += "</DataArray>\n</PointData>\n<CellData Scalars=\"body\">\n<DataArray type=\"Int32\" Name=\"body\" format=\"ascii\">\n";
    for (b, body) in topology.bodies().iter().enumerate() {
        for _ in 0..body.tet_count {
            let _ = writeln!(s, "{b}");
        }
    }
    s += "</DataArray>\n</CellData>\n<Points>\n<DataArray type=\"Float32\" Name=\"Points\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    for p in &frame.nodes {
        let _ = writeln!(s, "{} {} {}", p.position[0], p.position[1], p.position[2]);
    }
    s += "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
    for t in &topology.tets {
        let _ = writeln!(s, "{} {} {} {}", t[0], t[1], t[2], t[3]);
    }
    s += "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
    for i in 0..e {
        let _ = writeln!(s, "{}", 4 * (i + 1));
    }
    s += "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
    for _ in 0..e {
        s += "10\n";
    }
    s += "</DataArray>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
    std::fs::write(path, s)
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
