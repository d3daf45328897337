//! The serial intake end to end through a pseudo-terminal pair: the test writes frames on the
//! master side, as the board would; the real `serialport` code path of `aim` opens the slave
//! side by its path and decodes. Linux only (openpty).
#![cfg(target_os = "linux")]

mod common;

use std::io::{Read, Write};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use aim_tracker::link::{self, FrameSource};
use aim_wire::{Body, Doa, Frame, Header, Health, Peak, Peaks, MAX_ENCODED_LEN};

/// A run of frames of every kind the DSP sends, as one array would number them.
fn frames(n: u16) -> Vec<Frame> {
    (0..n)
        .map(|seq| {
            let body = match seq % 3 {
                0 => Body::Doa(Doa {
                    span_samples: 8192,
                    pairs_used: 28,
                    ..Doa::new(0.01 * f32::from(seq), 0.7, 0.3, 0.8)
                }),
                1 => Body::Peaks(Peaks {
                    span_samples: 24_576,
                    bpf_chz: 18_000 + u32::from(seq),
                    peaks: [Peak::new(180.0, -20.0, 0.9), Peak::new(240.5, -31.0, 0.5)]
                        .into_iter()
                        .collect(),
                    detection: aim_wire::Detection::Rotor,
                    quality: [200, 90].into_iter().collect(),
                }),
                _ => Body::Health(Health { blocks: u32::from(seq) * 8, ..Health::default() }),
            };
            Frame { header: Header { array_id: 5, seq, sample_index: u64::from(seq) * 8192 }, body }
        })
        .collect()
}

fn wire(frame: &Frame) -> Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED_LEN];
    let n = aim_wire::encode(frame, &mut buf).unwrap();
    buf[..n].to_vec()
}

/// A pty pair: the master as a file to write the board's bytes into, the slave's path, and the
/// slave descriptor (kept open so the pair lives as long as the test).
fn pty() -> (std::fs::File, String, std::os::fd::OwnedFd) {
    let pair = nix::pty::openpty(None, None).expect("openpty");
    let path = nix::unistd::ttyname(&pair.slave).expect("ttyname of the pty slave");
    (std::fs::File::from(pair.master), path.to_string_lossy().into_owned(), pair.slave)
}

#[test]
fn frames_cross_a_pty_and_a_corrupted_byte_costs_only_its_frame() {
    let (mut master, path, _slave) = pty();
    let port = link::serial::open(&path, link::serial::DEFAULT_BAUD).unwrap();
    let sent = frames(60);
    const DAMAGED: usize = 17;

    let expected_outcomes = sent.len();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut source = FrameSource::new(port);
        let mut outcomes = Vec::new();
        while outcomes.len() < expected_outcomes {
            match source.next_outcome() {
                Ok(Some(o)) => outcomes.push(o),
                Ok(None) | Err(_) => break,
            }
        }
        let _ = tx.send((outcomes, *source.stats()));
    });

    let mut written = 0;
    for (i, frame) in sent.iter().enumerate() {
        let mut bytes = wire(frame);
        if i == DAMAGED {
            let mid = bytes.len() / 2;
            bytes[mid] ^= 0x08;
        }
        master.write_all(&bytes).unwrap();
        written += bytes.len();
    }
    master.flush().unwrap();

    let (outcomes, stats) = rx
        .recv_timeout(Duration::from_secs(30))
        .expect("the reader decoded every chunk within 30 s");
    let decoded: Vec<Frame> = outcomes.iter().filter_map(|o| o.clone().ok()).collect();
    let mut expected = sent.clone();
    expected.remove(DAMAGED);
    assert_eq!(decoded, expected, "all frames but the damaged one, in order");
    assert_eq!(outcomes.iter().filter(|o| o.is_err()).count(), 1);
    assert_eq!(stats.crc_errors + stats.framing_errors, 1);
    assert_eq!((stats.seq_gaps, stats.frames_missed), (1, 1));
    assert_eq!(stats.bytes, written as u64);
}

#[test]
fn record_then_replay_gives_the_identical_frame_sequence() {
    let (mut master, path, _slave) = pty();
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("record-{}.aimraw", std::process::id()));
    let sent = frames(200);
    // Frame 50 is damaged on the line; `--frames` counts decoded frames only.
    let decodable = sent.len() - 1;
    let mut child = Command::new(env!("CARGO_BIN_EXE_aim"))
        .args(["record", "--serial", &path, "--out"])
        .arg(&out)
        .args(["--frames", &decodable.to_string()])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // `aim record` says "recording ..." once the port is open and raw: only then send.
    let mut stderr = child.stderr.take().unwrap();
    let said = common::first_line(&mut stderr, "aim record");
    assert!(said.starts_with("recording "), "{said:?}");

    let mut stream = vec![0x42, 0x17, 0x99]; // noise before the first frame
    for (i, frame) in sent.iter().enumerate() {
        let mut bytes = wire(frame);
        if i == 50 {
            bytes[3] ^= 0x80;
        }
        stream.extend_from_slice(&bytes);
    }
    master.write_all(&stream).unwrap();

    let deadline = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if Instant::now() > deadline {
            child.kill().unwrap();
            panic!("aim record did not stop after {decodable} frames");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut rest = String::new();
    stderr.read_to_string(&mut rest).unwrap();
    assert!(status.success(), "aim record failed: {rest}");

    // The file holds the bytes as sent...
    let recorded = std::fs::read(&out).unwrap();
    assert_eq!(recorded, stream);
    // ...and replaying it decodes exactly what a live decoder of those bytes decodes.
    let live: Vec<Frame> = FrameSource::new(&stream[..]).map(Result::unwrap).collect();
    let replayed: Vec<Frame> = FrameSource::new(link::open_input(out.to_str().unwrap()).unwrap())
        .map(Result::unwrap)
        .collect();
    assert_eq!(replayed, live);
    let mut expected = sent.clone();
    expected.remove(50);
    assert_eq!(replayed, expected);

    // `aim frames FILE` prints the same sequence, then the statistics.
    let printed = Command::new(env!("CARGO_BIN_EXE_aim")).arg("frames").arg(&out).output().unwrap();
    assert!(printed.status.success());
    let lines: Vec<serde_json::Value> = String::from_utf8(printed.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let (stats, frame_lines) = lines.split_last().unwrap();
    let seqs: Vec<u64> = frame_lines.iter().map(|v| v["seq"].as_u64().unwrap()).collect();
    let expected_seqs: Vec<u64> = expected.iter().map(|f| u64::from(f.header.seq)).collect();
    assert_eq!(seqs, expected_seqs);
    assert_eq!(stats["kind"], "stats");
    assert_eq!(stats["frames"], decodable as u64);
    assert_eq!(stats["frames_missed"], 1);
    assert_eq!(stats["bytes"], stream.len() as u64);
    let _ = std::fs::remove_file(&out);
}
