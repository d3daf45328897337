//! Per-microphone health through the product path: a simulated array with a faulty
//! microphone, its audio through the on-chip pipeline and the link's bytes, read back as
//! frames, and [`aim_tracker::status::Status`] (what `aim track` and `aim replay` report):
//! - a dead (all-zero) microphone: the direction fits lose its pairs and its level in `Health`
//!   is far under the others, so the array is flagged and the microphone named "dead";
//! - a microphone stuck at a constant: its pairs still carry weight in every fit (15 of 15: the
//!   constant's leakage, normalised by PHAT, looks like a signal), so only its level (no
//!   signal, a large DC) names it "stuck";
//! - a healthy array in the same flight raises no flag.
use aim_tracker::status::{MicFault, Status, MIC_HEALTH_WINDOW};
use host_sim::eval::link;
use host_sim::scenario::Scenario;

/// Each array's frames, as the link carries them, for the scenario `text`.
fn link_frames(text: &str) -> Vec<Vec<aim_wire::Frame>> {
    let scenario = Scenario::from_toml(text, "mic-health").unwrap();
    let (_, links) = link::simulate_links(
        &scenario,
        &host_sim::Options { threads: 2 },
        &indicatif::ProgressBar::hidden(),
        host_sim::DEFAULT_FULL_SCALE_PA,
    )
    .unwrap();
    links
        .iter()
        .map(|bytes| {
            let (frames, errors) = link::decode_frames(bytes);
            assert_eq!(errors, 0);
            frames
        })
        .collect()
}

#[test]
fn a_dead_microphone_is_flagged_and_a_healthy_array_is_not() {
    let text = r#"
        duration_s = 7.0
        seed = 3
        [drone]
        preset = "dji-mini-2"
        [path]
        kind = "hover"
        position = [1.0, 1.5, 2.0]
        [[array]]
        id = 1
        position = [0.0, 0.0, 0.05]
        dead_mics = [2]
        [[array]]
        id = 2
        position = [3.0, 0.0, 0.05]
        [render]
        rotor_sources = "centre"
        "#;
    let mut status = Status::new([(1, 6), (2, 6)]);
    for frames in link_frames(text) {
        for f in &frames {
            status.observe(f, 0.0);
        }
    }
    let summary: Vec<(u16, u64, Option<u8>, bool)> = [1u16, 2]
        .iter()
        .map(|&id| {
            let a = status.array(id).unwrap();
            (id, a.frames, a.mic.recent_max_pairs(), a.mic.suspect())
        })
        .collect();
    for &(id, frames, _, _) in &summary {
        assert!(frames > MIC_HEALTH_WINDOW as u64 + 5, "array {id}: {summary:?}");
    }
    // Six microphones: 15 pairs, 10 without one microphone.
    assert_eq!(summary[1].2, Some(15), "healthy array: {summary:?}");
    assert!(!summary[1].3, "healthy array flagged: {summary:?}");
    assert!(summary[0].3, "dead microphone not flagged: {summary:?}");
    assert_eq!(summary[0].2, Some(10), "dead microphone: {summary:?}");
    // The levels name it.
    assert_eq!(status.array(1).unwrap().mic.faults(), [(2, MicFault::Dead)]);
    assert!(status.array(2).unwrap().mic.faults().is_empty());
    let warnings = status.take_warnings();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].starts_with("array 1:"), "{warnings:?}");
}

#[test]
fn a_stuck_microphone_is_named_from_its_level() {
    let text = r#"
        duration_s = 6.0
        seed = 4
        [drone]
        preset = "dji-mini-2"
        [path]
        kind = "hover"
        position = [1.0, 1.5, 2.0]
        [[array]]
        id = 1
        position = [0.0, 0.0, 0.05]
        stuck_mics = [4]
        [render]
        rotor_sources = "centre"
        "#;
    let mut status = Status::new([(1, 6)]);
    let mut healths = 0;
    for f in &link_frames(text)[0] {
        if let aim_wire::Body::Health(h) = &f.body {
            healths += 1;
            assert_eq!(h.mic_levels.count, 6);
        }
        status.observe(f, 0.0);
    }
    assert!(healths >= 4, "{healths} Health frames");
    let mic = &status.array(1).unwrap().mic;
    // The fits keep every pair: they cannot see it.
    assert!(!mic.suspect(), "{:?}", mic.recent_max_pairs());
    assert_eq!(mic.faults(), [(4, MicFault::Stuck)]);
    let warnings = status.take_warnings();
    assert!(warnings.len() == 1 && warnings[0].contains("microphone 4 stuck"), "{warnings:?}");
}
