//! The haptic pipeline's settings for a scene on a device: the one place where the daemon
//! config, the scene's tool and the device's limits become the numbers the tick runs with, so
//! the live loop, the servo callback and the offline closed loop render the same law.

use lop_config::{DaemonConfig, Scene};
use lop_drivers::DeviceLimits;
use lop_sim::haptic::PipelineSettings;

use crate::{DeviceClamp, ToolLaws};

/// The pipeline settings of `scene`'s first tool on a device with `limits` under `config`.
pub fn pipeline_settings(
    config: &DaemonConfig,
    scene: &Scene,
    limits: &DeviceLimits,
) -> PipelineSettings {
    tool_pipeline_settings(config, scene, 0, limits)
}

/// The pipeline settings of `scene`'s tool `tool` (the first for an index past the last) on
/// the device that drives it, with `limits`, under `config`.
pub fn tool_pipeline_settings(
    config: &DaemonConfig,
    scene: &Scene,
    tool: usize,
    limits: &DeviceLimits,
) -> PipelineSettings {
    let spec = scene.tools.get(tool).unwrap_or(scene.tool());
    let rate = scene.rates.haptic_hz;
    let h = &config.haptic;
    // The one tool law per body, clamped to what the device renders (the deformation process
    // receives the same stiffness with every tool state).
    let laws = ToolLaws::of_tool(
        scene,
        tool,
        DeviceClamp {
            max_stiffness_n_per_mm: limits.max_stiffness_n_per_mm,
        },
    );
    PipelineSettings {
        rate_hz: rate,
        ramp_ticks: ((h.ramp_ms * 1e-3 * rate).round() as u32).max(1),
        max_force: h.max_force_n.min(spec.max_force).min(limits.max_force_n),
        max_continuous_force: limits.max_continuous_force_n,
        max_step: h.max_force_step_n,
        workspace: spec.workspace.transform(),
        workspace_min_mm: limits.workspace_min_mm,
        workspace_max_mm: limits.workspace_max_mm,
        tool: laws.tool,
        body_stiffness: laws.bodies.iter().map(|t| t.stiffness).collect(),
        damping: laws.damping,
        local_model: h.local_model,
        passivity_max_damping: h.passivity_max_damping,
        holds: spec.kind.holds(),
        cauterizes: spec.kind.cauterizes(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tool_stiffness_is_clamped_to_what_the_device_renders() {
        let path = lop_config::resolve_scene("organs").unwrap();
        let scene = lop_config::load_scene(&path).unwrap();
        let mut limits = lop_drivers::mock::MockDevice::omni_limits();
        // The shipped 300 N/m at workspace scale 2 is 0.6 N/mm at the stylus.
        let s = pipeline_settings(&DaemonConfig::default(), &scene, &limits);
        assert_eq!(s.tool.stiffness, 300.0);
        assert!(s.body_stiffness.iter().all(|&k| k == 300.0));
        // A device that renders only 0.3 N/mm: 0.3 / (1e-3 · 2) = 150 N/m.
        limits.max_stiffness_n_per_mm = 0.3;
        let s = pipeline_settings(&DaemonConfig::default(), &scene, &limits);
        assert!((s.tool.stiffness - 150.0).abs() < 1e-9);
        assert!(s.body_stiffness.iter().all(|&k| (k - 150.0).abs() < 1e-9));
    }
}
