//! Golden PDM input: the golden TDM signal of a scenario, each microphone turned into a
//! 3.072 MHz one-bit stream by an integer second-order sigma-delta modulator (each 48 kHz
//! sample held for 64 bits), packed as the SAI's PDM interface delivers it: one byte per
//! microphone per 8 bits, microphone `m` at offset `m` of each byte period, the earliest bit in
//! the MSB. Integer arithmetic only, so host and target produce the same bytes by construction.
use crate::signal::{Signal, MAX_MICS};
use aim_dsp::pdm::{BYTES_PER_OUTPUT, DECIMATION};

/// Modulator full scale: a 24-bit sample of ±2²³ is a constant all-ones / all-zeros stream.
const FULL_SCALE: i64 = 1 << 23;

/// Generator of PDM bytes (see the module docs).
#[derive(Debug, Clone)]
pub struct PdmSignal {
    signal: Signal,
    mics: usize,
    /// Per microphone: the modulator's two integrators and its last output (±FULL_SCALE).
    state: [[i64; 3]; MAX_MICS],
}

impl PdmSignal {
    /// PDM of `signal`'s first `mics` slots (`signal` must have exactly `mics` TDM slots).
    pub fn new(signal: Signal, mics: usize) -> Self {
        Self { signal, mics: mics.min(MAX_MICS), state: [[0, 0, FULL_SCALE]; MAX_MICS] }
    }

    /// Index of the next 48 kHz frame [`PdmSignal::fill`] starts with.
    pub fn sample_index(&self) -> u64 {
        self.signal.sample_index()
    }

    /// Bytes per 48 kHz frame: `8 · mics`.
    pub fn frame_bytes(&self) -> usize {
        BYTES_PER_OUTPUT * self.mics
    }

    /// Fills `bytes` with the next `bytes.len() / frame_bytes()` frames of PDM (a trailing
    /// partial frame is left zero).
    pub fn fill(&mut self, bytes: &mut [u8]) {
        bytes.fill(0);
        let mut words = [0i32; MAX_MICS];
        let frame_bytes = self.frame_bytes();
        for frame in bytes.chunks_exact_mut(frame_bytes) {
            self.signal.fill(&mut words[..self.mics]);
            for (m, (state, word)) in self.state.iter_mut().zip(words).take(self.mics).enumerate() {
                let x = i64::from(word >> 8);
                let [mut i1, mut i2, mut y] = *state;
                for byte in frame.iter_mut().skip(m).step_by(self.mics) {
                    let mut bits = 0u8;
                    for _ in 0..DECIMATION / BYTES_PER_OUTPUT {
                        i1 += x - y;
                        i2 += i1 - y;
                        let one = i2 >= 0;
                        y = if one { FULL_SCALE } else { -FULL_SCALE };
                        bits = (bits << 1) | u8::from(one);
                    }
                    *byte = bits;
                }
                *state = [i1, i2, y];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aim_dsp::pdm::PdmDecimator;

    #[test]
    fn decimated_golden_pdm_follows_the_golden_words() {
        // Oracle: the golden TDM words themselves. Output n of the decimator (order-2 CIC +
        // compensation) is centred 1.5 samples before the middle of hold n, i.e. between words
        // n − 2 and n − 1; the tone (330 Hz and harmonics up to 1.32 kHz) passes within a few
        // tenths of a dB, the white noise of the golden signal is low-passed by the CIC.
        let mics = 4;
        let mut pdm = PdmSignal::new(Signal::new(&[0, 3, 7, 11], mics, 48_000, 5), mics);
        let mut reference = Signal::new(&[0, 3, 7, 11], mics, 48_000, 5);
        let frames = 2048;
        let mut bytes = vec![0u8; frames * pdm.frame_bytes()];
        pdm.fill(&mut bytes);
        let mut words = vec![0i32; frames * mics];
        reference.fill(&mut words);
        let mut decimator = PdmDecimator::new(mics, mics);
        let mut out = vec![0i32; frames * mics];
        assert_eq!(decimator.push(&bytes, &mut out, mics), Ok(frames));
        for m in 0..mics {
            // PDM full scale maps to ±2^30 (half the 24-bit range): compare at that scale.
            let (mut error, mut power) = (0f64, 0f64);
            for n in 256..frames {
                let want = f64::from(words[(n - 2) * mics + m]) / 4.0
                    + f64::from(words[(n - 1) * mics + m]) / 4.0;
                let got = f64::from(out[n * mics + m]);
                error += (got - want).powi(2);
                power += want.powi(2);
            }
            let snr = 10.0 * (power / error).log10();
            eprintln!("mic {m}: decimated golden PDM against the golden words: {snr:.1} dB");
            assert!(snr > 40.0, "mic {m}: {snr:.1} dB");
        }
    }
}
