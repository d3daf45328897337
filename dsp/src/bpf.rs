//! Blade-passing-frequency tracking: decimated mono signal, long spectrum, harmonic peak groups.
//!
//! The mean of all microphones is low-pass filtered and decimated to [`DECIMATED_RATE_HZ`]
//! (windowed-sinc FIR, Blackman window, polyphase: one output per `factor` inputs). Every
//! [`ANALYSIS_HOP`] decimated samples the last [`ANALYSIS_LEN`] (0.512 s, Hann window) are
//! transformed (microfft `rfft_4096`, 1.95 Hz bins), every peak refined below one bin by the
//! Hann-window ratio estimator (Grandke): δ = (2α − 1)/(α + 1), α = |X(k±1)| / |X(k)|, exact
//! for a lone tone. The spectrum is whitened against a noise floor that follows its tilt and
//! searched for rotor combs with a detection test and continuity over analyses
//! ([`crate::comb`]); when nothing passes, the `Peaks` output says "no rotor signature".

use crate::{Config, Peaks};

/// Sample rate of the decimated mono signal, Hz.
pub const DECIMATED_RATE_HZ: u32 = 8_000;
/// Length of the BPF analysis window, decimated samples (0.512 s).
pub const ANALYSIS_LEN: usize = 4096;
/// Decimated samples between two analyses (50 % overlap, 0.256 s: 3.9 `Peaks` per second).
pub const ANALYSIS_HOP: usize = 2048;
/// Most FIR taps of the decimator.
pub const MAX_TAPS: usize = 96;
/// FIR taps per unit of decimation factor.
const TAPS_PER_FACTOR: usize = 16;
/// Decimator cut-off, Hz (Blackman: −74 dB from about 4.9 kHz at 48 kHz).
const CUTOFF_HZ: f32 = 3500.0;
/// Highest harmonic frequency analysed, Hz (the anti-alias filter rolls off above it).
pub const MAX_ANALYSIS_HZ: f32 = 3800.0;
/// Lowest frequency of the noise-floor estimate and the whitened spectrum, Hz.
const FLOOR_LOW_HZ: f32 = 40.0;

/// Polyphase FIR decimator.
#[derive(Debug, Clone)]
pub struct Decimator {
    taps: [f32; MAX_TAPS],
    len: usize,
    factor: usize,
    /// Delay line, appended at `end`: `line[end - len..end]` holds the last `len` inputs,
    /// oldest first. When full, the last `len` move to the front (one copy per
    /// `2·MAX_TAPS − len` inputs instead of two writes per input).
    line: [f32; 2 * MAX_TAPS],
    end: usize,
    phase: usize,
}

impl Decimator {
    /// An inert decimator; [`Decimator::configure`] designs the filter.
    pub const fn empty() -> Self {
        Self {
            taps: [0.0; MAX_TAPS],
            len: 1,
            factor: 1,
            line: [0.0; 2 * MAX_TAPS],
            end: 1,
            phase: 0,
        }
    }

    /// Designs the low-pass for `input_rate_hz` → [`DECIMATED_RATE_HZ`] and clears the state.
    pub fn configure(&mut self, input_rate_hz: u32) {
        let factor = (input_rate_hz / DECIMATED_RATE_HZ).max(1) as usize;
        let len = (TAPS_PER_FACTOR * factor).min(MAX_TAPS);
        let fc = CUTOFF_HZ / input_rate_hz as f32;
        let mid = (len - 1) as f32 / 2.0;
        let mut sum = 0.0f32;
        for (n, t) in self.taps[..len].iter_mut().enumerate() {
            let x = n as f32 - mid;
            let sinc = if x == 0.0 {
                2.0 * fc
            } else {
                libm::sinf(2.0 * core::f32::consts::PI * fc * x) / (core::f32::consts::PI * x)
            };
            let a = 2.0 * core::f32::consts::PI * n as f32 / (len - 1) as f32;
            let blackman = 0.42 - 0.5 * libm::cosf(a) + 0.08 * libm::cosf(2.0 * a);
            *t = sinc * blackman;
            sum += *t;
        }
        for t in &mut self.taps[..len] {
            *t /= sum;
        }
        self.len = len;
        self.factor = factor;
        self.line = [0.0; 2 * MAX_TAPS];
        self.end = len;
        self.phase = 0;
    }

