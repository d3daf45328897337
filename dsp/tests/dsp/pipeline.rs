//! Streaming behaviour of the pipeline: chunking, rates, stamps, other geometries and rates,
//! silence and clipping.

use crate::common;

use aim_dsp::{Config, Geometry, Output, Pipeline};
use common::{doas, to_tdm, Rng};

/// A plane wave of band-limited noise plus a harmonic comb near 328 Hz, 20 dB SNR, exact delays.
fn plane_wave(
    geometry: &Geometry,
    fs: f64,
    n: usize,
    az_deg: f64,
    zen_deg: f64,
    seed: u64,
) -> Vec<i32> {
    let high_hz = fs.min(16_000.0) * 0.45;
    to_tdm(&common::plane_wave(geometry, fs, n, (az_deg, zen_deg), 328, high_hz, seed), 8)
}

#[test]
fn outputs_do_not_depend_on_how_the_words_are_chunked() {
    let g = Geometry::respeaker_6mic();
    let words = plane_wave(&g, 48_000.0, 32_768, 120.0, 40.0, 1);
    let config = Config::new(g, 48_000);
    let mut whole = Pipeline::new(&config).unwrap();
    let mut a = Vec::new();
    whole.push(&words, &mut |o| a.push(o));
    let mut chunked = Pipeline::new(&config).unwrap();
    let b = common::run(&mut chunked, &words);
    assert!(!a.is_empty());
    assert_eq!(a, b, "identical bits whatever the chunking");
}

#[test]
fn output_rates_and_stamps_at_48_khz() {
    let g = Geometry::respeaker_6mic();
    let words = plane_wave(&g, 48_000.0, 65_536, 10.0, 30.0, 2);
    let mut p = Pipeline::new(&Config::new(g, 48_000)).unwrap();
    let out = common::run(&mut p, &words);
    let d = doas(&out);
    // 64 blocks of 1024, 8 blocks per DoA.
    assert_eq!(d.len(), 8);
    for (k, x) in d.iter().enumerate() {
        assert_eq!(x.sample_index, k as u64 * 8192);
        assert_eq!(x.span_samples, 8192);
    }
    let health: Vec<_> = out
        .iter()
        .filter_map(|o| if let Output::Health(h) = o { Some(*h) } else { None })
        .collect();
    assert_eq!(health.len(), 1); // every 48 blocks
    assert_eq!(health[0].blocks, 48);
    assert_eq!(health[0].clipped_samples, 0);
    assert!(health[0].peak_dbfs < -10.0 && health[0].peak_dbfs > -40.0, "{:?}", health[0]);
}

#[test]
fn sixteen_khz_and_other_geometries_find_the_direction() {
    let custom = Geometry::from_positions(&[
        [0.04, 0.0],
        [0.0, 0.03],
        [-0.05, 0.01],
        [-0.01, -0.045],
        [0.03, -0.03],
    ])
    .unwrap();
    for (g, fs) in [
        (Geometry::respeaker_4mic(), 16_000.0),
        (Geometry::respeaker_6mic(), 16_000.0),
        (Geometry::circle_8mic(), 48_000.0),
        (custom, 48_000.0),
    ] {
        for (az, zen) in [(-150.0f64, 35.0f64), (75.0, 65.0)] {
            let words = plane_wave(&g, fs, 32_768, az, zen, 3);
            let mut p = Pipeline::new(&Config::new(g, fs as u32)).unwrap();
            let d = doas(&common::run(&mut p, &words));
            assert!(d.len() >= 4, "{} mics at {fs}: {} DoA", g.len(), d.len());
            for x in &d {
                let daz =
                    ((x.azimuth_rad as f64).to_degrees() - az + 540.0).rem_euclid(360.0) - 180.0;
                let dzen = (x.zenith_rad as f64).to_degrees() - zen;
                assert!(
                    daz.abs() < 2.0 && dzen.abs() < 2.0,
                    "{} mics at {fs}, ({az}, {zen}): got {x:?}",
                    g.len()
                );
                assert!(x.residual < 0.2, "{x:?}");
            }
        }
    }
}

