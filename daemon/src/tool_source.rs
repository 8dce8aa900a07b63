//! Where an offline run (`lopd simulate`) takes the tool from: a mock script or a session
//! recording, both sampled on simulated time, so the run is deterministic either way.

use std::path::Path;

use anyhow::Result;
use lop_drivers::mock::{MockDevice, MockScript};
use lop_drivers::replay::Recording;
use lop_drivers::{DeviceLimits, DeviceSample};

/// A tool trajectory on simulated time.
pub enum ToolSource {
    /// `--script NAME|PATH` (or `--device mock:SCRIPT`).
    Script(MockScript),
    /// `--device replay:PATH`: a recorded session, by tick index.
    Replay(Recording),
}

impl ToolSource {
    /// Loads the script or the recording, if one is given (a script wins; the command line
    /// refuses both).
    pub fn load(script: Option<&Path>, replay: Option<&Path>) -> Result<Option<ToolSource>> {
        Ok(match (script, replay) {
            (Some(p), _) => Some(ToolSource::Script(MockScript::load(p)?)),
            (None, Some(p)) => Some(ToolSource::Replay(Recording::load(p)?)),
            (None, None) => None,
        })
    }

    /// The limits of the device this trajectory stands for: the mock's (an Omni's), or the
    /// recorded device's.
    pub fn limits(&self) -> DeviceLimits {
        match self {
            ToolSource::Script(_) => MockDevice::omni_limits(),
            ToolSource::Replay(r) => r.header().limits,
        }
    }

    /// The device sample at simulated time `t`, s.
    pub fn sample(&self, t: f64) -> DeviceSample {
        match self {
            ToolSource::Script(s) => s.sample(t),
            ToolSource::Replay(r) => r.sample(t),
        }
    }
}
