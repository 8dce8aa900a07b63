//! The scripted mock device: a [`MockScript`] of timed waypoints played by a [`MockDevice`] that
//! records every force it is sent in a fixed-capacity ring.
//!
//! Shipped scripts live in `config/scripts/*.toml`, four per scene (`poke`, `drag`, `grab`,
//! `heat`) and `cylinders-push` (cylinder A pushed sideways into cylinder B); `--device
//! mock:beam-poke` plays `config/scripts/beam-poke.toml`.

mod device;
mod record;
mod script;

pub use device::MockDevice;
pub use record::{ForceEntry, ForceRecord, ForceRecordIter, FORCE_RECORD_CAPACITY};
pub use script::{
    resolve_script, FaultWindow, Interpolation, MockScript, ScriptEnd, ScriptError, Waypoint,
    POSITION_SANITY_MM,
};
