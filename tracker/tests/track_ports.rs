//! `aim track --serial A --serial B`: two boards on two pseudo-terminals tracked at once; each
//! board's frames reach the intake (its counts in the statistics line, one `port` line per
//! link) and fixes come out. Linux only (openpty).
#![cfg(target_os = "linux")]

mod common;

use std::io::{Read, Write};
use std::process::{Command, Stdio};

use common::FS;

#[test]
fn aim_track_reads_two_boards_at_once() {
    let mut seq = 0;
    let one = common::link(0, 3 * FS, &mut seq, 11);
    // The second board: the same sound heard from a second array (another id, 3 m east).
    let two: Vec<aim_wire::Frame> = one
        .iter()
        .cloned()
        .map(|mut f| {
            f.header.array_id = 2;
            f
        })
        .collect();
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    let site = dir.join(format!("ports-site-{}.toml", std::process::id()));
    let text = format!("{}\n[[array]]\nid = 2\nposition = [3.0, 0.0, 0.0]\n", common::SITE_TOML);
    std::fs::write(&site, text).unwrap();

    let (mut m1, s1, p1) = common::pty();
    let (mut m2, s2, p2) = common::pty();
    let mut child = Command::new(env!("CARGO_BIN_EXE_aim"))
        .args(["track", "--reconnect", "false", "--status-every", "0", "--no-id"])
        .args(["--serial", p1.to_str().unwrap(), "--serial", p2.to_str().unwrap(), "--site"])
        .arg(&site)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let said = common::first_line(&mut stderr, "aim track");
    assert!(said.starts_with("tracking ") && said.contains(", "), "{said}");
    let mut stdout = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        stdout.read_to_string(&mut s).unwrap();
        s
    });
    // Each pair of frames when its audio has been sampled, as two boards send them: written
    // all at once, one port's reader could deliver its whole stream before the other's, and
    // the other array would read as fallen silent (a take-over mid-test).
    let start = std::time::Instant::now();
    for (a, b) in one.iter().zip(&two) {
        common::wait_until_sent(a, start);
        m1.write_all(&common::bytes(std::slice::from_ref(a))).unwrap();
        m2.write_all(&common::bytes(std::slice::from_ref(b))).unwrap();
    }
    // Both boards go away: the stream ends.
    std::thread::sleep(std::time::Duration::from_millis(300));
    drop((m1, s1, m2, s2));
    let fixes = reader.join().unwrap();
    child.wait().unwrap();
    let mut rest = String::new();
    stderr.read_to_string(&mut rest).unwrap();
    assert!(fixes.lines().count() > 10, "{fixes}\n{rest}");
    let stats: serde_json::Value = rest
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| v["kind"] == "stats")
        .unwrap_or_else(|| panic!("no statistics line: {rest}"));
    for id in ["1", "2"] {
        let n = stats["arrays"][id]["frames"].as_u64().unwrap_or(0);
        assert_eq!(n, one.len() as u64, "array {id}: {stats}");
    }
    assert_eq!(rest.matches("\"kind\":\"port\"").count(), 2, "{rest}");
}
