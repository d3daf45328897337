//! `aim track` on a pseudo-terminal fed at the link's real pace gives the fixes `aim replay`
//! gives for the same bytes, line for line. Linux only (openpty). No wall-clock asserts: the
//! pace only makes the live path wait for frames as it would on a board's link.
#![cfg(target_os = "linux")]

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use aim_tracker::filter::FilterKind;
use aim_tracker::intake::IntakeConfig;
use aim_tracker::profile::Profile;
use aim_tracker::session::Session;
use aim_tracker::tracker::{Tracker, TrackerConfig};
use common::FS;

#[test]
fn aim_track_on_a_pty_at_link_pace_equals_aim_replay() {
    let mut seq = 0;
    let frames = common::link(0, 4 * FS, &mut seq, 11);
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    let tag = std::process::id();
    let site = dir.join(format!("pty-site-{tag}.toml"));
    let recording = dir.join(format!("pty-{tag}.aimraw"));
    std::fs::write(&site, common::SITE_TOML).unwrap();
    std::fs::write(&recording, common::bytes(&frames)).unwrap();

    let replayed = common::aim_replay(&recording, &site);
    assert!(replayed.lines().count() > 20, "{replayed}");

    // How many fixes are out before the end of the stream (the rest come when the link ends).
    let mut session = Session::new(
        Tracker::new(
            common::site(),
            Profile::dji_mini_2(),
            FilterKind::Aim,
            TrackerConfig::default(),
        )
        .unwrap(),
        common::site(),
        IntakeConfig::default(),
    );
    let live: usize = frames.iter().map(|f| session.push(f).unwrap().len()).sum();
    assert!(live > 0 && live < replayed.lines().count());

    let (mut master, slave, path) = common::pty();
    let mut child = Command::new(env!("CARGO_BIN_EXE_aim"))
        // The end of the stream is the end of the link here (replug is link_unplug.rs's test).
        .args(["track", "--reconnect", "false", "--status-every", "0.5"])
        .args(["--serial", path.to_str().unwrap(), "--site"])
        .arg(&site)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // `aim track` says "tracking ..." once the port is open and raw: only then send.
    let mut stderr = child.stderr.take().unwrap();
    let said = common::first_line(&mut stderr, "aim track");
    assert!(said.starts_with("tracking "), "{said:?}");
    let (tx, rx) = std::sync::mpsc::channel();
    let stdout = child.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            if tx.send(line.unwrap()).is_err() {
                break;
            }
        }
    });

    // Each frame when the audio it describes has been sampled, as the board sends it.
    let start = Instant::now();
    for f in &frames {
        common::wait_until_sent(f, start);
        master.write_all(&common::bytes(std::slice::from_ref(f))).unwrap();
    }
    // Every live fix is out: all bytes were read. Then the board goes away.
    let mut tracked = Vec::new();
    while tracked.len() < live {
        tracked.push(rx.recv_timeout(Duration::from_secs(30)).expect("aim track fell silent"));
    }
    drop(master);
    drop(slave);
    while let Ok(line) = rx.recv_timeout(Duration::from_secs(30)) {
        tracked.push(line);
    }
    let status = child.wait().unwrap();
    let mut rest = String::new();
    stderr.read_to_string(&mut rest).unwrap();
    let tracked = tracked.join("\n") + "\n";
    assert_eq!(tracked, replayed, "aim track and aim replay differ; stderr: {rest}");
    // The end of the link is reported, after the statistics line.
    assert!(rest.contains("\"kind\":\"stats\""), "{rest}");
    // The status line came every 0.5 s of the 4 s run (at least once), with array 1's counts.
    let line = rest.lines().find(|l| l.starts_with("status ")).expect("a status line");
    assert!(line.contains("| array 1: ") && line.contains(" frames, 0 gaps"), "{line}");
    let _ = status;
    let _ = std::fs::remove_file(&recording);
    let _ = std::fs::remove_file(&site);
}
