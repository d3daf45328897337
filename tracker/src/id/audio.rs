//! Recordings to the features' input: one channel at 16 kHz, f32.
//!
//! Channels are averaged (the array's microphones hear the same drone; averaging lowers their
//! independent self-noise). 48 kHz is decimated by 3 after a linear-phase low-pass FIR (127
//! taps, Blackman-windowed sinc, cut-off 7 kHz, stop band below −70 dB from 8 kHz). Integer
//! samples are scaled to ±1 full scale; float samples are taken as they are (the features do
//! not depend on the scale).
use std::path::Path;

use anyhow::{bail, Context as _};

/// Sample rate of the features' input, Hz.
pub const RATE_HZ: u32 = 16_000;
/// Shortest clip accepted, s (the features need a few frames).
pub const MIN_SECS: f64 = 0.25;

/// Reads `path` as one 16 kHz channel. Errors name the file and the problem.
pub fn read_mono_16k(path: &Path) -> anyhow::Result<Vec<f32>> {
    let (mono, rate) = read_mono(path)?;
    let out = if rate == 48_000 { decimate_by_3(&mono) } else { mono };
    let secs = out.len() as f64 / f64::from(RATE_HZ);
    if secs < MIN_SECS {
        bail!("{}: {secs:.3} s of audio, at least {MIN_SECS} s needed", path.display());
    }
    Ok(out)
}

/// Reads `path` as one channel (the channels' mean) at its own rate, 16 or 48 kHz: (samples,
/// rate in Hz). Errors name the file and the problem.
pub fn read_mono(path: &Path) -> anyhow::Result<(Vec<f32>, u32)> {
    let reader = hound::WavReader::open(path)
        .with_context(|| format!("{}: not a readable WAV file", path.display()))?;
    let spec = reader.spec();
    let channels = usize::from(spec.channels);
    if channels == 0 {
        bail!("{}: WAV header says 0 channels", path.display());
    }
    let samples: Vec<f32> = match spec.sample_format {
        hound::SampleFormat::Float => reader
            .into_samples::<f32>()
            .collect::<Result<_, _>>()
            .with_context(|| format!("{}: corrupt float samples", path.display()))?,
        hound::SampleFormat::Int => {
            let scale = 1.0 / (1u64 << (spec.bits_per_sample.clamp(1, 32) - 1)) as f32;
            reader
                .into_samples::<i32>()
                .map(|s| s.map(|v| v as f32 * scale))
                .collect::<Result<_, _>>()
                .with_context(|| format!("{}: corrupt integer samples", path.display()))?
        }
    };
    if samples.iter().any(|v| !v.is_finite()) {
        bail!("{}: a sample is not a finite number", path.display());
    }
    let mono: Vec<f32> =
        samples.chunks_exact(channels).map(|f| f.iter().sum::<f32>() / channels as f32).collect();
    match spec.sample_rate {
        16_000 | 48_000 => {}
        other => {
            bail!("{}: sample rate {other} Hz is not supported (16000 or 48000 Hz)", path.display())
        }
    }
    let secs = mono.len() as f64 / f64::from(spec.sample_rate);
    if secs < MIN_SECS {
        bail!("{}: {secs:.3} s of audio, at least {MIN_SECS} s needed", path.display());
    }
    Ok((mono, spec.sample_rate))
}

/// Taps of the 48 → 16 kHz anti-aliasing filter.
const TAPS: usize = 127;

fn lowpass_taps() -> Vec<f32> {
    let fc = 7_000.0 / 48_000.0; // cycles per sample
    let mid = (TAPS - 1) as f64 / 2.0;
    let mut h: Vec<f64> = (0..TAPS)
        .map(|n| {
            let x = n as f64 - mid;
            let sinc = if x == 0.0 {
                2.0 * fc
            } else {
                (std::f64::consts::TAU * fc * x).sin() / (std::f64::consts::PI * x)
            };
            let a = std::f64::consts::TAU * n as f64 / (TAPS - 1) as f64;
            sinc * (0.42 - 0.5 * a.cos() + 0.08 * (2.0 * a).cos())
        })
        .collect();
    let sum: f64 = h.iter().sum();
    h.iter_mut().for_each(|v| *v /= sum);
    h.into_iter().map(|v| v as f32).collect()
}

