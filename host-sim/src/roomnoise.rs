//! Room backgrounds for the identification dataset (`host-sim id-dataset`): the noise of halls
//! in general, not of one hall. A [`RoomNoise`] is drawn from its own seed and is one of
//!
//! - the classic room noise of [`crate::tonal::background`] (brown below 200 Hz, pink above,
//!   mains hum), one background in four;
//! - coloured noise: a power spectrum falling or rising as a power law of random tilt
//!   (−7.5..+3 dB per octave; white is 0, pink −3, brown −6), between a lower edge log-uniform in
//!   20–200 Hz and an upper edge log-uniform in 2–8 kHz (both skirts 12 dB per octave), plus
//!   0–3 bands of noise (machines, ventilation, a motor's housing): centre log-uniform in
//!   100–3000 Hz, width log-uniform in 5–80 % of the centre (at least 10 Hz), skirts of a
//!   Butterworth band of order 1–4, each band −10..+15 dB relative to the coloured part, and
//!   with probability one half the mains hum of [`Negative::MainsHum`] 6–20 dB below the whole.
//!
//! The whole is scaled to the clip's background level (RMS over the clip, dB SPL). The
//! coloured part and the bands are synthesised in the frequency domain (independent complex
//! Gaussian bins of the wanted power, one inverse FFT of the clip's length), so they are
//! stationary Gaussian noise with exactly the drawn spectrum.
use rand::{rngs::StdRng, Rng, SeedableRng};
use rustfft::{num_complex::Complex, FftPlanner};

use crate::filter::Gaussian;
use crate::tonal::{add, background, scale_to_spl, Negative};

/// One band of noise in a [`RoomNoise`].
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseBand {
    /// Centre frequency, Hz.
    pub centre_hz: f64,
    /// Width between the −3 dB points, Hz.
    pub width_hz: f64,
    /// Order of the Butterworth skirts (1–4: 6–24 dB per octave of distance from the edge).
    pub order: u32,
    /// Power relative to the coloured broadband part, dB.
    pub level_db: f64,
}

/// A drawn room background (module docs).
#[derive(Clone, Debug, PartialEq)]
pub enum RoomNoise {
    /// [`crate::tonal::background`].
    Classic,
    /// Coloured noise with bands.
    Coloured {
        /// Power-law tilt of the broadband part, dB per octave.
        tilt_db_per_octave: f64,
        /// Lower edge of the broadband part (second-order high-pass corner), Hz.
        low_hz: f64,
        /// Upper edge of the broadband part (second-order low-pass corner), Hz.
        high_hz: f64,
        /// Bands of noise.
        bands: Vec<NoiseBand>,
        /// Mains hum relative to the whole, dB, if any.
        hum_db: Option<f64>,
    },
}

fn log_uniform(rng: &mut StdRng, a: f64, b: f64) -> f64 {
    (rng.random_range(a.ln()..b.ln())).exp()
}

impl RoomNoise {
    /// Draws a background (module docs).
    pub fn draw(rng: &mut StdRng) -> Self {
        if rng.random::<f64>() < 0.25 {
            return RoomNoise::Classic;
        }
        let tilt_db_per_octave = rng.random_range(-7.5..3.0);
        let low_hz = log_uniform(rng, 20.0, 200.0);
        let high_hz = log_uniform(rng, 2000.0, 8000.0);
        let n = match rng.random::<f64>() {
            u if u < 0.2 => 0,
            u if u < 0.6 => 1,
            u if u < 0.85 => 2,
            _ => 3,
        };
        let bands = (0..n)
            .map(|_| {
                let centre_hz = log_uniform(rng, 100.0, 3000.0);
                NoiseBand {
                    centre_hz,
                    width_hz: (centre_hz * log_uniform(rng, 0.05, 0.8)).max(10.0),
                    order: rng.random_range(1..=4),
                    level_db: rng.random_range(-10.0..15.0),
                }
            })
            .collect();
        let hum_db = (rng.random::<f64>() < 0.5).then(|| rng.random_range(-20.0..-6.0));
        RoomNoise::Coloured { tilt_db_per_octave, low_hz, high_hz, bands, hum_db }
    }

    /// `len` samples at `fs` of this background at `spl_db` (RMS over the clip), Pa.
    pub fn signal(&self, fs: f64, len: usize, spl_db: f64, seed: u64) -> Vec<f64> {
        let RoomNoise::Coloured { tilt_db_per_octave, low_hz, high_hz, bands, hum_db } = self
        else {
            return background(fs, len, spl_db, seed);
        };
        let mut rng = StdRng::seed_from_u64(seed);
        if len == 0 {
            return Vec::new();
        }
        // Power per bin of each part, each normalised to its relative power.
        let freq = |k: usize| k.min(len - k) as f64 * fs / len as f64;
        let broad = |f: f64| {
            if f <= 0.0 {
                return 0.0;
            }
            let hp = (f / low_hz).powi(4) / (1.0 + (f / low_hz).powi(4));
            let lp = 1.0 / (1.0 + (f / high_hz).powi(4));
            (f / 1000.0).powf(tilt_db_per_octave / (10.0 * 2f64.log10())) * hp * lp
        };
        let mut psd: Vec<f64> = normalised((0..len).map(|k| broad(freq(k))).collect(), 1.0);
        for b in bands {
            let shape = |f: f64| {
                let u = (f - b.centre_hz) / (0.5 * b.width_hz);
                if f <= 0.0 {
                    0.0
                } else {
                    1.0 / (1.0 + u.powi(2 * b.order as i32))
                }
            };
            let p = normalised((0..len).map(|k| shape(freq(k))).collect(), db(b.level_db));
            add(&mut psd, &p, 1.0);
        }
        let mut g = Gaussian::new(StdRng::seed_from_u64(rng.random()));
        let mut spec: Vec<Complex<f64>> =
            psd.iter().map(|p| Complex::new(g.sample(), g.sample()) * p.sqrt()).collect();
        FftPlanner::<f64>::new().plan_fft_inverse(len).process(&mut spec);
        let mut x: Vec<f64> = spec.iter().map(|c| c.re).collect();
        if let Some(h) = hum_db {
            scale_to_spl(&mut x, 0.0);
            // The hum's power h dB below the whole: h' relative to the rest.
            let rel = db(*h) / (1.0 - db(*h));
            let hum = Negative::MainsHum.signal(fs, len, 10.0 * rel.log10(), rng.random());
            add(&mut x, &hum, 1.0);
        }
        scale_to_spl(&mut x, spl_db);
        x
    }
}