    /// Decimation factor.
    pub fn factor(&self) -> usize {
        self.factor
    }

    /// Group delay of the filter, input samples.
    pub fn delay_samples(&self) -> f32 {
        (self.len - 1) as f32 / 2.0
    }

    /// Feeds a block of mono samples (`input[i] · scale`), calling `out` with every output
    /// sample; the same results as [`Decimator::push`] per sample, with the state in registers.
    pub fn push_block(&mut self, input: &[i32], scale: f32, out: &mut impl FnMut(f32)) {
        let factor = self.factor;
        let mut rest = input;
        while !rest.is_empty() {
            self.make_room();
            // Append as many inputs as fit, then the outputs whose windows end among them
            // (appending never overwrites a window still to be read).
            let start = self.end;
            let run = rest.len().min(self.line.len() - start);
            let (now, later) = rest.split_at(run);
            for (d, &m) in self.line[start..start + run].iter_mut().zip(now) {
                *d = m as f32 * scale;
            }
            self.end = start + run;
            let mut next = start + (factor - self.phase);
            while next <= self.end {
                out(self.output(next));
                next += factor;
            }
            self.phase = (self.phase + run) % factor;
            rest = later;
        }
    }

    /// Moves the last `len` inputs to the front of a full delay line.
    #[inline]
    fn make_room(&mut self) {
        if self.end == self.line.len() {
            let len = self.len;
            self.line.copy_within(self.end - len..self.end, 0);
            self.end = len;
        }
    }

    /// The filter output for the window ending before `end`.
    #[inline]
    fn output(&self, end: usize) -> f32 {
        // line[end - len .. end] holds the last `len` inputs, oldest first. The taps are
        // symmetric (linear phase): fold the window and multiply each tap once.
        let window = &self.line[end - self.len..end];
        let half = self.len / 2;
        let (head, tail) = window.split_at(self.len - half);
        let mut acc = if self.len % 2 == 1 { head[half] * self.taps[half] } else { 0.0 };
        // Pairs (oldest + newest, …) from both ends inwards; four per step.
        let (head, taps) = (&head[..half], &self.taps[..half]);
        for ((h, t), k) in head.chunks_exact(4).zip(tail.rchunks_exact(4)).zip(taps.chunks_exact(4))
        {
            acc += (h[0] + t[3]) * k[0];
            acc += (h[1] + t[2]) * k[1];
            acc += (h[2] + t[1]) * k[2];
            acc += (h[3] + t[0]) * k[3];
        }
        let done = half - half % 4;
        for i in done..half {
            acc += (head[i] + tail[half - 1 - i]) * taps[i];
        }
        acc
    }

    /// Feeds one input sample; returns an output sample every `factor` inputs.
    #[inline]
    pub fn push(&mut self, x: f32) -> Option<f32> {
        self.make_room();
        self.line[self.end] = x;
        self.end += 1;
        self.phase += 1;
        if self.phase < self.factor {
            return None;
        }
        self.phase = 0;
        Some(self.output(self.end))
    }
}

/// The spectral path's streaming state: decimator and the ring of decimated samples.
#[derive(Debug, Clone)]
pub struct SpectralPath {
    decimator: Decimator,
    /// Input samples per mono sample (the front end's spatial decimation).
    mono_decimation: usize,
    ring: [f32; ANALYSIS_LEN],
    write: usize,
    /// Decimated samples produced since configuration.
    produced: u64,
    since_analysis: usize,
    /// Passing groups of the previous analysis.
    history: crate::comb::History,
}

