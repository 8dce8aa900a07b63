//! Deterministic, dependency-free fuzzing for the "parsers survive anything" tests: a committed
//! corpus of seed inputs, and mutations of each seed drawn from the seeded [`Rng`](crate::rng::Rng).
//!
//! A parser's test reads its corpus with [`corpus`] (every file of a `tests/corpus/<parser>/`
//! folder, in name order), feeds each seed as it is, then [`rounds`] mutations of it made by
//! [`mutate`]. The same seed bytes and the same generator state give the same mutations on every
//! machine, so a failure printed by a test (seed name and round) replays exactly.
//!
//! Mutations work on bytes but know a little about text: truncation, byte flips and inserts,
//! token and line surgery, splices of the input into itself, huge and negative counts, NaN and
//! infinities, invalid UTF-8, very long lines, deep nesting, and aligned little-endian words
//! overwritten with extreme integers and floats (for binary formats). A parser's own
//! vocabulary (`$EndNodes`, `[[waypoint]]`, `"op"`) goes in through the `dictionary`.
//!
//! Environment: `LOP_FUZZ_ROUNDS=N` overrides the number of mutations per seed (CI runs the
//! default; run more locally when hunting), `LOP_FUZZ_LOG=1` prints every refusal.

use std::path::{Path, PathBuf};

pub use crate::rng::Rng;

/// One committed seed input.
#[derive(Clone, Debug)]
pub struct Seed {
    /// The file's name in its corpus folder (what a failure message names).
    pub name: String,
    /// Its path.
    pub path: PathBuf,
    /// Its bytes.
    pub bytes: Vec<u8>,
}

/// Every file of the corpus folder `dir`, in name order. Panics if the folder is missing or
/// empty: a corpus that silently vanished would make its test pass without testing anything.
pub fn corpus(dir: &Path) -> Vec<Seed> {
    let entries =
        std::fs::read_dir(dir).unwrap_or_else(|e| panic!("corpus folder {}: {e}", dir.display()));
    let mut seeds: Vec<Seed> = entries
        .map(|e| e.expect("a corpus entry").path())
        .filter(|p| p.is_file())
        .map(|path| Seed {
            name: path.file_name().unwrap().to_string_lossy().into_owned(),
            bytes: std::fs::read(&path).unwrap(),
            path,
        })
        .collect();
    seeds.sort_by(|a, b| a.name.cmp(&b.name));
    assert!(
        !seeds.is_empty(),
        "corpus folder {} is empty",
        dir.display()
    );
    seeds
}

/// Mutations per seed: `default`, or `LOP_FUZZ_ROUNDS` if set.
pub fn rounds(default: usize) -> usize {
    std::env::var("LOP_FUZZ_ROUNDS")
        .ok()
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or(default)
}

/// Whether to print every refusal (`LOP_FUZZ_LOG` set).
pub fn log() -> bool {
    std::env::var_os("LOP_FUZZ_LOG").is_some()
}

/// Tokens that break parsers whatever their format.
const NASTY: &[&[u8]] = &[
    b"",
    b"0",
    b"-1",
    b"1",
    b"nan",
    b"NaN",
    b"inf",
    b"-inf",
    b"1e999",
    b"-0.0",
    b"1000000000000",
    b"4294967296",
    b"18446744073709551616",
    b"99999999999999999999999999",
    b"9223372036854775807",
    b"\xef\xbb\xbf",
    b"\xff\xfe",
    b"\xc3",
    b"\0",
    b"\"",
    b"'",
    b"=",
    b"[",
    b"]",
    b"{",
    b"}",
    b"#",
    b",",
    b"\r\n",
    b"\\u0000",
    b"\\",
];

/// Little-endian words a binary field may be overwritten with.
const WORDS: &[u64] = &[
    0,
    1,
    u32::MAX as u64,
    0x7fff_ffff,
    0x8000_0000,
    u64::MAX,
    i64::MAX as u64,
    0x7ff8_0000_0000_0000, // f64 NaN
    0x7ff0_0000_0000_0000, // f64 +inf
    0xfff0_0000_0000_0000, // f64 -inf
    0x4122_7100_0000_0000, // f64 600000.0
    0xbff0_0000_0000_0000, // f64 -1.0
    1_000_000_000_000,
];

/// One to three mutations of `seed`; `dictionary` adds the format's own tokens to the generic
/// nasty ones.
pub fn mutate(rng: &mut Rng, seed: &[u8], dictionary: &[&[u8]]) -> Vec<u8> {
    let mut out = seed.to_vec();
    let n = 1 + rng.below(2) * rng.below(3);
    for _ in 0..n {
        mutate_once(rng, &mut out, dictionary);
    }
    out
}

fn token<'a>(rng: &mut Rng, dictionary: &[&'a [u8]]) -> &'a [u8] {
    if !dictionary.is_empty() && rng.below(2) == 0 {
        rng.pick(dictionary)
    } else {
        rng.pick(NASTY)
    }
}

