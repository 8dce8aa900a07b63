//! Mock-device scripts: a TOML list of timed waypoints, parsed once and then sampled by time.
//!
//! ```toml
//! name = "poke the liver"
//! description = "..."
//! end = "loop"             # "loop" | "hold" | "stop"; default "hold"
//! interpolation = "smooth" # "linear" | "smooth"; default "smooth"
//!
//! [[waypoint]]
//! t = 0.0                  # seconds, strictly increasing, the first must be 0
//! position = [0.0, 40.0, 30.0]  # device mm, inside the ±200 mm sanity box
//! buttons = []             # any of "grab", "heat"; held until the next waypoint
//!
//! [[fault]]                # optional: inject a device error (for safety tests)
//! from = 2.0               # seconds of run time (not wrapped by `end = "loop"`)
//! until = 2.5              # optional; without it the fault lasts for ever
//! error = "communication"  # "fault" | "communication" | "force_limit" | "velocity_limit" | "motors_warm"
//!
//! [[fault]]                # or a broken sample: the read succeeds but reports garbage
//! from = 3.0
//! until = 3.02
//! sample = "nan"           # "nan" | "out_of_workspace" (instead of `error`)
//!
//! [hand]                   # optional: the simulated hand's parameters (`--device hand:SCRIPT`)
//! hand_stiffness = 150.0   # any of the keys of `HandParameters`, SI units; missing keys keep
//! hand_damping = 2.0       # their defaults
//! ```
//!
//! The `[hand]` table is for [`crate::hand::HandDevice`], which plays the waypoints as a hand's
//! intent; the mock, which plays them as the stylus' position, ignores it. It is validated
//! whoever reads the script, so an unknown key or a bad value fails under either device.
//!
//! A `[[fault]]` has either an `error` (the read or the force write fails with that
//! [`DeviceError`]) or a `sample` ([`SampleFault`]: the read succeeds and reports a sample no
//! device should, a NaN position or one far outside the workspace — what a glitching encoder or
//! a cable fault looks like to the haptic loop, which must refuse it and ramp the force down).
//! The waypoints themselves stay finite and inside the sanity box; [`MockScript::sample`] is
//! the script alone, and the device applies the sample faults on top.
//!
//! Parsing is two-stage: TOML into raw structs with `deny_unknown_fields`, then validation into a
//! [`MockScript`] whose errors name the file, the key (`waypoint[3].t`) and the bad value. Checks
//! are written so that NaN fails them. [`MockScript::sample`] is pure and allocation-free, so the
//! mock can call it on the RT path.

use std::fmt;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::device::{
    DeviceError, DeviceLimits, DeviceSample, BUTTON_CUT, BUTTON_GRAB, BUTTON_HEAT,
};
use crate::hand::{HandParameters, RawHand};

/// Waypoint coordinates must lie within ±this many mm: anything larger is a typo (metres vs mm),
/// not a device position.
pub const POSITION_SANITY_MM: f64 = 200.0;

/// A loop script must end where it starts, to within this many mm (a mock must not teleport).
const LOOP_CLOSURE_TOLERANCE_MM: f64 = 1e-6;

/// Button names a script may use, with their bits.
const BUTTON_NAMES: [(&str, u32); 3] = [
    ("grab", BUTTON_GRAB),
    ("heat", BUTTON_HEAT),
    ("cut", BUTTON_CUT),
];

/// What the script does after its last waypoint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScriptEnd {
    /// Start again from the first waypoint: `t` is taken modulo the duration.
    Loop,
    /// Hold the last waypoint for ever.
    #[default]
    Hold,
    /// Hold the last waypoint; the daemon may end the run once [`MockScript::duration`] has
    /// passed.
    Stop,
}

/// How positions move between waypoints.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Interpolation {
    /// Constant velocity between waypoints (velocity jumps at waypoints).
    Linear,
    /// Cubic ease in/out (smoothstep `3u² − 2u³`): continuous velocity, zero at every waypoint.
    #[default]
    Smooth,
}

/// One validated waypoint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Waypoint {
    /// Seconds since the start of the script.
    pub t: f64,
    /// Device position, mm.
    pub position_mm: [f64; 3],
    /// Buttons pressed from this waypoint until the next one.
    pub buttons: u32,
}

/// A time window during which the mock reports an error.
///
/// Device errors (not [`DeviceError::is_recoverable`]) fail `read` and `write_force`; force
/// errors fail only `write_force`. Either way the mock renders zero force meanwhile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultWindow {
    /// Run time (seconds) the fault starts, inclusive.
    pub from: f64,
    /// Run time the fault ends, exclusive; `f64::INFINITY` for never.
    pub until: f64,
    /// The error reported meanwhile.
    pub error: DeviceError,
}

