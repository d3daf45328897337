//! The live map in a real headless browser: `aim replay --serve` of a small recording at 8×
//! the link's pace; Chromium loads the page, receives the fixes over server-sent events and
//! draws them. Oracle: `aim replay` of the same bytes (the page's fix count and last position
//! are the replay's). A screenshot goes to `$CARGO_TARGET_TMPDIR/live-map/live-map.png`.
//!
//! Chromium: `chromium` from Debian (`.ci/run` installs it), or the browser named by
//! `AIM_CHROMIUM`. Under CI (`CI` set) a missing browser fails the test; elsewhere it is
//! skipped with a notice on stderr. Linux only (signals).
#![cfg(target_os = "linux")]

mod common;
mod procs;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use procs::{Proc, PATIENCE};

/// The site of the synthetic array with a room and an obstacle for the plan.
const SITE: &str = "sample_rate_hz = 48000\n\n[[array]]\nid = 1\nposition = [0.0, 0.0, 0.0]\n\n\
                    [room]\nmin = [-2.0, -2.0, 0.0]\nmax = [9.0, 7.0, 4.0]\n\n\
                    [[obstacle]]\nname = \"shelf\"\nmin = [3.0, 4.5, 0.0]\nmax = [6.0, 5.2, 2.0]\n";

/// The browser, or `None` where there is none (and not under CI).
fn chromium() -> Option<PathBuf> {
    if let Some(path) = std::env::var_os("AIM_CHROMIUM") {
        return Some(path.into());
    }
    for name in ["chromium", "chromium-browser", "google-chrome"] {
        if let Ok(out) = Command::new("sh").args(["-c", &format!("command -v {name}")]).output() {
            let path = String::from_utf8_lossy(&out.stdout).trim().to_owned();
            if out.status.success() && !path.is_empty() {
                return Some(path.into());
            }
        }
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "no Chromium under CI: .ci/run installs the Debian package `chromium` (or set AIM_CHROMIUM)"
    );
    None
}

/// Runs the browser headless on `url` with `args`; its stdout. Fails after [`PATIENCE`].
fn browse(browser: &Path, profile: &Path, args: &[&str], url: &str) -> String {
    let mut child = Command::new(browser)
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"])
        .args(["--no-first-run", "--disable-extensions", "--window-size=1400,1000"])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("--virtual-time-budget=8000")
        .args(args)
        .arg(url)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting the browser");
    let deadline = Instant::now() + PATIENCE;
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("the browser did not finish {args:?} within {PATIENCE:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "browser {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Pixels of a PNG (8-bit RGB or RGBA) within 8 levels per channel of `rgb`.
fn pixels_of(png_bytes: &[u8], rgb: [u8; 3]) -> usize {
    let mut reader = png::Decoder::new(std::io::Cursor::new(png_bytes)).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.bit_depth, png::BitDepth::Eight, "screenshot bit depth");
    let step = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        other => panic!("screenshot colour type {other:?}"),
    };
    buf[..info.buffer_size()]
        .chunks_exact(step)
        .filter(|p| (0..3).all(|i| p[i].abs_diff(rgb[i]) <= 8))
        .count()
}

/// The text of the element with `id` in a dumped DOM.
fn text_of<'a>(dom: &'a str, id: &str) -> &'a str {
    let open = format!("id=\"{id}\"");
    let at = dom.find(&open).unwrap_or_else(|| panic!("no #{id} in the page:\n{dom}"));
    let rest = &dom[at..];
    let start = rest.find('>').unwrap() + 1;
    let end = rest[start..].find('<').unwrap() + start;
    &rest[start..end]
}

