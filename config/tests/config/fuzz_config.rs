//! Scene and daemon TOML against a corpus and its mutations: nothing panics, memory follows the
//! input, and every refusal names the file and says where (a line, or a key path).
//!
//! Seeds, each read as it is and then [`ROUNDS`] times mutated (`lop_test_support::fuzz`;
//! `LOP_FUZZ_ROUNDS` runs more, `LOP_FUZZ_LOG` prints each refusal):
//! - scenes: the shipped `config/scenes/*.toml` (read live, so new scenes join) and
//!   `tests/corpus/scene/` (a minimal scene, 3,000-deep arrays, inline tables and dotted keys,
//!   1e999 / NaN / ±inf / 20-digit integers, a 30 kB line, bytes that are not UTF-8, a BOM
//!   with CRLF, duplicate keys, 300 bodies, control characters, an empty file);
//! - daemon configurations: `deploy/lopd.toml` and `tests/corpus/daemon/` (every key, integer
//!   overflow, NaN, wrong types, deep nesting, not UTF-8, empty).
//!
//! Every seed is parsed as if it lived in `config/scenes/` (so `../../assets/meshes/liver` and
//! `../scripts/…` resolve as in the shipped scenes). Text is parsed with `parse_scene` /
//! `parse_daemon_config`; bytes that are not UTF-8 are written to a scratch file and loaded
//! with `load_scene` / `load_daemon_config`, whose refusal must name the line and the byte.
//!
//! A refusal's message must name the file and either a line or a key path; an out-of-range
//! value (`ConfigError::Invalid`) must also quote the value (`key = value`).

use std::path::{Path, PathBuf};

use lop_config::{load_daemon_config, load_scene, parse_daemon_config, parse_scene, ConfigError};
use lop_test_support::alloc::largest_on_this_thread;
use lop_test_support::fixtures::workspace_root;
use lop_test_support::fuzz::{self, Rng, Seed};

// The counting allocator (`Counting::armed_threads`) is installed once for this
// test binary, in `main.rs`.

/// Mutations per seed.
const ROUNDS: usize = 40;

/// TOML's and the schemas' own words, for the mutator.
const DICTIONARY: &[&[u8]] = &[
    b"[[body]]",
    b"[body.fem]",
    b"[body.msd]",
    b"[[body.fix]]",
    b"[scene]",
    b"[tool]",
    b"[haptic]",
    b"[deform]",
    b"young = ",
    b"poisson = ",
    b"dt = ",
    b"mesh = \"",
    b"model = \"fem\"",
    b"importance = \"",
    b"rt_priority = ",
    b"core = ",
    b"\"\"\"",
    b"'''",
    b"[[",
    b"]]",
    b"= {",
    b"1979-05-27T07:32:00Z",
    b"0x7fffffffffffffff",
    b"+nan",
    b"-inf",
    b"true",
    b"\\U0010FFFF",
    b"\\uD800",
];

/// Which parser a seed is for.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Kind {
    Scene,
    Daemon,
}

/// Where the seeds pretend to live: the shipped scenes' folder.
fn home() -> PathBuf {
    workspace_root().join("config/scenes")
}

fn seeds(kind: Kind) -> Vec<Seed> {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (corpus, shipped): (_, Vec<PathBuf>) = match kind {
        Kind::Scene => {
            let mut scenes: Vec<PathBuf> = std::fs::read_dir(home())
                .unwrap()
                .map(|e| e.unwrap().path())
                .filter(|p| p.extension().is_some_and(|e| e == "toml"))
                .collect();
            scenes.sort();
            (here.join("tests/corpus/scene"), scenes)
        }
        Kind::Daemon => (
            here.join("tests/corpus/daemon"),
            vec![workspace_root().join("deploy/lopd.toml")],
        ),
    };
    assert!(!shipped.is_empty());
    let mut seeds: Vec<Seed> = shipped
        .into_iter()
        .map(|path| Seed {
            name: format!("shipped-{}", path.file_name().unwrap().to_string_lossy()),
            bytes: std::fs::read(&path).unwrap(),
            path,
        })
        .collect();
    seeds.extend(fuzz::corpus(&corpus));
    seeds
}

