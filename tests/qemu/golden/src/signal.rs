//! Deterministic synthetic array input: a harmonic drone-like tone arriving with a fixed integer
//! sample delay per microphone, plus white noise, as interleaved TDM words.
//!
//! Microphone 0 also hears the synchronisation beacon (`aim_dsp::beacon`) once a second from
//! sample [`BEACON_FIRST`] on, at a fractional start, so parity covers the `Beacon` output.
//!
//! Integer arithmetic only, but for the beacon's `libm` f64 waveform (software maths, the same
//! bits on host and target), so host and target produce the same words by construction.

/// Most microphones (TDM slots carrying a signal).
pub const MAX_MICS: usize = 8;

/// Harmonics of the tone: frequency in millihertz and amplitude in 24-bit sample units.
/// A 3-blade propeller at 110 Hz rotation: BPF 330 Hz and its harmonics.
const HARMONICS: [(u64, i64); 4] =
    [(330_000, 1_200_000), (660_000, 700_000), (990_000, 400_000), (1_320_000, 250_000)];

/// Start of the first beacon emission on microphone 0, samples (fractional), then one every
/// [`BEACON_PERIOD`] samples.
pub const BEACON_FIRST: f64 = 5_000.37;
/// Beacon repetition period, samples.
pub const BEACON_PERIOD: u64 = 48_000;
/// Beacon peak amplitude, 24-bit sample units (about −32 dBFS).
const BEACON_AMPLITUDE: f64 = 200_000.0;

/// Peak amplitude of the white noise, 24-bit sample units.
const NOISE_AMPLITUDE: i32 = 60_000;

/// Generator of interleaved TDM words (slot-major frames of `tdm_slots` words; slot `i` carries
/// microphone `i` as a 24-bit sample left-justified in an `i32`; unused slots are zero).
#[derive(Debug, Clone)]
pub struct Signal {
    /// Per-microphone delay of the tone, samples (non-negative).
    delays: [u32; MAX_MICS],
    mics: usize,
    tdm_slots: usize,
    /// Phase increment per sample of each harmonic, 2^32 = one turn.
    increments: [u32; HARMONICS.len()],
    /// Index of the next sample (frame) to produce.
    sample: u64,
    noise: u32,
    /// The beacon's samples (24-bit units) from frame `BEACON_FIRST.ceil()` of an emission on,
    /// computed once in [`Signal::new`] so the per-sample synthesis stays cheap.
    beacon: [i32; aim_dsp::beacon::LEN],
}

impl Signal {
    /// A tone sampled at `sample_rate_hz`, delayed by `delays[i]` samples at microphone `i`
    /// (`delays.len()` microphones, at most `tdm_slots` and [`MAX_MICS`]), noise from `seed`.
    ///
    /// # Panics
    /// If there are more delays than slots or than [`MAX_MICS`], or `sample_rate_hz` is zero
    /// (a bug in the calling check, not bad data).
    pub fn new(delays: &[u32], tdm_slots: usize, sample_rate_hz: u32, seed: u32) -> Self {
        assert!(delays.len() <= tdm_slots.min(MAX_MICS) && sample_rate_hz > 0);
        let mut d = [0; MAX_MICS];
        d[..delays.len()].copy_from_slice(delays);
        let increments = HARMONICS.map(|(millihertz, _)| {
            ((millihertz << 32) / (u64::from(sample_rate_hz) * 1000)) as u32
        });
        let mut beacon = [0i32; aim_dsp::beacon::LEN];
        let first = libm::ceil(BEACON_FIRST);
        for (i, b) in beacon.iter_mut().enumerate() {
            let t = first + i as f64 - BEACON_FIRST;
            *b = libm::round(BEACON_AMPLITUDE * aim_dsp::beacon::waveform_at(t)) as i32;
        }
        Signal {
            delays: d,
            mics: delays.len(),
            tdm_slots,
            increments,
            sample: 0,
            noise: seed | 1,
            beacon,
        }
    }

    /// Index of the next frame [`Signal::fill`] writes.
    pub fn sample_index(&self) -> u64 {
        self.sample
    }

    /// Fills `words` with the next `words.len() / tdm_slots` frames (a trailing partial frame is
    /// left zero and not counted).
    pub fn fill(&mut self, words: &mut [i32]) {
        words.fill(0);
        for frame in words.chunks_exact_mut(self.tdm_slots) {
            for (mic, word) in frame.iter_mut().take(self.mics).enumerate() {
                let t = self.sample.wrapping_sub(u64::from(self.delays[mic])) as u32;
                let mut sample: i64 = 0;
                for (&(_, amplitude), &increment) in HARMONICS.iter().zip(&self.increments) {
                    sample += (amplitude * i64::from(sine_q15(t.wrapping_mul(increment)))) >> 15;
                }
                let noise = (self.next_noise() >> 8) as i32 % NOISE_AMPLITUDE;
                if mic == 0 {
                    sample += self.beacon_at(self.sample);
                }
                let sample = (sample as i32 + noise).clamp(-(1 << 23), (1 << 23) - 1);
                *word = sample << 8;
            }
            self.sample += 1;
        }
    }

