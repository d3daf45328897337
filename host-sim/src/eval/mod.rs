//! End-to-end evaluation: simulated recordings through the on-chip pipeline and the wire
//! format into the tracker, and the track against the truth.
//!
//! - [`link`]: an array's recording → TDM words → `aim-dsp` → frames encoded by
//!   `aim_wire::from_dsp` into the bytes a board would send, and decoded again;
//! - [`metrics`]: position error (mean, median, p90), availability, motion-class accuracy;
//! - [`plot`]: a PNG of the track against the truth (top view and height), no text needed;
//! - [`sync`]: the beacon clock model's error against the arrays' true clocks.

pub mod link;
pub mod metrics;
pub mod plot;
pub mod sync;

#[cfg(test)]
mod tests {
    use aim_tracker::filter::FilterKind;
    use aim_tracker::intake::IntakeConfig;
    use aim_tracker::link::FrameSource;
    use aim_tracker::profile::Profile;
    use aim_tracker::session::Session;
    use aim_tracker::tracker::{Tracker, TrackerConfig};

    use super::{link, metrics};
    use crate::scenario::Scenario;

    /// The whole chain on a short free-field flight: every byte decodes, every period after
    /// warm-up has a finite fix from both filters, and the LoS flag says what free field is.
    #[test]
    fn short_flight_end_to_end() {
        let text = r#"
seed = 3
[drone]
preset = "dji-mini-2"
[path]
kind = "waypoints"
points = [[2.0, 1.0, 1.5], [5.0, 1.0, 1.5]]
hover_start_s = 2.0
hover_end_s = 1.0
[[array]]
id = 4
position = [0.0, 0.0, 0.05]
"#;
        let scenario = Scenario::from_toml(text, "short").unwrap();
        let sim = crate::simulate(&scenario, &indicatif::ProgressBar::hidden()).unwrap();
        let site_text = sim.site.to_toml().unwrap();
        let site = aim_tracker::site::Site::parse(&site_text, "site.toml".as_ref()).unwrap();
        let bytes = link::link_bytes(&sim.arrays[0], crate::DEFAULT_FULL_SCALE_PA).unwrap();
        let (frames, errors) = link::decode_frames(&bytes);
        assert_eq!(errors, 0);
        assert!(frames.iter().any(|f| matches!(f.body, aim_wire::Body::Doa(_))));
        assert!(frames.iter().any(|f| matches!(f.body, aim_wire::Body::Peaks(_))));
        for kind in [FilterKind::Paper, FilterKind::Aim] {
            let tracker =
                Tracker::new(site.clone(), Profile::dji_mini_2(), kind, TrackerConfig::default())
                    .unwrap();
            let mut session = Session::new(tracker, site.clone(), IntakeConfig::default());
            let mut fixes = Vec::new();
            session
                .track_reader(&mut FrameSource::new(&bytes[..]), &mut |f| {
                    fixes.push(f.clone());
                    Ok(())
                })
                .unwrap();
            let i = session.intake_stats();
            assert_eq!(
                (i.late, i.out_of_window, i.bad_span, i.new_epochs, i.gaps),
                (0, 0, 0, 0, 0)
            );
            let (first, last) = session.inputs_span().unwrap();
            let s = metrics::evaluate(&fixes, &sim.truth, 0.1, first, last, 0);
            assert!(s.due > 40, "{s:?}");
            assert_eq!(s.availability, 1.0, "{kind:?}: {s:?}");
            assert!(fixes.iter().all(|f| f.position.iter().all(|x| x.is_finite())));
            assert!(s.los_accuracy.unwrap() >= 0.9, "{kind:?}: {s:?}");
            eprintln!("{kind:?}: {s:?}");
        }
    }
}