#[test]
fn silence_gives_no_direction_and_no_peaks_and_clipping_is_counted() {
    let config = Config::new(Geometry::respeaker_4mic(), 48_000);
    let mut p = Pipeline::new(&config).unwrap();
    let out = common::run(&mut p, &vec![0; 8 * 49_152]);
    assert!(doas(&out).is_empty());
    for o in &out {
        if let Output::Peaks(k) = o {
            assert_eq!(k.count, 0);
        }
    }
    // Full-scale square wave on mic 2: every sample clipped.
    let mut words = vec![0i32; 8 * 49_152];
    for (t, frame) in words.chunks_mut(8).enumerate() {
        frame[2] = if (t / 24) % 2 == 0 { 0x7FFF_FF00 } else { -0x7FFF_FF00 };
    }
    let mut p = Pipeline::new(&config).unwrap();
    let health: Vec<_> = common::run(&mut p, &words)
        .into_iter()
        .filter_map(|o| if let Output::Health(h) = o { Some(h) } else { None })
        .collect();
    assert_eq!(health[0].clipped_samples, 48 * 1024);
    assert!(health[0].peak_dbfs > -0.1);
}

#[test]
fn mfcc_outputs_follow_the_bpf_analyses_and_find_the_comb() {
    // The plane wave's comb sits on bin `n·328/fs` of the periodic signal: 48 kHz, 65 536
    // samples → bin 447, 327.39 Hz. One Mfcc per Peaks, same window, comb f0 within 0.5 Hz.
    let g = Geometry::respeaker_6mic();
    let (fs, n) = (48_000.0, 65_536);
    let words = plane_wave(&g, fs, n, 10.0, 30.0, 3);
    let hz = (n * 328 / fs as usize) as f64 * fs / n as f64;
    let mut config = Config::new(g, 48_000);
    let mut p = Pipeline::new(&config).unwrap();
    let out = common::run(&mut p, &words);
    let peaks: Vec<_> =
        out.iter().filter_map(|o| if let Output::Peaks(k) = o { Some(*k) } else { None }).collect();
    let mfcc: Vec<_> =
        out.iter().filter_map(|o| if let Output::Mfcc(f) = o { Some(*f) } else { None }).collect();
    assert!(peaks.len() >= 4, "{} Peaks", peaks.len());
    assert_eq!(mfcc.len(), peaks.len());
    for (f, k) in mfcc.iter().zip(&peaks) {
        assert_eq!((f.sample_index, f.span_samples), (k.sample_index, k.span_samples));
        let f0 = 250.0 * f64::from(f.harmonic.log2_f0).exp2();
        assert!((f0 - hz).abs() < 0.5, "comb f0 {f0} Hz, the signal's {hz} Hz");
        assert!(f.harmonic.salience_db > 10.0, "{:?}", f.harmonic);
    }
    // Every other analysis with `mfcc_interval` 2; none with 0.
    config.mfcc_interval = 2;
    let mut p = Pipeline::new(&config).unwrap();
    let every_other =
        common::run(&mut p, &words).iter().filter(|o| matches!(o, Output::Mfcc(_))).count();
    assert_eq!(every_other, peaks.len() / 2);
    config.mfcc_interval = 0;
    let mut p = Pipeline::new(&config).unwrap();
    assert!(!common::run(&mut p, &words).iter().any(|o| matches!(o, Output::Mfcc(_))));
}

