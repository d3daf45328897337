//! `host-sim fly` measures the product's path: its fixes are, line for line, what
//! `aim replay DIR/frames-<id>.aimraw --site DIR/site.toml` prints for the frames it wrote.
//!
//! The binary `host-sim fly` runs on a short flight; the replay is the code `aim replay` runs
//! (`Site::load` of the site file, the bundled profile, the default tracker and intake, the
//! recording's bytes through `Session::track_reader`, the bundled drone classifier), printed
//! with `Fix::to_json` as `aim
//! replay` prints it. (`aim track` against the `aim replay` binary: tracker/tests/track_pty.rs.)

use std::path::PathBuf;
use std::process::Command;

use aim_tracker::filter::FilterKind;
use aim_tracker::intake::IntakeConfig;
use aim_tracker::link::{self, FrameSource};
use aim_tracker::profile::Profile;
use aim_tracker::session::Session;
use aim_tracker::site::Site;
use aim_tracker::tracker::{Tracker, TrackerConfig};

const SCENARIO: &str = r#"
seed = 5
[drone]
preset = "dji-mini-2"
[path]
kind = "waypoints"
points = [[3.0, 2.0, 1.5], [6.0, 2.0, 1.5], [6.0, 4.0, 1.5]]
hover_start_s = 3.0
hover_end_s = 1.0
[[array]]
id = 4
position = [1.0, 0.5, 0.05]
"#;

/// What `aim replay FRAMES --site SITE --filter KIND` prints on stdout.
fn replay(frames: &std::path::Path, site: &std::path::Path, kind: FilterKind) -> String {
    let site = Site::load(site).unwrap();
    let tracker =
        Tracker::new(site.clone(), Profile::dji_mini_2(), kind, TrackerConfig::default()).unwrap();
    // `aim replay`'s default drone classifier: the bundled model, the profile free to follow.
    let model = aim_tracker::id::default_model();
    let profiles = aim_tracker::id::class_profiles(None, &model.classes).unwrap();
    let identifier = aim_tracker::session::Identifier::new(model, profiles).unwrap();
    let mut session =
        Session::new(tracker, site, IntakeConfig::default()).with_identifier(identifier);
    let mut source = FrameSource::new(link::open_input(frames.to_str().unwrap()).unwrap());
    let mut out = String::new();
    session
        .track_reader(&mut source, &mut |f| {
            out.push_str(&f.to_json());
            out.push('\n');
            Ok(())
        })
        .unwrap();
    out
}

#[test]
fn fly_fixes_equal_aim_replay_of_its_frames() {
    let dir = std::env::temp_dir().join(format!("aim-fly-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scenario = dir.join("short.toml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let out: PathBuf = dir.join("out");
    let run = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("fly")
        .arg(&scenario)
        .args(["--filter", "both", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let frames = out.join("frames-4.aimraw");
    for (name, kind) in [("paper", FilterKind::Paper), ("aim", FilterKind::Aim)] {
        let flown = std::fs::read_to_string(out.join(name).join("fixes.jsonl")).unwrap();
        let replayed = replay(&frames, &out.join("site.toml"), kind);
        assert!(flown.lines().count() > 50, "{name}: {flown}");
        assert_eq!(flown, replayed, "{name}: fly and replay differ");
        // track.csv holds the same fixes.
        let csv = std::fs::read_to_string(out.join(name).join("track.csv")).unwrap();
        let rows: Vec<String> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').take(4).collect::<Vec<_>>().join(","))
            .collect();
        let fixes: Vec<String> = flown
            .lines()
            .map(|l| {
                let v: serde_json::Value = serde_json::from_str(l).unwrap();
                ["t", "x", "y", "z"].map(|k| format!("{:.3}", v[k].as_f64().unwrap())).join(",")
            })
            .collect();
        assert_eq!(rows, fixes, "{name}: track.csv");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
