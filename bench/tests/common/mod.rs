//! Shared by the smoke tests: run `lop-bench` with a watchdog.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Runs `lop-bench ARGS`, killing it after `limit` (a hang, not a speed bound: generous for a
/// slow debug build on a busy 2-core machine). The pipes are drained in threads so a chatty
/// child never blocks on a full pipe. Panics, with both outputs, unless it exits successfully;
/// returns its standard output.
pub fn run_bench(args: &[&std::ffi::OsStr], limit: Duration) -> String {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lop-bench"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn lop-bench");
    let drain = |mut pipe: Box<dyn std::io::Read + Send>| {
        std::thread::spawn(move || {
            let mut s = String::new();
            let _ = pipe.read_to_string(&mut s);
            s
        })
    };
    let out_reader = drain(Box::new(child.stdout.take().unwrap()));
    let err_reader = drain(Box::new(child.stderr.take().unwrap()));
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait lop-bench") {
            break Some(s);
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let stdout = out_reader.join().unwrap_or_default();
    let stderr = err_reader.join().unwrap_or_default();
    let status =
        status.unwrap_or_else(|| panic!("lop-bench hung; stdout:\n{stdout}\nstderr:\n{stderr}"));
    assert!(
        status.success(),
        "lop-bench failed ({status}); stdout:\n{stdout}\nstderr:\n{stderr}"
    );
    stdout
}
