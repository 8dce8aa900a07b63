//! The DHD device frame and SI units mapped to lop's device frame (OpenHaptics convention).
//!
//! DHD reports positions in metres, velocities in m/s and takes forces in newtons, in the
//! device's world frame: origin at the centre of the workspace, **+x toward the operator,
//! +y to the operator's right, +z up** (the "world coordinate system" figure of Force
//! Dimension's device user manuals; CHAI3D, which Force Dimension maintains, uses this frame
//! unchanged as its own, with the camera on +x looking back at the origin and +z up).
//!
//! lop's device frame is OpenHaptics': millimetres, **+x right, +y up, +z toward the user**.
//! So lop (x, y, z) = DHD (y, z, x) × 1000 for positions and velocities, and a force lop
//! commands as (fx, fy, fz) is sent to DHD as (fz, fx, fy). The map is a cyclic permutation of
//! the axes — a proper rotation (determinant +1), so handedness, and with it the sign of
//! every cross product the loop takes, is kept.

/// Millimetres per metre.
const MM_PER_M: f64 = 1000.0;

/// A DHD position (m) or velocity (m/s) in lop's frame, in mm or mm/s.
pub fn to_lop_mm(dhd_m: [f64; 3]) -> [f64; 3] {
    [
        dhd_m[1] * MM_PER_M,
        dhd_m[2] * MM_PER_M,
        dhd_m[0] * MM_PER_M,
    ]
}

/// A force in lop's device frame (N) as DHD takes it (N).
pub fn force_to_dhd(lop_n: [f64; 3]) -> [f64; 3] {
    [lop_n[2], lop_n[0], lop_n[1]]
}

/// A force DHD reports or was sent (N), in lop's device frame (N).
pub fn force_to_lop(dhd_n: [f64; 3]) -> [f64; 3] {
    [dhd_n[1], dhd_n[2], dhd_n[0]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_map_toward_user_right_and_up() {
        // Toward the operator (DHD +x) is lop +z; right (DHD +y) is lop +x; up (+z) is lop +y.
        assert_eq!(to_lop_mm([0.01, 0.0, 0.0]), [0.0, 0.0, 10.0]);
        assert_eq!(to_lop_mm([0.0, 0.02, 0.0]), [20.0, 0.0, 0.0]);
        assert_eq!(to_lop_mm([0.0, 0.0, -0.03]), [0.0, -30.0, 0.0]);
        for f in [[1.0, 2.0, 3.0], [-0.5, 0.0, 7.0]] {
            assert_eq!(force_to_lop(force_to_dhd(f)), f);
        }
        // A force up in lop is a force up on the device.
        assert_eq!(force_to_dhd([0.0, 2.0, 0.0]), [0.0, 0.0, 2.0]);
    }

    #[test]
    fn the_map_is_a_rotation() {
        // Columns: lop's unit vectors written in DHD axes; right-handed iff det = +1.
        let ex = force_to_dhd([1.0, 0.0, 0.0]);
        let ey = force_to_dhd([0.0, 1.0, 0.0]);
        let ez = force_to_dhd([0.0, 0.0, 1.0]);
        let cross = [
            ex[1] * ey[2] - ex[2] * ey[1],
            ex[2] * ey[0] - ex[0] * ey[2],
            ex[0] * ey[1] - ex[1] * ey[0],
        ];
        assert_eq!(cross, ez);
    }
}
