//! `aim replay --mavlink udpout:…` received by an independent MAVLink implementation
//! (pymavlink, `tests/mavlink/receive.py`): every fix a rotor signature supports arrives once as a MAVLink 2
//! `VISION_POSITION_ESTIMATE` in the NED frame of the site's `[origin]` (x north, y east,
//! z down, metres), stamped in µs, with the fix's covariance turned into NED in the upper
//! triangle and the tracker's restart count as `reset_counter`; `HEARTBEAT`s come from the same
//! system. The oracle: the fixes of the same bytes through the library's session, turned into
//! NED here by projecting on the site's north, east and down unit vectors.
//!
//! Without pymavlink the test says so loudly and passes, except in CI (`CI=true`), where
//! `.ci/run` installs it and its absence fails.
mod common;

use std::io::{BufRead, BufReader, Read, Write as _};
use std::process::{Command, Stdio};

use aim_tracker::filter::FilterKind;
use aim_tracker::intake::IntakeConfig;
use aim_tracker::link::FrameSource;
use aim_tracker::profile::Profile;
use aim_tracker::session::Session;
use aim_tracker::site::Site;
use aim_tracker::tracker::{Fix, Tracker, TrackerConfig};
use serde_json::Value;

/// Heading of the site's +x axis from north, degrees: neither a multiple of 90° nor 45°, so a
/// swapped axis, sign or transposed rotation shows.
const HEADING_DEG: f64 = 30.0;
const ORIGIN: [f64; 3] = [1.0, 2.0, 0.5];

fn site_toml() -> String {
    format!(
        "{}\n[origin]\nposition = [{:?}, {:?}, {:?}]\nx_axis_from_north_deg = {HEADING_DEG:?}\n",
        common::SITE_TOML,
        ORIGIN[0],
        ORIGIN[1],
        ORIGIN[2]
    )
}

fn pymavlink_present() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import pymavlink"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        if std::env::var("CI").is_ok_and(|v| v == "true") {
            panic!("pymavlink is missing in CI: .ci/run installs it (pip install pymavlink)");
        }
        // Straight to the process's stderr: the test harness would swallow `eprintln!` of a
        // passing test.
        let _ = writeln!(
            std::io::stderr(),
            "\n*** SKIPPED mavlink_cli: pymavlink is not installed (python3 -m pip install \
             pymavlink); CI installs it and runs this test ***\n"
        );
    }
    ok
}

/// A flight with a 4 s silence (the array's sample index jumps): the tracker restarts once.
fn recording() -> Vec<u8> {
    let mut seq = 0;
    let mut frames = common::link(0, 12 * common::FS, &mut seq, 5);
    frames.extend(common::link(16 * common::FS, 28 * common::FS, &mut seq, 6));
    common::bytes(&frames)
}

/// The fixes of `bytes` through the library (what `aim replay` runs).
fn library_fixes(bytes: &[u8], site: &Site) -> Vec<Fix> {
    let tracker = Tracker::new(
        site.clone(),
        Profile::dji_mini_2(),
        FilterKind::Aim,
        TrackerConfig::default(),
    )
    .unwrap();
    let mut session = Session::new(tracker, site.clone(), IntakeConfig::default());
    let mut source = FrameSource::new(bytes);
    let mut fixes = Vec::new();
    session
        .track_reader(&mut source, &mut |f| {
            fixes.push(f.clone());
            Ok(())
        })
        .unwrap();
    fixes
}

