//! Snippets: the drone's band-limited sound, as a contiguous stream of short time-stamped
//! pieces, for inter-array delays on the host (`ALGORITHMS.md` §9, issue 14).
//!
//! The signal is the one the BPF path already makes ([`crate::bpf`]): the mean of all
//! microphones (the array's acoustic centre), low-passed (cut-off 3.5 kHz) and decimated to
//! [`crate::bpf::DECIMATED_RATE_HZ`] = 8 kHz, held in the spectral path's ring. Every
//! [`SNIPPET_LEN`] decimated samples (32 ms) the pipeline quantises the last ones into one
//! [`Snippet`] (block floating point: one exponent, `i8` mantissas); nothing is filtered twice,
//! so a snippet costs only its quantisation. Snippets follow each other without gap or overlap
//! (a gap in the capture drops the snippets that would span it), so the host can join any
//! arrays' streams over any window it likes: arrays start at arbitrary times and there is no
//! downlink, and a contiguous stream is the only schedule that guarantees two arrays' windows
//! overlap in true time. Measured trade-off (rate, band, format, length, host window, one
//! microphone or the mean): BENCHMARKS.md "Snippets for inter-array delays (issue 14)".
//!
//! Timing: sample `j` of a snippet is the decimated sample taken at input sample
//! `sample_index + j · decimation`. Its content lags that by the filters' group delay,
//! [`GROUP_DELAY_INPUT_SAMPLES`] at 48 kHz (the half-band and the BPF decimator): the same on
//! every array at the same rate, so it cancels in an inter-array delay.

/// Decimated samples per snippet (32 ms at 8 kHz). A power of two dividing the spectral
/// path's ring ([`crate::bpf::ANALYSIS_LEN`]), so a snippet never wraps in it.
pub const SNIPPET_LEN: usize = 256;
const _: () = assert!(crate::bpf::ANALYSIS_LEN.is_multiple_of(SNIPPET_LEN));

/// Lag of the snippet signal behind its stamps at 48 kHz input, input samples: the front
/// end's 7-tap half-band (centre tap 3 samples before the pair's second sample, stamped at its
/// first: 2) and the BPF decimator's 48-tap FIR at 24 kHz (centre 23.5 samples before the last
/// of the 3 inputs of an output, stamped at the first: 21.5 · 2 = 43). Checked against a tone's
/// phase (`dsp/tests/dsp/snippets.rs`).
pub const GROUP_DELAY_INPUT_SAMPLES: f32 = 45.0;

/// One snippet: [`SNIPPET_LEN`] samples of the array's mean signal, value of sample `j` =
/// `samples[j] · 2^exponent` (fraction of microphone full scale).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Snippet {
    /// Input-rate (48 or 16 kHz) sample index, on the array's own clock, of `samples[0]`.
    pub sample_index: u64,
    /// Input samples per snippet sample (6 at 48 kHz, 2 at 16 kHz: 8 kHz snippets).
    pub decimation: u8,
    /// Block exponent: a sample is `samples[j] · 2^exponent` of full scale.
    pub exponent: i8,
    /// Mantissas, −127..=127.
    pub samples: [i8; SNIPPET_LEN],
}

impl Default for Snippet {
    fn default() -> Self {
        Self { sample_index: 0, decimation: 1, exponent: 0, samples: [0; SNIPPET_LEN] }
    }
}

impl Snippet {
    /// Sample rate of the snippet for an input rate, Hz.
    pub fn rate_hz(&self, input_rate_hz: u32) -> f32 {
        input_rate_hz as f32 / f32::from(self.decimation.max(1))
    }

    /// Sample `j` as a fraction of full scale.
    pub fn value(&self, j: usize) -> f32 {
        f32::from(self.samples[j]) * libm::ldexpf(1.0, i32::from(self.exponent))
    }
}

/// Quantises `x` (fraction of full scale) to block floating point: the exponent puts the
/// largest magnitude in [64, 128) (then clamped to 127), each sample rounds to nearest (half
/// away from zero). Relative error per sample ≤ 2^-7 of the block's peak.
///
/// ```
/// let x = [0.5f32, -0.25, 0.001, 0.0];
/// let mut q = [0i8; 4];
/// let e = aim_dsp::snippet::quantize(&x, &mut q);
/// assert_eq!((e, q), (-7, [64, -32, 0, 0]));
/// ```
pub fn quantize(x: &[f32], out: &mut [i8]) -> i8 {
    let peak = x.iter().fold(0.0f32, |m, &v| m.max(libm::fabsf(v)));
    // peak = m · 2^e with m in [0.5, 1): peak · 2^(7 − e) in [64, 128).
    let (_, e) = libm::frexpf(peak);
    let exponent = (e - 7).clamp(-128, 127);
    let scale = libm::ldexpf(1.0, -exponent);
    for (o, &v) in out.iter_mut().zip(x) {
        let s = v * scale;
        // `as` truncates towards zero and saturates (one VCVT on the Cortex-M4F).
        let r = if s >= 0.0 { s + 0.5 } else { s - 0.5 } as i32;
        *o = r.clamp(-127, 127) as i8;
    }
    exponent as i8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantization_error_is_within_half_a_step() {
        // A harmonic signal at three levels: error ≤ half a step, peak in [64, 127].
        for level in [1e-5f32, 3e-3, 0.9] {
            let x: [f32; SNIPPET_LEN] = core::array::from_fn(|n| {
                let t = n as f32 / 8000.0;
                level
                    * (0.6 * libm::sinf(2.0 * core::f32::consts::PI * 330.0 * t)
                        + 0.4 * libm::sinf(2.0 * core::f32::consts::PI * 990.0 * t + 1.0))
            });
            let mut q = [0i8; SNIPPET_LEN];
            let e = quantize(&x, &mut q);
            let step = libm::ldexpf(1.0, i32::from(e));
            let top = q.iter().map(|v| v.unsigned_abs()).max().unwrap();
            assert!((64..=127).contains(&top), "peak mantissa {top}");
            for (&v, &m) in x.iter().zip(&q) {
                assert!((f32::from(m) * step - v).abs() <= 0.5 * step * 1.0001, "{v} {m} {e}");
            }
        }
        let mut q = [1i8; 4];
        assert_eq!(quantize(&[0.0; 4], &mut q), -7);
        assert_eq!(q, [0; 4]);
    }
}
