//! Accuracy of the spatial path against exact synthetic signals: pair delays (GCC-PHAT) and
//! direction of arrival, with white noise at a stated SNR and fixed seeds.
//!
//! SNR convention: signal power over the power of the added white noise *within the
//! 200 Hz – 6 kHz analysis band* (the full-band noise is 5.2 dB stronger at 48 kHz).

use crate::common;

use aim_dsp::{Config, Geometry, Output, Pipeline};
use common::{add_noise, rms, to_tdm, PeriodicSignal, Rng};

const FS: f64 = 48_000.0;
/// Samples per synthetic recording: 32 blocks, 4 averaging periods of 8 blocks, periodic.
const N: usize = 32_768;
/// Fraction of white-noise power inside 200 Hz – 6 kHz at 48 kHz.
const IN_BAND: f64 = (6000.0 - 200.0) / 24_000.0;

/// Harmonic comb (fundamental on the 65 536-point grid, 448 bins = 328.125 Hz) plus broadband.
fn drone_like(rng: &mut Rng, broadband_below_db: f64, harmonics: usize) -> PeriodicSignal {
    let mut s = PeriodicSignal::new(N);
    let amp = 0.02;
    for h in 1..=harmonics {
        s.add_tone_bin(448 * h, amp, 2.0 * std::f64::consts::PI * rng.uniform());
    }
    let comb_power = harmonics as f64 * amp * amp / 2.0;
    let bb_rms = (comb_power / 10f64.powf(broadband_below_db / 10.0)).sqrt();
    s.add_broadband(FS, 100.0, 8000.0, bb_rms, rng);
    s
}

/// Delays every channel, adds white noise at `snr_db` (in-band convention), returns TDM words.
fn render(signal: &PeriodicSignal, delays: &[f64], snr_db: f64, rng: &mut Rng) -> Vec<i32> {
    let mut channels: Vec<Vec<f64>> = delays.iter().map(|&d| signal.delayed(d)).collect();
    let p_signal = rms(&channels[0]).powi(2);
    let noise_rms = (p_signal / 10f64.powf(snr_db / 10.0) / IN_BAND).sqrt();
    for ch in &mut channels {
        add_noise(ch, noise_rms, rng);
    }
    to_tdm(&channels, 8)
}

#[test]
fn pair_delay_rms_error_at_10db_snr_is_below_a_tenth_of_a_sample() {
    let config = Config::new(Geometry::respeaker_4mic(), 48_000);
    let mut pipeline = Pipeline::new(&config).unwrap();
    let mut rng = Rng::new(0xD1A7);
    let (mut sq, mut count, mut worst) = (0.0f64, 0usize, 0.0f64);
    for _trial in 0..8 {
        // Broadband plus a harmonic comb of equal power.
        let signal = drone_like(&mut rng, 0.0, 10);
        let delays: Vec<f64> = (0..4).map(|_| -4.0 + 8.0 * rng.uniform()).collect();
        let words = render(&signal, &delays, 10.0, &mut rng);
        pipeline.configure(&config).unwrap();
        // One averaging period (8 blocks of 1024 frames of 8 words) per push.
        for period in words.chunks(8 * 1024 * 8) {
            pipeline.push(period, &mut |_| {});
            for (pair, est) in pipeline.pairs().iter().zip(pipeline.pair_delays()) {
                let truth = delays[pair.j as usize] - delays[pair.i as usize];
                let e = est.delay_samples as f64 - truth;
                sq += e * e;
                worst = worst.max(e.abs());
                count += 1;
            }
        }
    }
    let rms_error = (sq / count as f64).sqrt();
    println!("pair delay at 10 dB SNR: RMS error {rms_error:.4} samples, worst {worst:.4}, {count} estimates");
    assert_eq!(count, 8 * 4 * 6);
    assert!(rms_error <= 0.1, "RMS delay error {rms_error} samples");
}

fn angle_error_deg(a: f64, b: f64) -> f64 {
    let d = (a - b).to_degrees();
    (d + 180.0).rem_euclid(360.0) - 180.0
}

/// RMS azimuth and zenith errors (degrees) over 12 azimuths at one zenith, 6-mic circle.
fn direction_errors(zenith_deg: f64, seed: u64) -> (f64, f64, usize) {
    let geometry = Geometry::respeaker_6mic();
    let config = Config::new(geometry, 48_000);
    let mut pipeline = Pipeline::new(&config).unwrap();
    let mut rng = Rng::new(seed);
    let (mut sq_az, mut sq_zen, mut count) = (0.0f64, 0.0f64, 0usize);
    for a in 0..12 {
        let azimuth = (7.0 + 30.0 * a as f64).to_radians();
        let zenith = zenith_deg.to_radians();
        let u = [zenith.sin() * azimuth.cos(), zenith.sin() * azimuth.sin()];
        // Plane wave: mic i hears the source (p_i · u)/c earlier than the array centre.
        let delays: Vec<f64> = geometry
            .positions()
            .iter()
            .map(|p| -(p[0] as f64 * u[0] + p[1] as f64 * u[1]) / 343.0 * FS)
            .collect();
        let signal = drone_like(&mut rng, 10.0, 10);
        let snr: f64 = std::env::var("SNR").ok().and_then(|s| s.parse().ok()).unwrap_or(20.0);
        let words = render(&signal, &delays, snr, &mut rng);
        pipeline.configure(&config).unwrap();
        for o in common::run(&mut pipeline, &words) {
            if let Output::Doa(d) = o {
                sq_az += angle_error_deg(d.azimuth_rad as f64, azimuth).powi(2);
                sq_zen += (d.zenith_rad as f64 - zenith).to_degrees().powi(2);
                count += 1;
            }
        }
    }
    ((sq_az / count as f64).sqrt(), (sq_zen / count as f64).sqrt(), count)
}

#[test]
fn direction_rms_error_six_mic_circle_at_20db_snr() {
    let cases = [(10.0, 1.0), (30.0, 1.0), (45.0, 1.0), (60.0, 1.0), (80.0, 3.0)];
    let results: Vec<_> =
        cases.iter().map(|&(zenith, _)| direction_errors(zenith, 0xD0A + zenith as u64)).collect();
    for (&(zenith, _), &(az, zen, count)) in cases.iter().zip(&results) {
        println!("zenith {zenith:>4}°: RMS azimuth error {az:.3}°, RMS zenith error {zen:.3}° ({count} estimates)");
    }
    for ((zenith, zen_limit), (az, zen, count)) in cases.into_iter().zip(results) {
        assert_eq!(count, 12 * 4, "every period must give a Doa");
        assert!(zen <= zen_limit, "zenith {zenith}: RMS zenith error {zen}°");
        assert!(az <= 1.0, "zenith {zenith}: RMS azimuth error {az}°");
    }
}
