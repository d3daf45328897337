//! The streamed simulation (`simulate_to`, what `host-sim simulate` runs) writes the same bytes
//! the whole-run simulator wrote before streaming: golden FNV-1a hashes of the WAV files
//! (and the truth and site files) written by `host-sim simulate` at e48823c (the last commit
//! that held whole signals) for two
//! scenarios that exercise every renderer feature over several output blocks.
use std::path::{Path, PathBuf};

/// FNV-1a 64 of `bytes` (a fingerprint, not a security hash).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3))
}

fn scenario(name: &str) -> host_sim::scenario::Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name);
    host_sim::scenario::Scenario::load(&path).unwrap()
}

fn out_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("aim-stream-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Hash of every file in `dir`, by name.
fn hashes(dir: &Path) -> Vec<(String, u64)> {
    let mut v: Vec<(String, u64)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (e.file_name().to_string_lossy().into_owned(), fnv1a(&std::fs::read(e.path()).unwrap()))
        })
        .collect();
    v.sort();
    v
}

fn golden(name: &str, expected: &[(&str, u64)], threads: usize) {
    let s = scenario(name);
    let dir = out_dir(&format!("{name}-{threads}"));
    host_sim::write_streamed(
        &s,
        &host_sim::Options { threads },
        &indicatif::ProgressBar::hidden(),
        &dir,
        None,
    )
    .unwrap();
    let got = hashes(&dir);
    for (file, h) in expected {
        let g = got.iter().find(|(n, _)| n == file).map(|x| x.1);
        assert_eq!(g, Some(*h), "{name}: {file} (got {g:x?}, golden {h:x})");
    }
    // The kept (whole-recording) path writes the same bytes.
    let kept = host_sim::simulate_with(
        &s,
        &host_sim::Options { threads },
        &indicatif::ProgressBar::hidden(),
    )
    .unwrap();
    let dir2 = out_dir(&format!("{name}-{threads}-kept"));
    kept.write(&dir2).unwrap();
    assert_eq!(hashes(&dir2), got, "{name}: kept and streamed differ");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&dir2);
}

/// Room, reflections, obstacle (through-loss and diffraction), a point noise, a diffuse field,
/// two arrays with clock offsets and drifts, 2.3 s (three output blocks, the last partial).
#[test]
fn streamed_simulation_matches_the_whole_run_golden_hashes() {
    golden(
        "stream-golden.toml",
        &[
            ("array-1.wav", 0x3d9a_d1e1_5355_1e0a),
            ("array-4.wav", 0x9350_5228_eb07_1232),
            ("site.toml", 0xd756_f763_3e2b_90f3),
            ("truth.csv", 0xbf95_3604_c233_043b),
            ("truth.toml", 0x75d2_6e37_e6a2_5b74),
        ],
        2,
    );
}

/// Every rotor a source with all its paths, a late, slow clock; single-threaded.
#[test]
fn streamed_each_rotor_scenario_matches_its_golden_hash() {
    golden(
        "stream-golden-each.toml",
        &[
            ("array-2.wav", 0x1167_19e3_02fc_669d),
            ("site.toml", 0xd49c_b446_ce91_1379),
            ("truth.csv", 0x5a5d_77dd_d7d3_8aaa),
            ("truth.toml", 0x34ff_8ebc_75e9_e4f7),
        ],
        1,
    );
}

/// `host-sim fly`'s link bytes, rendered and piped block by block, are the bytes of the whole
/// recording through the pipeline.
#[test]
fn streamed_link_bytes_match_the_whole_recording_through_the_pipeline() {
    let s = scenario("stream-golden.toml");
    let opts = host_sim::Options { threads: 2 };
    let hidden = indicatif::ProgressBar::hidden();
    let fs = host_sim::DEFAULT_FULL_SCALE_PA;
    let (_, links) = host_sim::eval::link::simulate_links(&s, &opts, &hidden, fs).unwrap();
    let kept = host_sim::simulate_with(&s, &opts, &hidden).unwrap();
    assert_eq!(links.len(), 2);
    for (rec, bytes) in kept.arrays.iter().zip(&links) {
        let whole = host_sim::eval::link::link_bytes(rec, fs).unwrap();
        assert!(whole.len() > 300, "array {}: {} bytes", rec.id, whole.len());
        assert!(whole == *bytes, "array {}: streamed link bytes differ", rec.id);
    }
}

/// SIGTERM in the middle of `host-sim simulate` (as Ctrl-C) stops it with status 130 and
/// leaves no `.part` and no WAV behind; the signal arrives once the first `.part` file exists.
#[test]
fn a_signal_stops_simulate_and_removes_its_unfinished_recordings() {
    let dir = out_dir("sigterm");
    let scenario = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/square10-los.toml");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["simulate", scenario, "--out", dir.to_str().unwrap(), "--threads", "1"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let part = dir.join("array-1.wav.part");
    let started = std::time::Instant::now();
    while !part.exists() {
        assert!(started.elapsed().as_secs() < 120, "no {} after 120 s", part.display());
        assert!(child.try_wait().unwrap().is_none(), "simulate ended before it was signalled");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let kill = std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    assert!(!part.exists() && !dir.join("array-1.wav").exists(), "a recording was left behind");
}
