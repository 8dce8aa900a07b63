//! The control decoder (`control::decode`, what the deformation process does first with every
//! request that arrives over iceoryx2) on arbitrary requests: it never panics, and a refusal
//! quotes the field at fault.
//!
//! A request is plain bytes in shared memory, so any bit pattern can arrive. The seeds are one
//! valid request of every op (by body name and by index, every live key), built here rather
//! than committed: the request is a `repr(C)` struct whose layout `ipc/tests/contract/c_header.rs`
//! guards, so the bytes are what this test writes. Each seed is serialised field by field
//! (little-endian), mutated as bytes by `lop_test_support::fuzz` (truncations, flips, extreme
//! words such as NaN, ±inf and `u32::MAX`, invalid UTF-8 in the name and key) and read back
//! into a request; some rounds are wholly random bytes. `LOP_FUZZ_ROUNDS` runs more.
//!
//! For every request:
//! - a [`Command`] names an existing body and, for `SET`, a live key with a finite value in
//!   range; a `PIN` model is never `Auto`;
//! - a [`Refusal`] has a status other than OK and quotes what is wrong: the contract version,
//!   the op, the body's index or name, the key, or the value (NaN included), the model (a name
//!   or key that is not UTF-8 quoted with U+FFFD, never as a placeholder); it points at a body
//!   only if that body exists.

use lop_config::ModelPin;
use lop_daemon::control::{decode, field_text, Command, Refusal};
use lop_ipc::control::*;
use lop_ipc::CONTRACT_VERSION;
use lop_test_support::fuzz::{self, Rng};

const BODIES: [&str; 4] = ["liver", "spleen", "stomach", "pancreas"];

/// Mutations per seed.
const ROUNDS: usize = 2000;

fn seeds() -> Vec<ControlRequest> {
    let mut seeds = vec![
        ControlRequest::new(CONTROL_OP_RESET, ""),
        ControlRequest::new(CONTROL_OP_PAUSE, ""),
        ControlRequest::new(CONTROL_OP_RESUME, ""),
        ControlRequest::new(CONTROL_OP_GET, "liver"),
        ControlRequest::new(CONTROL_OP_RELEASE, "pancreas"),
        ControlRequest::pin("spleen", lop_ipc::BodyModel::Fem),
    ];
    let mut by_index = ControlRequest::new(CONTROL_OP_GET, "");
    by_index.body_index = 3;
    seeds.push(by_index);
    for (key, _) in CONTROL_KEYS {
        seeds.push(ControlRequest::set("stomach", key, 0.25));
    }
    seeds
}

/// The request's fields, little-endian, in declaration order.
fn to_bytes(r: &ControlRequest) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend(r.contract_version.to_le_bytes());
    b.extend(r.op.to_le_bytes());
    b.extend(r.body_index.to_le_bytes());
    b.extend(r.model.to_le_bytes());
    b.extend(r.body);
    b.extend(r.key);
    b.extend(r.value.to_le_bytes());
    b
}

/// Reads the fields back from `bytes` (zero-padded or cut to a request's size).
fn from_bytes(bytes: &[u8]) -> ControlRequest {
    let mut r = ControlRequest::default();
    let size = to_bytes(&r).len();
    let mut b = bytes.to_vec();
    b.resize(size, 0);
    let u32_at = |at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap());
    r.contract_version = u32_at(0);
    r.op = u32_at(4);
    r.body_index = u32_at(8) as i32;
    r.model = u32_at(12);
    let mut at = 16;
    let n = r.body.len();
    r.body.copy_from_slice(&b[at..at + n]);
    at += n;
    let n = r.key.len();
    r.key.copy_from_slice(&b[at..at + n]);
    at += n;
    r.value = f64::from_le_bytes(b[at..at + 8].try_into().unwrap());
    r
}

fn check(req: &ControlRequest, result: &Result<Command, Refusal>, what: &str) {
    match result {
        Ok(command) => check_command(req, command, what),
        Err(refusal) => check_refusal(req, refusal, what),
    }
}

fn check_command(req: &ControlRequest, command: &Command, what: &str) {
    assert_eq!(req.contract_version, CONTRACT_VERSION, "{what}");
    let body = match *command {
        Command::Reset | Command::Pause | Command::Resume => return,
        Command::Get { body } | Command::Release { body } => body,
        Command::Pin { body, pin } => {
            assert_ne!(pin, ModelPin::Auto, "{what}");
            body
        }
        Command::Set { body, key, value } => {
            assert!(CONTROL_KEYS.iter().any(|(k, _)| *k == key), "{what}: {key}");
            assert!(value.is_finite() && value >= 0.0, "{what}: {key} = {value}");
            body
        }
    };
    assert!(body < BODIES.len(), "{what}: body {body}");
}