impl FaultWindow {
    /// Whether the fault is active at run time `t`.
    pub fn contains(&self, t: f64) -> bool {
        t >= self.from && t < self.until
    }
}

/// How a [`SampleFaultWindow`] breaks the samples it covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SampleFault {
    /// Position and velocity are NaN.
    Nan,
    /// The position is [`OUT_OF_WORKSPACE_MM`] beyond the far corner of the device's workspace
    /// on every axis (the velocity is the script's).
    OutOfWorkspace,
}

/// How far beyond the workspace's upper corner an `out_of_workspace` sample lies, mm on each
/// axis: well past any slack a loop may give a real device near the edge of its reach.
pub const OUT_OF_WORKSPACE_MM: f64 = 100.0;

impl SampleFault {
    /// `sample` as this fault reports it on a device with `limits`.
    pub fn apply(self, sample: DeviceSample, limits: &DeviceLimits) -> DeviceSample {
        match self {
            SampleFault::Nan => DeviceSample {
                position_mm: [f64::NAN; 3],
                velocity_mm_s: [f64::NAN; 3],
                buttons: sample.buttons,
            },
            SampleFault::OutOfWorkspace => DeviceSample {
                position_mm: limits.workspace_max_mm.map(|c| c + OUT_OF_WORKSPACE_MM),
                ..sample
            },
        }
    }
}

/// A time window during which the mock's reads succeed but report a broken sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleFaultWindow {
    /// Run time (seconds) the fault starts, inclusive.
    pub from: f64,
    /// Run time the fault ends, exclusive; `f64::INFINITY` for never.
    pub until: f64,
    /// What the samples meanwhile look like.
    pub fault: SampleFault,
}

impl SampleFaultWindow {
    /// Whether the fault is active at run time `t`.
    pub fn contains(&self, t: f64) -> bool {
        t >= self.from && t < self.until
    }
}

/// Why a script could not be loaded. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum ScriptError {
    /// The file could not be read.
    #[error("cannot read mock script {}: {source}", path.display())]
    Read {
        /// The script file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not valid TOML (or not UTF-8) or does not fit the schema (unknown key, wrong
    /// type); the message has the line, the column and the key (or the line and the offset of
    /// the first byte that is not UTF-8).
    #[error("{}: {message}", path.display())]
    Syntax {
        /// The script file.
        path: PathBuf,
        /// The TOML parser's message.
        message: String,
    },
    /// The script has no `[[waypoint]]`.
    #[error("{}: no waypoints: add at least one [[waypoint]], the first at t = 0.0", path.display())]
    NoWaypoints {
        /// The script file.
        path: PathBuf,
    },
    /// A value is out of range.
    #[error("{}: `{key}` = {value}: {reason}", path.display())]
    Invalid {
        /// The script file.
        path: PathBuf,
        /// The offending key, e.g. `waypoint[3].t`.
        key: String,
        /// The offending value as written back in TOML-ish form, e.g. `nan`, `"grap"`.
        value: String,
        /// What the value must be.
        reason: String,
    },
}

/// A parsed, validated mock-device script.
#[derive(Clone, Debug, PartialEq)]
pub struct MockScript {
    name: String,
    description: String,
    end: ScriptEnd,
    interpolation: Interpolation,
    /// Never empty; `waypoints[0].t == 0`, strictly increasing `t`.
    waypoints: Vec<Waypoint>,
    faults: Vec<FaultWindow>,
    sample_faults: Vec<SampleFaultWindow>,
    /// The `[hand]` table over the defaults, validated; `None` without one.
    hand: Option<HandParameters>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScript {
    name: Option<String>,
    #[serde(default)]
    description: String,
    #[serde(default)]
    end: ScriptEnd,
    #[serde(default)]
    interpolation: Interpolation,
    #[serde(default)]
    waypoint: Vec<RawWaypoint>,
    #[serde(default)]
    fault: Vec<RawFault>,
    hand: Option<RawHand>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWaypoint {
    t: f64,
    position: [f64; 3],
    #[serde(default)]
    buttons: Vec<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFault {
    from: f64,
    until: Option<f64>,
    error: Option<FaultKind>,
    sample: Option<SampleFault>,
}

#[derive(Clone, Copy, Deserialize)]
#[serde(rename_all = "snake_case")]
enum FaultKind {
    Fault,
    Communication,
    ForceLimit,
    VelocityLimit,
    MotorsWarm,
}

impl From<FaultKind> for DeviceError {
    fn from(kind: FaultKind) -> Self {
        match kind {
            FaultKind::Fault => Self::Fault,
            FaultKind::Communication => Self::Communication,
            FaultKind::ForceLimit => Self::ForceLimitExceeded,
            FaultKind::VelocityLimit => Self::VelocityLimitExceeded,
            FaultKind::MotorsWarm => Self::MotorsWarm,
        }
    }
}

/// Formats an `f64` as TOML would spell it (`nan`, `inf`), for error messages.
struct TomlFloat(f64);

impl fmt::Display for TomlFloat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            v if v.is_nan() => f.write_str("nan"),
            v if v.is_infinite() => f.write_str(if v > 0.0 { "inf" } else { "-inf" }),
            v => write!(f, "{v:?}"),
        }
    }
}

