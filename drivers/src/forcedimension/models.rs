//! What each Force Dimension device type can render and reach, by `dhdGetSystemType`.
//!
//! DHD reports a device's type but not its force or workspace, so the limits come from this
//! table. The figures are Force Dimension's published specifications as CHAI3D (the open
//! haptics framework Force Dimension maintains) tabulates them per DHD type: one translational
//! force figure per model (lop uses it as both the peak and the continuous limit), the largest
//! stiffness the device renders stably and the workspace radius. The usable box is that radius
//! on each axis around the workspace centre (the haptic loop accepts readings up to
//! `WORKSPACE_SLACK_MM` beyond it).
//!
//! | DHD type | model | force, N | stiffness, N/mm | workspace radius, mm |
//! |---|---|---|---|---|
//! | 63 | delta.3 | 20 | 5.0 | 150 |
//! | 33 | omega.3 | 12 | 5.0 | 75 |
//! | 34, 36 | omega.6 (right, left) | 12 | 5.0 | 75 |
//! | 35, 37 | omega.7 (right, left) | 12 | 5.0 | 75 |
//! | 104, 105 | sigma.7 (right, left) | 12 | 4.0 | 75 |
//! | 60 | Novint Falcon | 8 | 3.0 | 40 |
//! | any other | unknown (sigma.3, lambda.x, controllers, custom) | 4 peak, 2 continuous | 1.0 | 40 |
//!
//! The row for an unknown type is not a specification but a floor: half the weakest listed
//! device's force, a fifth of the softest stiffness and the smallest workspace, so a device lop
//! does not know is never driven harder than the gentlest one it does. Add a row (with its
//! source) to use such a device fully.

use std::ffi::c_int;

use crate::DeviceLimits;

/// One device type's figures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeviceModel {
    /// The model as Force Dimension names it.
    pub name: &'static str,
    /// Its limits in lop's device frame.
    pub limits: DeviceLimits,
    /// Whether the type is in the table (else the conservative floor applies).
    pub known: bool,
}

const fn model(name: &'static str, force_n: f64, stiffness: f64, radius_mm: f64) -> DeviceModel {
    DeviceModel {
        name,
        limits: DeviceLimits {
            max_force_n: force_n,
            max_continuous_force_n: force_n,
            max_stiffness_n_per_mm: stiffness,
            workspace_min_mm: [-radius_mm; 3],
            workspace_max_mm: [radius_mm; 3],
        },
        known: true,
    }
}

/// The conservative floor for a type not in the table.
pub const UNKNOWN_MODEL: DeviceModel = DeviceModel {
    name: "unknown Force Dimension device",
    limits: DeviceLimits {
        max_force_n: 4.0,
        max_continuous_force_n: 2.0,
        max_stiffness_n_per_mm: 1.0,
        workspace_min_mm: [-40.0; 3],
        workspace_max_mm: [40.0; 3],
    },
    known: false,
};

/// The figures for a `dhdGetSystemType` value.
pub fn model_for(system_type: c_int) -> DeviceModel {
    match system_type {
        63 => model("delta.3", 20.0, 5.0, 150.0),
        33 => model("omega.3", 12.0, 5.0, 75.0),
        34 | 36 => model("omega.6", 12.0, 5.0, 75.0),
        35 | 37 => model("omega.7", 12.0, 5.0, 75.0),
        104 | 105 => model("sigma.7", 12.0, 4.0, 75.0),
        60 => model("Novint Falcon", 8.0, 3.0, 40.0),
        _ => UNKNOWN_MODEL,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_types_get_the_floor_below_every_known_device() {
        let floor = model_for(91).limits; // DHD_DEVICE_CUSTOM
        assert!(!model_for(91).known);
        for t in [63, 33, 34, 35, 36, 37, 104, 105, 60] {
            let m = model_for(t);
            assert!(m.known, "{t}");
            let l = m.limits;
            assert!(floor.max_force_n < l.max_force_n, "{t}");
            assert!(floor.max_continuous_force_n <= l.max_continuous_force_n);
            assert!(floor.max_stiffness_n_per_mm < l.max_stiffness_n_per_mm);
            assert!(floor.workspace_max_mm[0] <= l.workspace_max_mm[0]);
            assert!((0..3).all(|k| l.workspace_min_mm[k] < l.workspace_max_mm[k]));
        }
        assert_eq!(model_for(33).limits.max_force_n, 12.0);
        assert_eq!(model_for(-1), UNKNOWN_MODEL);
    }
}
