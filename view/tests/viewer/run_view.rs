//! `lopd run --view` starts the web viewer as a supervised child, prints its URL (with the
//! control token), serves the page, takes control requests only with that token, and stops it
//! with the rest on Ctrl-C.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::time::{Duration, Instant};

use lop_system_tests::{find_processes, unique_prefix, Daemon};
use tungstenite::client::IntoClientRequest;
use tungstenite::Message;

#[test]
fn lopd_run_view_serves_the_page_and_stops_it() {
    let prefix = unique_prefix("run-view");
    // A free loopback port (released just before lopd binds it).
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let bind = format!("127.0.0.1:{port}");
    let mut daemon = Daemon::spawn(
        &[
            "run",
            "--prefix",
            &prefix,
            "--quiet",
            "--view",
            "--view-bind",
            &bind,
        ],
        &prefix,
        Duration::from_secs(120),
    );
    let start = Instant::now();
    let page = loop {
        if let Ok(mut s) = TcpStream::connect(&bind) {
            s.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
            let mut text = String::new();
            let _ = s.read_to_string(&mut text);
            if text.starts_with("HTTP/1.1 200") {
                break text;
            }
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no page at {bind}\n{}",
            daemon.log_text()
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    assert!(page.contains("<title>lop-view</title>") && page.contains("app.js"));
    assert!(
        daemon
            .log_text()
            .contains(&format!("lop-view: http://{bind}/")),
        "{}",
        daemon.log_text()
    );
    assert_eq!(
        find_processes(&["--prefix", &prefix, "--bind", &bind]).len(),
        1
    );
    // The token lopd printed drives the daemon; none, read-only. It is not on the viewer's
    // command line.
    let log = daemon.log_text();
    let token = log
        .split(&format!("lop-view: http://{bind}/#token="))
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .unwrap_or_else(|| panic!("no token in lopd's URL line\n{log}"))
        .to_string();
    assert_eq!(token.len(), 32, "{token}");
    assert!(
        find_processes(&[&token]).is_empty(),
        "token on a command line"
    );
    let mut req = format!("ws://{bind}/ws").into_client_request().unwrap();
    req.headers_mut()
        .insert("Origin", format!("http://{bind}").parse().unwrap());
    let (mut ws, _) = tungstenite::connect(req).expect("websocket with the page's origin");
    if let tungstenite::stream::MaybeTlsStream::Plain(s) = ws.get_ref() {
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    }
    let mut control = |req: serde_json::Value| -> serde_json::Value {
        ws.send(Message::text(req.to_string())).unwrap();
        loop {
            if let Message::Text(t) = ws.read().expect("websocket") {
                let v: serde_json::Value = serde_json::from_str(t.as_str()).unwrap();
                if v["type"] == "control" {
                    return v;
                }
            }
        }
    };
    let r = control(serde_json::json!({"op": "pause"}));
    assert_eq!(r["read_only"], true, "{r}");
    let r = control(serde_json::json!({"op": "pause", "token": token}));
    assert_eq!(
        (r["ok"].clone(), r["paused"].clone()),
        (true.into(), true.into()),
        "{r}"
    );
    let r = control(serde_json::json!({"op": "resume", "token": token}));
    assert_eq!(r["paused"], false, "{r}");
    drop(ws);
    daemon.signal(libc::SIGINT);
    assert!(daemon
        .wait(Duration::from_secs(20))
        .expect("stops")
        .success());
    assert!(
        find_processes(&["--prefix", &prefix, "--bind", &bind]).is_empty(),
        "viewer left running"
    );
}
