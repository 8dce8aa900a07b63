//! The `--device` flag: which driver to open, as text the user types.
//!
//! Accepted forms: `mock`, `mock:SCRIPT`, `hand`, `hand:SCRIPT`, `replay:PATH`, `openhaptics`,
//! `openhaptics:NAME`. `SCRIPT` is a script name in the scripts folder or a path to a script file
//! (see [`crate::mock::resolve_script`]); the mock plays it as the stylus' path, the simulated
//! hand ([`crate::hand`]) as its intent; `NAME` is the OpenHaptics device name as configured in the
//! vendor's setup tool (without it, the default device). Parsing and [`Display`](std::fmt::Display)
//! round-trip.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

/// The accepted forms, for error messages and `--help`.
pub const DEVICE_SPEC_FORMS: &str =
    "`mock`, `mock:SCRIPT`, `hand`, `hand:SCRIPT`, `replay:PATH`, `openhaptics`, `openhaptics:NAME`";

/// Which device to open, parsed from `--device`.
#[derive(Clone, Debug, PartialEq)]
pub enum DeviceSpec {
    /// The scripted mock device; without a script it holds still.
    Mock {
        /// Script name or path, as given.
        script: Option<String>,
    },
    /// A stylus held by a simulated hand following a script; without a script the scene's
    /// default one (else it holds still).
    Hand {
        /// Script name or path, as given.
        script: Option<String>,
    },
    /// Replay of a recorded device stream.
    Replay {
        /// The recording.
        path: PathBuf,
    },
    /// A Phantom Omni / Touch through the OpenHaptics HD library.
    OpenHaptics {
        /// Configured device name; `None` for the library's default device.
        name: Option<String>,
    },
}

/// A `--device` value that is none of the accepted forms.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("invalid device `{value}`: {reason}; expected one of {DEVICE_SPEC_FORMS}")]
pub struct DeviceSpecError {
    /// The value as given.
    pub value: String,
    /// What is wrong with it.
    pub reason: &'static str,
}

impl FromStr for DeviceSpec {
    type Err = DeviceSpecError;

    fn from_str(value: &str) -> Result<Self, Self::Err> {
        let error = |reason| DeviceSpecError {
            value: value.to_owned(),
            reason,
        };
        let (kind, argument) = match value.split_once(':') {
            Some((kind, argument)) => (kind, Some(argument)),
            None => (value, None),
        };
        if argument == Some("") {
            return Err(error("nothing after `:`"));
        }
        match (kind, argument) {
            ("mock", script) => Ok(Self::Mock {
                script: script.map(str::to_owned),
            }),
            ("hand", script) => Ok(Self::Hand {
                script: script.map(str::to_owned),
            }),
            ("replay", Some(path)) => Ok(Self::Replay { path: path.into() }),
            ("replay", None) => Err(error("replay needs a recording path")),
            ("openhaptics", name) => Ok(Self::OpenHaptics {
                name: name.map(str::to_owned),
            }),
            _ => Err(error("unknown device kind")),
        }
    }
}

impl fmt::Display for DeviceSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Mock { script: None } => f.write_str("mock"),
            Self::Mock {
                script: Some(script),
            } => write!(f, "mock:{script}"),
            Self::Hand { script: None } => f.write_str("hand"),
            Self::Hand {
                script: Some(script),
            } => write!(f, "hand:{script}"),
            Self::Replay { path } => write!(f, "replay:{}", path.display()),
            Self::OpenHaptics { name: None } => f.write_str("openhaptics"),
            Self::OpenHaptics { name: Some(name) } => write!(f, "openhaptics:{name}"),
        }
    }
}