impl SpectralPath {
    /// An inert path; [`SpectralPath::configure`] prepares it.
    pub const fn empty() -> Self {
        Self {
            decimator: Decimator::empty(),
            mono_decimation: 1,
            ring: [0.0; ANALYSIS_LEN],
            write: 0,
            produced: 0,
            since_analysis: 0,
            history: crate::comb::History::new(),
        }
    }

    /// Designs the decimator for a mono signal at `input_rate_hz / mono_decimation` and clears
    /// the state.
    pub fn configure(&mut self, input_rate_hz: u32, mono_decimation: usize) {
        self.mono_decimation = mono_decimation.max(1);
        self.decimator.configure(input_rate_hz / self.mono_decimation as u32);
        self.ring = [0.0; ANALYSIS_LEN];
        self.write = 0;
        self.produced = 0;
        self.since_analysis = 0;
        self.history = crate::comb::History::new();
    }

    /// Feeds a block of mono samples (`mono[i] · scale`, fraction of full scale). Returns true
    /// when an analysis is due.
    pub fn push_block(&mut self, mono: &[i32], scale: f32) -> bool {
        let mut due = false;
        let Self { decimator, ring, write, produced, since_analysis, .. } = self;
        decimator.push_block(mono, scale, &mut |y| {
            ring[*write] = y;
            *write = (*write + 1) % ANALYSIS_LEN;
            *produced += 1;
            *since_analysis += 1;
            if *since_analysis >= ANALYSIS_HOP && *produced >= ANALYSIS_LEN as u64 {
                *since_analysis = 0;
                due = true;
            }
        });
        due
    }

    /// Feeds one mono sample (fraction of full scale). Returns true when an analysis is due.
    #[inline]
    pub fn push(&mut self, x: f32) -> bool {
        let Some(y) = self.decimator.push(x) else { return false };
        self.ring[self.write] = y;
        self.write = (self.write + 1) % ANALYSIS_LEN;
        self.produced += 1;
        self.since_analysis += 1;
        if self.since_analysis >= ANALYSIS_HOP && self.produced >= ANALYSIS_LEN as u64 {
            self.since_analysis = 0;
            return true;
        }
        false
    }

    /// Input-rate sample index of the first decimated sample of the current analysis window.
    /// (The window's content lags this by the decimator's group delay, under 1 ms: 47.5 input
    /// samples at 48 kHz, 15.5 at 16 kHz; the stamp leaves it out so stamps step by exactly
    /// one hop.)
    pub fn window_start_sample(&self) -> u64 {
        let first = self.produced.saturating_sub(ANALYSIS_LEN as u64);
        first * (self.decimator.factor() * self.mono_decimation) as u64
    }

    /// Decimated samples produced since [`SpectralPath::configure`].
    pub fn produced(&self) -> u64 {
        self.produced
    }

    /// Input samples per decimated sample (6 at 48 kHz, 2 at 16 kHz).
    pub fn input_per_output(&self) -> usize {
        self.decimator.factor() * self.mono_decimation
    }

    /// The `len` decimated samples from number `first` (counted as [`SpectralPath::produced`])
    /// when they are all still in the ring and do not wrap in it.
    pub fn recent(&self, first: u64, len: usize) -> Option<&[f32]> {
        let end = first.checked_add(len as u64)?;
        if end > self.produced || self.produced - first > ANALYSIS_LEN as u64 {
            return None;
        }
        let at = (first % ANALYSIS_LEN as u64) as usize;
        self.ring.get(at..at + len)
    }

    /// Input-rate samples spanned by one analysis window.
    pub fn window_span_samples(&self) -> u32 {
        (ANALYSIS_LEN * self.decimator.factor() * self.mono_decimation) as u32
    }

