//! The viewer's JSON control messages (`wire::control_request`, `wire::control_op_and_token`:
//! what the WebSocket handler does with every text frame a page sends) against a corpus and its
//! mutations: nothing panics, and a refusal quotes what is wrong.
//!
//! The corpus is `tests/corpus/control/*.json`: a message of every op (the value as a number
//! and as a string), NaN, 1e400 and 30-digit values, a null value, an unknown model and op, no
//! op, an op that is a number, an array instead of an object, 5,000-deep nesting, a 4 kB body
//! name, escapes (NUL, a lone surrogate), duplicate keys, a truncated message, an empty one.
//! Each seed is parsed as it is, then [`ROUNDS`] times mutated by `lop_test_support::fuzz`
//! (`LOP_FUZZ_ROUNDS` runs more, `LOP_FUZZ_LOG` prints each refusal). A WebSocket text frame
//! is UTF-8, so mutated bytes are made text with `from_utf8_lossy` first.
//!
//! For every message:
//! - a request that parses has a known op, and its body and key fields hold a prefix of the
//!   message's strings (cut at a character boundary to the field's size);
//! - a refusal quotes the bad part: serde_json's line and column for bad JSON, or the op, the
//!   model or the value as the page sent it;
//! - the op for the log is at most 32 characters.

use lop_client::*;
use lop_test_support::fuzz::{self, Rng};
use lop_view::wire::{control_op_and_token, control_request};
use serde_json::Value;

/// Mutations per seed.
const ROUNDS: usize = 600;

const WORDS: &[&[u8]] = &[
    b"\"op\":",
    b"\"get\"",
    b"\"set\"",
    b"\"pin\"",
    b"\"reset\"",
    b"\"body\":",
    b"\"key\":",
    b"\"value\":",
    b"\"model\":",
    b"\"fem\"",
    b"\"token\":",
    b"\"fem.young\"",
    b"\"lop.hold\"",
    b"1e400",
    b"-0",
    b"null",
    b"true",
    b"{}",
    b"[]",
    b"\\ud800",
    b"\\u0000",
];

fn corpus() -> Vec<fuzz::Seed> {
    fuzz::corpus(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/control"))
}

fn check(text: &str, what: &str) -> bool {
    let (op, _token) = control_op_and_token(text);
    assert!(op.chars().count() <= 32, "{what}: op {op:?}");
    match control_request(text) {
        Ok(req) => {
            let v: Value = serde_json::from_str(text).expect("parsed once already");
            let known = [
                CONTROL_OP_GET,
                CONTROL_OP_SET,
                CONTROL_OP_PIN,
                CONTROL_OP_RELEASE,
                CONTROL_OP_RESET,
                CONTROL_OP_PAUSE,
                CONTROL_OP_RESUME,
            ];
            assert!(known.contains(&req.op), "{what}: op {}", req.op);
            if req.op != CONTROL_OP_RESET
                && req.op != CONTROL_OP_PAUSE
                && req.op != CONTROL_OP_RESUME
            {
                let body = v["body"].as_str().unwrap_or("");
                assert!(body.starts_with(req.body_str()), "{what}: {body:?}");
            }
            if req.op == CONTROL_OP_SET {
                let key = v["key"].as_str().unwrap_or("");
                assert!(key.starts_with(req.key_str()), "{what}: {key:?}");
            }
            true
        }
        Err(msg) => {
            if fuzz::log() {
                eprintln!("{msg}");
            }
            let quoted = match serde_json::from_str::<Value>(text) {
                Err(_) => {
                    msg.starts_with("bad JSON: ")
                        && msg.contains(" line ")
                        && msg.contains(" column ")
                }
                Ok(v) => {
                    let field = match v["op"].as_str() {
                        Some("set") => "value",
                        Some("pin") => "model",
                        _ => "op",
                    };
                    msg.contains(&v[field].to_string())
                }
            };
            assert!(
                quoted,
                "{what}: the refusal does not quote the bad part: {msg}"
            );
            false
        }
    }
}

#[test]
fn control_messages_and_their_mutations_never_panic() {
    let seeds = corpus();
    let rounds = fuzz::rounds(ROUNDS);
    let mut outcomes = [0usize; 2];
    for seed in &seeds {
        let mut rng = Rng::for_seed(0x7e_b5_0c_4e_7e_b5_0c_4e, &seed.name);
        for round in 0..=rounds {
            let bytes = if round == 0 {
                seed.bytes.clone()
            } else {
                fuzz::mutate(&mut rng, &seed.bytes, WORDS)
            };
            let text = String::from_utf8_lossy(&bytes);
            let ok = check(&text, &format!("{} round {round}", seed.name));
            outcomes[usize::from(!ok)] += 1;
        }
    }
    println!(
        "control JSON: {} seeds, ok: {}, refused: {}",
        seeds.len(),
        outcomes[0],
        outcomes[1]
    );
    assert!(outcomes[0] >= 300 && outcomes[1] >= 1000, "{outcomes:?}");
}
