//! Snippets against an oracle: a pure tone's phase gives the stream's timing (the stamp plus
//! the documented group delay), its amplitude the filters' gain; the stream is contiguous.

use crate::common;

use aim_dsp::snippet::{GROUP_DELAY_INPUT_SAMPLES, SNIPPET_LEN};
use aim_dsp::{Config, Geometry, Output, Pipeline, Snippet};
use common::to_tdm;
use std::f64::consts::PI;

fn snippets(out: &[Output]) -> Vec<Snippet> {
    out.iter().filter_map(|o| if let Output::Snippet(x) = o { Some(*x) } else { None }).collect()
}

/// The snippets of `frames` input samples of a tone of `hz` at amplitude `amp` (fraction of
/// full scale), the same on every microphone, at `rate` Hz.
fn tone_snippets(rate: u32, hz: f64, amp: f64, frames: usize) -> Vec<Snippet> {
    let g = Geometry::respeaker_6mic();
    let x: Vec<f64> =
        (0..frames).map(|n| amp * (2.0 * PI * hz * n as f64 / f64::from(rate)).sin()).collect();
    let words = to_tdm(&vec![x; g.len()], 8);
    let mut p = Pipeline::new(&Config::new(g, rate)).unwrap();
    snippets(&common::run(&mut p, &words))
}

#[test]
fn a_tone_arrives_at_the_stamp_plus_the_group_delay() {
    for hz in [1000.0, 2500.0] {
        let amp = 0.25;
        let s = tone_snippets(48_000, hz, amp, 96_000);
        // Contiguous: 96 000 / 1 536 = 62 whole snippets, stamps one snippet apart.
        assert_eq!(s.len(), 62);
        for (k, x) in s.iter().enumerate() {
            assert_eq!((x.sample_index, x.decimation), (k as u64 * 1536, 6));
        }
        // After 0.5 s of settling: the complex amplitude of the tone against the stamps' clock.
        let (mut re, mut im, mut n) = (0.0, 0.0, 0.0);
        for x in &s[16..] {
            for j in 0..SNIPPET_LEN {
                let m = (x.sample_index + 6 * j as u64) as f64;
                let w = 2.0 * PI * hz * m / 48_000.0;
                let v = f64::from(x.value(j));
                re += v * w.sin();
                im += v * w.cos();
                n += 1.0;
            }
        }
        let gain = 2.0 * (re * re + im * im).sqrt() / n / amp;
        // v = a sin(w − φ): φ = atan2(−im, re); delay = φ / (2π f) in input samples.
        // Known modulo one period; the two tones' periods (48 and 19.2 samples) leave only
        // multiples of 96 samples, so unwrapping each near the constant tests it.
        let period = 48_000.0 / hz;
        let wrapped = (-im).atan2(re) / (2.0 * PI * hz) * 48_000.0;
        let expected = f64::from(GROUP_DELAY_INPUT_SAMPLES);
        let delay = wrapped + period * ((expected - wrapped) / period).round();
        println!("{hz} Hz: gain {gain:.4}, delay {delay:.3} input samples");
        assert!((delay - expected).abs() < 0.1, "delay {delay}");
        assert!((gain - 1.0).abs() < 0.02, "gain {gain}");
    }
}

#[test]
fn snippets_can_be_turned_off() {
    let g = Geometry::respeaker_4mic();
    let mut c = Config::new(g, 48_000);
    c.snippets = false;
    let words = to_tdm(&vec![vec![0.1; 30_000]; 4], 8);
    let out = common::run(&mut Pipeline::new(&c).unwrap(), &words);
    assert!(!out.is_empty() && snippets(&out).is_empty());
    c.snippets = true;
    let out = common::run(&mut Pipeline::new(&c).unwrap(), &words);
    assert_eq!(snippets(&out).len(), 30_000 / 1536);
}

#[test]
fn at_16_khz_the_snippets_are_8_khz_too() {
    let s = tone_snippets(16_000, 1000.0, 0.25, 16_000);
    assert_eq!(s.len(), 16_000 / 512);
    assert!(s.iter().all(|x| x.decimation == 2));
    assert_eq!(s[3].sample_index, 3 * 512);
}
