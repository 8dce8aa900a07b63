//! The human summary of a finished `lopd mesh tetrahedralize`.

use std::fmt::Write as _;

use lop_sim::mesh::DefectKind;

use super::{
    mesher_name, within, TetrahedralizeOptions, Tetrahedralized, MIN_DIHEDRAL, REAL_TIME_TETS,
    TETS_TOLERANCE,
};

impl Tetrahedralized {
    /// A human summary: the surface, what was done to it, the meshings, the mesh.
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
        if let Some(r) = &self.repair {
            let (before, after) = r.volume;
            writeln!(
                s,
                "repaired by fTetWild in {:.1} s: {} crossing triangle pairs, {} open edges \
                 (holes {:.2} % of the closed surface), {} other defects -> a closed surface \
                 of {} vertices, {} triangles; enclosed volume {:.4e} -> {:.4e} m^3 ({:+.2} %)",
                r.seconds,
                self.report.count(DefectKind::SelfIntersection),
                self.report.count(DefectKind::OpenEdge),
                r.open_share * 100.0,
                self.report.counts.iter().sum::<usize>()
                    - self.report.count(DefectKind::SelfIntersection)
                    - self.report.count(DefectKind::OpenEdge),
                r.vertices,
                r.triangles,
                before,
                after,
                100.0 * (after - before) / before
            )
            .ok();
        } else if !self.report.is_ok() {
            writeln!(s, "repaired by fTetWild while meshing (--mesher ftetwild)").ok();
        }
        if self.flipped {
            writeln!(
                s,
                "note: the surface was wound inward throughout (negative volume); every \
                 triangle was flipped"
            )
            .ok();
        }
        write!(
            s,
            "mesher: {} (the surface scaled from {} to m by {})",
            mesher_name(self.mesher),
            opts.units.name(),
            opts.units.metres()
        )
        .ok();
        if let Some(sw) = &self.switches {
            write!(s, "; tetgen {sw} surface.smesh").ok();
        }
        s.push('\n');
        if let Some(n) = self.asked {
            writeln!(
                s,
                "asked: {n} tetrahedra (±{:.0} %)",
                100.0 * TETS_TOLERANCE
            )
            .ok();
        }
        for (i, a) in self.attempts.iter().enumerate() {
            let edge = a
                .edge
                .map_or("-".to_owned(), |l| format!("{:.2} mm", l * 1e3));
            writeln!(
                s,
                "  meshing {}: edge {edge}, {} tetrahedra, smallest dihedral {:.1}°{}, {:.2} s{}",
                i + 1,
                a.tets,
                a.min_dihedral,
                if a.peeled.count > 0 {
                    format!(
                        " ({} boundary sliver{} peeled off, {:.3} mm^3)",
                        a.peeled.count,
                        if a.peeled.count == 1 { "" } else { "s" },
                        a.peeled.volume * 1e9
                    )
                } else {
                    String::new()
                },
                a.seconds,
                if i == self.kept { "  <- kept" } else { "" }
            )
            .ok();
        }
        writeln!(s, "{}", self.mesh.info()).ok();
        writeln!(s, "{}", self.dihedrals).ok();
        let (volume, enclosed) = self.volume;
        writeln!(
            s,
            "fit:               volume {:+.2} % of the surface's; boundary vertices {:.4} mm \
             from the input surface at most ({:.4} mm mean; allowed {:.4} mm)",
            100.0 * (volume - enclosed) / enclosed,
            self.distance.max * 1e3,
            self.distance.mean * 1e3,
            self.tolerance * 1e3
        )
        .ok();
        let (n, d) = self.distance.over_holes;
        if n > 0 {
            writeln!(
                s,
                "                   {n} boundary vertices over patched holes, {:.4} mm from the \
                 holes' fans at most (not held to the allowance)",
                d * 1e3
            )
            .ok();
        }
        if let Some(n) = self.asked {
            let made = self.mesh.tets.len();
            if !within(made, n) {
                writeln!(
                    s,
                    "warning: asked for {n} tetrahedra, made {made} ({:+.0} %) after {} \
                     meshings: the surface's detail sets the count (try another --mesher)",
                    100.0 * (made as f64 / n as f64 - 1.0),
                    self.attempts.len()
                )
                .ok();
            }
        }
        if self.dihedrals.min < MIN_DIHEDRAL {
            writeln!(
                s,
                "warning: the smallest dihedral angle is {:.1}°, under {MIN_DIHEDRAL}°: slivers \
                 slow the step in contact (try another --tets or --mesher)",
                self.dihedrals.min
            )
            .ok();
        }
        if self.mesh.tets.len() > REAL_TIME_TETS {
            writeln!(
                s,
                "warning: {} tetrahedra. A touched body steps its FEM every millisecond where \
                 the machine keeps up, else at a longer period (up to [deform] max_period_ms, \
                 10 ms by default) with frames that much older; on a 2-core machine the shipped \
                 liver (1,706 tetrahedra) takes about 0.8 ms in contact, a generated mesh of \
                 4,500 about 2.4 ms (it steps at 4 ms) and one of 8,000 about 5.7 ms (10 ms), and \
                 one of 20,000 about 32 ms, beyond 10 ms, so its tissue lags the hand. Keep a \
                 body under about {REAL_TIME_TETS} tetrahedra (--tets) to be felt at 1 kHz \
                 unless the machine is faster",
                self.mesh.tets.len()
            )
            .ok();
        }
        write!(
            s,
            "wrote {}.node, .ele, .face, .bnd (no fixed nodes: fix them in the scene, e.g. with \
             [[body.fix]]), and the input surface to draw the organ by, {} ({} vertices, {} \
             triangles; `lopd scene new` uses it)",
            opts.out.display(),
            self.render.display(),
            self.report.vertices,
            self.report.triangles
        )
        .ok();
        s
    }
}