    /// Windows the last [`ANALYSIS_LEN`] samples into `scratch`, transforms, finds peak groups.
    /// `tw`: the phasor table ([`crate::gcc_phat::Twiddles::new`]) for the window.
    pub fn analyze(
        &mut self,
        config: &Config,
        scratch: &mut [f32; ANALYSIS_LEN],
        tw: &crate::gcc_phat::Twiddles,
    ) -> Peaks {
        let (old, new) = self.ring.split_at(self.write);
        scratch[..new.len()].copy_from_slice(new);
        scratch[new.len()..].copy_from_slice(old);
        crate::window::apply_hann(scratch, tw);
        let mut peaks = find_peaks(scratch, config, &mut self.history);
        peaks.sample_index = self.window_start_sample();
        peaks.span_samples = self.window_span_samples();
        peaks
    }
}

/// Transforms a windowed [`ANALYSIS_LEN`]-sample buffer (decimated rate), whitens the
/// spectrum and finds the rotor groups ([`crate::comb`]); `history` carries the passing groups
/// from one analysis to the next. On return `buf[..ANALYSIS_LEN / 2]` holds the magnitude
/// spectrum up to [`MAX_ANALYSIS_HZ`] (0 above) and `buf[ANALYSIS_LEN / 2..]` the whitened
/// levels.
pub fn find_peaks(
    buf: &mut [f32; ANALYSIS_LEN],
    config: &Config,
    history: &mut crate::comb::History,
) -> Peaks {
    {
        let spectrum = microfft::real::rfft_4096(buf);
        spectrum[0].im = 0.0; // the Nyquist bin is packed here; it is outside every band used
    }
    let bin_hz = DECIMATED_RATE_HZ as f32 / ANALYSIS_LEN as f32;
    let top = ((MAX_ANALYSIS_HZ / bin_hz) as usize).min(ANALYSIS_LEN / 2 - 2);
    // Magnitudes in place, up to the analysed band: bin k reads buf[2k], buf[2k+1] and writes
    // buf[k] ≤ 2k.
    for k in 0..top + 2 {
        let (re, im) = (buf[2 * k], buf[2 * k + 1]);
        let p = re * re + im * im;
        buf[k] = if p > 0.0 { p * crate::gcc_phat::rsqrt(p) } else { 0.0 };
    }
    buf[top + 2..ANALYSIS_LEN / 2].fill(0.0);
    let (mags, white) = buf.split_at_mut(ANALYSIS_LEN / 2);
    let low = (FLOOR_LOW_HZ / bin_hz) as usize;
    crate::comb::whiten(mags, white, low, top);
    let spec = crate::comb::Spectrum { mags, white, bin_hz, top };
    let hop_s = ANALYSIS_HOP as f32 / DECIMATED_RATE_HZ as f32;
    crate::comb::detect(&spec, config, hop_s, history)
}

/// Refines a spectral peak at bin `k`: (fractional bin, amplitude of the sinusoid in the
/// units of the time signal, for a Hann window of [`ANALYSIS_LEN`]).
pub fn refine_peak(mags: &[f32], k: usize) -> (f32, f32) {
    let (m0, ml, mr) = (mags[k], mags[k - 1], mags[k + 1]);
    let delta = if m0 <= 0.0 {
        0.0
    } else if mr > ml {
        let a = mr / m0;
        (2.0 * a - 1.0) / (a + 1.0)
    } else {
        let a = ml / m0;
        -(2.0 * a - 1.0) / (a + 1.0)
    };
    let delta = delta.clamp(-0.5, 0.5);
    // Hann response at offset δ relative to its centre: sinc(δ) / (1 − δ²).
    let gain = if libm::fabsf(delta) < 1e-6 {
        1.0
    } else {
        let x = core::f32::consts::PI * delta;
        sin_half_turn(x) / x / (1.0 - delta * delta)
    };
    // A real sinusoid of amplitude A gives |X| = A·N/4 with a Hann window at the bin centre.
    let amplitude = 4.0 * m0 / (ANALYSIS_LEN as f32 * gain);
    (k as f32 + delta, amplitude)
}

