//! The `--device` flag: which driver to open, as text the user types.
//!
//! Accepted forms: `mock`, `mock:SCRIPT`, `hand`, `hand:SCRIPT`, `replay:PATH`, `openhaptics`,
//! `openhaptics:NAME`, `dhd`, `dhd:ID`. `SCRIPT` is a script name in the scripts folder or a
//! path to a script file (see [`crate::mock::resolve_script`]); the mock plays it as the
//! stylus' path, the simulated hand ([`crate::hand`]) as its intent; `NAME` is the OpenHaptics
//! device name as configured in the vendor's setup tool (without it, the default device); `ID`
//! is a Force Dimension device's index in the DHD SDK's enumeration, `0..N-1` for N devices
//! (without it, index 0; `lopd doctor --device dhd` lists them). Parsing and
//! [`Display`](std::fmt::Display) round-trip.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

/// The accepted forms, for error messages and `--help`.
pub const DEVICE_SPEC_FORMS: &str = "`mock`, `mock:SCRIPT`, `hand`, `hand:SCRIPT`, `replay:PATH`, \
     `openhaptics`, `openhaptics:NAME`, `dhd`, `dhd:ID`";

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
    /// A Force Dimension device through the DHD SDK.
    ForceDimension {
        /// The SDK's device index (`0..N-1`); `None` for index 0.
        id: Option<u8>,
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
            ("dhd", None) => Ok(Self::ForceDimension { id: None }),
            ("dhd", Some(id)) => parse_dhd_id(id)
                .map(|id| Self::ForceDimension { id: Some(id) })
                .ok_or_else(|| {
                    error(
                        "a Force Dimension device ID is the DHD SDK's device index, a whole \
                         number from 0 to 127 (`lopd doctor --device dhd` lists the devices)",
                    )
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
            Self::ForceDimension { id: None } => f.write_str("dhd"),
            Self::ForceDimension { id: Some(id) } => write!(f, "dhd:{id}"),
        }
    }
}

/// A device index as written: decimal digits only (no sign, no spaces, no leading zeros, so
/// the text round-trips), at most the SDK's largest index.
fn parse_dhd_id(text: &str) -> Option<u8> {
    let digits = text.bytes().all(|b| b.is_ascii_digit());
    let canonical = text == "0" || !text.starts_with('0');
    let id: u8 = text.parse().ok().filter(|_| digits && canonical)?;
    (id <= crate::forcedimension::MAX_DEVICE_INDEX).then_some(id)
}