impl MockScript {
    /// Reads and validates the script at `path`.
    pub fn load(path: &Path) -> Result<MockScript, ScriptError> {
        let bytes = std::fs::read(path).map_err(|source| ScriptError::Read {
            path: path.to_owned(),
            source,
        })?;
        let text = String::from_utf8(bytes).map_err(|e| {
            // Name the line and the byte, as the TOML parser's messages do.
            let valid = e.utf8_error().valid_up_to();
            let bytes = e.as_bytes();
            let line = 1 + bytes[..valid].iter().filter(|&&b| b == b'\n').count();
            ScriptError::Syntax {
                path: path.to_owned(),
                message: format!(
                    "line {line}: not UTF-8 text: byte {valid} is 0x{:02x}",
                    bytes.get(valid).copied().unwrap_or(0)
                ),
            }
        })?;
        Self::parse(&text, path)
    }

    /// Parses and validates script `text`; `path` is only used to name the file in errors and
    /// as the default `name`.
    pub fn parse(text: &str, path: &Path) -> Result<MockScript, ScriptError> {
        let raw: RawScript = toml::from_str(text).map_err(|e| ScriptError::Syntax {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        Validator { path }.script(raw)
    }

    /// A script that holds still at `position_mm` for ever, with no buttons: what `--device mock`
    /// without a script plays.
    pub fn stationary(position_mm: [f64; 3]) -> MockScript {
        MockScript {
            name: "stationary".to_owned(),
            description: String::new(),
            end: ScriptEnd::Hold,
            interpolation: Interpolation::Smooth,
            waypoints: vec![Waypoint {
                t: 0.0,
                position_mm,
                buttons: 0,
            }],
            faults: Vec::new(),
            sample_faults: Vec::new(),
            hand: None,
        }
    }

    /// The script's `name` (the file stem if it has none).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The script's `description`, possibly empty.
    pub fn description(&self) -> &str {
        &self.description
    }

    /// What happens after the last waypoint.
    pub fn ends(&self) -> ScriptEnd {
        self.end
    }

    /// How positions move between waypoints.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// The waypoints, in time order; never empty.
    pub fn waypoints(&self) -> &[Waypoint] {
        &self.waypoints
    }

    /// The injected device errors (`[[fault]]` with `error`), in file order.
    pub fn faults(&self) -> &[FaultWindow] {
        &self.faults
    }

    /// The injected broken samples (`[[fault]]` with `sample`), in file order.
    pub fn sample_faults(&self) -> &[SampleFaultWindow] {
        &self.sample_faults
    }

    /// The sample fault active at run time `t`, if any (the first in file order).
    /// Allocation-free.
    pub fn sample_fault_at(&self, t: f64) -> Option<SampleFault> {
        self.sample_faults
            .iter()
            .find(|w| w.contains(t))
            .map(|w| w.fault)
    }

    /// The simulated hand's parameters from the `[hand]` table (defaults for the keys it
    /// leaves out), or `None` if the script has no `[hand]` table. The mock ignores them.
    pub fn hand(&self) -> Option<HandParameters> {
        self.hand
    }

    /// Time of the last waypoint, seconds (0 for a single waypoint).
    pub fn duration(&self) -> f64 {
        self.waypoints.last().map_or(0.0, |w| w.t)
    }

    /// The device sample at run time `t` seconds: piecewise interpolation between waypoints,
    /// velocity by the analytic derivative of that interpolation. Pure and allocation-free.
    ///
    /// Before the start (negative or NaN `t`) it is the first waypoint; after the end it wraps
    /// (`loop`) or holds the last waypoint at rest (`hold`, `stop`). At a waypoint's `t` the
    /// position is that waypoint's exactly, and the buttons are that waypoint's.
    pub fn sample(&self, t: f64) -> DeviceSample {
        let t = self.script_time(t);
        // First waypoint with `w.t > t`; at least 1 because `waypoints[0].t == 0 <= t`.
        let next = self.waypoints.partition_point(|w| w.t <= t).max(1);
        let from = &self.waypoints[next - 1];
        let Some(to) = self.waypoints.get(next) else {
            return DeviceSample {
                position_mm: from.position_mm,
                velocity_mm_s: [0.0; 3],
                buttons: from.buttons,
            };
        };
        let span = to.t - from.t;
        let u = (t - from.t) / span;
        let (s, ds_du) = match self.interpolation {
            Interpolation::Linear => (u, 1.0),
            Interpolation::Smooth => (u * u * (3.0 - 2.0 * u), 6.0 * u * (1.0 - u)),
        };
        let mut sample = DeviceSample {
            buttons: from.buttons,
            ..DeviceSample::default()
        };
        for k in 0..3 {
            let delta = to.position_mm[k] - from.position_mm[k];
            sample.position_mm[k] = from.position_mm[k] + delta * s;
            sample.velocity_mm_s[k] = delta * ds_du / span;
        }
        sample
    }

    /// Maps run time to script time in `[0, duration]` according to `end`.
    fn script_time(&self, t: f64) -> f64 {
        if t.is_nan() || t <= 0.0 {
            return 0.0;
        }
        let duration = self.duration();
        match self.end {
            ScriptEnd::Loop if duration > 0.0 => {
                let wrapped = t % duration;
                // `inf % d` is NaN.
                if wrapped.is_finite() {
                    wrapped
                } else {
                    0.0
                }
            }
            ScriptEnd::Loop | ScriptEnd::Hold | ScriptEnd::Stop => t.min(duration),
        }
    }
}

/// Second stage of parsing: raw structs to a validated [`MockScript`].
struct Validator<'a> {
    path: &'a Path,
}

impl Validator<'_> {
    fn invalid(&self, key: String, value: impl fmt::Display, reason: String) -> ScriptError {
        ScriptError::Invalid {
            path: self.path.to_owned(),
            key,
            value: value.to_string(),
            reason,
        }
    }

