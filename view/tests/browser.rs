//! The web viewer in a real browser: headless Chromium (Debian's `chromium`, installed by
//! `scripts/setup.sh`) loads lop-view's page against a running daemon, and two screenshots
//! taken apart show the four organs drawn in their colours and the organs' region changing
//! (the default mock poke moves the liver and the tool).
//!
//! No browser, no pass: a machine without chromium fails this test with a message saying how
//! to install it.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use common::Viewer;
use lop_system_tests::{unique_prefix, Daemon};

/// The page's layout: the 3D view is everything left of the 340 px side panel.
const WIDTH: u32 = 1200;
const HEIGHT: u32 = 700;
const SIDE_PANEL: u32 = 340;
/// Organ colours of the default scene (config/scenes/abdomen.toml; the liver is drawn by its
/// render surface).
const ORGANS: [(&str, [f32; 3]); 4] = [
    ("liver", [0.47, 0.13, 0.11]),
    ("spleen", [0.40, 0.12, 0.30]),
    ("stomach", [0.86, 0.56, 0.52]),
    ("pancreas", [0.90, 0.74, 0.50]),
];

fn chromium() -> PathBuf {
    for name in ["chromium", "chromium-browser"] {
        for dir in std::env::var("PATH").unwrap_or_default().split(':') {
            let p = Path::new(dir).join(name);
            if p.exists() {
                return p;
            }
        }
    }
    panic!("chromium not found on PATH: run `bash scripts/setup.sh` (installs Debian's chromium)");
}

fn screenshot(url: &str, out: &Path, profile: &Path) {
    let status = Command::new(chromium())
        .args([
            "--headless=new",
            "--no-sandbox",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-dev-shm-usage",
            "--hide-scrollbars",
            &format!("--window-size={WIDTH},{HEIGHT}"),
            // Virtual time: the page connects, gets the topology and frames, draws.
            "--virtual-time-budget=3000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--screenshot={}", out.display()))
        .arg(url)
        .output()
        .expect("run chromium");
    assert!(
        status.status.success() && out.exists(),
        "chromium failed: {}\n{}",
        status.status,
        String::from_utf8_lossy(&status.stderr)
    );
}

/// RGB pixels of a PNG.
fn pixels(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let decoder = png::Decoder::new(std::fs::File::open(path).expect("png"));
    let mut reader = decoder.read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("png frame");
    let step = info.color_type.samples();
    assert!(
        step >= 3,
        "unexpected PNG colour type {:?}",
        info.color_type
    );
    let px = buf[..info.buffer_size()]
        .chunks_exact(step)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    (info.width, info.height, px)
}