#[test]
fn whole_frame_runs_count_clipping_and_peaks_like_the_frame_by_frame_path() {
    // Loud noise with words at and around the clip thresholds (|x| ≥ 0x7FFF_FE00 counts,
    // 0x7FFF_FDFF and −0x7FFF_FDFF do not) and at both ends of the i32 range, in every slot of
    // an 8-mic circle. Pushed whole, the runs of frames take the decimation loop with its
    // clip screen and zigzag peak; pushed word by word, every frame takes the frame-by-frame
    // path that counts each word. Health (clipped words, peak) and every other output must
    // agree bit for bit.
    let specials = [
        0x7FFF_FE00,
        0x7FFF_FDFF,
        -0x7FFF_FE00,
        -0x7FFF_FDFF,
        -0x7FFF_FE01,
        i32::MAX,
        i32::MIN,
        i32::MIN + 1,
        0x4000_0000,
        -0x4000_0000,
    ];
    let mut rng = Rng::new(7);
    let frames = 49_152 + 2048;
    let mut words = Vec::with_capacity(8 * frames);
    for t in 0..frames {
        for slot in 0..8 {
            let r = rng.next_u64();
            // A stretch of loud noise without specials, then specials now and then: both
            // sides of the screen.
            let loud = ((r >> 8) as u32 as i32) >> (1 + (t / 4096) % 3);
            let w = if t > 8192 && r % 97 == slot as u64 {
                specials[(r >> 40) as usize % specials.len()]
            } else {
                loud
            };
            words.push(w);
        }
    }
    let config = Config::new(Geometry::circle_8mic(), 48_000);
    let mut whole = Pipeline::new(&config).unwrap();
    let mut a = Vec::new();
    whole.push(&words, &mut |o| a.push(o));
    let mut single = Pipeline::new(&config).unwrap();
    let mut b = Vec::new();
    for w in &words {
        single.push(core::slice::from_ref(w), &mut |o| b.push(o));
    }
    // Runs of an odd number of frame pairs (7 frames per push: 3 pairs, then a split pair).
    let mut odd = Pipeline::new(&config).unwrap();
    let mut c = Vec::new();
    for chunk in words.chunks(7 * 8) {
        odd.push(chunk, &mut |o| c.push(o));
    }
    let health: Vec<_> =
        a.iter().filter_map(|o| if let Output::Health(h) = o { Some(*h) } else { None }).collect();
    assert_eq!(health.len(), 1);
    assert!(health[0].clipped_samples > 100, "{:?}", health[0]);
    assert_eq!(a, b);
    assert_eq!(c, b);
}

#[test]
fn bands_end_below_the_spatial_paths_nyquist_frequency() {
    // The spatial path runs at 24 kHz from 48 kHz input (12 kHz Nyquist) and at 16 kHz from
    // 16 kHz (8 kHz). A band reaching that frequency is refused; one ending just below it runs
    // (its top bin is the FFT's bin N/2 − 1) and gives finite directions.
    let g = Geometry::respeaker_6mic();
    for (fs, block) in [(16_000u32, 512usize), (16_000, 1024), (48_000, 512), (48_000, 1024)] {
        let mut config = Config::new(g, fs);
        config.block_len = block;
        let nyquist = config.spatial_rate_hz() as f32 / 2.0;
        let bin = config.bin_hz();
        config.band_low_hz = nyquist - 40.0 * bin;
        config.band_high_hz = nyquist;
        assert!(Pipeline::new(&config).is_err(), "{fs} Hz, block {block}: band to Nyquist");
        config.band_high_hz = nyquist - 0.25 * bin;
        let mut p = Pipeline::new(&config).unwrap_or_else(|e| panic!("{fs} Hz, {block}: {e:?}"));
        let words = plane_wave(&g, f64::from(fs), 16_384, 60.0, 50.0, 7);
        let out = common::run(&mut p, &words);
        let d = doas(&out);
        assert!(!d.is_empty(), "{fs} Hz, block {block}: no direction");
        assert!(d.iter().all(|d| d.azimuth_rad.is_finite() && d.zenith_rad.is_finite()));
    }
    // The audit's case: 10–16 kHz at 48 kHz (above the 24 kHz spatial rate's Nyquist).
    let mut config = Config::new(g, 48_000);
    (config.band_low_hz, config.band_high_hz) = (10_000.0, 16_000.0);
    assert!(Pipeline::new(&config).is_err());
}