    fn script(&self, raw: RawScript) -> Result<MockScript, ScriptError> {
        if raw.waypoint.is_empty() {
            return Err(ScriptError::NoWaypoints {
                path: self.path.to_owned(),
            });
        }
        let mut waypoints = Vec::with_capacity(raw.waypoint.len());
        for (i, raw_waypoint) in raw.waypoint.iter().enumerate() {
            let waypoint = self.waypoint(i, raw_waypoint, waypoints.last())?;
            waypoints.push(waypoint);
        }
        if raw.end == ScriptEnd::Loop {
            self.check_loop_closes(&waypoints)?;
        }
        let mut faults = Vec::new();
        let mut sample_faults = Vec::new();
        for (i, fault) in raw.fault.iter().enumerate() {
            match self.fault(i, fault)? {
                Fault::Error(w) => faults.push(w),
                Fault::Sample(w) => sample_faults.push(w),
            }
        }
        let name = raw.name.unwrap_or_else(|| {
            self.path
                .file_stem()
                .map_or_else(|| "mock script".to_owned(), |s| s.to_string_lossy().into())
        });
        let hand = match &raw.hand {
            Some(table) => {
                let params = table.over_defaults();
                params.validate().map_err(|e| {
                    self.invalid(format!("hand.{}", e.key), TomlFloat(e.value), e.reason)
                })?;
                Some(params)
            }
            None => None,
        };
        Ok(MockScript {
            name,
            description: raw.description,
            end: raw.end,
            interpolation: raw.interpolation,
            waypoints,
            faults,
            sample_faults,
            hand,
        })
    }