fn db(level_db: f64) -> f64 {
    10f64.powf(level_db / 10.0)
}

fn normalised(mut p: Vec<f64>, total: f64) -> Vec<f64> {
    let s: f64 = p.iter().sum();
    if s > 0.0 {
        p.iter_mut().for_each(|v| *v *= total / s);
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sound::rms_pa_to_spl;

    /// Power in `lo..hi` Hz of `x` (Welch: Hann windows of 4096, half overlap), a density
    /// estimate independent of the synthesis (other length, windowed).
    fn band_power(x: &[f64], fs: f64, lo: f64, hi: f64) -> f64 {
        let n = 4096;
        let fft = FftPlanner::<f64>::new().plan_fft_forward(n);
        let w: Vec<f64> =
            (0..n).map(|i| (std::f64::consts::PI * i as f64 / n as f64).sin().powi(2)).collect();
        let mut total = 0.0;
        for start in (0..x.len() - n).step_by(n / 2) {
            let mut s: Vec<Complex<f64>> =
                (0..n).map(|i| Complex::new(x[start + i] * w[i], 0.0)).collect();
            fft.process(&mut s);
            total += (1..n / 2)
                .filter(|&k| (lo..hi).contains(&(k as f64 * fs / n as f64)))
                .map(|k| s[k].norm_sqr())
                .sum::<f64>();
        }
        total
    }

    /// Level, tilt and band as drawn: the RMS is the level asked for; a pure tilt of −6 dB per
    /// octave puts 6 dB less power per hertz an octave up (the octave 1–2 kHz, twice as wide,
    /// holds 3 dB less than 0.5–1 kHz); a band 15 dB above a flat floor holds its share of the
    /// power within its −3 dB edges (a second-order Butterworth band keeps 78.06 % of its power
    /// there, ∫₀¹ du/(1+u⁴) over ∫₀^∞, the floor 15 dB down over the band's share of 0–8 kHz adds little).
    #[test]
    fn level_tilt_and_band_as_drawn() {
        let fs = 16_000.0;
        let len = 64_000;
        let tilted = RoomNoise::Coloured {
            tilt_db_per_octave: -6.0,
            low_hz: 20.0,
            high_hz: 7900.0,
            bands: vec![],
            hum_db: None,
        };
        let x = tilted.signal(fs, len, 63.0, 7);
        let spl = rms_pa_to_spl((x.iter().map(|v| v * v).sum::<f64>() / len as f64).sqrt());
        assert!((spl - 63.0).abs() < 1e-9, "{spl}");
        let ratio_db =
            10.0 * (band_power(&x, fs, 1000.0, 2000.0) / band_power(&x, fs, 500.0, 1000.0)).log10();
        assert!((ratio_db + 3.0).abs() < 0.5, "{ratio_db}");

        let banded = RoomNoise::Coloured {
            tilt_db_per_octave: 0.0,
            low_hz: 20.0,
            high_hz: 7900.0,
            bands: vec![NoiseBand { centre_hz: 800.0, width_hz: 200.0, order: 2, level_db: 15.0 }],
            hum_db: None,
        };
        let x = banded.signal(fs, len, 60.0, 8);
        let share = band_power(&x, fs, 700.0, 900.0) / band_power(&x, fs, 0.0, 8000.0);
        // Band: 0.7806 · 31.6 / 32.6; floor: 200/7900 of 1/32.6.
        let want = (0.7806 * db(15.0) + 200.0 / 7900.0) / (1.0 + db(15.0));
        assert!((share - want).abs() < 0.03, "{share} vs {want}");
        // Same seed, same noise; another seed, other noise.
        assert_eq!(x, banded.signal(fs, len, 60.0, 8));
        assert_ne!(x, banded.signal(fs, len, 60.0, 9));
    }

    /// Draws stay within their stated ranges.
    #[test]
    fn draws_within_ranges() {
        let mut rng = StdRng::seed_from_u64(1);
        let mut classic = 0;
        for _ in 0..400 {
            match RoomNoise::draw(&mut rng) {
                RoomNoise::Classic => classic += 1,
                RoomNoise::Coloured { tilt_db_per_octave, low_hz, high_hz, bands, hum_db } => {
                    assert!((-7.5..3.0).contains(&tilt_db_per_octave));
                    assert!((20.0..200.0).contains(&low_hz) && (2000.0..8000.0).contains(&high_hz));
                    assert!(bands.len() <= 3);
                    for b in bands {
                        assert!((100.0..3000.0).contains(&b.centre_hz));
                        assert!(b.width_hz >= 10.0 && b.width_hz <= 0.8 * b.centre_hz);
                        assert!((1..=4).contains(&b.order) && (-10.0..15.0).contains(&b.level_db));
                    }
                    assert!(hum_db.is_none_or(|h| (-20.0..-6.0).contains(&h)));
                }
            }
        }
        assert!((70..130).contains(&classic), "{classic}");
    }
}
