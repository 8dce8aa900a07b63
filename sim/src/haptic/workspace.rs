//! The device-to-scene workspace transform and the Euler-angle convention shared with body
//! placement.
//!
//! The per-tick maps are [`glam::DAffine3`] / [`glam::DMat3`] products. glam's `f64` matrix
//! times vector is `x_axis·v.x + y_axis·v.y + z_axis·v.z`, left to right, without `mul_add`:
//! per component exactly the row-by-vector sums this module computed by hand before, so the
//! transform is bit-for-bit what it was.

use glam::{DAffine3, DMat3, DVec3};

/// A 3×3 rotation matrix, row-major: `m[row][col]`.
pub type Mat3 = [[f64; 3]; 3];

/// sin and cos of an angle in degrees, exact at multiples of 90° (so `rotate_deg = [0, 90, 0]`
/// maps axes onto axes without 6e-17 residues).
fn sin_cos_deg(deg: f64) -> (f64, f64) {
    let r = deg.rem_euclid(360.0);
    if r == 0.0 {
        (0.0, 1.0)
    } else if r == 90.0 {
        (1.0, 0.0)
    } else if r == 180.0 {
        (0.0, -1.0)
    } else if r == 270.0 {
        (-1.0, 0.0)
    } else {
        deg.to_radians().sin_cos()
    }
}

fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, cell) in row.iter_mut().enumerate() {
            *cell = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// The row-major `m` as a glam matrix (glam stores columns).
fn dmat3(m: &Mat3) -> DMat3 {
    DMat3::from_cols_array_2d(m).transpose()
}

/// `R v`.
pub fn mat_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    dmat3(m).mul_vec3(DVec3::from_array(v)).to_array()
}

/// `Rᵀ v`.
pub fn mat_t_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    // The columns of the row-major array are the rows of `R`: that matrix is `Rᵀ`.
    DMat3::from_cols_array_2d(m)
        .mul_vec3(DVec3::from_array(v))
        .to_array()
}

/// The rotation of `rotate_deg = [x, y, z]` (degrees): first about the fixed x axis, then about
/// the fixed y axis, then about the fixed z axis, i.e. `R = Rz(z) · Ry(y) · Rx(x)`. Positive
/// angles turn counter-clockwise looking down the axis towards the origin (right-handed).
/// Used for both `[workspace] rotate_deg` and `[[body]] rotate_deg`.
pub fn rotation_xyz_deg(deg: [f64; 3]) -> Mat3 {
    let (sx, cx) = sin_cos_deg(deg[0]);
    let (sy, cy) = sin_cos_deg(deg[1]);
    let (sz, cz) = sin_cos_deg(deg[2]);
    let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
    let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
    let rz = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
    mat_mul(&rz, &mat_mul(&ry, &rx))
}

/// How device positions (millimetres, the device's own frame) map into the scene (metres):
/// `scene_m = R(rotate_deg) · (device_mm · 1e-3 · scale) + offset`.
///
/// Forces are not scaled, only rotated back into the device frame. Note that a scale `s` makes a
/// scene stiffness `k` (N/m) feel like `k · s` at the stylus, since one device metre is `s` scene
/// metres.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkspaceMap {
    /// Scene metres per device metre (> 0).
    pub scale: f64,
    /// Rotation from the device frame into the scene frame, XYZ Euler degrees
    /// (see [`rotation_xyz_deg`]).
    pub rotate_deg: [f64; 3],
    /// Scene position (m) of the device origin.
    pub offset: [f64; 3],
}

impl Default for WorkspaceMap {
    fn default() -> Self {
        WorkspaceMap {
            scale: 1.0,
            rotate_deg: [0.0; 3],
            offset: [0.0; 3],
        }
    }
}

impl WorkspaceMap {
    /// The rotation matrix `R(rotate_deg)`.
    pub fn rotation(&self) -> Mat3 {
        rotation_xyz_deg(self.rotate_deg)
    }

    /// The same map with its rotation precomputed, for per-tick use (no trigonometry, no
    /// allocation).
    pub fn transform(&self) -> WorkspaceTransform {
        WorkspaceTransform {
            rotation: self.rotation(),
            scale: self.scale,
            offset: self.offset,
        }
    }

