//! `lopd run --view` starts the web viewer as a supervised child, prints its URL, serves the
//! page, and stops it with the rest on Ctrl-C.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::time::{Duration, Instant};

use lop_system_tests::{find_processes, unique_prefix, Daemon};

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
