//! The beacon from loudspeaker to the chip's `Beacon` output: host-sim renders the speaker
//! (its own drifting clock) and a flying drone into three arrays at 5, 10 and 20 m (each with
//! its own clock); the aim-dsp pipeline runs on each array's TDM words; every detection is
//! compared with the geometric truth converted to that array's clock
//! (`BeaconSpeaker::reported_arrival_on_clock`: the emission's centre + straight path / c at
//! microphone 0, on the array's clock, less LEN/2 samples: what the chip reports).
//! Truth is used here, in the evaluation, only.
//!
//! `beacon_sweep` (ignored; run with `--ignored --nocapture`) prints the table of
//! BENCHMARKS.md "Beacon detection on the chip (issue 14)".
use host_sim::scenario::Scenario;

/// Distances of the three arrays from the speaker, m.
const DISTANCES_M: [f64; 3] = [5.0, 10.0, 20.0];

fn scenario(level_db: Option<f64>, seed: u64, duration_s: f64) -> Scenario {
    let beacon = level_db.map_or(String::new(), |l| {
        format!(
            r#"
            [[beacon]]
            position = [0.0, 0.0, 1.5]
            level_db = {l}
            clock_drift_ppm = 37.0
            start_s = 0.3
            "#
        )
    });
    // Arrays at the speaker's height, at 5 m (+x), 10 m (+y) and 20 m (+x); each clock with an
    // offset and a drift within ±100 ppm. The drone flies 12 m along y = 6 at 2 m height,
    // 4-8 m from the arrays.
    let text = format!(
        r#"
        duration_s = {duration_s}
        seed = {seed}
        [drone]
        preset = "dji-mini-2"
        [path]
        kind = "waypoints"
        points = [[2.0, 6.0, 2.0], [14.0, 6.0, 2.0], [2.0, 6.0, 2.0]]
        speed_mps = 1.5
        hover_start_s = 1.0
        {beacon}
        [[array]]
        id = 1
        geometry = "respeaker-4mic"
        phase_mismatch_us = {pm}
        position = [{d0}, 0.0, 1.5]
        clock_offset_s = 0.0123
        clock_drift_ppm = 55.0
        [[array]]
        id = 2
        geometry = "respeaker-4mic"
        phase_mismatch_us = {pm}
        position = [0.0, {d1}, 1.5]
        yaw_deg = 70.0
        clock_offset_s = -0.0377
        clock_drift_ppm = -80.0
        [[array]]
        id = 3
        geometry = "respeaker-4mic"
        phase_mismatch_us = {pm}
        position = [{d2}, 0.0, 1.5]
        yaw_deg = -20.0
        clock_offset_s = 0.2501
        clock_drift_ppm = 100.0
        [render]
        rotor_sources = "centre"
        "#,
        d0 = DISTANCES_M[0],
        d1 = DISTANCES_M[1],
        d2 = DISTANCES_M[2],
        pm = std::env::var("BEACON_PM").ok().and_then(|v| v.parse::<f64>().ok()).unwrap_or(2.0),
    );
    Scenario::from_toml(&text, "beacon-test").unwrap()
}

/// Per array: (arrival errors in µs of the detections matched to an emission, detections not
/// matched to any emission, emissions expected).
fn run(s: &Scenario) -> Vec<(Vec<f64>, usize, usize)> {
    let sim = host_sim::simulate(s, &host_sim::progress_bar("")).unwrap();
    let fs = f64::from(s.sample_rate_hz);
    let c = s.air.speed_of_sound_mps();
    let mut result = Vec::new();
    for (a, rec) in s.arrays.iter().zip(&sim.arrays) {
        let geometry = aim_dsp::Geometry::from_positions(
            &rec.positions.iter().map(|p| [p[0] as f32, p[1] as f32]).collect::<Vec<_>>(),
        )
        .unwrap();
        let config = aim_dsp::Config::new(geometry, s.sample_rate_hz);
        let mut p = aim_dsp::Pipeline::new(&config).unwrap();
        let words = rec.tdm_words(host_sim::DEFAULT_FULL_SCALE_PA, config.tdm_slots);
        let mut found = Vec::new();
        for chunk in words.chunks(256 * config.tdm_slots) {
            p.push(chunk, &mut |o| {
                if let aim_dsp::Output::Beacon(b) = o {
                    found.push(b);
                }
            });
        }
        let len_samples = rec.channels[0].len() as f64;
        let (mut errors, mut unmatched, mut expected) = (Vec::new(), 0, 0);
        for b in &s.beacons {
            // Emissions wholly heard within the recording, the last second excluded (the
            // detector reports about 0.2 s after the arrival).
            let truths: Vec<f64> = (0..)
                .map(|k| b.reported_arrival_on_clock(k, a, 0, c, fs))
                .take_while(|&n| n < len_samples)
                .filter(|&n| n > 0.0)
                .collect();
            expected += truths.iter().filter(|&&n| n + fs < len_samples).count();
            for d in &found {
                let got = d.sample_index as f64 + f64::from(d.fraction);
                match truths.iter().map(|t| got - t).find(|e| e.abs() < 0.25 * fs) {
                    Some(e) if got + fs < len_samples => errors.push(e / fs * 1e6),
                    Some(_) => {}
                    None => unmatched += 1,
                }
            }
        }
        if s.beacons.is_empty() {
            unmatched = found.len();
        }
        result.push((errors, unmatched, expected));
    }
    result
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    (mean, var.sqrt())
}

