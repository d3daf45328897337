//! `host-sim bench` on the CI-sized suite (`host-sim/suites/ci.toml`): every family × seed ×
//! filter ran, the summary is the mean ± sd of the per-run rows, nothing from the truth reached
//! a run's site file, and the truth file holds the drawn airframe.
use std::path::Path;
use std::process::Command;

use host_sim::eval::metrics::CLASSES;

fn column(header: &str, name: &str) -> usize {
    header.split(',').position(|c| c == name).unwrap_or_else(|| panic!("no column {name}"))
}

#[test]
fn ci_suite_runs_every_seed_and_filter_and_summarises_them() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("aim-bench-ci-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let status = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("bench")
        .arg(root.join("suites/ci.toml"))
        .arg("--out")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());

    let runs = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    let mut lines = runs.lines();
    let header = lines.next().unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    // One family × two evaluation seeds × two filters; the tuning seed never ran.
    assert_eq!(rows.len(), 4, "{runs}");
    let seed = column(header, "seed");
    let mut seeds: Vec<&str> = rows.iter().map(|r| r[seed]).collect();
    seeds.sort();
    assert_eq!(seeds, ["2", "2", "3", "3"]);
    let (mean, filter, avail) =
        (column(header, "mean_m"), column(header, "filter"), column(header, "availability"));
    for r in &rows {
        let m: f64 = r[mean].parse().unwrap();
        assert!(m.is_finite() && m > 0.0, "{r:?}");
        let a: f64 = r[avail].parse().unwrap();
        assert!((0.0..=1.0).contains(&a), "{r:?}");
        // The accuracy is the recalls' mean weighted by each true class's fixes, so it lies
        // between the smallest and the largest recall of the classes the run has.
        let acc: f64 = r[column(header, "motion_accuracy")].parse().unwrap();
        let recalls: Vec<f64> = CLASSES
            .iter()
            .filter_map(|c| r[column(header, &format!("recall_{}", c.as_str()))].parse().ok())
            .collect();
        assert!(!recalls.is_empty(), "{r:?}");
        let lo = recalls.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = recalls.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert!(lo - 1e-4 <= acc && acc <= hi + 1e-4, "{r:?}");
    }

    // The summary is the mean and sample sd over seeds of the per-run figures.
    let summary = std::fs::read_to_string(out.join("summary.csv")).unwrap();
    let mut sl = summary.lines();
    let sh = sl.next().unwrap();
    let srows: Vec<Vec<&str>> = sl.map(|l| l.split(',').collect()).collect();
    assert_eq!(srows.len(), 2, "{summary}");
    for s in &srows {
        let f = s[column(sh, "filter")];
        let x: Vec<f64> =
            rows.iter().filter(|r| r[filter] == f).map(|r| r[mean].parse().unwrap()).collect();
        assert_eq!(x.len(), 2);
        let m = (x[0] + x[1]) / 2.0;
        let sd = (x[0] - x[1]).abs() / 2f64.sqrt();
        let got_m: f64 = s[column(sh, "mean_m")].parse().unwrap();
        let got_sd: f64 = s[column(sh, "mean_m_sd")].parse().unwrap();
        assert!((got_m - m).abs() < 2e-4 && (got_sd - sd).abs() < 2e-4, "{s:?} vs {m} ± {sd}");
        assert_eq!(s[column(sh, "seeds")], "2");
    }
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(md.contains("| short-leg | aim | 2 |"), "{md}");
    assert!(md.contains("| family | filter | hover | yaw | horizontal | vertical |"), "{md}");

    // Truth stays in truth: the site file names no clock and no airframe key; the truth file
    // holds the airframe this seed drew.
    for seed in [2, 3] {
        let dir = out.join(format!("runs/short-leg/seed-{seed}"));
        let site = std::fs::read_to_string(dir.join("site.toml")).unwrap();
        for key in ["clock", "drift", "wake", "thrust", "cg_offset", "jitter", "chipped"] {
            assert!(!site.contains(key), "site.toml of seed {seed} mentions {key}:\n{site}");
        }
        let truth = std::fs::read_to_string(dir.join("truth.toml")).unwrap();
        assert!(truth.contains("[airframe]") && truth.contains("wake_gain"), "{truth}");
        assert!(truth.contains("clock_offset_s"), "{truth}");
    }
    let a = std::fs::read_to_string(out.join("runs/short-leg/seed-2/truth.toml")).unwrap();
    let b = std::fs::read_to_string(out.join("runs/short-leg/seed-3/truth.toml")).unwrap();
    assert_ne!(a, b, "two seeds drew the same airframe");

    // `--rescore`: the stored frames tracked again give the same figures (the truth read back
    // at truth.csv's printed precision moves an error by micrometres at most), and no new
    // simulation ran (the re-scored directory holds no frames of its own).
    let again = out.with_extension("rescored");
    let _ = std::fs::remove_dir_all(&again);
    let status = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("bench")
        .arg(root.join("suites/ci.toml"))
        .arg("--out")
        .arg(&again)
        .arg("--rescore")
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let rescored = std::fs::read_to_string(again.join("runs.csv")).unwrap();
    let rrows: Vec<Vec<&str>> = rescored.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rrows.len(), rows.len(), "{rescored}");
    for (a, b) in rows.iter().zip(&rrows) {
        assert_eq!((a[seed], a[filter]), (b[seed], b[filter]));
        let (x, y): (f64, f64) = (a[mean].parse().unwrap(), b[mean].parse().unwrap());
        assert!((x - y).abs() < 1e-3, "{a:?} vs rescored {b:?}");
        assert_eq!(a[avail], b[avail]);
    }
    assert!(!again.join("runs/short-leg/seed-2/frames-1.aimraw").exists());
    // A directory without the stored runs is one error, before any run, naming what is
    // missing.
    let missing = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("bench")
        .arg(root.join("suites/ci.toml"))
        .arg("--out")
        .arg(&again)
        .arg("--rescore")
        .arg(again.join("nowhere"))
        .output()
        .unwrap();
    assert!(!missing.status.success());
    let err = String::from_utf8_lossy(&missing.stderr);
    assert!(
        err.contains("no recorded run runs/short-leg/seed-") && err.contains("2 of 2"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    let _ = std::fs::remove_dir_all(&again);
    let _ = std::fs::remove_dir_all(&out);
}