#[test]
fn fixes_arrive_as_vision_position_estimates_in_ned() {
    if !pymavlink_present() {
        return;
    }
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    let id = std::process::id();
    let site_path = dir.join(format!("mavlink-site-{id}.toml"));
    let rec = dir.join(format!("mavlink-{id}.aimraw"));
    std::fs::write(&site_path, site_toml()).unwrap();
    let bytes = recording();
    std::fs::write(&rec, &bytes).unwrap();

    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/mavlink/receive.py");
    let mut receiver = Command::new("python3")
        .arg(script)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut out = BufReader::new(receiver.stdout.take().unwrap());
    let mut first = String::new();
    out.read_line(&mut first).unwrap();
    let port: u16 =
        first.trim().strip_prefix("port ").expect("receiver's port line").parse().unwrap();

    let udpout = format!("udpout:127.0.0.1:{port}");
    let aim = common::aim_replay_output(&rec, &site_path, &["--mavlink", &udpout]);
    if !aim.status.success() {
        let _ = receiver.kill();
        panic!("aim replay failed: {}", String::from_utf8_lossy(&aim.stderr));
    }
    let mut rest = String::new();
    out.read_to_string(&mut rest).unwrap();
    assert!(receiver.wait().unwrap().success());
    let messages: Vec<Value> = serde_json::from_str(rest.trim()).expect("receiver's JSON");

    let site = Site::parse(&site_toml(), "site.toml".as_ref()).unwrap();
    let fixes = library_fixes(&bytes, &site);
    // The JSON lines of the same run are those fixes.
    let lines: Vec<&str> = std::str::from_utf8(&aim.stdout).unwrap().lines().collect();
    assert_eq!(lines.len(), fixes.len());
    for (line, fix) in lines.iter().zip(&fixes) {
        assert_eq!(*line, fix.to_json());
    }
    assert!(fixes.len() > 100, "{} fixes", fixes.len());

    assert!(messages.iter().all(|m| m["type"] != "BAD_DATA"), "a message failed to parse");
    let vision: Vec<&Value> =
        messages.iter().filter(|m| m["mavpackettype"] == "VISION_POSITION_ESTIMATE").collect();
    let heartbeats: Vec<&Value> =
        messages.iter().filter(|m| m["mavpackettype"] == "HEARTBEAT").collect();
    // Fixes no rotor signature supports are withheld (the first ones, before the detector's
    // first decision); every other arrives once.
    let withheld = fixes.iter().filter(|f| !f.heard).count();
    let fixes: Vec<Fix> = fixes.into_iter().filter(|f| f.heard).collect();
    assert!(withheld < 20, "{withheld} fixes withheld");
    assert_eq!(vision.len(), fixes.len(), "one message per heard fix, each once");
    let stderr = String::from_utf8_lossy(&aim.stderr);
    let counts = format!(
        "{{\"kind\":\"mavlink\",\"sent\":{},\"withheld\":{withheld},\"failed\":0}}",
        fixes.len()
    );
    assert!(stderr.lines().any(|l| l == counts), "{stderr}");
    assert!(!heartbeats.is_empty(), "no HEARTBEAT");
    for h in &heartbeats {
        assert_eq!(h["type"], 18, "MAV_TYPE_ONBOARD_CONTROLLER: {h}");
        assert_eq!(h["autopilot"], 8, "MAV_AUTOPILOT_INVALID: {h}");
        assert_eq!((h["_sysid"].as_u64(), h["_compid"].as_u64()), (Some(1), Some(197)));
    }

    // The site's unit vectors, north, east and down, in site coordinates.
    let psi = HEADING_DEG.to_radians();
    let north = [psi.cos(), psi.sin(), 0.0];
    let east = [psi.sin(), -psi.cos(), 0.0];
    let down = [0.0, 0.0, -1.0];
    let axes = [north, east, down];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut resets_seen = Vec::new();
    for (m, fix) in vision.iter().zip(&fixes) {
        assert_eq!(m["_version2"], true, "MAVLink 2 (covariance and reset_counter are extensions)");
        assert_eq!((m["_sysid"].as_u64(), m["_compid"].as_u64()), (Some(1), Some(197)));
        // µs of the fix's instant.
        assert_eq!(m["usec"].as_u64().unwrap(), (fix.t * 1e6).round() as u64, "{m}");
        // Metres north, east, down of the origin.
        let d =
            [fix.position[0] - ORIGIN[0], fix.position[1] - ORIGIN[1], fix.position[2] - ORIGIN[2]];
        let got = [m["x"].as_f64().unwrap(), m["y"].as_f64().unwrap(), m["z"].as_f64().unwrap()];
        for k in 0..3 {
            let want = dot(axes[k], d);
            assert!((got[k] - want).abs() <= 1e-6 * (1.0 + want.abs()), "axis {k}: {got:?} {want}");
        }
        // Upper triangle, row-major, of the 6×6 pose covariance: position block = the fix's
        // covariance seen along north/east/down; attitude unknown (NaN → null).
        let cov: Vec<Option<f64>> =
            m["covariance"].as_array().unwrap().iter().map(Value::as_f64).collect();
        assert_eq!(cov.len(), 21);
        let c = &fix.covariance;
        let mut k = 0;
        for i in 0..6 {
            for j in i..6 {
                if i < 3 && j < 3 {
                    let want: f64 = (0..3)
                        .map(|a| (0..3).map(|b| axes[i][a] * c[a][b] * axes[j][b]).sum::<f64>())
                        .sum();
                    let got = cov[k].unwrap_or_else(|| panic!("covariance[{k}] is NaN: {m}"));
                    assert!(
                        (got - want).abs() <= 1e-5 * (1.0 + want.abs()),
                        "({i},{j}): {got} {want}"
                    );
                } else {
                    assert!(cov[k].is_none(), "attitude covariance ({i},{j}) must be unknown: {m}");
                }
                k += 1;
            }
        }
        // The variances add up to the fix's σ² (a rotation keeps the trace).
        let trace = cov[0].unwrap() + cov[6].unwrap() + cov[11].unwrap();
        let sigma2: f64 = fix.sigma.iter().map(|s| s * s).sum();
        assert!((trace - sigma2).abs() <= 1e-5 * sigma2.max(1.0), "{trace} {sigma2}");
        assert!(m["roll"].is_null() && m["pitch"].is_null() && m["yaw"].is_null(), "{m}");
        let r = m["reset_counter"].as_u64().unwrap();
        assert_eq!(r, u64::from(fix.resets));
        if resets_seen.last() != Some(&(r, fix.t >= 12.0)) {
            resets_seen.push((r, fix.t >= 12.0));
        }
    }
    // One track before the silence (reset_counter 0), one after it (1).
    assert_eq!(resets_seen, vec![(0, false), (1, true)]);
    let _ = std::fs::remove_file(&site_path);
    let _ = std::fs::remove_file(&rec);
}