fn mutate_once(rng: &mut Rng, out: &mut Vec<u8>, dictionary: &[&[u8]]) {
    let len = out.len();
    match rng.below(14) {
        0 => out.truncate(rng.below(len + 1)),
        1 => {
            // Replace a whitespace-separated token.
            let spans = tokens(out);
            if let Some((a, b)) = (!spans.is_empty()).then(|| rng.pick(&spans)) {
                let with = token(rng, dictionary).to_vec();
                out.splice(a..b, with);
            }
        }
        2 => {
            // Delete or duplicate a line.
            let lines = line_spans(out);
            if !lines.is_empty() {
                let (a, b) = rng.pick(&lines);
                if rng.below(2) == 0 {
                    out.drain(a..b);
                } else {
                    let line = out[a..b].to_vec();
                    out.splice(a..a, line);
                }
            }
        }
        3 => {
            if len > 0 {
                let k = rng.below(len);
                out[k] = rng.next_u64() as u8;
            }
        }
        4 => {
            let k = rng.below(len + 1);
            out.insert(k, rng.next_u64() as u8);
        }
        5 => {
            // Swap two digits: changes indices and counts plausibly.
            let digits: Vec<usize> = (0..len).filter(|&i| out[i].is_ascii_digit()).collect();
            if digits.len() >= 2 {
                let (a, b) = (rng.pick(&digits), rng.pick(&digits));
                out.swap(a, b);
            }
        }
        6 => {
            let k = rng.below(len + 1);
            let with = token(rng, dictionary).to_vec();
            out.splice(k..k, with);
        }
        7 => {
            // Copy a chunk of the input somewhere else (repeats a section, a record, a table).
            if len > 0 {
                let a = rng.below(len);
                let b = (a + 1 + rng.below(256)).min(len);
                let chunk = out[a..b].to_vec();
                let k = rng.below(len + 1);
                out.splice(k..k, chunk);
            }
        }
        8 => {
            // A run of digits becomes a huge or negative count.
            let runs = digit_runs(out);
            if !runs.is_empty() {
                let (a, b) = rng.pick(&runs);
                let with: &[u8] = rng.pick(&[
                    &b"1000000000000"[..],
                    b"18446744073709551615",
                    b"4294967295",
                    b"-1",
                    b"0",
                ]);
                out.splice(a..b, with.iter().copied());
            }
        }
        9 => {
            // A very long line.
            let k = rng.below(len + 1);
            let c = rng.pick(b"x9 [\"");
            out.splice(k..k, std::iter::repeat_n(c, 4096 + rng.below(4096)));
        }
        10 => {
            // Deep nesting.
            let k = rng.below(len + 1);
            let open: &[u8] = rng.pick(&[&b"["[..], b"{\"a\":", b"[[", b"{a={"]);
            let depth = 64 + rng.below(2048);
            let nest: Vec<u8> = open
                .iter()
                .copied()
                .cycle()
                .take(open.len() * depth)
                .collect();
            out.splice(k..k, nest);
        }
        11 => {
            // An aligned little-endian word of a binary field.
            let width = if rng.below(2) == 0 { 4 } else { 8 };
            if len >= width {
                let k = rng.below(len / width) * width;
                let w = rng.pick(WORDS).to_le_bytes();
                out[k..k + width].copy_from_slice(&w[..width]);
            }
        }
        12 => {
            // Invalid UTF-8 in the middle of the text.
            let k = rng.below(len + 1);
            let bad: &[u8] = rng.pick(&[&b"\xff"[..], b"\xc3", b"\xed\xa0\x80", b"\xf8\x88"]);
            out.splice(k..k, bad.iter().copied());
        }
        _ => {
            // Flip one bit.
            if len > 0 {
                let k = rng.below(len);
                out[k] ^= 1 << rng.below(8);
            }
        }
    }
}

/// Byte ranges of the whitespace-separated tokens.
fn tokens(b: &[u8]) -> Vec<(usize, usize)> {
    runs(b, |c| !c.is_ascii_whitespace())
}

/// Byte ranges of the maximal runs of bytes that satisfy `keep`.
fn runs(b: &[u8], keep: impl Fn(u8) -> bool) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut start = None;
    for (i, &c) in b.iter().enumerate() {
        match (keep(c), start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                spans.push((s, i));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        spans.push((s, b.len()));
    }
    spans
}

/// Byte ranges of the lines, each with its newline.
fn line_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut start = 0;
    for (i, &c) in b.iter().enumerate() {
        if c == b'\n' {
            spans.push((start, i + 1));
            start = i + 1;
        }
    }
    if start < b.len() {
        spans.push((start, b.len()));
    }
    spans
}

/// Byte ranges of the runs of ASCII digits.
fn digit_runs(b: &[u8]) -> Vec<(usize, usize)> {
    runs(b, |c| c.is_ascii_digit())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutations_are_deterministic_and_change_the_input() {
        let seed = b"8 3 0 0\n1 0 0 0\n[[waypoint]]\nt = 0.5\n";
        let run = |state| {
            let mut rng = Rng::for_seed(state, "x");
            (0..200)
                .map(|_| mutate(&mut rng, seed, &[b"$EndNodes"]))
                .collect::<Vec<_>>()
        };
        let a = run(1);
        assert_eq!(a, run(1));
        assert_ne!(a, run(2));
        assert!(a.iter().filter(|m| m.as_slice() != seed).count() > 150);
    }
}