    /// The beacon on microphone 0 at frame `n`, 24-bit sample units.
    fn beacon_at(&self, n: u64) -> i64 {
        let first = libm::ceil(BEACON_FIRST) as u64;
        if n < first {
            return 0;
        }
        let i = ((n - first) % BEACON_PERIOD) as usize;
        self.beacon.get(i).map_or(0, |&b| i64::from(b))
    }

    /// xorshift32.
    fn next_noise(&mut self) -> u32 {
        let mut x = self.noise;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.noise = x;
        x
    }
}

/// Sine of `phase` (2^32 = one turn) in Q15, integer only: the parabola 4x(1 − |x|) with the
/// usual 0.225 correction; within 0.1 % of full scale of `sin`.
pub fn sine_q15(phase: u32) -> i32 {
    // x in [-1, 1) as Q15, for the angle in [-π, π).
    let x = (phase as i32) >> 16;
    let y = (x * (32_768 - x.abs())) >> 13; // Q15, in [-32768, 32768]
                                            // y + 0.225 (y|y| − y), 0.225 ≈ 7373 / 2^15
    y + ((7_373 * (((y * y.abs()) >> 15) - y)) >> 15)
}

/// Integer arrival delays (samples, the earliest microphone at zero) of a far-field plane wave
/// travelling along −`direction_q15` (the unit vector towards the source, x and y in Q15), for
/// microphones at `positions_mm` (millimetres, array frame), speed of sound 343 m/s.
///
/// Writes `positions_mm.len().min(delays.len())` delays.
pub fn plane_wave_delays(
    positions_mm: &[[i32; 2]],
    direction_q15: [i32; 2],
    sample_rate_hz: u32,
    delays: &mut [u32],
) {
    // Arrival at p relative to the centre: −(p · u) / c seconds; in samples, rounded half up.
    let denominator = (1i64 << 15) * 1000 * 343;
    let arrival = |p: &[i32; 2]| {
        let dot = i64::from(p[0]) * i64::from(direction_q15[0])
            + i64::from(p[1]) * i64::from(direction_q15[1]);
        (-2 * dot * i64::from(sample_rate_hz) + denominator).div_euclid(2 * denominator)
    };
    let earliest = positions_mm.iter().map(arrival).min().unwrap_or(0);
    for (p, d) in positions_mm.iter().zip(delays.iter_mut()) {
        *d = (arrival(p) - earliest) as u32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_wave_delays_match_the_far_field_law() {
        // Mics 10 cm apart on x, and at the centre; source along +x (u = (1, 0)), zenith 90°.
        let positions = [[-100, 0], [0, 0], [100, 0]];
        let mut delays = [0u32; 3];
        plane_wave_delays(&positions, [32_767, 0], 48_000, &mut delays);
        // The mic at +x hears first; 0.1 m / 343 m/s · 48 kHz = 13.99 samples per 10 cm.
        assert_eq!(delays, [28, 14, 0]);
        // Oracle in f64 for an oblique direction and an irregular layout.
        let positions = [[46, 0], [23, 40], [-23, 40], [-46, 0], [-23, -40], [23, -40]];
        let u = [21_739, 18_241];
        let mut delays = [0u32; 6];
        plane_wave_delays(&positions, u, 48_000, &mut delays);
        let arrival = |p: &[i32; 2]| {
            -(f64::from(p[0]) * f64::from(u[0]) + f64::from(p[1]) * f64::from(u[1]))
                / 32_768.0
                / 1000.0
                / 343.0
                * 48_000.0
        };
        let earliest = positions.iter().map(arrival).fold(f64::INFINITY, f64::min);
        for (p, d) in positions.iter().zip(delays) {
            let exact = arrival(p) - earliest;
            assert!((f64::from(d) - exact).abs() <= 1.0, "{p:?}: {d} vs {exact}");
        }
    }

    #[test]
    fn words_are_left_justified_delayed_copies_in_their_slots() {
        let mut signal = Signal::new(&[0, 5], 4, 48_000, 7);
        let mut words = [0i32; 4 * 256];
        signal.fill(&mut words);
        assert_eq!(signal.sample_index(), 256);
        for frame in words.chunks_exact(4) {
            assert_eq!(frame[0] & 0xFF, 0, "24-bit samples, left-justified");
            assert_eq!(&frame[2..], &[0, 0], "slots without a microphone stay zero");
        }
        // Mic 1 is mic 0 five samples later, up to the noise (below 60 000 · 2 in 24 bits).
        let tone = 2 * NOISE_AMPLITUDE as i64;
        for t in 5..256 {
            let m0 = i64::from(words[4 * (t - 5)] >> 8);
            let m1 = i64::from(words[4 * t + 1] >> 8);
            assert!((m0 - m1).abs() <= tone, "sample {t}: {m0} vs {m1}");
        }
        // The same seed gives the same words: both sides synthesise identical input.
        let mut again = Signal::new(&[0, 5], 4, 48_000, 7);
        let mut words2 = [0i32; 4 * 256];
        again.fill(&mut words2);
        assert_eq!(words, words2);
    }

    #[test]
    fn integer_sine_stays_close_to_sine() {
        for k in 0..4096u32 {
            let phase = k << 20;
            let exact = (f64::from(phase) / 4_294_967_296.0 * core::f64::consts::TAU).sin();
            let error = (f64::from(sine_q15(phase)) / 32_768.0 - exact).abs();
            assert!(error < 2e-3, "phase {phase}: error {error}");
        }
    }
}