/// Low-pass filters `x` (48 kHz) and keeps every third sample (zero-padded at the edges).
pub fn decimate_by_3(x: &[f32]) -> Vec<f32> {
    let h = lowpass_taps();
    let half = TAPS / 2;
    (0..x.len() / 3)
        .map(|i| {
            let c = 3 * i;
            let mut acc = 0.0f32;
            for (k, hk) in h.iter().enumerate() {
                let j = c as isize + k as isize - half as isize;
                if j >= 0 && (j as usize) < x.len() {
                    acc += hk * x[j as usize];
                }
            }
            acc
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tone(fs: f64, hz: f64, n: usize) -> Vec<f32> {
        (0..n).map(|k| (std::f64::consts::TAU * hz * k as f64 / fs).sin() as f32).collect()
    }

    fn rms(x: &[f32]) -> f32 {
        (x.iter().map(|v| v * v).sum::<f32>() / x.len() as f32).sqrt()
    }

    #[test]
    fn decimation_passes_the_band_and_stops_aliases() {
        // 1 kHz passes at unit gain; 12 kHz (would alias to 4 kHz) is stopped.
        let pass = decimate_by_3(&tone(48_000.0, 1_000.0, 48_000));
        assert!((rms(&pass[100..15_900]) / std::f32::consts::FRAC_1_SQRT_2 - 1.0).abs() < 0.01);
        let stop = decimate_by_3(&tone(48_000.0, 12_000.0, 48_000));
        assert!(rms(&stop[100..15_900]) < 1e-3, "{}", rms(&stop[100..15_900]));
    }

    #[test]
    fn reads_mono_and_stereo_int_and_float_and_rejects_bad_files() {
        let dir = std::env::temp_dir().join(format!("aim-id-audio-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let write = |name: &str, channels: u16, rate: u32, float: bool, n: usize| {
            let path = dir.join(name);
            let spec = hound::WavSpec {
                channels,
                sample_rate: rate,
                bits_per_sample: if float { 32 } else { 16 },
                sample_format: if float {
                    hound::SampleFormat::Float
                } else {
                    hound::SampleFormat::Int
                },
            };
            let mut w = hound::WavWriter::create(&path, spec).unwrap();
            for k in 0..n {
                for _ in 0..channels {
                    let v = (std::f64::consts::TAU * 500.0 * k as f64 / f64::from(rate)).sin();
                    if float {
                        w.write_sample(v as f32).unwrap();
                    } else {
                        w.write_sample((v * 16_000.0) as i16).unwrap();
                    }
                }
            }
            w.finalize().unwrap();
            path
        };
        let a = read_mono_16k(&write("a.wav", 1, 16_000, false, 16_000)).unwrap();
        assert_eq!(a.len(), 16_000);
        assert!((rms(&a) - 16_000.0 / 32_768.0 * std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-3);
        let b = read_mono_16k(&write("b.wav", 6, 48_000, true, 48_000)).unwrap();
        assert_eq!(b.len(), 16_000);
        let short = write("c.wav", 1, 16_000, false, 1_000);
        assert!(read_mono_16k(&short).unwrap_err().to_string().contains("at least"));
        let odd = write("d.wav", 1, 22_050, false, 22_050);
        assert!(read_mono_16k(&odd).unwrap_err().to_string().contains("22050 Hz"));
        let junk = dir.join("e.wav");
        std::fs::write(&junk, b"not a wav").unwrap();
        let e = format!("{:#}", read_mono_16k(&junk).unwrap_err());
        assert!(e.contains("e.wav") && e.contains("not a readable WAV"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
