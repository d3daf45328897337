//! The intake on crafted recordings (every frame passes the CRC): the time base, the window,
//! the reorder stage, and what reaches the fixes. Oracle: the audio the array actually sent —
//! at most one fix per output period of it, none across a silence, the track again after a
//! reboot — and causality (a fix uses no frame that arrived after its `available`).

mod common;

use aim_tracker::filter::FilterKind;
use aim_tracker::intake::{IntakeConfig, IntakeError};
use aim_tracker::link::FrameSource;
use aim_tracker::profile::Profile;
use aim_tracker::session::Session;
use aim_tracker::tracker::{Fix, Tracker, TrackerConfig};
use aim_wire::{Body, Doa, Frame, Header, Hello};
use common::{link, FS};
use proptest::prelude::*;

const PERIOD: f64 = 0.1;

/// The fix lies in the drone's direction from the array at time `truth_t` (within 5°; one
/// array's range is the filters' business, the direction is what the frames say).
fn on_bearing(f: &Fix, truth_t: f64) -> bool {
    let p = common::position(truth_t);
    let dot: f64 = (0..3).map(|i| p[i] * f.position[i]).sum();
    let cos = dot / (norm(p) * norm(f.position));
    cos > 5f64.to_radians().cos()
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn session() -> Session {
    let site = common::site();
    let tracker = Tracker::new(
        site.clone(),
        Profile::dji_mini_2(),
        FilterKind::Aim,
        TrackerConfig::default(),
    )
    .unwrap();
    Session::new(tracker, site, IntakeConfig::default())
}

/// Every frame through a fresh session (through the bytes, as `aim replay` reads them):
/// the fixes, the session, and the first intake error if any.
fn run(frames: &[Frame]) -> (Vec<Fix>, Session, Option<String>) {
    let mut s = session();
    let bytes = common::bytes(frames);
    let mut fixes = Vec::new();
    let result = s.track_reader(&mut FrameSource::new(&bytes[..]), &mut |f| {
        fixes.push(f.clone());
        Ok(())
    });
    (fixes, s, result.err().map(|e| format!("{e:#}")))
}

/// Seconds of audio the frames describe: the union of their spans on the array clock.
fn audio_s(frames: &[Frame]) -> (f64, usize) {
    let mut spans: Vec<(u64, u64)> = frames
        .iter()
        .filter_map(|f| {
            let span = match &f.body {
                Body::Doa(d) => d.span_samples,
                Body::Peaks(p) => p.span_samples,
                _ => return None,
            };
            (span > 0).then(|| {
                let s = f.header.sample_index;
                (s, s.saturating_add(u64::from(span)))
            })
        })
        .collect();
    spans.sort_unstable();
    let (mut total, mut pieces, mut cur): (u64, usize, Option<(u64, u64)>) = (0, 0, None);
    for (a, b) in spans {
        cur = match cur {
            Some((ca, cb)) if a <= cb => Some((ca, cb.max(b))),
            Some((ca, cb)) => {
                total += cb - ca;
                pieces += 1;
                Some((a, b))
            }
            None => Some((a, b)),
        };
    }
    if let Some((a, b)) = cur {
        total += b - a;
        pieces += 1;
    }
    (total as f64 / FS as f64, pieces)
}

/// The oracle every crafted recording meets: fixes in strictly increasing time, each available
/// no earlier than it describes, and at most one per output period of audio actually sent.
fn check_bounded(frames: &[Frame], fixes: &[Fix]) {
    assert!(fixes.windows(2).all(|w| w[1].t > w[0].t + 0.5 * PERIOD), "one fix per instant");
    assert!(fixes.iter().all(|f| f.available >= f.t), "available before the instant");
    let (audio, pieces) = audio_s(frames);
    let bound = audio / PERIOD + pieces as f64;
    assert!(fixes.len() as f64 <= bound, "{} fixes for {audio} s of audio", fixes.len());
}

#[test]
fn a_clean_link_tracks_in_order_with_bounded_latency() {
    let mut seq = 0;
    let frames = link(0, 20 * FS, &mut seq, 1);
    let (fixes, s, err) = run(&frames);
    assert!(err.is_none(), "{err:?}");
    check_bounded(&frames, &fixes);
    let i = *s.intake_stats();
    assert_eq!((i.late, i.out_of_window, i.bad_span, i.new_epochs, i.gaps), (0, 0, 0, 0, 0));
    // Every Doa and Peaks frame became an input; the Peaks frames were not dropped.
    let inputs = frames.iter().filter(|f| matches!(f.body, Body::Doa(_) | Body::Peaks(_))).count();
    assert_eq!(i.inputs, inputs as u64);
    // A fix per period from the first bearing to the last input (the aim filter needs no
    // warm-up beyond a bearing).
    assert!(fixes.len() >= 190, "{} fixes", fixes.len());
    let f = s.fix_stats();
    // Latency: the reorder hold (0.3 s) plus at most one Doa frame (0.171 s) and the last
    // period; only the last fixes (emitted at the end of the stream) are less late.
    assert!(f.max_latency_s <= 0.3 + 0.171 + PERIOD + 1e-9, "{f:?}");
    assert!(f.mean_latency_s >= 0.3, "{f:?}");
    assert!(fixes.iter().filter(|f| f.t > 1.0).all(|f| on_bearing(f, f.t)), "off the drone");
}

#[test]
fn a_fix_uses_no_frame_that_arrived_after_it_became_available() {
    let mut seq = 0;
    let frames = link(0, 12 * FS, &mut seq, 2);
    // Frame by frame: which fixes each frame made available, and the end of its audio.
    let mut s = session();
    let mut emitted: Vec<(usize, Fix)> = Vec::new();
    for (k, f) in frames.iter().enumerate() {
        emitted.extend(s.push(f).unwrap().into_iter().map(|x| (k, x)));
    }
    emitted.extend(s.finish().into_iter().map(|x| (frames.len(), x)));
    assert!(frames.len() > 120);
    for &cut in &[30, 57, 88, 120] {
        // A session that never saw the frames from `cut` on gives the same fixes up to there.
        let mut prefix = session();
        let mut got = Vec::new();
        for f in &frames[..cut] {
            got.extend(prefix.push(f).unwrap());
        }
        let want: Vec<&Fix> = emitted.iter().filter(|(k, _)| *k < cut).map(|(_, f)| f).collect();
        assert_eq!(got.iter().collect::<Vec<_>>(), want, "cut at frame {cut}");
        assert!(!want.is_empty());
        // `available` is the end of the newest frame's audio at that moment.
        let newest_end = frames[..cut]
            .iter()
            .filter_map(|f| match &f.body {
                Body::Doa(d) => Some(f.header.sample_index + u64::from(d.span_samples)),
                Body::Peaks(p) => Some(f.header.sample_index + u64::from(p.span_samples)),
                _ => None,
            })
            .max()
            .unwrap();
        let last = want.last().unwrap();
        assert!(last.available <= newest_end as f64 / FS as f64 + 1e-9);
    }
}

#[test]
fn a_far_future_frame_is_set_aside_not_followed() {
    let mut seq = 0;
    let mut frames = link(0, 20 * FS, &mut seq, 3);
    let clean = run(&frames).0;
    let far = Frame {
        header: Header { array_id: 1, seq: 7, sample_index: 1 << 50 },
        body: Body::Doa(Doa { span_samples: 8192, ..Doa::new(0.1, 0.2, 0.1, 0.9) }),
    };
    frames.insert(100, far);
    let (fixes, s, err) = run(&frames);
    assert!(err.is_none(), "{err:?}");
    assert_eq!(s.intake_stats().out_of_window, 1);
    // The track is the clean one, fix for fix.
    assert_eq!(fixes, clean);
}

#[test]
fn a_hello_contradicting_the_site_is_an_error_naming_both() {
    let mut seq = 0;
    let mut frames = link(0, 10 * FS, &mut seq, 4);
    let hello = Frame {
        header: Header { array_id: 1, seq: 9, sample_index: 5 * FS },
        body: Body::Hello(Hello::new([0, 1, 0], 1, 1024, &[])),
    };
    frames.insert(80, hello);
    let (fixes, _, err) = run(&frames);
    let err = err.expect("a 1 Hz Hello against a 48 kHz site is an error");
    assert!(err.contains("1 Hz") && err.contains("48000 Hz"), "{err}");
    check_bounded(&frames[..80], &fixes);

    // The geometry too, against a site file that gives it.
    let site_text = format!(
        "{}positions = [[0.05, 0.0], [0.0, 0.05], [-0.05, 0.0], [0.0, -0.05]]\n",
        common::SITE_TOML
    );
    let site = aim_tracker::site::Site::parse(&site_text, "site.toml".as_ref()).unwrap();
    let mut intake = aim_tracker::intake::Intake::new(site, IntakeConfig::default());
    let hello = |m: &[[f32; 2]]| Frame {
        header: Header { array_id: 1, seq: 0, sample_index: 0 },
        body: Body::Hello(Hello::new([0, 1, 0], 48_000, 1024, m)),
    };
    let square = [[0.05, 0.0], [0.0, 0.05], [-0.05, 0.0], [0.0, -0.05]];
    assert!(intake.push(&hello(&square), &mut |_| {}).is_ok());
    let moved = [[0.06, 0.0], [0.0, 0.05], [-0.05, 0.0], [0.0, -0.05]];
    let e = intake.push(&hello(&moved), &mut |_| {}).unwrap_err();
    assert!(matches!(e, IntakeError::Geometry { .. }));
    let text = e.to_string();
    assert!(text.contains("0.06") && text.contains("0.05"), "{text}");
}

#[test]
fn after_a_reboot_the_track_starts_again_on_a_new_epoch() {
    let mut seq = 0;
    let mut frames = link(0, 15 * FS, &mut seq, 5);
    let first_boot = frames.len();
    let mut seq2 = 0; // the board's counters restart too
    frames.extend(link(0, 15 * FS, &mut seq2, 6));
    let (fixes, s, err) = run(&frames);
    assert!(err.is_none(), "{err:?}");
    // Each boot's audio bounds its own fixes.
    let split = fixes.iter().position(|f| f.t > 15.0).unwrap();
    check_bounded(&frames[..first_boot], &fixes[..split]);
    check_bounded(&frames[first_boot..], &fixes[split..]);
    let i = *s.intake_stats();
    assert_eq!((i.new_epochs, i.out_of_window, i.late), (1, 0, 0));
    // The second boot is placed after the first's last audio and the epoch gap.
    let gap = IntakeConfig::default().epoch_gap_s;
    let before = fixes.iter().filter(|f| f.t <= 15.0).count();
    let after: Vec<&Fix> = fixes.iter().filter(|f| f.t >= 15.0 + gap).collect();
    assert!(before >= 140 && after.len() >= 140, "{before} fixes before, {} after", after.len());
    assert!(fixes.iter().all(|f| !(15.0 + 1e-9..15.0 + gap).contains(&f.t)));
    // ... and tracks there (the second boot's clock starts at 0 again: the synthetic drone is
    // where it was at that time of the first boot).
    let t0 = after[0].t;
    assert!(after.iter().filter(|f| f.t > t0 + 1.0).all(|f| on_bearing(f, f.t - 15.0 - gap)));
}

#[test]
fn no_fix_is_invented_across_a_long_silence() {
    let mut seq = 0;
    let mut frames = link(0, 10 * FS, &mut seq, 7);
    frames.extend(link(610 * FS, 620 * FS, &mut seq, 8));
    let (fixes, s, err) = run(&frames);
    assert!(err.is_none(), "{err:?}");
    check_bounded(&frames, &fixes);
    assert_eq!(s.intake_stats().gaps, 1);
    // Nothing between the last audio before the gap and the first after it.
    assert!(fixes.iter().all(|f| f.t <= 10.0 || f.t >= 610.0), "a fix inside the silence");
    assert!(fixes.iter().filter(|f| f.t >= 610.0).count() >= 90);
}

/// `frames` with every Hello's boot count set to `boot`.
fn with_boot(frames: Vec<Frame>, boot: u32) -> Vec<Frame> {
    frames
        .into_iter()
        .map(|mut f| {
            if let Body::Hello(h) = &mut f.body {
                h.boot_count = boot;
            }
            f
        })
        .collect()
}

/// A frame with random header and body fields (all valid on the wire).
fn random_frame() -> impl Strategy<Value = Frame> {
    let header = (0u8..3, any::<u16>(), prop_oneof![0u64..2_000_000, any::<u64>()])
        .prop_map(|(array_id, seq, sample_index)| Header { array_id, seq, sample_index });
    let body = prop_oneof![
        (any::<u32>(), any::<i16>(), any::<u16>(), any::<u16>(), any::<u8>()).prop_map(
            |(span, az, zen, res, q)| Body::Doa(Doa {
                span_samples: span % 100_000,
                azimuth_cdeg: az,
                zenith_cdeg: zen,
                residual_csamples: res,
                quality: q,
                pairs_used: 3,
            })
        ),
        (any::<u32>(), any::<u32>()).prop_map(|(span, hz)| {
            let peak =
                aim_wire::Peak { freq_chz: hz % 100_000, amplitude_ddb: -200, harmonicity: 9 };
            Body::Peaks(aim_wire::Peaks {
                span_samples: span,
                bpf_chz: hz,
                peaks: [peak].into_iter().collect(),
                detection: aim_wire::Detection::Rotor,
                quality: [230].into_iter().collect(),
            })
        }),
        prop_oneof![Just(48_000u32), any::<u32>()].prop_map(|rate| Body::Hello(Hello::new(
            [0, 1, 0],
            rate,
            1024,
            &[]
        ))),
    ];
    (header, body).prop_map(|(header, body)| Frame { header, body })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Random frames (valid CRC, random fields) mixed into a clean link: the session ends, and
    /// its fixes stay within one per output period of the audio the frames describe.
    #[test]
    fn random_fields_never_flood(
        junk in proptest::collection::vec((0usize..240, random_frame()), 1..12),
        seed in 1u64..1000,
    ) {
        let mut seq = 0;
        let mut frames = link(0, 8 * FS, &mut seq, seed);
        for (at, f) in junk {
            let at = at.min(frames.len());
            frames.insert(at, f);
        }
        let (fixes, s, err) = run(&frames);
        if let Some(e) = &err {
            prop_assert!(e.contains("Hello"), "{}", e);
        }
        prop_assert!(fixes.windows(2).all(|w| w[1].t > w[0].t + 0.5 * PERIOD));
        let (audio, pieces) = audio_s(&frames);
        // Two boots of overlapping clocks count their audio twice.
        let epochs = 1.0 + s.intake_stats().new_epochs as f64;
        prop_assert!(
            fixes.len() as f64 <= epochs * (audio / PERIOD + pieces as f64),
            "{} fixes for {} s of audio", fixes.len(), audio
        );
    }
}

#[test]
fn a_hello_with_a_new_boot_count_starts_a_new_epoch_even_inside_the_window() {
    // A board that crashes 0.8 s after start and boots again: the second boot's sample indices
    // fall inside the first boot's plausibility window, so only the Hello's boot count tells.
    let mut seq = 0;
    let mut frames = with_boot(link(0, 38_400, &mut seq, 5), 1);
    let first_boot = frames.len();
    let mut seq2 = 0;
    frames.extend(with_boot(link(0, 15 * FS, &mut seq2, 6), 2));
    let (fixes, s, err) = run(&frames);
    assert!(err.is_none(), "{err:?}");
    let i = *s.intake_stats();
    assert_eq!((i.new_epochs, i.reboots_announced, i.late), (1, 1, 0), "{i:?}");
    // Nothing of the second boot is placed before the first boot's last audio and the gap.
    let gap = IntakeConfig::default().epoch_gap_s;
    let first_end = 38_400.0 / FS as f64;
    assert!(fixes.iter().all(|f| f.t <= first_end + 1e-9 || f.t >= first_end + gap - 1e-9));
    let after = fixes.iter().filter(|f| f.t >= first_end + gap).count();
    assert!(after >= 140, "{after} fixes after the reboot");
    check_bounded(&frames[first_boot..], &fixes[fixes.len() - after..]);
}

#[test]
fn a_frame_a_second_or_two_ahead_costs_only_itself() {
    // A frame whose sample index is wrong by 0.6–2 s (it passes the CRC): set aside, the rest
    // of the track is the clean one, fix for fix.
    let mut seq = 0;
    let frames = link(0, 20 * FS, &mut seq, 3);
    let clean = run(&frames).0;
    for ahead_s in [0.6, 1.0, 1.5, 2.0] {
        let mut bad = frames.clone();
        let i = bad.iter().position(|f| matches!(f.body, Body::Doa(_)) && f.header.seq > 150);
        let mut moved = bad[i.unwrap()].clone();
        moved.header.sample_index += (ahead_s * FS as f64) as u64;
        bad.insert(i.unwrap() + 1, moved);
        let (fixes, s, err) = run(&bad);
        assert!(err.is_none(), "{err:?}");
        let st = *s.intake_stats();
        assert_eq!(
            (st.out_of_window, st.late, st.new_epochs, st.gaps),
            (1, 0, 0, 0),
            "{ahead_s} s: {st:?}"
        );
        assert_eq!(fixes, clean, "{ahead_s} s ahead");
    }
}

#[test]
fn a_hello_announcing_a_reboot_while_the_count_goes_on_is_withdrawn() {
    // A Hello with a new boot count and sample index 0 in the middle of a boot, the frames after
    // it going on with the old count: no new time base, every fix at its own time.
    let mut seq = 0;
    let mut frames = link(0, 20 * FS, &mut seq, 3);
    let clean = run(&frames).0;
    let i = frames.iter().position(|f| f.header.sample_index > 10 * FS).unwrap();
    let liar = Frame {
        header: Header { array_id: 1, seq: 999, sample_index: 0 },
        body: Body::Hello(Hello {
            boot_count: 999_999,
            ..Hello::new([0, 1, 0], FS as u32, 1024, &[])
        }),
    };
    frames.insert(i, liar);
    let (fixes, s, err) = run(&frames);
    assert!(err.is_none(), "{err:?}");
    let st = *s.intake_stats();
    assert_eq!((st.new_epochs, st.reboots_announced, st.reboots_withdrawn), (0, 0, 1), "{st:?}");
    // The reorder stage released the old boot's inputs at the Hello: a few that followed are
    // late. Every fix is at a time of the clean track, on the drone's bearing.
    assert!(st.late <= 6, "{st:?}");
    assert!(fixes.len() + 3 >= clean.len(), "{} fixes against {}", fixes.len(), clean.len());
    let times: Vec<f64> = clean.iter().map(|f| f.t).collect();
    assert!(fixes.iter().all(|f| times.iter().any(|t| (t - f.t).abs() < 1e-9)));
    assert!(fixes.iter().filter(|f| f.t > 2.0).all(|f| on_bearing(f, f.t)));
}

/// Where a frame's audio ends, sample index.
fn frame_end(f: &Frame) -> u64 {
    f.header.sample_index
        + match &f.body {
            Body::Doa(d) => u64::from(d.span_samples),
            Body::Peaks(p) => u64::from(p.span_samples),
            _ => 0,
        }
}

#[test]
fn frames_lost_on_the_link_cost_a_wait_not_a_new_time_base() {
    // Half a second of frames lost right after a Peaks frame (whose 0.512 s span is longer
    // than the window): the frames after the hole wait for confirmation and go on with the
    // same time base, every fix at a time of the clean track.
    let mut seq = 0;
    let frames = link(0, 20 * FS, &mut seq, 3);
    let clean = run(&frames).0;
    let p = frames
        .iter()
        .position(|f| matches!(f.body, Body::Peaks(_)) && frame_end(f) > 10 * FS)
        .unwrap();
    let n = frame_end(&frames[p]);
    let hole = |f: &&Frame| {
        matches!(f.body, Body::Doa(_) | Body::Peaks(_))
            && frame_end(f) > n
            && frame_end(f) <= n + FS / 2
    };
    let lossy: Vec<Frame> = frames.iter().filter(|f| !hole(f)).cloned().collect();
    assert!(frames.len() - lossy.len() >= 3);
    let (fixes, s, err) = run(&lossy);
    assert!(err.is_none(), "{err:?}");
    let st = *s.intake_stats();
    assert_eq!((st.new_epochs, st.gaps), (0, 1), "{st:?}");
    let times: Vec<f64> = clean.iter().map(|f| f.t).collect();
    assert!(fixes.iter().all(|f| times.iter().any(|t| (t - f.t).abs() < 1e-9)));
    assert_eq!(fixes.last().map(|f| f.t), clean.last().map(|f| f.t));
}

#[test]
fn a_reboot_soon_after_start_with_its_first_frames_lost_stays_a_reboot() {
    let mut seq = 0;
    let mut frames = with_boot(link(0, 57_600, &mut seq, 5), 1); // 1.2 s
    let mut seq2 = 0;
    let mut lost = 0;
    let second: Vec<Frame> = with_boot(link(0, 15 * FS, &mut seq2, 6), 2)
        .into_iter()
        .filter(|f| {
            let drop = matches!(f.body, Body::Doa(_)) && lost < 2;
            lost += usize::from(drop);
            !drop
        })
        .collect();
    frames.extend(second);
    let (fixes, s, err) = run(&frames);
    assert!(err.is_none(), "{err:?}");
    let st = *s.intake_stats();
    assert_eq!((st.new_epochs, st.reboots_announced, st.reboots_withdrawn), (1, 1, 0), "{st:?}");
    let gap = IntakeConfig::default().epoch_gap_s;
    let after = fixes.iter().filter(|f| f.t >= 1.2 + gap).count();
    assert!(after >= 130, "{after} fixes after the reboot");
}