    /// `scene_m = R · (device_mm · 1e-3 · scale) + offset`.
    pub fn device_to_scene(&self, mm: [f64; 3]) -> [f64; 3] {
        self.transform().device_to_scene(mm)
    }

    /// The inverse of [`device_to_scene`](Self::device_to_scene).
    pub fn scene_to_device(&self, m: [f64; 3]) -> [f64; 3] {
        self.transform().scene_to_device(m)
    }

    /// A scene direction or force in the device frame: `Rᵀ v` (rotation only, no scaling).
    pub fn scene_dir_to_device(&self, v: [f64; 3]) -> [f64; 3] {
        self.transform().scene_dir_to_device(v)
    }

    /// A device direction in the scene frame: `R v` (rotation only).
    pub fn device_dir_to_scene(&self, v: [f64; 3]) -> [f64; 3] {
        self.transform().device_dir_to_scene(v)
    }
}

/// A [`WorkspaceMap`] with its rotation matrix precomputed. `Copy`, allocation-free: fit for the
/// real-time loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorkspaceTransform {
    /// `R(rotate_deg)`.
    pub rotation: Mat3,
    /// Scene metres per device metre.
    pub scale: f64,
    /// Scene position (m) of the device origin.
    pub offset: [f64; 3],
}

impl WorkspaceTransform {
    /// The rigid part, `x ↦ R x + offset`, applied to scaled device metres. The scale stays
    /// outside the matrix (`R (s x)`, not `(s R) x`), which keeps the rounding what it was.
    fn rigid(&self) -> DAffine3 {
        DAffine3::from_mat3_translation(dmat3(&self.rotation), DVec3::from_array(self.offset))
    }

    /// `scene_m = R · (device_mm · 1e-3 · scale) + offset`.
    pub fn device_to_scene(&self, mm: [f64; 3]) -> [f64; 3] {
        let k = 1e-3 * self.scale;
        self.rigid()
            .transform_point3(DVec3::from_array(mm) * k)
            .to_array()
    }

    /// `device_mm = Rᵀ · (scene_m − offset) / (1e-3 · scale)`.
    pub fn scene_to_device(&self, m: [f64; 3]) -> [f64; 3] {
        let d = mat_t_vec(
            &self.rotation,
            (DVec3::from_array(m) - DVec3::from_array(self.offset)).to_array(),
        );
        let k = 1e3 / self.scale;
        (DVec3::from_array(d) * k).to_array()
    }

    /// `Rᵀ v`: a scene direction or force in the device frame.
    pub fn scene_dir_to_device(&self, v: [f64; 3]) -> [f64; 3] {
        mat_t_vec(&self.rotation, v)
    }

    /// `R v`: a device direction in the scene frame.
    pub fn device_dir_to_scene(&self, v: [f64; 3]) -> [f64; 3] {
        mat_vec(&self.rotation, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_turns_are_exact_and_right_handed() {
        // 90° about z takes +x to +y.
        let r = rotation_xyz_deg([0.0, 0.0, 90.0]);
        assert_eq!(mat_vec(&r, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0]);
        // 90° about x takes +y to +z.
        let r = rotation_xyz_deg([90.0, 0.0, 0.0]);
        assert_eq!(mat_vec(&r, [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
        // x first, then z: +y → +z (about x) → +z (about z).
        let r = rotation_xyz_deg([90.0, 0.0, 90.0]);
        assert_eq!(mat_vec(&r, [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
        // and +z → -y (about x) → +x (about z).
        assert_eq!(mat_vec(&r, [0.0, 0.0, 1.0]), [1.0, 0.0, 0.0]);
    }

    #[test]
    fn rotation_is_orthonormal() {
        let r = rotation_xyz_deg([12.0, -70.0, 133.0]);
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((dot - want).abs() < 1e-15, "RᵀR[{i}][{j}] = {dot}");
            }
        }
    }

    #[test]
    fn identity_map_converts_millimetres() {
        let w = WorkspaceMap::default();
        assert_eq!(w.device_to_scene([1000.0, -20.0, 0.0]), [1.0, -0.02, 0.0]);
    }
}
