//! lop's boundary file (`.bnd`): the list of fixed (Dirichlet) nodes of a mesh.
//!
//! ```text
//! # comments start with '#', anywhere on a line; blank lines are ignored
//! 3          # first data line: the number N of fixed nodes
//! 1          # then N lines with one node number each,
//! 2          # in the numbering of the mesh file it belongs to
//! 7
//! ```

use std::io::Write;
use std::path::Path;

use super::text::{self, DataLines};
use super::MeshReadError;

/// Reads the boundary file at `path` if it exists. `resolve(line, number)` maps a node number
/// as written to a 0-based node index, or explains why it cannot.
///
/// The result is sorted and unique (a node listed twice is fixed once).
pub(crate) fn read_optional(
    path: &Path,
    mut resolve: impl FnMut(usize, i64) -> Result<u32, MeshReadError>,
) -> Result<Option<Vec<u32>>, MeshReadError> {
    let Some(text) = text::read_optional_text(path)? else {
        return Ok(None);
    };
    let mut lines = DataLines::new(&text, true);
    let Some(header) = lines.next() else {
        return Err(text::eof_error(
            path,
            lines.eof_line(),
            "the number of fixed nodes",
        ));
    };
    let fields = header.fields(false);
    text::expect_fields(path, &header, &fields, 1, "the number of fixed nodes")?;
    let declared = text::parse_count(path, header.no, fields[0], "the number of fixed nodes")?;
    // The shortest line, a digit and its newline, takes 2 bytes.
    let mut fixed = Vec::with_capacity(text::capacity_within(declared, text.len(), 2));
    text::read_records(
        path,
        &mut lines,
        header.no,
        declared,
        "boundary nodes",
        |_, line| {
            let fields = line.fields(false);
            text::expect_fields(path, &line, &fields, 1, "one node number")?;
            let number = text::parse_i64(path, line.no, fields[0], "a boundary node number")?;
            fixed.push(resolve(line.no, number)?);
            Ok(())
        },
    )?;
    fixed.sort_unstable();
    fixed.dedup();
    Ok(Some(fixed))
}

/// Writes a boundary file listing `fixed` (0-based node indices) numbered from `first_number`
/// (use the numbering of the mesh file it goes with: 0 for VTK, the TetGen file's first number,
/// which is 1 for [`super::write_tetgen`]).
///
/// # Errors
/// Any I/O error from creating or writing the file.
pub fn write_bnd(fixed: &[u32], first_number: u32, path: &Path) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(
        out,
        "# fixed (Dirichlet) nodes, numbered from {first_number}"
    )?;
    writeln!(out, "{}", fixed.len())?;
    for &n in fixed {
        writeln!(out, "{}", u64::from(n) + u64::from(first_number))?;
    }
    out.flush()
}
