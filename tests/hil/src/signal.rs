//! A synthetic array recording for the DSP timing check: a far-field plane wave of broadband
//! noise plus a harmonic series (a propeller's blade-passing frequency), with integer sample
//! delays per microphone, as interleaved TDM words (24-bit samples left-justified in `i32`).
//!
//! Every sample is a pure function of its index, so any chunk can be generated on its own and
//! the board and a host produce the same words.

/// Speed of sound used for the delays, m/s.
pub const SPEED_OF_SOUND_M_S: f32 = 343.0;
/// Fundamental of the harmonic series, Hz.
pub const BPF_HZ: f32 = 180.0;
/// Harmonics in the series.
pub const HARMONICS: u32 = 4;

/// A plane wave arriving from a direction, sampled by the microphones of an array.
#[derive(Debug, Clone)]
pub struct PlaneWave {
    /// Delay of each microphone relative to the array centre, samples (negative: earlier).
    delays: [i32; 8],
    mics: usize,
    slots: usize,
    sample_rate_hz: f32,
}

impl PlaneWave {
    /// A wave from azimuth `azimuth_rad` (from +x towards +y) and zenith `zenith_rad` (from +z)
    /// at microphones `positions_m` (metres), `slots` TDM slots per frame.
    pub fn new(
        positions_m: &[[f32; 2]],
        slots: usize,
        sample_rate_hz: u32,
        azimuth_rad: f32,
        zenith_rad: f32,
    ) -> Self {
        let fs = sample_rate_hz as f32;
        let s = libm::sinf(zenith_rad);
        let u = [libm::cosf(azimuth_rad) * s, libm::sinf(azimuth_rad) * s];
        let mut delays = [0; 8];
        for (d, p) in delays.iter_mut().zip(positions_m) {
            // A microphone displaced towards the source hears the wave earlier.
            *d = libm::roundf(-(p[0] * u[0] + p[1] * u[1]) / SPEED_OF_SOUND_M_S * fs) as i32;
        }
        Self { delays, mics: positions_m.len().min(8), slots, sample_rate_hz: fs }
    }

    /// The source signal at sample `n`, as a fraction of full scale (about ±0.4).
    fn source(&self, n: i64) -> f32 {
        let mut x = (n as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        x ^= x >> 31;
        x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x ^= x >> 29;
        let noise = ((x >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 0.4;
        // Time within the current second: every harmonic of a whole-Hz BPF completes whole
        // cycles per second, so wrapping here keeps f32 phases exact at any `n`.
        let t = n.rem_euclid(self.sample_rate_hz as i64) as f32 / self.sample_rate_hz;
        let mut tone = 0.0;
        for k in 1..=HARMONICS {
            let cycles = t * BPF_HZ * k as f32;
            tone += 0.05 / k as f32 * libm::sinf(2.0 * core::f32::consts::PI * cycles);
        }
        noise + tone
    }

    /// Fills `words` (whole frames) with the frames starting at sample `first_frame`.
    pub fn fill(&self, first_frame: u64, words: &mut [i32]) {
        for (f, frame) in words.chunks_exact_mut(self.slots).enumerate() {
            let n = first_frame as i64 + f as i64;
            for (slot, word) in frame.iter_mut().enumerate() {
                *word = if slot < self.mics {
                    let v = self.source(n - i64::from(self.delays[slot]));
                    ((v * 8_388_607.0) as i32) << 8
                } else {
                    0
                };
            }
        }
    }
}
