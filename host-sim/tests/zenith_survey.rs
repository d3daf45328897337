//! The zenith survey (`host_sim::survey`) and the site calibration it fits
//! (`aim_tracker::zenith`), against the truth: in a small hall whose ceiling image pulls the
//! zenith low, a correction fitted on one survey brings the zenith of another survey of the
//! same room (other noise, other microphones' mismatch) closer to the truth.
use std::path::Path;

use aim_tracker::zenith::{self, ZenithCorrection};
use host_sim::scenario::Scenario;
use host_sim::survey::Survey;

const HALL: &str = r#"
description = "test: a 9 m x 7 m x 3 m hall, one array on the floor"
[drone]
preset = "dji-mini-2"
[path]
kind = "waypoints"
points = [[2.0, 3.0, 1.5], [6.0, 3.0, 1.5]]
speed_mps = 1.0
[room]
size_m = [9.0, 7.0, 3.0]
absorption = [0.15, 0.15, 0.15, 0.15, 0.05, 0.1]
reflection_order = 1
[[array]]
id = 1
geometry = "respeaker-6mic"
position = [4.5, 1.5, 0.05]
"#;

/// Median |measured − true| zenith of a survey's frames, degrees, each frame's zenith first
/// corrected by `correction`.
fn median_error_deg(survey: &Survey, correction: &ZenithCorrection) -> f64 {
    let site = aim_tracker::site::Site::parse(&survey.site_text, Path::new("site.toml")).unwrap();
    let reference = zenith::Reference::parse(&survey.truth_csv, Path::new("truth.csv")).unwrap();
    let mut source = aim_tracker::link::FrameSource::new(survey.links[0].as_slice());
    let (bearings, _) = zenith::bearings_of(&site, &mut source).unwrap();
    let mut e: Vec<f64> = zenith::pairs(&site, &[], &bearings, &reference)
        .iter()
        .map(|(_, p)| (correction.correct(p.measured_rad) - p.true_rad).abs().to_degrees())
        .collect();
    assert!(e.len() > 100, "{} frames", e.len());
    e.sort_by(f64::total_cmp);
    e[e.len() / 2]
}

#[test]
fn a_surveys_correction_brings_another_surveys_zenith_closer_to_the_truth() {
    let dir = std::env::temp_dir().join(format!("aim-zenith-survey-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("hall.toml");
    std::fs::write(&path, HALL).unwrap();
    let scenario = Scenario::load(&path).unwrap();

    let a = host_sim::survey::calibrate(&scenario, 5, 0).unwrap();
    let b = host_sim::survey::calibrate(&scenario, 6, 0).unwrap();
    let fitted = a.corrections();
    assert_eq!(fitted.len(), 1, "one array, one correction");
    let correction = &fitted[0].1;
    assert!(correction.to_degrees().len() >= 4, "{:?}", a.fits[0].bins);

    let none = ZenithCorrection::default();
    let (raw_a, raw_b) = (median_error_deg(&a, &none), median_error_deg(&b, &none));
    let (cal_a, cal_b) = (median_error_deg(&a, correction), median_error_deg(&b, correction));
    // On its own survey (the sign of the correction) and on the other (it transfers).
    assert!(cal_a < 0.7 * raw_a, "own survey: {raw_a:.2}° → {cal_a:.2}°");
    assert!(cal_b < 0.8 * raw_b, "other survey: {raw_b:.2}° → {cal_b:.2}°");

    // The site file it writes carries the correction and reads back.
    let text =
        zenith::site_with_corrections(&a.site_text, Path::new("site.toml"), &fitted).unwrap();
    let site = aim_tracker::site::Site::parse(&text, Path::new("site.toml")).unwrap();
    assert_eq!(site.array(1).unwrap().zenith_correction.to_toml_line(), correction.to_toml_line());

    // Stored and read back, a survey is the same survey: its seed, its inputs, its fit.
    let stored = dir.join("survey-a");
    a.store(&stored).unwrap();
    let back = Survey::load_seeded(&stored, 5).unwrap();
    assert_eq!(back.seed, Some(5));
    assert_eq!(back.reference_csv, a.reference_csv);
    assert_eq!(back.links, a.links);
    let lines = |s: &Survey| -> Vec<_> {
        s.corrections().iter().map(|(id, c)| (*id, c.to_toml_line())).collect()
    };
    assert_eq!(lines(&back), lines(&a));
    // Reused for another seed, it is refused by name; without its reference, refused too.
    let Err(e) = Survey::load_seeded(&stored, 6) else { panic!("seed 6 accepted") };
    let e = format!("{e:#}");
    assert!(e.contains("surveyed with seed 5, not 6"), "{e}");
    std::fs::remove_file(stored.join("reference.csv")).unwrap();
    let Err(e) = Survey::load(&stored) else { panic!("loaded without its reference") };
    let e = format!("{e:#}");
    assert!(e.contains("has no reference.csv"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