    fn waypoint(
        &self,
        i: usize,
        raw: &RawWaypoint,
        previous: Option<&Waypoint>,
    ) -> Result<Waypoint, ScriptError> {
        let key = format!("waypoint[{i}].t");
        if !raw.t.is_finite() {
            return Err(self.invalid(key, TomlFloat(raw.t), "must be finite".into()));
        }
        match previous {
            None if raw.t != 0.0 => {
                return Err(self.invalid(
                    key,
                    TomlFloat(raw.t),
                    "the first waypoint must be at t = 0.0".into(),
                ));
            }
            Some(previous) if raw.t <= previous.t => {
                let reason = format!(
                    "must be greater than waypoint[{}].t = {}",
                    i - 1,
                    TomlFloat(previous.t)
                );
                return Err(self.invalid(key, TomlFloat(raw.t), reason));
            }
            _ => {}
        }
        for (k, &v) in raw.position.iter().enumerate() {
            let key = format!("waypoint[{i}].position[{k}]");
            if !v.is_finite() {
                return Err(self.invalid(key, TomlFloat(v), "must be finite".into()));
            }
            if v.abs() > POSITION_SANITY_MM {
                let reason = format!(
                    "outside the ±{POSITION_SANITY_MM} mm sanity box (positions are device millimetres)"
                );
                return Err(self.invalid(key, TomlFloat(v), reason));
            }
        }
        let mut buttons = 0;
        for (b, name) in raw.buttons.iter().enumerate() {
            match BUTTON_NAMES.iter().find(|(known, _)| known == name) {
                Some((_, bit)) => buttons |= bit,
                None => {
                    return Err(self.invalid(
                        format!("waypoint[{i}].buttons[{b}]"),
                        format_args!("{name:?}"),
                        "unknown button: expected \"grab\", \"heat\" or \"cut\"".into(),
                    ));
                }
            }
        }
        Ok(Waypoint {
            t: raw.t,
            position_mm: raw.position,
            buttons,
        })
    }

    fn check_loop_closes(&self, waypoints: &[Waypoint]) -> Result<(), ScriptError> {
        let (first, last) = (waypoints[0], waypoints[waypoints.len() - 1]);
        let closes = (0..3).all(|k| {
            (last.position_mm[k] - first.position_mm[k]).abs() <= LOOP_CLOSURE_TOLERANCE_MM
        });
        if closes {
            return Ok(());
        }
        let [x, y, z] = first.position_mm.map(TomlFloat);
        let [lx, ly, lz] = last.position_mm.map(TomlFloat);
        Err(self.invalid(
            format!("waypoint[{}].position", waypoints.len() - 1),
            format_args!("[{lx}, {ly}, {lz}]"),
            format!(
                "an end = \"loop\" script must end where it starts, at [{x}, {y}, {z}] (a device cannot jump)"
            ),
        ))
    }

    fn fault(&self, i: usize, raw: &RawFault) -> Result<Fault, ScriptError> {
        if !raw.from.is_finite() || raw.from < 0.0 {
            return Err(self.invalid(
                format!("fault[{i}].from"),
                TomlFloat(raw.from),
                "must be a finite time >= 0".into(),
            ));
        }
        let until = raw.until.unwrap_or(f64::INFINITY);
        if until.is_nan() || until <= raw.from {
            return Err(self.invalid(
                format!("fault[{i}].until"),
                TomlFloat(until),
                format!(
                    "must be greater than fault[{i}].from = {}",
                    TomlFloat(raw.from)
                ),
            ));
        }
        match (raw.error, raw.sample) {
            (Some(error), None) => Ok(Fault::Error(FaultWindow {
                from: raw.from,
                until,
                error: error.into(),
            })),
            (None, Some(fault)) => Ok(Fault::Sample(SampleFaultWindow {
                from: raw.from,
                until,
                fault,
            })),
            (Some(_), Some(fault)) => Err(self.invalid(
                format!("fault[{i}].sample"),
                format_args!("{:?}", sample_fault_name(fault)),
                "a fault has either `error` or `sample`, not both".into(),
            )),
            (None, None) => Err(self.invalid(
                format!("fault[{i}]"),
                format_args!("from = {}", TomlFloat(raw.from)),
                "needs `error = \"communication\"` (or another device error) or `sample = \"nan\"` \
                 (or \"out_of_workspace\")"
                    .into(),
            )),
        }
    }
}

/// One validated `[[fault]]`.
enum Fault {
    Error(FaultWindow),
    Sample(SampleFaultWindow),
}

/// A sample fault as the script spells it.
fn sample_fault_name(fault: SampleFault) -> &'static str {
    match fault {
        SampleFault::Nan => "nan",
        SampleFault::OutOfWorkspace => "out_of_workspace",
    }
}

/// Where `--device mock:SCRIPT` finds its script: `SCRIPT` itself if it looks like a path
/// (contains a path separator or ends in `.toml`), else `SCRIPT.toml` in `scripts_dir`.
pub fn resolve_script(script: &str, scripts_dir: &Path) -> PathBuf {
    if script.ends_with(".toml") || script.contains(std::path::is_separator) {
        PathBuf::from(script)
    } else {
        scripts_dir.join(format!("{script}.toml"))
    }
}
