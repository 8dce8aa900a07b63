//! Mock-device scripts (with the hand device's `[hand]` table) and session recordings against a
//! corpus and its mutations: nothing panics, memory follows the input, and every refusal names
//! the file and says where.
//!
//! Seeds, each read as it is and then mutated (`lop_test_support::fuzz`; `LOP_FUZZ_ROUNDS` runs
//! more, `LOP_FUZZ_LOG` prints each refusal):
//! - scripts: the shipped `config/scripts/*.toml` (read live) and `tests/corpus/script/` (every
//!   optional table, NaN and infinite hand parameters, unknown keys, 1e999 times, huge
//!   positions, odd buttons, NaN fault windows, 1,000 waypoints, 3,000-deep arrays, bytes that
//!   are not UTF-8, no waypoints, wrong types, an empty file). Loaded with `MockScript::load`
//!   from a scratch file; a refusal names the file and a line (syntax, schema, not UTF-8) or a
//!   key with its value (`waypoint[3].t` = nan, `hand.hand_mass` = nan), or is the whole-file
//!   "no waypoints". A script that loads is sampled at a few times: every sample is finite.
//! - recordings: `tests/corpus/recording/*.rec` (a valid one and every kind of damage:
//!   truncated header and record, wrong or short magic, version 2, a metadata length of 4 GiB
//!   or past the end, metadata that is not UTF-8, NaN and infinite samples, ticks that go
//!   back, an unknown status, a NaN rate, inverted limits, an empty file). Parsed with
//!   `Recording::parse`; a refusal names the file and the byte offset (or, for a wrong magic
//!   or version, the bytes it found). A recording that parses is played by a `ReplayDevice`
//!   to its end.

use std::path::{Path, PathBuf};

use lop_drivers::mock::{MockScript, ScriptError};
use lop_drivers::replay::{Recording, RecordingError, ReplayDevice};
use lop_drivers::HapticDevice;
use lop_test_support::alloc::largest_on_this_thread;
use lop_test_support::fixtures::{temp_dir, workspace_root};
use lop_test_support::fuzz::{self, Rng, Seed};

// The counting allocator (`Counting::armed_threads`) is installed once for this
// test binary, in `main.rs`.

/// Mutations per script seed (about 750 loads, two seconds in the dev profile).
const ROUNDS: usize = 24;

/// Mutations per recording seed (parsing is cheap: about 1,500 parses in a few milliseconds).
const RECORDING_ROUNDS: usize = 80;

const SCRIPT_WORDS: &[&[u8]] = &[
    b"[[waypoint]]",
    b"[[fault]]",
    b"[hand]",
    b"t = ",
    b"position = [",
    b"buttons = [\"grab\"]",
    b"end = \"loop\"",
    b"end = \"stop\"",
    b"interpolation = \"linear\"",
    b"error = \"fault\"",
    b"sample = \"nan\"",
    b"sample = \"out_of_workspace\"",
    b"hand_mass = ",
    b"grip_stiffness = ",
    b"from = ",
    b"until = ",
    b"200.0",
    b"200.000001",
];

fn corpus_dir(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/corpus")
        .join(name)
}

fn allowed(len: usize) -> u64 {
    (4 << 20) + 64 * len as u64
}

