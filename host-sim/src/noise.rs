//! Noise in the room: point sources of band noise (the paper's 100 Hz-wide bands at 300, 600,
//! 900 Hz, 50–65 dB at 2 m) and a diffuse field.
//!
//! A point source emits Gaussian noise through a band-pass (two cascaded resonators at the
//! centre frequency, Q = centre / bandwidth), scaled so that its SPL at `distance_m` in free
//! field is `spl_db`. The diffuse field is a set of uncorrelated band-noise plane waves from
//! directions spread evenly over the sphere (Fibonacci lattice), modelled as sources far away
//! whose spreading loss is compensated; their SPLs add up to `spl_db` at the array.
use nalgebra::Vector3;
use rand::{rngs::StdRng, SeedableRng};

use crate::filter::{Biquad, Cascade, Gaussian};
use crate::sound::{spl_to_rms_pa, SignalBlocks, SourceSignal};

/// A point source of band noise.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseSource {
    /// Position, ENU m.
    pub position_m: Vector3<f64>,
    /// Centre frequency, Hz.
    pub centre_hz: f64,
    /// Bandwidth, Hz.
    pub bandwidth_hz: f64,
    /// Sound pressure level at `distance_m`, dB re 20 µPa.
    pub spl_db: f64,
    /// Distance at which `spl_db` holds, m.
    pub distance_m: f64,
}

impl NoiseSource {
    /// Checks the numbers; names the problem, starting with the key at fault.
    pub fn validate(&self, sample_rate_hz: f64) -> Result<(), String> {
        if !(self.centre_hz > 0.0
            && self.bandwidth_hz > 0.0
            && self.centre_hz + self.bandwidth_hz / 2.0 < sample_rate_hz / 2.0)
        {
            return Err(format!(
                "centre_hz: the band {} Hz ± {} Hz (bandwidth_hz) of the source at {:?} must lie \
                 between 0 and Nyquist",
                self.centre_hz,
                self.bandwidth_hz / 2.0,
                self.position_m.as_slice(),
            ));
        }
        if self.distance_m.is_nan() || self.distance_m <= 0.0 {
            return Err(format!("distance_m must be positive, got {}", self.distance_m));
        }
        if !self.spl_db.is_finite() {
            return Err(format!("spl_db must be finite, got {}", self.spl_db));
        }
        Ok(())
    }
}

/// The diffuse noise field.
#[derive(Clone, Debug, PartialEq)]
pub struct DiffuseNoise {
    /// Total sound pressure level at the arrays, dB re 20 µPa.
    pub spl_db: f64,
    /// Band, Hz.
    pub low_hz: f64,
    /// See `low_hz`.
    pub high_hz: f64,
    /// Number of plane waves.
    pub directions: usize,
}

/// Distance of the far sources standing for the diffuse field's plane waves, m.
pub const DIFFUSE_DISTANCE_M: f64 = 200.0;

/// Band-limited Gaussian noise with RMS `rms_pa`.
pub fn band_noise(
    filter: Cascade,
    rms_pa: f64,
    t0_s: f64,
    sample_rate_hz: f64,
    len: usize,
    seed: u64,
) -> SourceSignal {
    let mut g = BandNoise::new(filter, rms_pa, sample_rate_hz, len, seed);
    let mut samples = vec![0.0; len];
    g.fill(&mut samples);
    SourceSignal { t0_s, sample_rate_hz, samples }
}

/// Band-limited Gaussian noise ([`band_noise`]) generated block by block.
pub struct BandNoise {
    filter: Cascade,
    noise: Gaussian,
    scale: f64,
    /// Samples left before the signal ends.
    left: usize,
}

impl BandNoise {
    /// `len` samples of noise through `filter` with RMS `rms_pa`; the filter settles for 0.1 s
    /// before the first sample.
    pub fn new(filter: Cascade, rms_pa: f64, sample_rate_hz: f64, len: usize, seed: u64) -> Self {
        let scale = rms_pa / filter.white_noise_power_gain().sqrt();
        let mut filter = filter;
        let mut noise = Gaussian::new(StdRng::seed_from_u64(seed));
        // Let the filter settle before the first sample used.
        for _ in 0..(sample_rate_hz as usize / 10) {
            filter.process(noise.sample());
        }
        Self { filter, noise, scale, left: len }
    }
}

