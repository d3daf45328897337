//! Issue 17, "aim track memory grows by about 3.8 MB per tracked hour (the per-output
//! diagnostics are never cleared)": past [`DIAGNOSTICS_KEPT`] output instants the diagnostics
//! stop growing (a ring of the newest), while the fixes keep coming. The 24 h replay's flat
//! memory is a benchmark (BENCHMARKS.md, "Long runs and memory"), not a test.
mod common;

use aim_tracker::filter::FilterKind;
use aim_tracker::intake::IntakeConfig;
use aim_tracker::profile::Profile;
use aim_tracker::session::Session;
use aim_tracker::tracker::{Tracker, TrackerConfig, DIAGNOSTICS_KEPT};

#[test]
fn diagnostics_are_a_ring_past_their_bound() {
    // 10 ms outputs over 75 s of link: 7500 instants, more than the ring holds.
    let period = 0.01;
    let config = TrackerConfig { output_period_s: period, ..TrackerConfig::default() };
    let site = common::site();
    let tracker =
        Tracker::new(site.clone(), Profile::dji_mini_2(), FilterKind::Aim, config).unwrap();
    let mut session = Session::new(tracker, site, IntakeConfig::default());
    let mut seq = 0;
    let frames = common::link(0, 75 * common::FS, &mut seq, 17);
    let mut fixes = 0usize;
    let mut most = 0usize;
    for f in &frames {
        fixes += session.push(f).unwrap().len();
        most = most.max(session.tracker().diagnostics().len());
    }
    fixes += session.finish().len();
    let kept = session.tracker().diagnostics().len();
    assert!(fixes > DIAGNOSTICS_KEPT + 500, "{fixes} fixes");
    assert_eq!(kept, DIAGNOSTICS_KEPT, "{fixes} fixes, {kept} diagnostics kept");
    assert!(most <= DIAGNOSTICS_KEPT, "{most}");
}
