//! Issue 17's silent problems, through `aim replay`: sequence gaps, the board's `Health`
//! counters, CRC errors and a dead microphone reach the final statistics; frames from an array
//! the site does not list are warned about once, then counted.
mod common;

use std::process::Command;

use aim_wire::{Body, Frame, Header, Health};

fn replay(frames: &[u8], tag: &str) -> (String, serde_json::Value) {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    let id = std::process::id();
    let site = dir.join(format!("status-site-{id}-{tag}.toml"));
    let rec = dir.join(format!("status-{id}-{tag}.aimraw"));
    std::fs::write(&site, common::SITE_TOML).unwrap();
    std::fs::write(&rec, frames).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_aim"))
        .arg("replay")
        .arg(&rec)
        .arg("--site")
        .arg(&site)
        .output()
        .unwrap();
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(out.status.success(), "{stderr}");
    let stats = stderr.lines().find(|l| l.contains("\"kind\":\"stats\"")).expect("stats line");
    let stats = serde_json::from_str(stats).unwrap();
    let _ = std::fs::remove_file(&site);
    let _ = std::fs::remove_file(&rec);
    (stderr, stats)
}

#[test]
fn gaps_health_crc_and_unknown_arrays_reach_the_statistics() {
    let mut seq = 0;
    let mut frames = common::link(0, 6 * common::FS, &mut seq, 3);
    let n = frames.len();
    // Three frames lost on the link (a sequence gap of 3) ...
    frames.drain(40..43);
    // ... the board reports its losses in a Health frame ...
    let health = Health {
        dma_overruns: 2,
        sai_overruns: 1,
        dsp_overloads: 3,
        dropped_frames: 5,
        uart_errors: 4,
        clipped_samples: 17,
        ..Health::default()
    };
    let at = frames.len() - 1;
    frames[at].body = Body::Health(health);
    // ... and a board not in the site file talks on the same link.
    let stranger = |k: u16| Frame {
        header: Header { array_id: 9, seq: k, sample_index: 0 },
        body: Body::Health(Health::default()),
    };
    for k in 0..4 {
        frames.insert(10 + 7 * k as usize, stranger(k));
    }
    let mut bytes = common::bytes(&frames);
    // One frame damaged on the line: a CRC error, that frame lost.
    let cut = bytes.len() / 2;
    let mid = bytes[cut..].iter().position(|&b| b == 0).unwrap() + cut + 5;
    bytes[mid] ^= 0x40;
    let (stderr, stats) = replay(&bytes, "gaps");
    let warnings: Vec<&str> = stderr.lines().filter(|l| l.starts_with("warning:")).collect();
    assert_eq!(warnings.len(), 1, "{stderr}");
    assert!(warnings[0].contains("array 9"), "{stderr}");
    assert_eq!(stats["unknown_arrays"]["9"], 4, "{stats}");
    assert_eq!(stats["link"]["crc_errors"], 1, "{stats}");
    let a = &stats["arrays"]["1"];
    // 3 dropped + 1 damaged frame missing from array 1's sequence.
    assert_eq!(a["frames"].as_u64().unwrap(), n as u64 - 4, "{a}");
    assert_eq!(a["frames_missed"], 4, "{a}");
    assert_eq!(a["seq_gaps"], 2, "{a}");
    assert_eq!(a["seq_resets"], 0, "{a}");
    for (k, v) in [
        ("ring_overruns", 2),
        ("sai_overruns", 1),
        ("dsp_overloads", 3),
        ("uplink_drops", 5),
        ("uart_errors", 4),
        ("clipped_samples", 17),
    ] {
        assert_eq!(a[k], v, "{k}: {a}");
    }
    assert_eq!(a["mic_suspect"], false, "{a}");
}

#[test]
fn a_status_period_out_of_range_is_refused_naming_the_flag() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    let site = dir.join(format!("status-flag-site-{}.toml", std::process::id()));
    std::fs::write(&site, common::SITE_TOML).unwrap();
    for bad in ["-1", "nan", "1e-9", "1e9"] {
        let out = Command::new(env!("CARGO_BIN_EXE_aim"))
            .args(["track", "--serial", "/nonexistent/port", "--site"])
            .arg(&site)
            .arg(format!("--status-every={bad}"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{bad}: {stderr}");
        assert!(stderr.contains("--status-every must be"), "{bad}: {stderr}");
    }
    let _ = std::fs::remove_file(&site);
}

/// A recording shorter than the output period gives no fix, and says so (not a silent,
/// successful empty output).
#[test]
fn audio_that_ends_before_the_first_fix_is_said() {
    let dir = std::env::temp_dir().join(format!("aim-status-period-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (site, rec) = (dir.join("site.toml"), dir.join("short.aimraw"));
    std::fs::write(&site, common::SITE_TOML).unwrap();
    let mut seq = 0;
    std::fs::write(&rec, common::bytes(&common::link(0, 4 * common::FS, &mut seq, 5))).unwrap();
    for (period, warned) in [("0.1", false), ("30", true)] {
        let out = common::aim_replay_output(&rec, &site, &["--no-id", "--period", period]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert_eq!(out.stdout.is_empty(), warned, "--period {period}");
        assert_eq!(stderr.contains("inputs and no fix"), warned, "--period {period}: {stderr}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
