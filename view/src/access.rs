//! Who may open the viewer's WebSocket and who may drive the daemon through it.
//!
//! A browser does not hold WebSockets to the same-origin rule: any page open on the rig's
//! browser (or, on a non-loopback bind, anyone on the network) could connect to `/ws` and send
//! control requests. Two checks stop that:
//!
//! - **Origin** (at the handshake): a browser always sends the page's origin. It must be the
//!   viewer's own address, `http://HOST:PORT` with the port the viewer listens on and HOST the
//!   address it is bound to; on a loopback (or any-address) bind also `localhost`, `127.0.0.1`
//!   and `[::1]`; on an any-address bind (`0.0.0.0`, `[::]`) an IP literal when the request's
//!   `Host` names the same address (the browser reached this viewer there, so the page came
//!   from it). Host *names* other than `localhost` are only taken from the allow-list
//!   (`--allow-origin`), so a DNS name pointed at the rig by someone else (DNS rebinding) is
//!   refused. A refused handshake gets HTTP 403 and one stderr line naming the origin. A
//!   request with **no** `Origin` does not come from a browser page (tests, scripts, curl); it
//!   is accepted, read-only unless it carries the token like any other client.
//! - **Control token** (on every control message): a per-run secret, 128 bits from
//!   `/dev/urandom` in hex, or the user's (`--token`, `LOP_VIEW_TOKEN`). The printed URL
//!   carries it in its fragment (`#token=…`, never sent in an HTTP request), the page copies it
//!   into each control message, and a message without it or with another one is refused
//!   (read-only). On a non-loopback bind no token is generated: control needs one given
//!   explicitly.

use std::net::{IpAddr, SocketAddr};

use lop_client::view_token;
pub use lop_client::view_token::{check as check_token, generate as generate_token};
/// Environment variable holding the control token (same as `--token`).
pub const TOKEN_ENV: &str = view_token::ENV;
/// Bytes of a generated token.
pub const TOKEN_BYTES: usize = view_token::BYTES;

/// Whether `ip` only reaches this machine.
pub fn is_loopback(ip: IpAddr) -> bool {
    match ip {
        IpAddr::V4(v) => v.is_loopback(),
        IpAddr::V6(v) => v.is_loopback() || v.to_ipv4_mapped().is_some_and(|m| m.is_loopback()),
    }
}

/// The control token a viewer bound at `local` uses: the given one (checked), else on loopback
/// a generated one, else none (read-only).
pub fn control_token(local: SocketAddr, given: Option<&str>) -> Result<Option<String>, String> {
    match given {
        Some(t) => check_token(t).map(|()| Some(t.to_string())),
        None if is_loopback(local.ip()) => generate_token()
            .map(Some)
            .map_err(|e| format!("cannot read /dev/urandom for a control token: {e}")),
        None => Ok(None),
    }
}

/// The URL to print: `http://ADDR/`, with `#token=…` when control is enabled.
pub fn url(local: SocketAddr, token: Option<&str>) -> String {
    match token {
        Some(t) => format!("http://{local}/#token={t}"),
        None => format!("http://{local}/"),
    }
}

/// Compares a control message's token with the run's in time independent of where they differ.
pub fn token_matches(expected: &str, given: &str) -> bool {
    let (a, b) = (expected.as_bytes(), given.as_bytes());
    let mut diff = u8::from(a.len() != b.len());
    for (i, x) in a.iter().enumerate() {
        diff |= x ^ b.get(i).copied().unwrap_or(!x);
    }
    std::hint::black_box(diff) == 0
}

/// Splits `http://HOST[:PORT]` into the host (brackets kept for IPv6) and port (80 if absent).
fn parse_http_origin(origin: &str) -> Option<(&str, u16)> {
    let rest = origin.strip_prefix("http://")?;
    if rest.is_empty() || rest.contains(['/', '?', '#', '@']) {
        return None;
    }
    let (host, port) = if rest.starts_with('[') {
        let end = rest.find(']')?;
        let (h, p) = rest.split_at(end + 1);
        (h, p)
    } else {
        match rest.rfind(':') {
            Some(i) => rest.split_at(i),
            None => (rest, ""),
        }
    };
    let port = match port {
        "" => 80,
        p => p.strip_prefix(':')?.parse().ok()?,
    };
    Some((host, port))
}

