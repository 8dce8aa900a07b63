//! The tissue library: soft-tissue parameters from the literature, by organ, for scenes made
//! from a user's own meshes (`lopd scene new --tissue liver`). The four abdominal organs carry
//! exactly the values of the shipped `abdomen` scene (`config/scenes/abdomen.toml`, where every
//! choice is argued at length); a test keeps the two in step. Each entry cites its source.
//!
//! What does not depend on the mesh is stored here; the two mass-spring values that do (a
//! spring network's stiffness grows with its edge length, its damping acts on node masses) are
//! derived from the mesh by [`Tissue::msd_stiffness`] and [`Tissue::msd_damping`], with the
//! calibration the `abdomen` scene documents.

use crate::scene::{HeatParams, Importance};

/// One tissue: what a body made of it gets in a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Tissue {
    /// Name as `--tissue` takes it.
    pub name: &'static str,
    /// Young's modulus E, Pa (low strain).
    pub young: f64,
    /// Poisson's ratio.
    pub poisson: f64,
    /// Density, kg/m³ (for FEM and mass-spring alike).
    pub density: f64,
    /// FEM damping α of `D = α M`, 1/s.
    pub fem_damping: f64,
    /// FEM and mass-spring time step, s.
    pub dt: f64,
    /// Cage time step, s.
    pub gc_dt: f64,
    /// Which precise model the organ gets when touched.
    pub importance: Importance,
    /// Viewer colour, sRGB.
    pub color: [f32; 3],
    /// Thermal properties.
    pub heat: HeatParams,
    /// Where E comes from, as a TOML comment block (lines without the `#`).
    pub source: &'static str,
}

/// A spring network on the mesh edges behaves roughly like a solid of Young's modulus
/// `k / (c l)` (`l` the mean edge length): `k = c E l`, with `c` calibrated on the liver against
/// its FEM (config/scenes/abdomen.toml).
pub const MSD_CALIBRATION: f64 = 0.82;

impl Tissue {
    /// Spring stiffness, N/m, for a mesh of mean edge length `mean_edge` (m): `c E l`.
    pub fn msd_stiffness(&self, mean_edge: f64) -> f64 {
        MSD_CALIBRATION * self.young * mean_edge
    }

    /// Mass-spring damping γ, N·s/m per node, for a mean node mass `mean_node_mass` (kg): the
    /// FEM's `α m`, so both models lose their motion alike.
    pub fn msd_damping(&self, mean_node_mass: f64) -> f64 {
        self.fem_damping * mean_node_mass
    }
}

const HEAT: HeatParams = HeatParams {
    conductivity: 0.52,
    specific_heat: 3540.0,
    density: 1060.0,
    initial: 37.0,
    coagulation: 60.0,
    burn_stiffening: 1.0,
};

/// Poisson's ratio, density, damping and steps shared by every tissue (argued in
/// config/scenes/abdomen.toml: ν 0.45 keeps linear tetrahedra from locking; 1050 kg/m³ after
/// Duck FA (1990), Physical Properties of Tissue, Academic Press; α 30 1/s stops a touched
/// organ wobbling within ~0.26 s). The precise models step at the haptic rate (1 ms): they run
/// only while the tool touches the body and while it settles, and the surface under the hand is
/// then at most a millisecond old; the cage keeps 20 ms.
const POISSON: f64 = 0.45;
const DENSITY: f64 = 1050.0;
const FEM_DAMPING: f64 = 30.0;
const DT: f64 = 0.001;
const GC_DT: f64 = 0.02;

/// Every tissue of the library.
pub const TISSUES: [Tissue; 5] = [
    Tissue {
        name: "liver",
        young: 4100.0,
        poisson: POISSON,
        density: DENSITY,
        fem_damping: FEM_DAMPING,
        dt: DT,
        gc_dt: GC_DT,
        importance: Importance::Important,
        color: [0.47, 0.13, 0.11],
        heat: HEAT,
        source: "liver E 4.1 kPa: Fung J et al. (2013), \"Defining normal liver stiffness range in a\n\
                 normal healthy Chinese population without liver disease\", PLoS ONE 8(12):e85067 —\n\
                 transient elastography in vivo, 530 healthy adults, mean 4.1 kPa (2.3-5.9 kPa).",
    },
    Tissue {
        name: "spleen",
        young: 18000.0,
        poisson: POISSON,
        density: DENSITY,
        fem_damping: FEM_DAMPING,
        dt: DT,
        gc_dt: GC_DT,
        importance: Importance::Normal,
        color: [0.40, 0.12, 0.30],
        heat: HEAT,
        source: "spleen E 18 kPa: Giuffre M et al. (2019), \"Evaluation of spleen stiffness in\n\
                 healthy volunteers using point shear wave elastography\", Annals of Hepatology\n\
                 18(5):736-741 — in vivo, 100 healthy adults, 18.14 +/- 3.08 kPa.",
    },
    Tissue {
        name: "stomach",
        young: 10000.0,
        poisson: POISSON,
        density: DENSITY,
        fem_damping: FEM_DAMPING,
        dt: DT,
        gc_dt: GC_DT,
        importance: Importance::Important,
        color: [0.86, 0.56, 0.52],
        heat: HEAT,
        source: "stomach E 10 kPa: Dargar S et al. (2019), \"In vivo layer-specific mechanical\n\
                 characterization of porcine stomach tissue using a customized ultrasound\n\
                 elastography system\", J Biomech Eng 141(10):101004 — fundic muscularis shear\n\
                 modulus 3.42 kPa, E = 2 (1 + nu) mu ~ 10 kPa.",
    },
    Tissue {
        name: "pancreas",
        young: 1400.0,
        poisson: POISSON,
        density: DENSITY,
        fem_damping: FEM_DAMPING,
        dt: DT,
        gc_dt: GC_DT,
        importance: Importance::Normal,
        color: [0.90, 0.74, 0.50],
        heat: HEAT,
        source: "pancreas E 1.4 kPa: Pagnanelli M et al. (2024), \"Analysis of the mechanical\n\
                 characteristics of human pancreas through indentation: preliminary in vitro\n\
                 results on surgical samples\", Biomedicines 12(1):91 — ex vivo human surgical\n\
                 samples, 1.40 +/- 0.47 kPa.",
    },
    Tissue {
        name: "kidney",
        young: 4400.0,
        poisson: POISSON,
        density: DENSITY,
        fem_damping: FEM_DAMPING,
        dt: DT,
        gc_dt: GC_DT,
        importance: Importance::Important,
        color: [0.55, 0.22, 0.20],
        heat: HEAT,
        source: "kidney E 4.4 kPa: Samir AE et al. (2015), \"Shear wave elastography in chronic\n\
                 kidney disease: a pilot experience in native kidneys\", BMC Nephrology 16:119 —\n\
                 shear-wave elastography in vivo, 20 healthy controls: median Young's modulus\n\
                 4.40 kPa (quartiles 3.68-5.70 kPa). Not part of the abdomen scene.",
    },
];

/// The tissue called `name` (case-insensitive), if the library has it.
pub fn tissue(name: &str) -> Option<&'static Tissue> {
    TISSUES.iter().find(|t| t.name.eq_ignore_ascii_case(name))
}

/// The names `--tissue` takes.
pub fn tissue_names() -> Vec<&'static str> {
    TISSUES.iter().map(|t| t.name).collect()
}
