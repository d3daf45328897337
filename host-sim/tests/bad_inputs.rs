//! The hostile inputs of issue 17 against `host-sim`: each is refused up front with a message
//! that names the key (and, from a file, its line), never a panic, an abort or NaN audio.

use std::path::{Path, PathBuf};
use std::process::Command;

use host_sim::scenario::Scenario;

const BASE: &str = r#"sample_rate_hz = 48000
duration_s = 10.0
[drone]
preset = "dji-mini-2"
[path]
kind = "square"
side_m = 4.0
start = [1.0, 1.0]
height_m = 2.0
[room]
size_m = [10.0, 10.0, 4.0]
[[array]]
id = 1
position = [3.0, 0.5, 0.05]
"#;

/// BASE's square path without its height (a continuous kind replaces it).
const SQUARE: &str = "kind = \"square\"\nside_m = 4.0\nstart = [1.0, 1.0]";

/// BASE with `from` replaced by `to` (which must occur).
fn edit(from: &str, to: &str) -> String {
    assert!(BASE.contains(from), "{from}");
    BASE.replacen(from, to, 1)
}

fn refused(text: &str) -> String {
    match Scenario::from_toml(text, "t") {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn the_base_scenario_is_fine() {
    let s = Scenario::from_toml(BASE, "t").unwrap();
    assert_eq!(s.arrays.len(), 1);
}

#[test]
fn every_scenario_input_of_the_issue_is_refused_by_key() {
    let cases: Vec<(String, &str)> = vec![
        (edit("side_m = 4.0", "side_m = 4.0\nloops = 4000000000"), "path.loops 4000000000 must be 1 to 1000"),
        (edit("height_m = 2.0", "height_m = 2.0\nmax_accel_mps2 = 1e-300"), "path.max_accel_mps2"),
        (edit("side_m = 4.0", "side_m = 1e300"), "path.side_m"),
        (edit("height_m = 2.0", "height_m = 1e6"), "path.height_m"),
        (format!("{BASE}[diffuse_noise]\nspl_db = 40.0\ndirections = 10000000\n"), "diffuse_noise.directions"),
        (edit("position = [3.0, 0.5, 0.05]", "position = [1e300, 0.5, 0.05]"), "array[0].position"),
        (edit("position = [3.0, 0.5, 0.05]", "position = [30.0, 0.5, 0.05]"), "outside the room"),
        (edit("preset = \"dji-mini-2\"", "preset = \"dji-mini-2\"\ninertia_kgm2 = [1e-300, 1e-3, 1e-3]"), "drone.inertia_kgm2[0]"),
        (format!("{BASE}[[noise]]\nposition = [nan, 1.0, 1.0]\ncentre_hz = 500.0\nspl_db = 50.0\n"), "noise[0].position"),
        (format!("{BASE}[[noise]]\nposition = [5.0, 1.0, 1.0]\ncentre_hz = 500.0\nspl_db = 1000.0\n"), "noise[0].spl_db"),
        (edit("position = [3.0, 0.5, 0.05]", "position = [3.0, 0.5, 0.05]\ngain_mismatch_db = 1e6"), "array[0].gain_mismatch_db"),
        (edit("preset = \"dji-mini-2\"", "preset = \"dji-mini-2\"\nmass_kg = 1e9"), "drone.mass_kg"),
        (edit("preset = \"dji-mini-2\"", "preset = \"dji-mini-2\"\nspl_1m_db = 1e5"), "drone.spl_1m_db"),
        // The DSP runs at 16 and 48 kHz only: `fly` and `analyze` would refuse it afterwards.
        (edit("sample_rate_hz = 48000", "sample_rate_hz = 44100"), "on-chip pipeline refuses this array at 44100 Hz"),
        // A microphone fault on a microphone the array does not have.
        (edit("position = [3.0, 0.5, 0.05]", "position = [3.0, 0.5, 0.05]\ndead_mics = [6]"), "name microphone 6, but it has 6"),
        (edit("size_m = [10.0, 10.0, 4.0]", "size_m = [10.0, 10.0, 4.0]\nrt60_s = 0.8\nabsorption = 0.2"), "give absorption or rt60_s, not both"),
        (edit("size_m = [10.0, 10.0, 4.0]", "size_m = [10.0, 10.0, 4.0]\nrt60_s = -1.0"), "room.rt60_s -1 must lie"),
        (edit("size_m = [10.0, 10.0, 4.0]", "size_m = [10.0, 10.0, 4.0]\nreflection_order = 13"), "room.reflection_order 13"),
        // The beacon is not rendered into a late reverberant tail.
        (
            format!("{}[[beacon]]\nposition = [5.0, 5.0, 0.3]\nlevel_db = 60.0\nperiod_s = 1.0\n", edit("size_m = [10.0, 10.0, 4.0]", "size_m = [10.0, 10.0, 4.0]\nrt60_s = 0.8")),
            "[[beacon]] in a room with a late reverberant tail",
        ),
        (
            edit("position = [3.0, 0.5, 0.05]", "position = [3.0, 0.5, 0.05]\npositions = [[0.0, 0.0], [0.5, 0.0], [0.0, 0.5], [0.5, 0.5]]"),
            "on-chip pipeline refuses",
        ),
        // The continuous kinds' numbers (a NaN angle or an infinite centre panicked in the
        // path's geometry once).
        (edit(SQUARE, "kind = \"circle\"\ncentre = [5.0, 5.0]\nradius_m = 2.0\nstart_deg = nan"), "path.start_deg NaN"),
        (edit(SQUARE, "kind = \"circle\"\ncentre = [inf, 5.0]\nradius_m = 2.0"), "path.centre [inf, 5.0]"),
        (edit(SQUARE, "kind = \"eight\"\ncentre = [5.0, 5.0]\nlength_m = 4.0\naxis_deg = -inf"), "path.axis_deg"),
        (
            edit(SQUARE, "kind = \"walk\"\nposition = [5.0, 5.0, 2.0]\narea_min = [nan, 1.0, 1.0]\narea_max = [9.0, 9.0, 3.0]"),
            "path.area_min",
        ),
        // Where a drone cannot be: outside the room, inside a solid box, on an array.
        (edit("side_m = 4.0", "side_m = 12.0"), "path leaves the room"),
        (
            format!("{BASE}[[obstacle]]\nname = \"crate\"\nmin = [2.5, 0.5, 1.5]\nmax = [3.5, 1.5, 2.5]\n"),
            "path passes through obstacle `crate`",
        ),
        (edit(SQUARE, "kind = \"hover\"\nposition = [3.0, 0.5, 0.2]"), "path comes within 0.25 m of array 1's centre"),
    ];
    for (text, message) in &cases {
        let e = refused(text);
        assert!(e.contains(message), "expected {message:?} in: {e}");
    }
}

#[test]
fn a_refused_value_is_named_with_its_file_and_line() {
    let path = scratch("loops.toml");
    std::fs::write(&path, edit("side_m = 4.0", "side_m = 4.0\nloops = 4000000000")).unwrap();
    let e = format!("{:#}", Scenario::load(&path).unwrap_err());
    // `loops` is on line 8 of the file.
    assert!(e.starts_with(&format!("{}:8: path.loops", path.display())), "{e}");
    let path = scratch("array.toml");
    std::fs::write(&path, edit("position = [3.0, 0.5, 0.05]", "position = [1e300, 0.5, 0.05]"))
        .unwrap();
    let e = format!("{:#}", Scenario::load(&path).unwrap_err());
    assert!(e.starts_with(&format!("{}:14: array[0].position", path.display())), "{e}");
    // An array's own check names the line of its `id`.
    let path = scratch("drift.toml");
    let drift =
        edit("position = [3.0, 0.5, 0.05]", "position = [3.0, 0.5, 0.05]\nclock_drift_ppm = nan");
    std::fs::write(&path, drift).unwrap();
    let e = format!("{:#}", Scenario::load(&path).unwrap_err());
    assert!(e.starts_with(&format!("{}:13: array 1: clock_drift_ppm NaN", path.display())), "{e}");
    // The second obstacle's, a noise source's, the diffuse noise's and the air's own checks:
    // the line of the key at fault (BASE has 14 lines; the additions follow).
    let extra = [
        (
            "[[obstacle]]\nmin = [1.0, 1.0, 0.0]\nmax = [2.0, 2.0, 1.0]\n\
             [[obstacle]]\nname = \"shelf\"\nmin = [3.0, 3.0, 0.0]\nmax = [2.0, 4.0, 1.0]",
            "20: obstacle[1].min must be below max on every axis (obstacle `shelf`)",
        ),
        (
            "[[obstacle]]\nmin = [1.0, 1.0, 0.0]\nmax = [2.0, 2.0, 1.0]\nloss_db = -3.0",
            "18: obstacle[0].loss_db",
        ),
        (
            "[[noise]]\nposition = [1.0, 1.0, 1.0]\ncentre_hz = 100.0\nbandwidth_hz = 10.0\n\
             spl_db = 60.0\n[[noise]]\nposition = [1.0, 2.0, 1.0]\ncentre_hz = 30000.0\n\
             bandwidth_hz = 10.0\nspl_db = 60.0",
            "22: noise[1].centre_hz: the band 30000 Hz",
        ),
        (
            "[[noise]]\nposition = [1.0, 1.0, 1.0]\ncentre_hz = 100.0\nbandwidth_hz = 10.0\n\
             spl_db = 60.0\ndistance_m = -1.0",
            "20: noise[0].distance_m must be positive",
        ),
        ("[diffuse_noise]\nspl_db = 60.0\ndirections = 0", "17: diffuse_noise.directions"),
        ("[air]\nhumidity_percent = 120.0", "16: air.humidity_percent must be 0 to 100 %"),
        (
            "[[array]]\nid = 2\nposition = [3.0, 0.55, 0.05]",
            "16: array 2: position is 0.050 m from array 1's",
        ),
    ];
    for (i, (table, want)) in extra.iter().enumerate() {
        let path = scratch(&format!("item{i}.toml"));
        std::fs::write(&path, format!("{BASE}{table}\n")).unwrap();
        let e = format!("{:#}", Scenario::load(&path).unwrap_err());
        assert!(e.starts_with(&format!("{}:{want}", path.display())), "{e}");
    }
    // A room's absorption of the wrong length names the surfaces' order.
    let path = scratch("absorption.toml");
    let three = "size_m = [10.0, 10.0, 4.0]\nabsorption = [0.1, 0.2, 0.3]";
    std::fs::write(&path, edit("size_m = [10.0, 10.0, 4.0]", three)).unwrap();
    let e = format!("{:#}", Scenario::load(&path).unwrap_err());
    let want = "12: absorption: invalid length 3, expected a number (every surface) or an array \
                of 6 numbers (walls x = 0, x = Lx, y = 0, y = Ly, floor, ceiling)";
    assert!(e.starts_with(&format!("{}:{want}", path.display())), "{e}");
    // The TOML parser's own errors too, on one line.
    let path = scratch("typo.toml");
    std::fs::write(&path, edit("height_m = 2.0", "height_m = 2.0\nspeeed = 2")).unwrap();
    let e = format!("{:#}", Scenario::load(&path).unwrap_err());
    assert!(e.starts_with(&format!("{}:10: unknown field `speeed`", path.display())), "{e}");
    assert!(!e.contains('\n'), "{e}");
    // A wrong type in a file built on a `base` names its own line, as in a plain file.
    std::fs::write(scratch("base.toml"), BASE).unwrap();
    let path = scratch("child.toml");
    std::fs::write(&path, "base = \"base.toml\"\n\n[air]\ntemperature_c = \"warm\"\n").unwrap();
    let e = format!("{:#}", Scenario::load(&path).unwrap_err());
    assert!(e.starts_with(&format!("{}:4: temperature_c: invalid type", path.display())), "{e}");
    // A `base` that names the file itself: one message, not the chain eight times.
    let path = scratch("loop.toml");
    std::fs::write(&path, "base = \"loop.toml\"\n").unwrap();
    let e = format!("{:#}", Scenario::load(&path).unwrap_err());
    assert!(e.contains("loops back to it") && e.matches("loop.toml").count() <= 3, "{e}");
}

#[test]
fn coordinates_of_the_wrong_count_are_refused_at_their_line() {
    // serde reads `[f64; 3]` from the first three numbers of a longer array and drops the rest;
    // a scenario file must say what it meant instead.
    let cases = [
        (
            "position = [3.0, 0.5, 0.05]",
            "position = [3.0, 0.5, 0.05, 9.0]",
            14,
            "invalid length 4, expected an array of 3 numbers",
        ),
        (
            "start = [1.0, 1.0]",
            "start = [1.0]",
            8,
            "invalid length 1, expected an array of 2 numbers",
        ),
        (
            "size_m = [10.0, 10.0, 4.0]",
            "size_m = [10.0, 10.0, 4.0, 1.0]",
            11,
            "invalid length 4, expected an array of 3 numbers",
        ),
    ];
    for (i, (from, to, line, count)) in cases.iter().enumerate() {
        let path = scratch(&format!("count{i}.toml"));
        std::fs::write(&path, edit(from, to)).unwrap();
        let e = format!("{:#}", Scenario::load(&path).unwrap_err());
        assert!(e.starts_with(&format!("{}:{line}:", path.display())), "{e}");
        assert!(e.contains(count), "{e}");
    }
    let path = scratch("count-obstacle.toml");
    let obstacle = "[[obstacle]]\nmin = [1.0, 1.0, 0.0, 5.0]\nmax = [2.0, 2.0, 1.0]\n";
    std::fs::write(&path, format!("{BASE}{obstacle}")).unwrap();
    let e = format!("{:#}", Scenario::load(&path).unwrap_err());
    assert!(e.starts_with(&format!("{}:16:", path.display())), "{e}");
    // A drone profile's own vectors too.
    let e = refused(&edit(
        "preset = \"dji-mini-2\"",
        "preset = \"dji-mini-2\"\ninertia_kgm2 = [0.001, 0.001, 0.002, 7.0]",
    ));
    assert!(e.contains("invalid length 4, expected an array of 3 numbers"), "{e}");
}

#[test]
fn a_zenith_survey_on_the_flights_own_seed_is_refused_before_anything_is_written() {
    let scenario = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/square10-los.toml");
    let out = scratch("same-seed");
    // square10-los.toml flies seed 10.
    let run = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("fly")
        .arg(&scenario)
        .args(["--zenith-survey", "10", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{stderr}");
    assert!(stderr.contains("--zenith-survey 10 is the flight's own seed"), "{stderr}");
    assert!(!out.exists(), "{} was created", out.display());
}

#[test]
fn memory_is_estimated_and_a_run_past_the_limit_is_refused_up_front() {
    // The issue measured ~190 MB per simulated minute for one 6-mic array when the whole run
    // was held; streamed, a minute needs the flight log and the truth (~25 MB) and windows of
    // the sources' signals that do not depend on the duration.
    let est = |d: f64| {
        let text = edit("duration_s = 10.0", &format!("duration_s = {d}"))
            .replace("side_m = 4.0", "side_m = 4.0\nloops = 200");
        Scenario::from_toml(&text, "t").unwrap().memory_estimate_bytes() as f64 / 1e6
    };
    let (minute, two) = (est(60.0), est(120.0));
    assert!((15.0..=60.0).contains(&minute), "{minute} MB for a minute");
    let per_minute = two - minute;
    assert!((20.0..=30.0).contains(&per_minute), "{per_minute} MB per further minute");
    let path = scratch("hour.toml");
    let hour = edit("duration_s = 10.0", "duration_s = 3600.0")
        .replace("side_m = 4.0", "side_m = 4.0\nloops = 200");
    std::fs::write(&path, hour).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("simulate")
        .arg(&path)
        .arg("--out")
        .arg(scratch("hour-out"))
        .args(["--max-memory-mb", "1000"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("needs about") && stderr.contains("--max-memory-mb 1000"), "{stderr}");
    assert!(!scratch("hour-out").exists(), "nothing written");
    // `fly` refuses it the same way, before simulating.
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("fly")
        .arg(&path)
        .arg("--out")
        .arg(scratch("hour-fly"))
        .args(["--max-memory-mb", "1000"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("needs about"), "{stderr}");
    assert!(!scratch("hour-fly").exists(), "nothing written");
}

#[test]
fn analyze_refuses_a_nan_sample_by_its_index() {
    let path = scratch("nan.wav");
    let spec = hound::WavSpec {
        channels: 6,
        sample_rate: 48_000,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(&path, spec).unwrap();
    for k in 0..6 * 4800 {
        let x = if k == 6 * 1000 + 2 { f32::NAN } else { 0.01 * ((k as f32) * 0.1).sin() };
        w.write_sample(x).unwrap();
    }
    w.finalize().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["analyze", "--array", "respeaker6"])
        .arg(&path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("sample 1000 of channel 2"), "{stderr}");
    assert!(stderr.contains("NaN"), "{stderr}");
}
