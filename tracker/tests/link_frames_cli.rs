//! `aim frames` on input that is not a clean recording: it must finish cleanly with statistics.

use std::io::Write;
use std::process::{Command, Stdio};

fn aim_frames_stdin(input: &[u8], extra: &[&str]) -> std::process::Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_aim"))
        .arg("frames")
        .arg("-")
        .args(extra)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let data = input.to_vec();
    let writer = std::thread::spawn(move || stdin.write_all(&data));
    let output = child.wait_with_output().unwrap();
    writer.join().unwrap().unwrap();
    output
}

/// Seeded xorshift bytes; every eighth one forced to a delimiter in `dense` mode.
fn random_bytes(len: usize, seed: u64, dense: bool) -> Vec<u8> {
    let mut s = seed;
    (0..len)
        .map(|i| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            if dense && i % 8 == 0 {
                0
            } else {
                (s >> 24) as u8
            }
        })
        .collect()
}

#[test]
fn random_bytes_give_statistics_and_no_panic() {
    for (seed, dense) in [(0x5EED_0001, false), (0x5EED_0002, true)] {
        let input = random_bytes(1 << 20, seed, dense);
        let out = aim_frames_stdin(&input, &[]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "exit {:?}: {stderr}", out.status);
        assert!(stderr.is_empty(), "{stderr}");
        let stdout = String::from_utf8(out.stdout).unwrap();
        let last: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
        assert_eq!(last["kind"], "stats");
        assert_eq!(last["bytes"], 1u64 << 20);
        assert_eq!(last["frames"], 0);
        // Every chunk between delimiters was accounted for as some kind of error.
        let chunks = input.split(|&b| b == 0).filter(|c| !c.is_empty()).count() as u64;
        assert_eq!(last["errors"], chunks);
        assert_eq!(stdout.lines().count(), 1, "random bytes decoded as a frame");
    }
}

#[test]
fn errors_flag_describes_damage_on_stderr() {
    let out = aim_frames_stdin(&[0x00, 0x05, 0x01, 0x02, 0x00], &["--errors"]);
    assert!(out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("-: chunk 1: COBS run past the end"), "{stderr}");
}

#[test]
fn a_missing_recording_is_a_clear_error() {
    let out = Command::new(env!("CARGO_BIN_EXE_aim"))
        .args(["frames", "/nonexistent/recording.aimraw"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.starts_with("error: opening recording /nonexistent/recording.aimraw:"),
        "{stderr}"
    );
}

/// `aim frames --errors F 2>&1 | head -1`: stdout and stderr are one pipe whose reader goes
/// away after a line. Writing the damage notes to the closed stderr must not panic (exit
/// status 101); the run ends as a closed stdout does, with status 0.
#[test]
fn a_closed_stderr_is_not_a_panic() {
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("noise-{}.aimraw", std::process::id()));
    std::fs::write(&path, random_bytes(1 << 20, 0x5EED_0003, true)).unwrap();
    let (reader, writer) = std::io::pipe().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_aim"))
        .args(["frames", "--errors"])
        .arg(&path)
        .stdout(writer.try_clone().unwrap())
        .stderr(writer)
        .spawn()
        .unwrap();
    let mut first = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(reader), &mut first).unwrap();
    assert!(first.contains("chunk 1:"), "{first}");
    // The reader is dropped here, like `head -1` exiting.
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(0), "{status:?}");
    let _ = std::fs::remove_file(&path);
}