fn script_seeds() -> Vec<Seed> {
    let mut shipped: Vec<PathBuf> = std::fs::read_dir(workspace_root().join("config/scripts"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    shipped.sort();
    assert!(!shipped.is_empty());
    let mut seeds: Vec<Seed> = shipped
        .into_iter()
        .map(|path| Seed {
            name: format!("shipped-{}", path.file_name().unwrap().to_string_lossy()),
            bytes: std::fs::read(&path).unwrap(),
            path,
        })
        .collect();
    seeds.extend(fuzz::corpus(&corpus_dir("script")));
    seeds
}

fn check_script_refusal(err: &ScriptError, path: &Path, what: &str) {
    let msg = err.to_string();
    if fuzz::log() {
        eprintln!("{msg}");
    }
    assert!(
        msg.contains(path.to_str().unwrap()),
        "{what}: the message does not name the file: {msg}"
    );
    match err {
        ScriptError::Syntax { message, .. } => assert!(
            message.contains("line "),
            "{what}: a syntax or schema error names no line: {msg}"
        ),
        ScriptError::Invalid { key, value, .. } => assert!(
            !key.is_empty() && !value.is_empty() && msg.contains(&format!("`{key}` = {value}")),
            "{what}: the key and value are not quoted: {msg}"
        ),
        ScriptError::NoWaypoints { .. } => {}
        ScriptError::Read { .. } => panic!("{what}: a scratch file could not be read: {msg}"),
    }
}

fn check_script(script: &MockScript, what: &str) {
    let end = script.duration() * 2.0 + 1.0;
    for k in 0..=20 {
        let t = end * f64::from(k) / 20.0;
        let s = script.sample(t);
        assert!(
            s.is_finite(),
            "{what}: sample at t = {t} is not finite: {s:?}"
        );
    }
    if let Some(hand) = script.hand() {
        assert!(hand.validate().is_ok(), "{what}: {hand:?}");
    }
}

#[test]
fn scripts_and_their_mutations_never_panic() {
    let dir = temp_dir("lop-drivers-fuzz-script");
    let seeds = script_seeds();
    let rounds = fuzz::rounds(ROUNDS);
    let mut outcomes = [0usize; 2];
    for seed in &seeds {
        let mut rng = Rng::for_seed(0x5c41_97f0_0d5c_41a7, &seed.name);
        for round in 0..=rounds {
            let bytes = if round == 0 {
                seed.bytes.clone()
            } else {
                fuzz::mutate(&mut rng, &seed.bytes, SCRIPT_WORDS)
            };
            let what = format!("{} round {round}", seed.name);
            let path = dir.join(&seed.name);
            std::fs::write(&path, &bytes).unwrap();
            let (result, largest) = largest_on_this_thread(|| MockScript::load(&path));
            assert!(
                largest <= allowed(bytes.len()),
                "{what}: an allocation of {largest} bytes for a {}-byte script",
                bytes.len()
            );
            match result {
                Ok(script) => {
                    check_script(&script, &what);
                    outcomes[0] += 1;
                }
                Err(err) => {
                    check_script_refusal(&err, &path, &what);
                    outcomes[1] += 1;
                }
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!(
        "scripts: {} seeds, ok: {}, refused: {}",
        seeds.len(),
        outcomes[0],
        outcomes[1]
    );
    assert!(outcomes[0] >= 100 && outcomes[1] >= 200, "{outcomes:?}");
}

#[test]
fn script_not_utf8_is_refused_at_its_line_and_byte() {
    let dir = temp_dir("lop-drivers-fuzz-utf8");
    let path = dir.join("bad.toml");
    std::fs::write(&path, b"name = \"x\"\n[[waypoint]]\nt = 0\xff\n").unwrap();
    let msg = MockScript::load(&path).unwrap_err().to_string();
    println!("{msg}");
    assert!(
        msg.contains("bad.toml: line 3: not UTF-8 text: byte 29 is 0xff"),
        "{msg}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

fn check_recording_refusal(err: &RecordingError, path: &Path, what: &str) {
    let msg = err.to_string();
    if fuzz::log() {
        eprintln!("{msg}");
    }
    assert!(
        msg.contains(path.to_str().unwrap()),
        "{what}: the message does not name the file: {msg}"
    );
    match err {
        RecordingError::Truncated { .. } | RecordingError::Invalid { .. } => assert!(
            msg.contains(": byte ") || msg.contains("truncated at byte "),
            "{what}: no byte offset: {msg}"
        ),
        RecordingError::NotARecording { .. } => {
            assert!(msg.contains("bytes 0..8 are"), "{what}: {msg}")
        }
        RecordingError::Version { found, .. } => {
            assert!(
                msg.contains(&format!("version {found} at byte 8")),
                "{what}: {msg}"
            )
        }
        RecordingError::Io { .. } => panic!("{what}: parse does no I/O: {msg}"),
    }
}

fn play(recording: Recording, what: &str) {
    let n = recording.records().len();
    let dt = 1.0 / recording.header().rate_hz;
    let path = recording.path().to_path_buf();
    let mut device = ReplayDevice::new(recording);
    if let Err(e) = device.start() {
        // A recording without samples cannot be played: refused when the device starts.
        assert_eq!(n, 0, "{what}: start: {e}");
        assert!(
            e.to_string().contains(path.to_str().unwrap()),
            "{what}: {e}"
        );
        return;
    }
    // Past the end: the replay device holds or reports its end, never panics.
    for k in 0..n + 3 {
        if let Ok(s) = device.read(k as f64 * dt) {
            assert!(s.is_finite(), "{what}: {s:?}");
        }
        let _ = device.write_force([0.0; 3]);
    }
}

#[test]
fn recordings_and_their_mutations_never_panic() {
    let seeds = fuzz::corpus(&corpus_dir("recording"));
    let rounds = fuzz::rounds(RECORDING_ROUNDS);
    let mut outcomes = [0usize; 2];
    for seed in &seeds {
        let mut rng = Rng::for_seed(0x7ec0_7d1e_7ec0_7d1e, &seed.name);
        let path = corpus_dir("recording").join(format!("fuzz-{}", seed.name));
        for round in 0..=rounds {
            let bytes = if round == 0 {
                seed.bytes.clone()
            } else {
                fuzz::mutate(&mut rng, &seed.bytes, &[b"LOP-REC\0", b"scene=", b"\n"])
            };
            let what = format!("{} round {round}", seed.name);
            let (result, largest) = largest_on_this_thread(|| Recording::parse(&bytes, &path));
            assert!(
                largest <= allowed(bytes.len()),
                "{what}: an allocation of {largest} bytes for a {}-byte recording",
                bytes.len()
            );
            match result {
                Ok(recording) => {
                    play(recording, &what);
                    outcomes[0] += 1;
                }
                Err(err) => {
                    check_recording_refusal(&err, &path, &what);
                    outcomes[1] += 1;
                }
            }
        }
    }
    println!(
        "recordings: {} seeds, ok: {}, refused: {}",
        seeds.len(),
        outcomes[0],
        outcomes[1]
    );
    assert!(outcomes[0] >= 50 && outcomes[1] >= 500, "{outcomes:?}");
}

/// The corpus' damaged recordings are refused for the damage they carry, at its byte.
#[test]
fn damaged_recordings_are_refused_where_the_damage_is() {
    let expect: &[(&str, &str)] = &[
        (
            "truncated-header.rec",
            "truncated at byte 20: the device limits: 72 bytes expected, 20 left",
        ),
        ("truncated-record.rec", "record 2 has 30 of 72 bytes"),
        (
            "wrong-magic.rec",
            "not a lop session recording (bytes 0..8 are",
        ),
        ("short-magic.rec", "not a lop session recording"),
        ("empty.rec", "not a lop session recording"),
        ("version-2.rec", "recording format version 2 at byte 8"),
        (
            "huge-metadata.rec",
            "byte 92: metadata length 4294967295 is implausible",
        ),
        (
            "metadata-longer-than-file.rec",
            "truncated at byte 96: the metadata: 60000 bytes expected",
        ),
        ("metadata-not-utf8.rec", "byte 96: metadata is not UTF-8"),
        (
            "nan-position.rec",
            "record 1 (tick 1): non-finite position [NaN",
        ),
        ("inf-velocity.rec", "record 0 (tick 0): non-finite position"),
        (
            "ticks-backwards.rec",
            "record 1: tick 3 does not follow tick 5",
        ),
        ("unknown-status.rec", "record 0: unknown status 4294967295"),
        (
            "bad-rate.rec",
            "byte 12: tick rate NaN Hz is not in (0, 100000]",
        ),
        ("bad-limits.rec", "byte 20: device limits"),
    ];
    let seeds = fuzz::corpus(&corpus_dir("recording"));
    for (name, needle) in expect {
        let seed = seeds.iter().find(|s| s.name == *name).expect(name);
        let msg = Recording::parse(&seed.bytes, &seed.path)
            .expect_err(name)
            .to_string();
        println!("{msg}");
        assert!(msg.contains(needle), "{needle:?} missing from {msg}");
        assert!(msg.contains(name), "{msg}");
    }
    for name in ["valid.rec", "header-only.rec", "no-metadata.rec"] {
        let seed = seeds.iter().find(|s| s.name == name).expect(name);
        Recording::parse(&seed.bytes, &seed.path).unwrap_or_else(|e| panic!("{e}"));
    }
}
