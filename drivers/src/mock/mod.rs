//! The scripted mock device: a [`MockScript`] of timed waypoints played by a [`MockDevice`] that
//! records every force it is sent in a fixed-capacity ring.
//!
//! Shipped scripts live in `config/scripts/*.toml`, four per scene (`poke`, `drag`, `grab`,
//! `heat`) and `cylinders-push` (cylinder A pushed sideways into cylinder B); `--device
//! mock:beam-poke` plays `config/scripts/beam-poke.toml`.
//!
//! The same scripts drive the simulated hand ([`crate::hand`]): there the waypoints are the
//! hand's intent, and an optional `[hand]` table sets the hand's parameters. The mock plays the
//! waypoints directly and ignores that table (it still validates it, so a typo fails under
//! either device).

mod device;
mod record;
mod script;

pub use device::MockDevice;
pub(crate) use device::FORCE_LIMIT_TOLERANCE;
pub(crate) use record::{write_force_csv_with, ForceRing, Ring};
pub use record::{ForceEntry, ForceRecord, ForceRecordIter, FORCE_RECORD_CAPACITY};
pub use script::{
    resolve_script, FaultWindow, Interpolation, MockScript, SampleFault, SampleFaultWindow,
    ScriptEnd, ScriptError, Waypoint, OUT_OF_WORKSPACE_MM, POSITION_SANITY_MM,
};