/// sin x for |x| ≤ π/2 by its Taylor series to x¹¹ (truncation below 6·10⁻⁹): plain f32, no
/// `libm::sinf` (which reduces in f64, software on the Cortex-M4F).
fn sin_half_turn(x: f32) -> f32 {
    let x2 = x * x;
    x * (1.0
        - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0 * (1.0 - x2 / 110.0)))))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Output RMS over input RMS of a tone through the decimator (after its transient).
    fn gain(input_rate: u32, hz: f32) -> f32 {
        let mut d = Decimator::empty();
        d.configure(input_rate);
        let (mut num, mut n) = (0.0f64, 0usize);
        for t in 0..input_rate as usize / 2 {
            let x = libm::sinf(2.0 * core::f32::consts::PI * hz * (t as f32 / input_rate as f32));
            if let Some(y) = d.push(x) {
                if t > 2 * MAX_TAPS {
                    num += (y as f64).powi(2);
                    n += 1;
                }
            }
        }
        ((num / n as f64).sqrt() / core::f64::consts::FRAC_1_SQRT_2) as f32
    }

    #[test]
    fn decimator_passes_the_bpf_band_and_stops_what_would_alias_into_it() {
        for rate in [48_000, 16_000] {
            for hz in [100.0, 1000.0, 2000.0] {
                let g = gain(rate, hz);
                assert!((g - 1.0).abs() < 0.01, "{rate} Hz input: gain {g} at {hz} Hz");
            }
        }
        // 48 kHz: everything above 5 kHz lands in 0–3 kHz after decimation by 6.
        for hz in [5000.0, 6000.0, 9000.0, 13_000.0] {
            let g = gain(48_000, hz);
            assert!(g < 1e-3, "gain {g} at {hz} Hz");
        }
    }

    #[test]
    fn half_turn_sine_matches_f64() {
        for i in -1000..=1000 {
            let x = i as f32 * core::f32::consts::FRAC_PI_2 / 1000.0;
            let e = (x as f64).sin();
            assert!((sin_half_turn(x) as f64 - e).abs() < 2e-7, "sin {x}");
        }
    }

    #[test]
    fn block_and_sample_pushes_agree_bit_for_bit() {
        let (mut a, mut b) = (Decimator::empty(), Decimator::empty());
        a.configure(48_000);
        b.configure(48_000);
        let input: Vec<i32> =
            (0..5000).map(|i: i32| i.wrapping_mul(2_654_435_761u32 as i32) >> 16).collect();
        let scale = 1.0 / 32768.0;
        let one: Vec<f32> = input.iter().filter_map(|&m| a.push(m as f32 * scale)).collect();
        let mut block = Vec::new();
        for chunk in input.chunks(777) {
            b.push_block(chunk, scale, &mut |y| block.push(y));
        }
        assert_eq!(one.len(), 5000 / 6);
        assert!(
            one.iter().zip(&block).all(|(x, y)| x.to_bits() == y.to_bits())
                && one.len() == block.len()
        );
    }

    #[test]
    fn hann_ratio_refinement_recovers_off_bin_tones() {
        for &offset in &[-0.45f32, -0.2, 0.0, 0.13, 0.37, 0.49] {
            let bin = 200.0 + offset;
            let mut buf = [0.0f32; ANALYSIS_LEN];
            for (t, x) in buf.iter_mut().enumerate() {
                *x = 0.3
                    * libm::cosf(
                        2.0 * core::f32::consts::PI * bin * t as f32 / ANALYSIS_LEN as f32 + 0.4,
                    );
            }
            crate::window::apply_hann(&mut buf, &crate::gcc_phat::Twiddles::new());
            let config = Config::new(crate::Geometry::respeaker_4mic(), 48_000);
            let _ = find_peaks(&mut buf, &config, &mut crate::comb::History::new()); // leaves the magnitudes in buf
            let k = (199..=201).max_by(|&a, &b| buf[a].total_cmp(&buf[b])).unwrap();
            let (b, amp) = refine_peak(&buf[..ANALYSIS_LEN / 2], k);
            assert!((b - bin).abs() < 2e-3, "offset {offset}: bin {b}");
            assert!((amp - 0.3).abs() < 0.3 * 0.01, "offset {offset}: amplitude {amp}");
        }
    }
}