/// Parses `bytes` as seed `name` would be; returns the refusal, if any.
fn parse(kind: Kind, name: &str, bytes: &[u8], scratch: &Path) -> Option<(ConfigError, PathBuf)> {
    match std::str::from_utf8(bytes) {
        Ok(text) => {
            let path = home().join(format!("fuzz-{name}"));
            let err = match kind {
                Kind::Scene => parse_scene(text, &path).err(),
                Kind::Daemon => parse_daemon_config(text, &path).err(),
            };
            err.map(|e| (e, path))
        }
        Err(_) => {
            let path = scratch.join(format!("fuzz-{name}"));
            std::fs::write(&path, bytes).unwrap();
            let err = match kind {
                Kind::Scene => load_scene(&path).err(),
                Kind::Daemon => load_daemon_config(&path).err(),
            };
            let err = err.expect("text that is not UTF-8 is refused");
            assert!(
                matches!(&err, ConfigError::Syntax { detail, .. } if detail.contains("not UTF-8 text: byte ")),
                "{name}: not UTF-8, refused without naming the byte: {err}"
            );
            Some((err, path))
        }
    }
}

fn check_refusal(err: &ConfigError, path: &Path, what: &str) {
    let msg = err.to_string();
    if fuzz::log() {
        eprintln!("{msg}");
    }
    assert!(
        msg.contains(path.to_str().unwrap()),
        "{what}: the message does not name the file: {msg}"
    );
    assert_eq!(err.file(), Some(path), "{what}: {msg}");
    let located = err.line().is_some() || err.key().is_some();
    assert!(
        located,
        "{what}: the message names no line and no key: {msg}"
    );
    if let ConfigError::Invalid { key, value, .. } = err {
        assert!(
            msg.contains(&format!("{key} = {value}")),
            "{what}: the value is not quoted: {msg}"
        );
    }
}

fn run(kind: Kind, state: u64) -> [usize; 2] {
    let scratch = lop_test_support::fixtures::temp_dir(&format!("lop-config-fuzz-{kind:?}"));
    let seeds = seeds(kind);
    let rounds = fuzz::rounds(ROUNDS);
    let mut outcomes = [0; 2];
    for seed in &seeds {
        let mut rng = Rng::for_seed(state, &seed.name);
        for round in 0..=rounds {
            let bytes = if round == 0 {
                seed.bytes.clone()
            } else {
                fuzz::mutate(&mut rng, &seed.bytes, DICTIONARY)
            };
            let what = format!("{} round {round}", seed.name);
            let (refusal, largest) =
                largest_on_this_thread(|| parse(kind, &seed.name, &bytes, &scratch));
            let allowed = (4 << 20) + 64 * bytes.len() as u64;
            assert!(
                largest <= allowed,
                "{what}: an allocation of {largest} bytes for {} bytes of TOML",
                bytes.len()
            );
            match refusal {
                None => outcomes[0] += 1,
                Some((err, path)) => {
                    check_refusal(&err, &path, &what);
                    outcomes[1] += 1;
                }
            }
        }
    }
    let _ = std::fs::remove_dir_all(&scratch);
    println!(
        "{kind:?}: {} seeds, ok: {}, refused: {}",
        seeds.len(),
        outcomes[0],
        outcomes[1]
    );
    outcomes
}

#[test]
fn scenes_and_their_mutations_never_panic() {
    let [ok, refused] = run(Kind::Scene, 0x5ce7_e5ce_7e5c_e7e5);
    assert!(ok >= 20 && refused >= 200, "ok {ok}, refused {refused}");
}

#[test]
fn daemon_configs_and_their_mutations_never_panic() {
    let [ok, refused] = run(Kind::Daemon, 0xdae7_0dae_70da_e70d);
    assert!(ok >= 20 && refused >= 50, "ok {ok}, refused {refused}");
}

#[test]
fn text_that_is_not_utf8_is_refused_at_its_byte() {
    let scratch = lop_test_support::fixtures::temp_dir("lop-config-fuzz-utf8");
    let path = scratch.join("bad.toml");
    std::fs::write(&path, b"[scene]\nname = \"a\xff\"\n").unwrap();
    let err = load_scene(&path).unwrap_err();
    let msg = err.to_string();
    println!("{msg}");
    assert_eq!(err.line(), Some(2));
    assert!(
        msg.contains("bad.toml: invalid TOML: line 2, column 10"),
        "{msg}"
    );
    assert!(msg.contains("byte 17 is 0xff"), "{msg}");
    let _ = std::fs::remove_dir_all(&scratch);
}