fn check_refusal(req: &ControlRequest, r: &Refusal, what: &str) {
    let m = &r.message;
    if fuzz::log() {
        eprintln!("{m}");
    }
    assert!(r.body.is_none_or(|b| b < BODIES.len()), "{what}: {r:?}");
    let quotes = match r.status {
        CONTROL_STATUS_BAD_REQUEST => {
            m.contains(&format!("contract version {}", req.contract_version))
                || m.contains(&format!("op {}", req.op))
        }
        CONTROL_STATUS_UNKNOWN_BODY => {
            m.contains(&format!("index {}", req.body_index))
                || m.contains(&format!("{:?}", field_text(&req.body)))
        }
        CONTROL_STATUS_UNKNOWN_KEY => m.contains(&format!("{:?}", field_text(&req.key))),
        CONTROL_STATUS_BAD_VALUE => {
            m.contains(&format!("{} = {}", req.key_str(), req.value))
                || m.contains(&format!("model = {}", req.model))
        }
        other => panic!("{what}: decode answered status {other}: {m}"),
    };
    assert!(quotes, "{what}: the message does not quote the field: {m}");
}

#[test]
fn seeds_decode_to_their_commands() {
    let seeds = seeds();
    for req in &seeds {
        let result = decode(req, &BODIES);
        check(req, &result, "seed");
        assert!(result.is_ok(), "{req:?}: {result:?}");
    }
    let set = ControlRequest::set("stomach", "fem.poisson", 0.25);
    assert_eq!(
        decode(&set, &BODIES),
        Ok(Command::Set {
            body: 2,
            key: "fem.poisson",
            value: 0.25
        })
    );
}

#[test]
fn nan_and_out_of_range_values_are_refused_with_the_value() {
    for (key, _) in CONTROL_KEYS {
        for value in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -1.0] {
            let req = ControlRequest::set("liver", key, value);
            let refusal = decode(&req, &BODIES).expect_err(key);
            assert_eq!(refusal.status, CONTROL_STATUS_BAD_VALUE, "{key} = {value}");
            assert_eq!(refusal.body, Some(0));
            assert!(refusal.message.contains(&format!("{key} = {value}")));
        }
    }
}

#[test]
fn arbitrary_requests_never_panic_and_refusals_quote_the_field() {
    let rounds = fuzz::rounds(ROUNDS);
    let words: Vec<&[u8]> = BODIES
        .iter()
        .map(|b| b.as_bytes())
        .chain(CONTROL_KEYS.iter().map(|(k, _)| k.as_bytes()))
        .collect();
    let mut outcomes = [0usize; 2];
    for (k, seed) in seeds().iter().enumerate() {
        let mut rng = Rng::for_seed(0xc0de_c0de_c0de_c0de, &k.to_string());
        let bytes = to_bytes(seed);
        for round in 0..rounds {
            let mutated = if round % 10 == 9 {
                (0..bytes.len()).map(|_| rng.next_u64() as u8).collect()
            } else {
                fuzz::mutate(&mut rng, &bytes, &words)
            };
            let req = from_bytes(&mutated);
            let result = decode(&req, &BODIES);
            check(&req, &result, &format!("seed {k} round {round}"));
            outcomes[usize::from(result.is_err())] += 1;
        }
    }
    println!("control: ok: {}, refused: {}", outcomes[0], outcomes[1]);
    assert!(outcomes[0] >= 500 && outcomes[1] >= 1000, "{outcomes:?}");
}

#[test]
fn names_that_are_not_utf8_are_quoted_not_replaced() {
    let mut req = ControlRequest::new(CONTROL_OP_GET, "");
    req.body[..4].copy_from_slice(b"li\xffr");
    let r = decode(&req, &BODIES).unwrap_err();
    assert_eq!(r.status, CONTROL_STATUS_UNKNOWN_BODY);
    assert!(r.message.contains("\"li\u{fffd}r\""), "{}", r.message);
    let mut req = ControlRequest::set("liver", "", 1.0);
    req.key[..5].copy_from_slice(b"fem.\xc3");
    let r = decode(&req, &BODIES).unwrap_err();
    assert_eq!(r.status, CONTROL_STATUS_UNKNOWN_KEY);
    assert!(r.message.contains("\"fem.\u{fffd}\""), "{}", r.message);
}