impl SignalBlocks for BandNoise {
    fn fill(&mut self, out: &mut [f32]) {
        let n = out.len().min(self.left);
        for y in &mut out[..n] {
            *y = (self.filter.process(self.noise.sample()) * self.scale) as f32;
        }
        out[n..].fill(0.0);
        self.left -= n;
    }
}

impl NoiseSource {
    /// The source's signal as pressure at 1 m, Pa.
    pub fn signal(&self, t0_s: f64, sample_rate_hz: f64, len: usize, seed: u64) -> SourceSignal {
        let mut g = self.blocks(sample_rate_hz, len, seed);
        let mut samples = vec![0.0; len];
        g.fill(&mut samples);
        SourceSignal { t0_s, sample_rate_hz, samples }
    }

    /// [`Self::signal`] generated block by block.
    pub fn blocks(&self, sample_rate_hz: f64, len: usize, seed: u64) -> BandNoise {
        let q = self.centre_hz / self.bandwidth_hz;
        // Two resonators in cascade: flatter top and steeper skirts than one.
        let filter = Cascade(vec![
            Biquad::bandpass(self.centre_hz, q * std::f64::consts::FRAC_1_SQRT_2, sample_rate_hz),
            Biquad::bandpass(self.centre_hz, q * std::f64::consts::FRAC_1_SQRT_2, sample_rate_hz),
        ]);
        let rms_1m = spl_to_rms_pa(self.spl_db) * self.distance_m;
        BandNoise::new(filter, rms_1m, sample_rate_hz, len, seed)
    }
}

impl DiffuseNoise {
    /// Checks the numbers; names the problem, starting with the key at fault.
    pub fn validate(&self, sample_rate_hz: f64) -> Result<(), String> {
        if !(self.low_hz > 0.0 && self.low_hz < self.high_hz && self.high_hz < sample_rate_hz / 2.0)
        {
            return Err(format!(
                "low_hz: need 0 < low_hz < high_hz < Nyquist ({} Hz), got {} and {} Hz",
                sample_rate_hz / 2.0,
                self.low_hz,
                self.high_hz
            ));
        }
        if self.directions < 1 {
            return Err("directions must be at least 1".into());
        }
        if !self.spl_db.is_finite() {
            return Err(format!("spl_db must be finite, got {}", self.spl_db));
        }
        Ok(())
    }

    /// Unit vectors of the plane waves' directions of arrival (from the array towards where
    /// the wave comes from), evenly spread over the sphere.
    pub fn directions(&self) -> Vec<Vector3<f64>> {
        let n = self.directions;
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let a = golden * i as f64;
                Vector3::new(r * a.cos(), r * a.sin(), z)
            })
            .collect()
    }

    /// Signal of one plane wave, as pressure at 1 m from a source `DIFFUSE_DISTANCE_M` away, Pa.
    pub fn signal(&self, t0_s: f64, sample_rate_hz: f64, len: usize, seed: u64) -> SourceSignal {
        let mut g = self.blocks(sample_rate_hz, len, seed);
        let mut samples = vec![0.0; len];
        g.fill(&mut samples);
        SourceSignal { t0_s, sample_rate_hz, samples }
    }

    /// [`Self::signal`] generated block by block.
    pub fn blocks(&self, sample_rate_hz: f64, len: usize, seed: u64) -> BandNoise {
        let filter = Cascade(vec![
            Biquad::highpass(self.low_hz, std::f64::consts::FRAC_1_SQRT_2, sample_rate_hz),
            Biquad::lowpass(self.high_hz, std::f64::consts::FRAC_1_SQRT_2, sample_rate_hz),
        ]);
        let rms = spl_to_rms_pa(self.spl_db) / (self.directions as f64).sqrt() * DIFFUSE_DISTANCE_M;
        BandNoise::new(filter, rms, sample_rate_hz, len, seed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sound::rms_pa_to_spl;

    #[test]
    fn point_noise_has_its_spl_at_its_distance() {
        let n = NoiseSource {
            position_m: Vector3::zeros(),
            centre_hz: 600.0,
            bandwidth_hz: 100.0,
            spl_db: 60.0,
            distance_m: 2.0,
        };
        let s = n.signal(0.0, 48_000.0, 480_000, 3);
        let rms = (s.samples.iter().map(|&x| (x as f64).powi(2)).sum::<f64>()
            / s.samples.len() as f64)
            .sqrt();
        // At 1 m the level is 6.02 dB above the level at 2 m.
        assert!((rms_pa_to_spl(rms) - 66.02).abs() < 0.3, "{}", rms_pa_to_spl(rms));
    }
}
