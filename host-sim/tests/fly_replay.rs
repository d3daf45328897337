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
    replay_with(frames, site, kind, None)
}

/// What `aim replay FRAMES... --site SITE --filter KIND` prints for several recordings (read
/// as one link by `link::Merged`).
fn replay_merged(frames: &[PathBuf], site: &std::path::Path, kind: FilterKind) -> String {
    let paths: Vec<String> = frames.iter().map(|f| f.display().to_string()).collect();
    let merged = link::Merged::open(&paths, &Site::load(site).unwrap()).unwrap();
    let source = FrameSource::new(merged);
    replay_source(source, site, kind, None)
}

/// [`replay`] with `--profile NAME` when `profile` is given (the classifier then only names
/// the drone).
fn replay_with(
    frames: &std::path::Path,
    site: &std::path::Path,
    kind: FilterKind,
    profile: Option<&str>,
) -> String {
    let source = FrameSource::new(link::open_input(frames.to_str().unwrap()).unwrap());
    replay_source(source, site, kind, profile)
}

/// [`replay_with`] of any frame source.
fn replay_source<R: std::io::Read>(
    mut source: FrameSource<R>,
    site: &std::path::Path,
    kind: FilterKind,
    profile: Option<&str>,
) -> String {
    let site = Site::load(site).unwrap();
    let start = profile.map_or_else(Profile::dji_mini_2, |p| Profile::bundled(p).unwrap());
    let tracker = Tracker::new(site.clone(), start, kind, TrackerConfig::default()).unwrap();
    // `aim replay`'s default drone classifier: the bundled model, the profile free to follow.
    let model = aim_tracker::id::default_model();
    let profiles = match profile {
        Some(_) => Vec::new(),
        None => aim_tracker::id::class_profiles(None, &model.classes).unwrap(),
    };
    let identifier = aim_tracker::session::Identifier::new(model, profiles).unwrap();
    let mut session =
        Session::new(tracker, site, IntakeConfig::default()).with_identifier(identifier);
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

/// Runs `host-sim fly` on `scenario` (its text) with `--filter FILTER` into `dir/out`;
/// returns that folder and what it printed on stderr.
fn fly(dir: &std::path::Path, scenario: &str, filter: &str) -> (PathBuf, String) {
    let (out, _, stderr) = fly_args(dir, scenario, &["--filter", filter]);
    (out, stderr)
}

/// `host-sim fly SCENARIO ARGS --out dir/out`: that folder, stdout and stderr.
fn fly_args(dir: &std::path::Path, scenario: &str, args: &[&str]) -> (PathBuf, String, String) {
    std::fs::create_dir_all(dir).unwrap();
    let file = dir.join("scenario.toml");
    std::fs::write(&file, scenario).unwrap();
    let out = dir.join("out");
    let run = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("fly")
        .arg(&file)
        .args(args)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(run.status.success(), "{stderr}");
    (out, String::from_utf8_lossy(&run.stdout).into_owned(), stderr)
}

/// The mean error `fly` printed (`... aim: mean 0.85 m, ...`), m.
fn printed_mean(stdout: &str) -> f64 {
    let at = stdout.find("mean ").unwrap_or_else(|| panic!("no mean in {stdout}")) + 5;
    stdout[at..].split(' ').next().unwrap().parse().unwrap()
}

/// Three arrays around a short flight: `fly` tracks every array's recording merged, as
/// `aim replay frames-1.aimraw frames-2.aimraw frames-3.aimraw` does, bit for bit; the other
/// arrays' bearings pin the range the first array alone has to infer (oracle: the truth;
/// the tracked array alone on the same frames, `--no-fuse`, is worse); with the tracked
/// array's link down for 2 s the track goes on.
#[test]
fn several_arrays_fly_equals_the_merged_replay_and_crossing_rays_find_the_range() {
    let dir = std::env::temp_dir().join(format!("aim-fly-arrays-{}", std::process::id()));
    let arrays = SCENARIO.split("[[array]]").next().unwrap().to_string()
        + "[[array]]\nid = 1\nposition = [1.0, 0.5, 0.05]\n"
        + "[[array]]\nid = 2\nposition = [8.0, 1.0, 0.05]\nyaw_deg = 90.0\n"
        + "[[array]]\nid = 3\nposition = [4.0, 7.0, 0.05]\nyaw_deg = 200.0\n";
    let (out, stdout, _) = fly_args(&dir, &arrays, &["--filter", "aim"]);
    let fused = printed_mean(&stdout);
    let frames: Vec<PathBuf> = (1..=3).map(|i| out.join(format!("frames-{i}.aimraw"))).collect();
    let flown = std::fs::read_to_string(out.join("fixes.jsonl")).unwrap();
    assert!(flown.lines().count() > 50, "{flown}");
    assert_eq!(flown, replay_merged(&frames, &out.join("site.toml"), FilterKind::Aim));
    let (_, stdout, _) = fly_args(&dir.join("single"), &arrays, &["--filter", "aim", "--no-fuse"]);
    let single = printed_mean(&stdout);
    // Measured: fused 0.10 m, the first array alone 2.74 m (seed 5).
    assert!(fused < 0.4 && fused < 0.5 * single, "fused {fused} m, first array alone {single} m");
    // The tracked array's link down for 2 s mid-flight: another array takes over, no instant
    // goes without a fix.
    let unplugged = arrays.replace(
        "id = 1\nposition = [1.0, 0.5, 0.05]\n",
        "id = 1\nposition = [1.0, 0.5, 0.05]\nlink_down_s = [4.0, 6.0]\n",
    );
    assert_ne!(unplugged, arrays);
    let (out, stdout, _) = fly_args(&dir.join("unplugged"), &unplugged, &["--filter", "aim"]);
    assert!(stdout.contains("availability 100.0 %"), "{stdout}");
    assert!(printed_mean(&stdout) < 0.4, "{stdout}");
    let times: Vec<f64> = std::fs::read_to_string(out.join("fixes.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["t"].as_f64().unwrap())
        .collect();
    assert!(times.windows(2).all(|w| w[1] - w[0] < 0.15), "a gap in {times:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn fly_fixes_equal_aim_replay_of_its_frames() {
    let dir = std::env::temp_dir().join(format!("aim-fly-replay-{}", std::process::id()));
    let (out, _) = fly(&dir, SCENARIO, "both");
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

/// A drone of another type than the default: `aim replay` without `--profile` recognises it,
/// takes its profile and re-tracks the flight from its start, so from the switch on its fixes
/// are those of `aim replay --profile <type>`, bit for bit (oracle: the run given the right
/// profile from the start), and `host-sim fly` prints the same as `aim replay`.
#[test]
fn a_recognised_type_tracks_as_if_its_profile_was_given() {
    let dir = std::env::temp_dir().join(format!("aim-fly-type-{}", std::process::id()));
    // Long enough for the choice (10 s of verdicts) and a stretch of flight after it.
    let hexa = SCENARIO
        .replace("dji-mini-2", "hexacopter")
        .replace("hover_end_s = 1.0", "hover_end_s = 10.0");
    let (out, stderr) = fly(&dir, &hexa, "aim");
    assert!(stderr.contains("classified as hexacopter"), "{stderr}");
    let (frames, site) = (out.join("frames-4.aimraw"), out.join("site.toml"));
    let flown = std::fs::read_to_string(out.join("fixes.jsonl")).unwrap();
    let auto = replay(&frames, &site, FilterKind::Aim);
    assert_eq!(flown, auto, "fly and replay differ");
    let given = replay_with(&frames, &site, FilterKind::Aim, Some("hexacopter"));
    let (auto, given): (Vec<&str>, Vec<&str>) = (auto.lines().collect(), given.lines().collect());
    assert_eq!(auto.len(), given.len());
    // The switch needs 6 frames for a window and 40 verdicts: about 11.8 s of audio, and
    // the re-tracked fixes are the given profile's from there on.
    let same_from = (0..auto.len()).rev().find(|&i| auto[i] != given[i]).map_or(0, |i| i + 1);
    assert!(same_from <= 130, "fixes differ up to line {same_from}: {}", auto[same_from - 1]);
    assert!(auto.len() >= same_from + 50, "{} fixes, equal from {same_from}", auto.len());
    let _ = std::fs::remove_dir_all(&dir);
}
