//! Property test of `aim replay` (the tracker behind `aim track`) fed arbitrary frame
//! sequences with valid CRCs: any field values of any kind, any order, any array. It must
//! never panic, always exit cleanly, and every line it prints must be a JSON fix with finite
//! numbers.
//!
//! Sample indices stay below 2^28 and `Hello` sample rates within 8–192 kHz: far-future
//! frames and absurd time bases are the clock-trust cases of the intake's own tests (a jump of
//! 2^64 samples is a time base question, not a panic or NaN one).

use std::io::Write as _;
use std::process::Command;

use aim_wire::{Body, Doa, Frame, Header, Health, Hello, Peak, Peaks, MAX_ENCODED_LEN};
use proptest::prelude::*;

fn arb_header() -> impl Strategy<Value = Header> {
    (prop_oneof![Just(1u8), Just(2u8), any::<u8>()], any::<u16>(), 0u64..(1 << 28))
        .prop_map(|(array_id, seq, sample_index)| Header { array_id, seq, sample_index })
}

fn arb_body() -> impl Strategy<Value = Body> {
    let doa = (any::<u32>(), any::<i16>(), any::<u16>(), any::<u16>(), any::<u8>(), any::<u8>())
        .prop_map(|(span_samples, az, zen, res, quality, pairs_used)| {
            Body::Doa(Doa {
                span_samples,
                azimuth_cdeg: az,
                zenith_cdeg: zen,
                residual_csamples: res,
                quality,
                pairs_used,
            })
        });
    let peak =
        (any::<u32>(), any::<i16>(), any::<u8>()).prop_map(|(freq_chz, amp, harmonicity)| Peak {
            freq_chz,
            amplitude_ddb: amp,
            harmonicity,
        });
    // BPF-like frequencies most of the time, so that the spectra reach the dynamics.
    let bpf_peak = (15_000u32..60_000, -900i16..0, any::<u8>())
        .prop_map(|(freq_chz, amp, h)| Peak { freq_chz, amplitude_ddb: amp, harmonicity: h });
    let peaks = (
        any::<u32>(),
        any::<u32>(),
        prop::collection::vec(prop_oneof![peak, bpf_peak], 0..=aim_wire::MAX_PEAKS),
        0..3usize,
        prop::collection::vec(any::<u8>(), 0..=aim_wire::MAX_PEAKS),
    )
        .prop_map(|(span_samples, bpf_chz, list, detection, quality)| {
            use aim_wire::Detection;
            Body::Peaks(Peaks {
                span_samples,
                bpf_chz,
                peaks: list.into_iter().collect(),
                detection: [Detection::Unstated, Detection::NoRotor, Detection::Rotor][detection],
                quality: quality.into_iter().collect(),
            })
        });
    let hello = (8_000u32..=192_000, any::<u16>(), prop::collection::vec(any::<[i16; 2]>(), 0..=8))
        .prop_map(|(rate, block_len, mics)| {
            let mut h = Hello::new([0, 1, 0], rate, 1024, &[]);
            h.block_len = block_len;
            h.mic_positions_decimm = mics.into_iter().collect();
            Body::Hello(h)
        });
    let health = (any::<u32>(), any::<u32>(), any::<i16>(), any::<i8>()).prop_map(
        |(blocks, clipped, peak, exp)| {
            Body::Health(Health {
                blocks,
                clipped_samples: clipped,
                peak_ddbfs: peak,
                block_exponent: exp,
                ..Health::default()
            })
        },
    );
    prop_oneof![4 => doa, 4 => peaks, 1 => hello, 1 => health]
}

fn arb_frames() -> impl Strategy<Value = Vec<Frame>> {
    // Half the cases in time order (so the filters run long), half shuffled.
    (prop::collection::vec((arb_header(), arb_body()), 1..400), any::<bool>()).prop_map(
        |(frames, sorted)| {
            let mut frames: Vec<Frame> =
                frames.into_iter().map(|(header, body)| Frame { header, body }).collect();
            if sorted {
                frames.sort_by_key(|f| f.header.sample_index);
            }
            frames
        },
    )
}

fn scratch(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("arbitrary-{}-{name}", std::process::id()))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn replay_of_arbitrary_frames_never_panics_nor_prints_non_finite(
        frames in arb_frames(),
        filter in prop_oneof![Just("aim"), Just("paper")],
    ) {
        let site = scratch("site.toml");
        std::fs::write(
            &site,
            "[[array]]\nid = 1\nposition = [1.0, 2.0, 0.1]\n\
             [[array]]\nid = 2\nposition = [8.0, 2.0, 0.1]\nyaw_deg = 90.0\n\
             [room]\nsize = [10.0, 10.0, 4.0]\n",
        )
        .unwrap();
        let recording = scratch("frames.aimraw");
        let mut file = std::fs::File::create(&recording).unwrap();
        for frame in &frames {
            let mut buf = [0u8; MAX_ENCODED_LEN];
            let n = aim_wire::encode(frame, &mut buf).unwrap();
            file.write_all(&buf[..n]).unwrap();
        }
        drop(file);
        let out = Command::new(env!("CARGO_BIN_EXE_aim"))
            .args(["replay", "--filter", filter, "--site"])
            .arg(&site)
            .arg(&recording)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        // Success, or the one refusal the intake makes on purpose (issue 12): a Hello that
        // contradicts the site file or an earlier Hello is an error naming both values, exit 1.
        let refused = out.status.code() == Some(1)
            && stderr.lines().any(|l| l.starts_with("error:") && l.contains("Hello"));
        prop_assert!(out.status.success() || refused, "exit {:?}: {}", out.status, stderr);
        prop_assert!(!stderr.contains("panicked"), "{}", stderr);
        let stdout = String::from_utf8(out.stdout).unwrap();
        for line in stdout.lines() {
            let fix: serde_json::Value = serde_json::from_str(line)
                .map_err(|e| TestCaseError::fail(format!("not JSON: {line}: {e}")))?;
            for key in ["t", "x", "y", "z"] {
                let v = fix[key].as_f64();
                prop_assert!(v.is_some_and(f64::is_finite), "{key} not a finite number: {line}");
            }
        }
    }
}

/// Bytes that hold no frame at all are not a recording: an error naming the file and the
/// bytes, exit 1. An empty file is (nothing was sent): a warning, exit 0.
#[test]
fn bytes_with_no_frame_are_refused_and_an_empty_file_is_not() {
    let site = scratch("plain-site.toml");
    std::fs::write(&site, "[[array]]\nid = 1\nposition = [1.0, 2.0, 0.1]\n").unwrap();
    // A fixed pseudo-random byte string (xorshift), no zero byte: no COBS frame ends in it.
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    let noise: Vec<u8> = (0..20_000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x % 255) as u8 + 1
        })
        .collect();
    for (name, bytes, code, needle) in [
        ("noise.bin", noise, 1, "20000 bytes and no AIM frame in them"),
        ("empty.bin", Vec::new(), 0, "empty, no frame to track"),
    ] {
        let path = scratch(name);
        std::fs::write(&path, bytes).unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_aim"))
            .args(["replay", "--no-id", "--site"])
            .arg(&site)
            .arg(&path)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{name}: {stderr}");
        assert!(stderr.contains(needle) && stderr.contains(name), "{name}: {stderr}");
        assert!(out.stdout.is_empty(), "{name}: fixes from no frame");
    }
}