#[test]
fn arrival_at_60_db_is_within_the_carrier_bound() {
    // Bound: a quarter of the carrier period, 1/(4 · 18 kHz) = 13.9 µs, for every arrival (a
    // carrier-cycle slip or a reflection locking the peak elsewhere exceeds it), and the rms
    // error below 3 µs at 5 and 10 m (the host's 20 µs sync target needs a few µs per
    // arrival). Every emission heard is detected once, nothing else.
    // Microphone phase mismatch off (BEACON_PM unset → 0 here): a microphone's own delay error
    // (2 µs sd by default) is a calibration error of the array, outside the detector.
    std::env::set_var("BEACON_PM", "0");
    let s = scenario(Some(60.0), 41, 8.0);
    for (i, (errors, unmatched, expected)) in run(&s).into_iter().enumerate() {
        if DISTANCES_M[i] > 10.0 {
            // 20 m at 60 dB: detections are rare and slip carrier cycles (BENCHMARKS.md).
            continue;
        }
        let (mean, sd) = mean_sd(&errors);
        let rms = (mean * mean + sd * sd).sqrt();
        println!("{} m: {} of {expected}, {mean:.2} ± {sd:.2} µs", DISTANCES_M[i], errors.len());
        assert_eq!((errors.len(), unmatched), (expected, 0), "array at {} m", DISTANCES_M[i]);
        assert!(errors.iter().all(|e| e.abs() < 1e6 / (4.0 * 18_000.0)), "{errors:?}");
        if DISTANCES_M[i] <= 10.0 {
            assert!(rms < 3.0, "{} m: rms {rms} µs", DISTANCES_M[i]);
        }
    }
}

/// An arrival further than this from the truth counts as a false detection in the sweep, µs.
const FALSE_US: f64 = 100.0;

#[test]
#[ignore = "measurement: the BENCHMARKS.md table (several minutes)"]
fn beacon_sweep() {
    // Detections within ±0.25 s of an emission are matched to it; those within FALSE_US of the
    // truth are arrivals (their error is reported), the others and the unmatched ones are false.
    let seeds = [101u64, 102, 103];
    // A slip: an arrival a carrier cycle (55.6 µs) off, i.e. beyond a quarter period (13.9 µs).
    println!("level_db distance_m detected/expected false slips mean_us sd_us max_abs_us");
    for level in [40.0, 50.0, 60.0, 70.0] {
        let mut per = vec![(Vec::new(), 0usize, 0usize); DISTANCES_M.len()];
        for &seed in &seeds {
            for (i, (e, u, x)) in run(&scenario(Some(level), seed, 12.0)).into_iter().enumerate() {
                let (good, off): (Vec<f64>, Vec<f64>) =
                    e.into_iter().partition(|v| v.abs() <= FALSE_US);
                per[i].0.extend(good);
                per[i].1 += u + off.len();
                per[i].2 += x;
            }
        }
        for (i, (e, f, x)) in per.iter().enumerate() {
            let (mean, sd) = mean_sd(e);
            let max = e.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let slips = e.iter().filter(|v| v.abs() > 1e6 / (4.0 * 18_000.0)).count();
            println!(
                "{level:.0} {:.0} {}/{x} {f} {slips} {mean:.2} {sd:.2} {max:.2}",
                DISTANCES_M[i],
                e.len()
            );
        }
    }
    // False detections: the same flights without a beacon.
    let mut false_alarms = 0;
    let mut minutes = 0.0;
    for &seed in &seeds {
        let s = scenario(None, seed, 20.0);
        for (_, u, _) in run(&s) {
            false_alarms += u;
            minutes += s.duration_s / 60.0;
        }
    }
    println!("no beacon: {false_alarms} detections in {minutes:.1} array-minutes");
}

/// zigzag10-los (a room: arrays on the floor, the speaker under the ceiling; seed 20): every
/// array's arrivals against the straight path. Before the first-path search array 3 timed
/// the ceiling reflection, 1.97 ms late.
#[test]
#[ignore = "measurement: BENCHMARKS.md, beacon first path (about a minute)"]
fn zigzag10_first_path() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/zigzag10-los.toml");
    let s = Scenario::load(&path).unwrap();
    println!("array detected/expected unmatched mean_us sd_us max_abs_us");
    for (a, (errors, unmatched, expected)) in s.arrays.iter().zip(run(&s)) {
        let (mean, sd) = mean_sd(&errors);
        let max = errors.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        println!("{} {}/{expected} {unmatched} {mean:.2} {sd:.2} {max:.2}", a.id, errors.len());
        println!("  {:?}", &errors[..errors.len().min(8)]);
    }
}