#[test]
fn the_page_receives_and_draws_the_fixes_of_aim_replay() {
    let Some(browser) = chromium() else {
        eprintln!("SKIPPED the live-map browser test: no chromium (apt-get install chromium)");
        return;
    };
    let mut seq = 0;
    let frames = common::link(0, 8 * common::FS, &mut seq, 5);
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("live-map");
    std::fs::create_dir_all(&dir).unwrap();
    let site = dir.join("hall.toml");
    let recording = dir.join("flight.aimraw");
    std::fs::write(&site, SITE).unwrap();
    std::fs::write(&recording, common::bytes(&frames)).unwrap();

    let replayed = common::aim_replay(&recording, &site);
    let fixes: Vec<serde_json::Value> =
        replayed.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert!(fixes.len() > 20);

    let mut command = Command::new(env!("CARGO_BIN_EXE_aim"));
    command.arg("replay").arg(&recording).arg("--site").arg(&site);
    command.args(["--serve", "127.0.0.1:0", "--pace", "8"]);
    let mut server = Proc::spawn("aim replay --serve", &mut command);
    let line = server.wait_for("live map on http://");
    let url = line.trim_start_matches("live map on ").to_owned();
    // The whole recording has been replayed (and served) before the browser looks: the page
    // gets every event from the backlog, so what it shows is fixed by the recording.
    server.wait_for("replay done");
    let served: Vec<String> = (0..fixes.len())
        .map(|_| server.stdout.recv_timeout(PATIENCE).expect("the fixes on stdout"))
        .collect();
    assert_eq!(served.join("\n") + "\n", replayed, "--serve changed the fixes");

    let profile = dir.join("browser-profile");
    let dom = browse(&browser, &profile, &["--dump-dom"], &url);
    let last = fixes.last().unwrap();
    assert_eq!(text_of(&dom, "fix-count"), fixes.len().to_string(), "fix count on the page");
    let position = format!(
        "{:.2}, {:.2}, {:.2} m",
        last["x"].as_f64().unwrap(),
        last["y"].as_f64().unwrap(),
        last["z"].as_f64().unwrap()
    );
    assert_eq!(text_of(&dom, "last-pos"), position, "last position on the page");
    assert_eq!(text_of(&dom, "motion"), last["motion"].as_str().unwrap());
    assert_eq!(text_of(&dom, "state"), format!("ended ({} fixes)", fixes.len()));
    let doa = frames.iter().filter(|f| matches!(f.body, aim_wire::Body::Doa(_))).count();
    let peaks = frames.iter().filter(|f| matches!(f.body, aim_wire::Body::Peaks(_))).count();
    assert_eq!(text_of(&dom, "doa-count"), doa.to_string(), "DoA frames on the page");
    assert_eq!(text_of(&dom, "bpf-count"), peaks.to_string(), "BPF frames on the page");
    assert_eq!(text_of(&dom, "site"), "— hall.toml");

    let shot = dir.join("live-map.png");
    let _ = std::fs::remove_file(&shot);
    browse(&browser, &profile, &[&format!("--screenshot={}", shot.display())], &url);
    let png = std::fs::read(&shot).expect("the screenshot");
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    // The canvases were drawn, not only the text: beyond the legend's 12 × 12 px swatches
    // (HTML, 144 px each), the array's marker (#2e7d32, plan only: ≈ 180 px) and the track's
    // line-of-sight colour (#1565c0: plan track, ellipse edge, panel lines) are on the screenshot.
    let count = |rgb: [u8; 3]| pixels_of(&png, rgb);
    let (array_px, track_px) = (count([0x2e, 0x7d, 0x32]), count([0x15, 0x65, 0xc0]));
    eprintln!("screenshot pixels: array colour {array_px}, track colour {track_px}");
    const SWATCH: usize = 144;
    assert!(array_px >= SWATCH + 100, "array marker: {array_px} pixels of #2e7d32");
    assert!(track_px >= SWATCH + 300, "track: {track_px} pixels of #1565c0");
    eprintln!("live map screenshot: {}", shot.display());

    server.terminate();
    let (code, said) = server.finish();
    assert_eq!(code, Some(0), "{said}");
}
