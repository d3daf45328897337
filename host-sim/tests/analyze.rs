//! `host-sim analyze` end to end: a synthetic recording with a known direction and BPF is
//! written as a WAV, analysed by the binary, and its JSON lines are checked against the truth.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::process::Command;

const FS: u32 = 48_000;
const SECONDS: f64 = 1.5;
const AZIMUTH_DEG: f64 = 40.0;
const ZENITH_DEG: f64 = 50.0;
const BPF_HZ: f64 = 328.0;

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("aim-analyze-test-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A plane wave of a drone-like sound (10 BPF harmonics plus 80 broadband tones) on the
/// ReSpeaker 6-mic circle, exact per-microphone delays, written as 32-bit float pascals.
fn write_recording(path: &Path) {
    let positions: Vec<[f64; 2]> = (0..6)
        .map(|i| {
            let a = i as f64 * PI / 3.0;
            [0.0463 * a.cos(), 0.0463 * a.sin()]
        })
        .collect();
    let (az, zen) = (AZIMUTH_DEG.to_radians(), ZENITH_DEG.to_radians());
    let u = [zen.sin() * az.cos(), zen.sin() * az.sin()];
    let mut state = 0x1234_5678_9ABC_DEF1u64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    // (frequency Hz, amplitude Pa, phase rad)
    let mut tones: Vec<(f64, f64, f64)> =
        (1..=10).map(|h| (BPF_HZ * h as f64, 0.02, 2.0 * PI * uniform())).collect();
    for _ in 0..80 {
        tones.push((300.0 + 5500.0 * uniform(), 0.004, 2.0 * PI * uniform()));
    }
    let n = (SECONDS * FS as f64) as usize;
    let spec = hound::WavSpec {
        channels: 6,
        sample_rate: FS,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut channels = vec![vec![0.0f32; n]; 6];
    for (ch, p) in channels.iter_mut().zip(&positions) {
        // The wave reaches this microphone (p · u)/c before the array centre.
        let lead = (p[0] * u[0] + p[1] * u[1]) / 343.0;
        for (t, v) in ch.iter_mut().enumerate() {
            let time = t as f64 / FS as f64 + lead;
            *v = tones.iter().map(|&(f, a, ph)| a * (2.0 * PI * f * time + ph).sin()).sum::<f64>()
                as f32;
        }
    }
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for t in 0..n {
        for ch in &channels {
            w.write_sample(ch[t]).unwrap();
        }
    }
    w.finalize().unwrap();
}

fn analyze(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim")).arg("analyze").args(args).output().unwrap()
}

#[test]
fn analyze_reports_the_true_direction_and_bpf() {
    let dir = scratch_dir("truth");
    let wav = dir.join("array-1.wav");
    write_recording(&wav);
    let out = analyze(&[wav.to_str().unwrap(), "--array", "respeaker6", "--jsonl"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let doa: Vec<_> = lines.iter().filter(|v| v["kind"] == "doa").collect();
    let peaks: Vec<_> = lines.iter().filter(|v| v["kind"] == "peaks").collect();
    // 72 000 samples: 8 DoA periods of 8192, and windows of 24 576 every 12 288: 4 analyses.
    assert_eq!(doa.len(), 8, "{lines:?}");
    assert_eq!(peaks.len(), 4, "{lines:?}");
    for (k, d) in doa.iter().enumerate() {
        let t = d["t"].as_f64().unwrap();
        assert!((t - k as f64 * 8192.0 / FS as f64).abs() < 1e-9, "t = {t}");
        let az = d["azimuth_deg"].as_f64().unwrap();
        let zen = d["zenith_deg"].as_f64().unwrap();
        assert!((az - AZIMUTH_DEG).abs() < 1.0, "azimuth {az}");
        assert!((zen - ZENITH_DEG).abs() < 1.0, "zenith {zen}");
        assert!(d["quality"].as_f64().unwrap() > 0.5);
    }
    // A comb is reported once it has held for `MIN_AGE` analyses: before, "no rotor
    // signature", no BPF.
    let settling = aim_dsp::comb::MIN_AGE as usize - 1;
    for p in &peaks[..settling] {
        assert_eq!((p["rotor"].as_bool(), p["bpf_hz"].as_f64()), (Some(false), Some(0.0)));
    }
    for p in &peaks[settling..] {
        assert_eq!(p["rotor"], true);
        let bpf = p["bpf_hz"].as_f64().unwrap();
        assert!((bpf - BPF_HZ).abs() < 0.1, "bpf {bpf}");
        let first = &p["peaks"][0];
        assert!((first["hz"].as_f64().unwrap() - BPF_HZ).abs() < 0.1);
        // The group's level: root-sum-square of the lines it found among harmonics 1-8 (the
        // `harmonics` default), each 0.02 Pa at 20 Pa full scale: between one line's 0.001
        // and all eight's 0.001·√8 (±20 %).
        let amp = first["amp"].as_f64().unwrap();
        assert!((0.0008..=0.0012 * 8f64.sqrt()).contains(&amp), "amp {amp}");
    }
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn analyze_refuses_mismatched_or_malformed_arrays_with_clear_errors() {
    let dir = scratch_dir("errors");
    let wav = dir.join("six.wav");
    let spec = hound::WavSpec {
        channels: 6,
        sample_rate: FS,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(&wav, spec).unwrap();
    for i in 0..6 * 4800 {
        w.write_sample((i % 100) as i16).unwrap();
    }
    w.finalize().unwrap();
    let wav = wav.to_str().unwrap();

    let out = analyze(&[wav, "--array", "respeaker4"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert!(err.contains("6 channels") && err.contains("4 microphones"), "{err}");

    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "# my array\npositions = [[0.0, 0.0], [0.05, 0.0], [0.1, 0.0], [0.15, 0.0], [0.2, 0.0], [0.25, 0.0]]\n").unwrap();
    let out = analyze(&[wav, "--array", bad.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        err.contains("bad.toml") && err.contains("line 2") && err.contains("one line"),
        "{err}"
    );

    let out = analyze(&[wav, "--array", "hexagon"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("neither a preset"), "{err}");
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn a_mono_clip_runs_the_bpf_path_and_skips_doa() {
    // A 16-bit mono 16 kHz clip, as a user's recording would be: a 240 Hz comb.
    let dir = scratch_dir("mono");
    let wav = dir.join("mono.wav");
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 16_000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(&wav, spec).unwrap();
    for t in 0..16_000 * 3 {
        let x: f64 = (1..=8)
            .map(|h| (2.0 * PI * 240.0 * h as f64 * t as f64 / 16_000.0).sin() / h as f64)
            .sum();
        w.write_sample((3000.0 * x) as i16).unwrap();
    }
    w.finalize().unwrap();
    let out = analyze(&[wav.to_str().unwrap(), "--array", "respeaker6", "--jsonl"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("one channel") && err.contains("DoA skipped"), "{err}");
    let lines: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(lines.iter().all(|v| v["kind"] != "doa"), "no DoA from one channel");
    let bpfs: Vec<f64> = lines
        .iter()
        .filter(|v| v["kind"] == "peaks" && v["rotor"] == true)
        .map(|v| v["bpf_hz"].as_f64().unwrap())
        .collect();
    assert!(bpfs.len() >= 3 && bpfs.iter().all(|b| (b - 240.0).abs() < 0.1), "{bpfs:?}");
    std::fs::remove_dir_all(dir).ok();
}

/// `--frames`: the bytes a board would send for the recording. They decode without error into
/// a Hello of the array and one frame per printed output, with the printed values; and `aim
/// calibrate` reads them against a reference at the true direction (the product's survey
/// path) and finds no bias beyond the pipeline's free-field accuracy.
#[test]
fn analyze_writes_the_links_frames_and_aim_calibrate_reads_them() {
    let dir = scratch_dir("frames");
    let wav = dir.join("array-1.wav");
    write_recording(&wav);
    let raw = dir.join("frames-3.aimraw");
    let out = analyze(&[
        wav.to_str().unwrap(),
        "--array",
        "respeaker6",
        "--jsonl",
        "--frames",
        raw.to_str().unwrap(),
        "--id",
        "3",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let printed: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let (frames, errors) = host_sim::eval::link::decode_frames(&std::fs::read(&raw).unwrap());
    assert_eq!(errors, 0);
    assert!(frames.iter().all(|f| f.header.array_id == 3));
    let aim_wire::Body::Hello(hello) = &frames[0].body else {
        panic!("the first frame is not a Hello: {:?}", frames[0])
    };
    assert_eq!((hello.sample_rate_hz, hello.mic_positions_decimm.len()), (FS, 6));
    // 0.0463 m is 463 tenths of a millimetre.
    assert_eq!(hello.mic_positions_decimm[0], [463, 0]);
    let doa: Vec<_> = frames
        .iter()
        .filter_map(|f| match &f.body {
            aim_wire::Body::Doa(d) => Some((f.header.sample_index, *d)),
            _ => None,
        })
        .collect();
    let printed_doa: Vec<_> = printed.iter().filter(|v| v["kind"] == "doa").collect();
    assert_eq!(doa.len(), printed_doa.len());
    for ((index, d), p) in doa.iter().zip(&printed_doa) {
        assert!((*index as f64 / f64::from(FS) - p["t"].as_f64().unwrap()).abs() < 1e-9);
        // The wire carries centidegrees.
        let az = f64::from(d.azimuth_cdeg) / 100.0;
        let zen = f64::from(d.zenith_cdeg) / 100.0;
        assert!((az - p["azimuth_deg"].as_f64().unwrap()).abs() <= 0.006, "{az} {p}");
        assert!((zen - p["zenith_deg"].as_f64().unwrap()).abs() <= 0.006, "{zen} {p}");
    }
    let count = |kind: &str| printed.iter().filter(|v| v["kind"] == kind).count();
    let peaks = frames.iter().filter(|f| matches!(f.body, aim_wire::Body::Peaks(_))).count();
    assert_eq!(peaks, count("peaks"));

    // The source 5 m away along the true direction, the whole recording.
    let (az, zen) = (AZIMUTH_DEG.to_radians(), ZENITH_DEG.to_radians());
    let p = [5.0 * zen.sin() * az.cos(), 5.0 * zen.sin() * az.sin(), 5.0 * zen.cos()];
    let reference = dir.join("reference.csv");
    let rows: String =
        (0..=15).map(|k| format!("{:.1},{},{},{}\n", k as f64 * 0.1, p[0], p[1], p[2])).collect();
    std::fs::write(&reference, format!("t,x,y,z\n{rows}")).unwrap();
    let site_text = "sample_rate_hz = 48000\nspeed_of_sound_mps = 343.0\n\n[[array]]\nid = 3\n\
                     geometry = \"respeaker-6mic\"\nposition = [0.0, 0.0, 0.0]\nyaw_deg = 0.0\n";
    let site = aim_tracker::site::Site::parse(site_text, "site.toml".as_ref()).unwrap();
    let reference = aim_tracker::zenith::Reference::parse(
        &std::fs::read_to_string(&reference).unwrap(),
        &reference,
    )
    .unwrap();
    let bytes = std::fs::read(&raw).unwrap();
    let mut source = aim_tracker::link::FrameSource::new(&bytes[..]);
    let (bearings, _) = aim_tracker::zenith::bearings_of(&site, &mut source).unwrap();
    assert_eq!(bearings.len(), doa.len());
    let config = aim_tracker::zenith::FitConfig { min_frames: 5, ..Default::default() };
    let fits = aim_tracker::zenith::calibrate(&site, &[], &bearings, &reference, config);
    assert_eq!(fits.len(), 1);
    let points = fits[0].correction.to_degrees();
    assert!(!points.is_empty(), "{fits:?}");
    for [measured, bias] in points {
        assert!((measured - ZENITH_DEG).abs() <= 5.0 && bias.abs() < 1.0, "{fits:?}");
    }
    std::fs::remove_dir_all(dir).ok();
}

/// `--frames` on a recording cut short: the run fails naming the cut, no `FILE` appears that
/// could pass for a whole recording's frames, and the frames of the audio read before the cut
/// are kept in `FILE.part`: as many directions as were printed.
#[test]
fn a_recording_cut_short_leaves_its_frames_in_a_part_file() {
    let dir = scratch_dir("frames-cut");
    let wav = dir.join("array-1.wav");
    write_recording(&wav);
    let bytes = std::fs::read(&wav).unwrap();
    // The header still declares every sample; 60 % of the data remains.
    std::fs::write(&wav, &bytes[..bytes.len() * 3 / 5]).unwrap();
    let raw = dir.join("frames-1.aimraw");
    // An earlier run's output: a failed run must not leave it looking like its own.
    std::fs::write(&raw, b"an earlier run").unwrap();
    let out = analyze(&[
        wav.to_str().unwrap(),
        "--array",
        "respeaker6",
        "--jsonl",
        "--frames",
        raw.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains("cut short") && stderr.contains("frames-1.aimraw.part"), "{stderr}");
    assert!(!raw.exists(), "the earlier run's {} is still there", raw.display());
    let printed = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .filter(|l| l.contains(r#""kind":"doa""#))
        .count();
    let part = std::fs::read(dir.join("frames-1.aimraw.part")).unwrap();
    let (frames, errors) = host_sim::eval::link::decode_frames(&part);
    assert_eq!(errors, 0);
    assert!(matches!(frames[0].body, aim_wire::Body::Hello(_)), "{:?}", frames[0]);
    assert!(printed > 0);
    let doa = frames.iter().filter(|f| matches!(f.body, aim_wire::Body::Doa(_))).count();
    assert_eq!(doa, printed);
    std::fs::remove_dir_all(dir).ok();
}

/// `--frames` naming the recording itself is refused before anything is removed or written.
#[test]
fn frames_that_name_an_input_are_refused_and_the_input_kept() {
    let dir = scratch_dir("frames-input");
    let wav = dir.join("array-1.wav");
    write_recording(&wav);
    let before = std::fs::read(&wav).unwrap();
    let out = analyze(&[
        wav.to_str().unwrap(),
        "--array",
        "respeaker6",
        "--frames",
        wav.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains("that is an input of this run"), "{stderr}");
    assert_eq!(std::fs::read(&wav).unwrap(), before);
    assert!(!dir.join("array-1.wav.part").exists());
    std::fs::remove_dir_all(dir).ok();
}
