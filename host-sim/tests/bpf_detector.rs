//! The BPF detector on its own simulated data (`host_sim::bpf_bench`): non-drone sources with
//! tones and noise give no BPF, a realistic drone gives its BPF. A small set (tuning seed 1,
//! 6 s clips); `host-sim bpf-bench` runs the full one.
use aim_dsp::bpf::{ANALYSIS_HOP, ANALYSIS_LEN, DECIMATED_RATE_HZ};
use host_sim::bpf_bench::{airframes, drone_case, negative_case, Score, HALLS, SETTLING_FRAMES};

/// Analyses of a 6 s clip: one per hop once the first window is full.
const ANALYSES_6S: usize = (6 * DECIMATED_RATE_HZ as usize - ANALYSIS_LEN) / ANALYSIS_HOP + 1;
use host_sim::tonal::Negative;

#[test]
fn machinery_noise_and_hum_give_no_bpf() {
    let mut total = Score::default();
    for kind in [
        Negative::PinkNoise,
        Negative::DeskFan,
        Negative::Pump,
        Negative::Vacuum,
        Negative::Machinery,
        Negative::Vehicle,
        Negative::MainsHum,
    ] {
        let s = negative_case(kind, HALLS[0], 65.0, 55.0, 6.0, 1).unwrap();
        // Every analysis of the 6 s clip but the settling ones is scored.
        assert_eq!(s.frames, ANALYSES_6S - SETTLING_FRAMES, "{}", kind.name());
        total += s;
    }
    let rate = total.with_bpf as f64 / total.frames as f64;
    println!(
        "non-drone (no speech/music): BPF in {:.1} % of {} frames",
        100.0 * rate,
        total.frames
    );
    assert!(rate <= 0.02, "BPF in {:.1} % of non-drone frames", 100.0 * rate);
}

#[test]
fn a_two_blade_quad_in_a_hall_is_heard_at_its_bpf() {
    let mini = airframes().into_iter().next().unwrap();
    let s = drone_case(&mini, HALLS[0], 3.0, 55.0, 6.0, 1).unwrap();
    let correct = s.correct as f64 / s.frames as f64;
    let octave = s.octave as f64 / s.frames as f64;
    println!("{}: {s:?}", mini.name);
    // Measured with this seed: see BENCHMARKS.md (BPF detector). Floors, not the targets.
    assert!(correct >= 0.6, "within 2 Hz in {:.1} %", 100.0 * correct);
    assert!(octave <= 0.05, "octave errors in {:.1} %", 100.0 * octave);
}

/// Weak lines: a three-blade quad 5 m away in the 1.6 s hall over a 70 dB background, where
/// its upper lines stand 2.5–3× over the floor (issue 19's misses). In the diffuse hall
/// (session 16) the detector of then found its BPF within 2 Hz in 20 of the 28 scored frames
/// of this 8 s clip; with a line search of ±0.2 % it found 19, with also the line ratio at 3.0
/// and the quality threshold at 0.35 (before session 9) 14 (`bpf_cache tune 8` +
/// `bpf_replay`, BENCHMARKS.md issue 19, session 16). Session 43's four-analysis start with
/// lower thresholds: 24 of 27. Oracle: the rotors' true BPFs from the
/// flight log.
#[test]
fn a_quad_over_a_loud_background_in_a_reverberant_hall_is_heard_at_its_bpf() {
    let bebop = airframes().into_iter().find(|p| p.name.starts_with("bebop")).unwrap();
    let s = drone_case(&bebop, HALLS[1], 5.0, 70.0, 8.0, 2).unwrap();
    let correct = s.correct as f64 / s.frames as f64;
    let octave = s.octave as f64 / s.frames as f64;
    println!("{}: {s:?}", bebop.name);
    assert!(correct >= 0.6, "within 2 Hz in {:.1} %", 100.0 * correct);
    assert!(octave <= 0.05, "octave errors in {:.1} %", 100.0 * octave);
}