fn host_ip(host: &str) -> Option<IpAddr> {
    host.trim_start_matches('[')
        .trim_end_matches(']')
        .parse()
        .ok()
}

fn normalize(origin: &str) -> String {
    origin.trim().trim_end_matches('/').to_ascii_lowercase()
}

/// Whether a WebSocket handshake with `Origin: origin` (and `Host: host`) may proceed on a
/// viewer bound at `local` with the `--allow-origin` list `allow`. See the module docs.
pub fn origin_allowed(
    origin: &str,
    host: Option<&str>,
    local: SocketAddr,
    allow: &[String],
) -> bool {
    let origin = normalize(origin);
    if allow.iter().any(|a| normalize(a) == origin) {
        return true;
    }
    let Some((h, port)) = parse_http_origin(&origin) else {
        return false;
    };
    if port != local.port() {
        return false;
    }
    let bound = local.ip();
    let ip = host_ip(h);
    if (h == "localhost" || ip.is_some_and(is_loopback))
        && (is_loopback(bound) || bound.is_unspecified())
    {
        return true;
    }
    match ip {
        Some(ip) if ip == bound => true,
        Some(_) if bound.is_unspecified() => {
            let authority = origin.trim_start_matches("http://");
            host.map(|h| h.trim().to_ascii_lowercase())
                .is_some_and(|h| {
                    h == authority || (port == 80 && h.trim_end_matches(":80") == authority)
                })
        }
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn a(s: &str) -> SocketAddr {
        s.parse().unwrap()
    }

    #[test]
    fn own_and_loopback_origins_pass_others_fail() {
        let lo = a("127.0.0.1:8733");
        for o in [
            "http://127.0.0.1:8733",
            "http://localhost:8733",
            "http://[::1]:8733",
            "HTTP://LOCALHOST:8733/",
        ] {
            assert!(origin_allowed(o, None, lo, &[]), "{o}");
        }
        for o in [
            "http://evil.example",
            "http://evil.example:8733",
            "http://127.0.0.1:8734",
            "https://127.0.0.1:8733",
            "null",
            "",
            "http://127.0.0.1:8733@evil.example",
            "http://10.0.0.5:8733",
        ] {
            assert!(!origin_allowed(o, Some("127.0.0.1:8733"), lo, &[]), "{o}");
        }
        let allow = vec!["http://rig.local:8733/".to_string()];
        assert!(origin_allowed("http://rig.local:8733", None, lo, &allow));
    }

    #[test]
    fn any_address_bind_takes_an_ip_literal_the_browser_reached() {
        let any = a("0.0.0.0:8733");
        assert!(origin_allowed(
            "http://10.0.0.5:8733",
            Some("10.0.0.5:8733"),
            any,
            &[]
        ));
        assert!(!origin_allowed(
            "http://10.0.0.7:8733",
            Some("10.0.0.5:8733"),
            any,
            &[]
        ));
        assert!(!origin_allowed("http://10.0.0.5:8733", None, any, &[]));
        // A name resolving to the rig is not proof of anything (DNS rebinding).
        assert!(!origin_allowed(
            "http://evil.example:8733",
            Some("evil.example:8733"),
            any,
            &[]
        ));
        assert!(origin_allowed("http://localhost:8733", None, any, &[]));
        let one = a("10.0.0.5:8733");
        assert!(origin_allowed("http://10.0.0.5:8733", None, one, &[]));
        assert!(!origin_allowed("http://localhost:8733", None, one, &[]));
    }

    #[test]
    fn tokens() {
        let t = generate_token().unwrap();
        assert_eq!(t.len(), 2 * TOKEN_BYTES);
        assert_ne!(t, generate_token().unwrap());
        assert!(token_matches(&t, &t));
        assert!(!token_matches(&t, &t[..t.len() - 1]));
        assert!(!token_matches(&t, ""));
        assert!(!token_matches(&t, &format!("{t}0")));
        assert!(check_token("short").is_err());
        assert!(check_token("has a space in it, too long").is_err());
        assert!(check_token("0123456789abcdef").is_ok());
        assert_eq!(control_token(a("10.0.0.5:1"), None), Ok(None));
        assert!(control_token(a("127.0.0.1:1"), None).unwrap().is_some());
        assert_eq!(
            url(a("127.0.0.1:1"), Some("ab")),
            "http://127.0.0.1:1/#token=ab"
        );
    }
}
