//! Issue 16 through the `aim id` command line: a small labelled dataset made by host-sim's
//! generator (`host_sim::iddata`, the six drone types and `none`), trained, evaluated and
//! classified by `aim id`, checked against the folders' labels; and the errors on bad input.
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use host_sim::iddata::{self, Options, SampleFormat};

fn aim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_aim")).arg("id").args(args).output().unwrap()
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn tmp(tag: &str) -> PathBuf {
    let d =
        Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("id-cli-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn train_eval_classify_on_simulated_recordings() {
    let root = tmp("flow");
    let (train, eval) = (root.join("train"), root.join("eval"));
    // Training: 1 s mono 16 kHz 16-bit clips, as a phone would record them; evaluation on
    // other seeds, half of it as the array records (48 kHz, 4 channels, float).
    let o = Options { clips_per_class: 24, seed_base: 10, ..Options::default() };
    iddata::write_dataset(&train, &o).unwrap();
    let e16 = Options { clips_per_class: 6, seed_base: 5_000, ..Options::default() };
    iddata::write_dataset(&eval, &e16).unwrap();
    let e48 = Options {
        clips_per_class: 3,
        seed_base: 6_000,
        rate_hz: 48_000,
        channels: 4,
        format: SampleFormat::F32,
        ..Options::default()
    };
    iddata::write_dataset(&eval, &e48).unwrap();
    let model = root.join("model.json");
    let out = aim(&["train", train.to_str().unwrap(), "--out", model.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(text(&out).contains("trained on 168 clips, 7 classes"), "{}", text(&out));

    let out = aim(&["eval", eval.to_str().unwrap(), "--model", model.to_str().unwrap(), "--json"]);
    assert!(out.status.success(), "{}", text(&out));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["clips"], 63);
    let classes: Vec<String> = serde_json::from_value(j["confusion"]["classes"].clone()).unwrap();
    let counts: Vec<Vec<usize>> = serde_json::from_value(j["confusion"]["counts"].clone()).unwrap();
    // Every clip is counted once, in its folder's row.
    for row in &counts {
        assert_eq!(row.iter().sum::<usize>(), 9);
    }
    // Far above chance (1/7) on unseen seeds, even from 24 clips a class.
    let accuracy = j["accuracy"].as_f64().unwrap();
    assert!(accuracy > 0.6, "accuracy {accuracy}: {j}");
    assert!(j["detection"]["auc"].as_f64().unwrap() > 0.8, "{j}");
    assert_eq!(j["detection"]["drone_clips"], 54);

    // classify: each file's class against its folder; the count of right answers is the
    // confusion matrix's diagonal (the same features and model).
    let files: Vec<(String, PathBuf)> = iddata::class_names()
        .into_iter()
        .flat_map(|c| {
            let dir = eval.join(c);
            let mut f: Vec<PathBuf> =
                std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
            f.sort();
            f.into_iter().map(move |p| (c.to_string(), p))
        })
        .collect();
    let mut args = vec!["classify".to_string(), "--model".into(), model.display().to_string()];
    args.extend(files.iter().map(|(_, p)| p.display().to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = aim(&args);
    assert!(out.status.success(), "{}", text(&out));
    let lines: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), files.len());
    let mut right = 0;
    for ((label, path), l) in files.iter().zip(&lines) {
        assert_eq!(l["file"], path.display().to_string());
        let p = l["probabilities"][label.as_str()].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&p));
        right += usize::from(l["class"] == label.as_str());
        let none = l["probabilities"]["none"].as_f64().unwrap();
        assert!((l["drone_probability"].as_f64().unwrap() - (1.0 - none)).abs() < 1e-6);
    }
    let diagonal: usize = (0..classes.len()).map(|c| counts[c][c]).sum();
    assert_eq!(right, diagonal);
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn per_recording_scores_the_live_verdict_once_per_recording() {
    // The bundled chip model. 2 s clips hold one window: scored per window or per recording,
    // the same numbers. 6 s clips hold three: three windows, one recording each.
    let root = tmp("perrec");
    let model = concat!(env!("CARGO_MANIFEST_DIR"), "/models/drone-id-chip.json");
    let (short, long) = (root.join("short"), root.join("long"));
    let o = Options { clips_per_class: 2, seed_base: 8_000_000, secs: 2.0, ..Options::default() };
    iddata::write_dataset(&short, &o).unwrap();
    let o = Options { clips_per_class: 1, seed_base: 8_100_000, secs: 6.0, ..Options::default() };
    iddata::write_dataset(&long, &o).unwrap();
    let eval = |dir: &PathBuf, extra: &[&str]| -> serde_json::Value {
        let mut args = vec!["eval", dir.to_str().unwrap(), "--model", model, "--json"];
        args.extend_from_slice(extra);
        let out = aim(&args);
        assert!(out.status.success(), "{}", text(&out));
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let (w, r) = (eval(&short, &[]), eval(&short, &["--per-recording"]));
    assert_eq!(w["clips"], 14);
    assert_eq!(r["clips"], 14);
    assert_eq!(r["per_recording"], true);
    assert_eq!(w["confusion"], r["confusion"]);
    assert_eq!(w["detection"], r["detection"]);
    let (w, r) = (eval(&long, &[]), eval(&long, &["--per-recording"]));
    assert_eq!(w["clips"], 21, "three windows of 6 frames in 22 frames");
    assert_eq!(r["clips"], 7);
    assert_eq!((&w["scored"], &r["scored"]), (&"windows".into(), &"recordings".into()));
    let one = eval(&long, &["--per-recording", "--decision-windows", "1"]);
    assert_eq!(one["clips"], 7);
    // `--scores`: one row per recording, whose verdicts are the confusion matrix's.
    let csv = root.join("scores.csv");
    let threshold: f64 =
        serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(model).unwrap())
            .unwrap()["drone_threshold"]
            .as_f64()
            .unwrap();
    let with = eval(&long, &["--per-recording", "--scores", csv.to_str().unwrap()]);
    assert_eq!(with["confusion"], r["confusion"]);
    let classes: Vec<String> = serde_json::from_value(r["confusion"]["classes"].clone()).unwrap();
    let mut counts = vec![vec![0u64; classes.len()]; classes.len()];
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("path,class,drone_probability,verdict"));
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        assert!(f[0].ends_with(".wav") && f[0].contains(f[1]), "{line}");
        let p: f64 = f[2].parse().unwrap();
        assert!((0.0..=1.0).contains(&p), "{line}");
        let at = |name: &str| classes.iter().position(|c| c == name).expect(line);
        counts[at(f[1])][at(f[3])] += 1;
        // The verdict is `none` exactly when the drone probability is not above the model's
        // threshold (read from the model file here).
        assert_eq!(f[3] == "none", p <= threshold + 5e-7, "{line} (threshold {threshold})");
    }
    let want: Vec<Vec<u64>> = serde_json::from_value(r["confusion"]["counts"].clone()).unwrap();
    assert_eq!(counts, want);
    // `classify` gives each recording the same verdict and drone probability.
    let rows: Vec<Vec<String>> =
        text.lines().skip(1).map(|l| l.split(',').map(String::from).collect()).collect();
    let mut args = vec!["classify", "--model", model];
    args.extend(rows.iter().map(|r| r[0].as_str()));
    let out = aim(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let verdicts: Vec<serde_json::Value> = std::str::from_utf8(&out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(verdicts.len(), rows.len());
    for (row, v) in rows.iter().zip(&verdicts) {
        assert_eq!((v["file"].as_str(), v["class"].as_str()), (Some(&*row[0]), Some(&*row[3])));
        let p = v["drone_probability"].as_f64().unwrap();
        assert!((p - row[2].parse::<f64>().unwrap()).abs() < 1e-6, "{row:?}: {v}");
    }
    assert!(aim(&["eval", long.to_str().unwrap(), "--model", model, "--scores", "x.csv"])
        .stderr
        .starts_with(b"error"));
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn bad_input_gets_a_clear_error() {
    let root = tmp("bad");
    let data = root.join("data");
    let o = Options { clips_per_class: 3, secs: 0.5, ..Options::default() };
    iddata::write_dataset(&data, &o).unwrap();
    let model = root.join("model.json");
    let ok =
        aim(&["train", data.to_str().unwrap(), "--out", model.to_str().unwrap(), "--epochs", "5"]);
    assert!(ok.status.success(), "{}", text(&ok));
    let fails = |args: &[&str], needle: &str| {
        let out = aim(args);
        assert_eq!(out.status.code(), Some(1), "{}", text(&out));
        assert!(text(&out).contains(needle), "wanted `{needle}` in: {}", text(&out));
    };
    // An unreadable recording in a known class, named.
    let m = model.to_str().unwrap();
    std::fs::write(data.join("none/zz.wav"), b"junk").unwrap();
    fails(&["eval", data.to_str().unwrap(), "--model", m], "zz.wav: not a readable WAV");
    std::fs::remove_file(data.join("none/zz.wav")).unwrap();
    // An empty class folder.
    std::fs::create_dir_all(data.join("empty")).unwrap();
    fails(&["train", data.to_str().unwrap(), "--out", "x.json"], "class `empty` has no .wav");
    // A class the model does not know.
    std::fs::copy(data.join("none/none-1000.wav"), data.join("empty/a.wav")).unwrap();
    fails(
        &["eval", data.to_str().unwrap(), "--model", m],
        "class `empty` is not one the model knows",
    );
    // WAV files straight in the folder.
    fails(
        &["train", data.join("none").to_str().unwrap(), "--out", "x.json"],
        "directly in the dataset folder",
    );
    // Not a WAV, not a model, a missing file.
    let junk = root.join("junk.wav");
    std::fs::write(&junk, b"RIFF....").unwrap();
    fails(&["classify", junk.to_str().unwrap(), "--model", m], "junk.wav: not a readable WAV");
    fails(
        &["classify", junk.to_str().unwrap(), "--model", junk.to_str().unwrap()],
        "not an aim id model",
    );
    fails(&["classify", "/nonexistent.wav", "--model", m], "/nonexistent.wav");
    std::fs::remove_dir_all(&root).unwrap();
}
