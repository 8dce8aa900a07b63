//! The web viewer's control token, shared by the daemon that fixes it for a run (`lopd run
//! --view`) and the viewer that checks it: one rule for what a token may be, one way to make
//! one, and the environment variable that carries it from one to the other (never the command
//! line, where `ps` would show it).

use std::io::Read;

/// Environment variable holding the control token (same as `lop-view --token`).
pub const ENV: &str = "LOP_VIEW_TOKEN";
/// Bytes of a generated token (hex-encoded: twice as many characters).
pub const BYTES: usize = 16;
/// Shortest token accepted from the user.
pub const MIN_LEN: usize = 16;
/// Longest token accepted from the user.
pub const MAX_LEN: usize = 256;

/// A new token: [`BYTES`] from `/dev/urandom`, in lower-case hex.
pub fn generate() -> std::io::Result<String> {
    let mut bytes = [0u8; BYTES];
    std::fs::File::open("/dev/urandom")?.read_exact(&mut bytes)?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Checks a user's token: [`MIN_LEN`] to [`MAX_LEN`] characters of `A-Z a-z 0-9 . _ ~ -`, so it
/// goes into a URL fragment as it is. The message gives the length, never the token.
pub fn check(token: &str) -> Result<(), String> {
    let ok_char = |c: char| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '~' | '-');
    if token.len() < MIN_LEN || token.len() > MAX_LEN || !token.chars().all(ok_char) {
        return Err(format!(
            "token of {} characters: must be {MIN_LEN} to {MAX_LEN} of A-Z a-z 0-9 . _ ~ -",
            token.chars().count()
        ));
    }
    Ok(())
}