/// Which organ a pixel shows, if any: the page shades a body's colour `c` as `k·c` with
/// `k` in 0.30..1.05 (plus smooth interpolation), so a pixel is organ `i` when it is close to a
/// multiple of that organ's colour.
fn organ_of(p: [u8; 3]) -> Option<usize> {
    let q = p.map(|v| v as f32 / 255.0);
    let mut best = None;
    for (i, (_, c)) in ORGANS.iter().enumerate() {
        let k =
            (q[0] * c[0] + q[1] * c[1] + q[2] * c[2]) / (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        if !(0.35..=1.1).contains(&k) {
            continue;
        }
        let r = ((q[0] - k * c[0]).powi(2) + (q[1] - k * c[1]).powi(2) + (q[2] - k * c[2]).powi(2))
            .sqrt();
        if r < 0.05 && best.is_none_or(|(_, br)| r < br) {
            best = Some((i, r));
        }
    }
    best.map(|(i, _)| i)
}

/// Whether (x, y) is in the 3D view, away from the text overlays at its top and bottom.
fn in_scene(x: u32, y: u32, w: u32, h: u32) -> bool {
    x < w - SIDE_PANEL && y > 30 && y < h - 30
}

#[test]
fn browser_shows_the_organs_drawn_and_moving() {
    let prefix = unique_prefix("view-browser");
    let mut daemon = Daemon::spawn(
        &["run", "--scene", "abdomen", "--prefix", &prefix, "--quiet"],
        &prefix,
        Duration::from_secs(180),
    );
    // Wait until the daemon publishes frames, so the page has something to draw.
    let mut client = lop_client::Attachment::open(&prefix, Duration::from_secs(60))
        .unwrap_or_else(|e| panic!("attach: {e}\n{}", daemon.log_text()));
    client
        .wait_topology(Duration::from_secs(60))
        .expect("topology");
    client.next_frame(Duration::from_secs(30)).expect("frame");
    let viewer = Viewer::spawn(&prefix, Duration::from_secs(180));

    let dir = std::env::temp_dir().join(format!("{prefix}-shots"));
    std::fs::create_dir_all(&dir).unwrap();
    let shot = |i: usize| {
        let out = dir.join(format!("shot{i}.png"));
        screenshot(&viewer.url, &out, &dir.join(format!("profile{i}")));
        pixels(&out)
    };

    // The first screenshot: every organ drawn, in its colour.
    let (w, h, first) = shot(0);
    assert_eq!((w, h), (WIDTH, HEIGHT));
    let mut counts = [0usize; 4];
    let mut scene_px = 0;
    for (n, p) in first.iter().enumerate() {
        let (x, y) = (n as u32 % w, n as u32 / w);
        if in_scene(x, y, w, h) {
            scene_px += 1;
            if let Some(i) = organ_of(*p) {
                counts[i] += 1;
            }
        }
    }
    for (i, (name, _)) in ORGANS.iter().enumerate() {
        assert!(
            counts[i] > 1000,
            "{name}: only {} pixels in its colour out of {scene_px} (counts {counts:?}); screenshot {}",
            counts[i],
            dir.join("shot0.png").display()
        );
    }
    assert!(
        counts[0] > scene_px / 20,
        "the liver covers only {} of {scene_px} pixels",
        counts[0]
    );

    // Later screenshots: the organs' region changes (the poke dents the liver, the tool moves).
    // The mock poke loops every few seconds; up to eleven more shots (more than a poke's loop
    // of 700 ms steps), each compared with every earlier one, so that two of them are at
    // different phases even when a loaded machine makes the screenshots slow and their spacing
    // close to the poke's period (six were once not enough: 171 pixels in a full-suite run).
    let changed = |a: &[[u8; 3]], b: &[[u8; 3]]| {
        a.iter()
            .zip(b)
            .enumerate()
            .filter(|(n, (a, b))| {
                let (x, y) = (*n as u32 % w, *n as u32 / w);
                in_scene(x, y, w, h)
                    && (organ_of(**a).is_some() || organ_of(**b).is_some())
                    && a.iter().zip(b.iter()).any(|(p, q)| p.abs_diff(*q) > 12)
            })
            .count()
    };
    let mut shots = vec![first];
    let mut best_changed = 0;
    for i in 1..12 {
        std::thread::sleep(Duration::from_millis(700));
        let (_, _, later) = shot(i);
        for earlier in &shots {
            best_changed = best_changed.max(changed(earlier, &later));
        }
        shots.push(later);
        if best_changed > 200 {
            break;
        }
    }
    assert!(
        best_changed > 200,
        "the organs' region did not change between screenshots ({best_changed} pixels); see {}",
        dir.display()
    );
    drop(viewer);
    daemon.signal(libc::SIGINT);
    let status = daemon
        .wait(Duration::from_secs(20))
        .expect("lopd run stops");
    assert!(status.success(), "{}", daemon.log_text());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The page's DOM after it ran (headless Chromium's `--dump-dom`).
fn dom(url: &str, profile: &Path) -> String {
    let out = Command::new(chromium())
        .args([
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--virtual-time-budget=1000",
            "--dump-dom",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(url)
        .output()
        .expect("run chromium");
    assert!(
        out.status.success(),
        "chromium failed: {}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn browser_page_without_the_token_is_read_only() {
    // No daemon needed: the panel's state depends on the URL alone.
    let prefix = unique_prefix("view-browser-ro");
    let viewer = Viewer::spawn(&prefix, Duration::from_secs(120));
    let dir = std::env::temp_dir().join(format!("{prefix}-dom"));
    std::fs::create_dir_all(&dir).unwrap();
    let bare = dom(&format!("http://{}/", viewer.addr), &dir.join("p0"));
    assert!(bare.contains("read-only: open the URL lopd printed to control"));
    assert!(
        bare.contains(r#"<div id="ctl-ro">"#)
            && bare.contains(r#"<fieldset id="ctl-panel" disabled="""#),
        "without the token the notice shows and the panel is disabled:\n{bare}"
    );
    let with = dom(&viewer.url, &dir.join("p1"));
    assert!(
        with.contains(r#"<div id="ctl-ro" hidden="">"#)
            && with.contains(r#"<fieldset id="ctl-panel">"#),
        "with the printed URL the panel is enabled:\n{with}"
    );
}
