//! The synchronisation beacon: its published waveform and the chip's matched-filter detector.
//!
//! # Waveform (`aim-beacon-v1`)
//! A 127-chip m-sequence ([`chips`]: Fibonacci LFSR x⁷ + x⁶ + 1, seed all ones, chip = +1 for
//! a 1 bit) at 2 000 chips/s, each chip a sin² (Hann) pulse two chips long (48 samples at
//! 48 kHz, pulses overlap by half so equal neighbours add to a flat 1), BPSK on an 18 kHz
//! cosine carrier:
//!
//! `s(t) = Σₖ cₖ · sin²(π (t − 24k) / 48) · cos(2π · 18 000 · t / 48 000)` for `0 ≤ t − 24k < 48`,
//!
//! t in 48 kHz samples from the first sample of the emission, [`LEN`] = 3 072 samples
//! (64 ms), peak amplitude 1. The Hann pulse puts the main lobe exactly on 16–20 kHz (its first
//! null at ±1/T_chip = ±2 kHz), side lobes −31 dB and falling 18 dB per octave, far above the
//! drone DSP's bands (DoA ≤ 6 kHz, BPF ≤ 2 kHz). [`waveform_at`] evaluates it at any real time
//! (the simulator's loudspeaker); the detector uses it at integer samples. It is a published
//! product constant like a CRC polynomial.
//!
//! # Detector
//! Fed one microphone's raw 48 kHz words (the reference microphone, mic 0, before the
//! half-band and without DC removal: the band-pass below has no response at DC).
//! 1. **Mix, chip-matched filter and decimate by 12** in one complex FIR: `y[m] = Σₖ g[k] ·
//!    x[12m − k]`, `g[k] = sin²(πk/48) · e^{j 3πk/4}` (the chip pulse on the 18 kHz carrier,
//!    48 taps): complex baseband at 4 kHz, the 16–20 kHz band folded onto ±2 kHz. The taps
//!    come in conjugate pairs (`g[48 − k] = conj(g[k])`), a quarter of the real and of the
//!    imaginary parts are zero: one output costs 23 sums or differences and 35
//!    multiply-adds.
//! 2. **Correlate** with the template `r` (the same FIR applied to the waveform, 260 samples)
//!    by overlap-save: 512-point complex FFT of the newest 512 baseband samples, product with
//!    the template's stored spectrum, inverse FFT; 253 new lags per transform (≈ 15.8 per
//!    second). The radix-4 pair [`crate::fft::dif_512`] / [`crate::fft::dit_512`]: the
//!    product is formed in the DIF's scrambled bin order, no reordering.
//! 3. **Pick** local maxima of `|c|` whose quality `q = |c| / √(Σ|r|² · Σ|y_window|²)` (the
//!    normalised correlation, 0..1, Cauchy–Schwarz) is at least [`QUALITY_MIN`]; the strongest
//!    one within [`GUARD`] baseband samples is the emission (one output per emission: echoes
//!    and side lobes inside the guard are not reported). **First path:** a reflection can be
//!    stronger than the direct sound (a ceiling or floor bounce with the direct path shadowed
//!    or off the microphone's axis); the reported peak is the earliest local maximum within
//!    [`FIRST_PATH_WINDOW`] lags (7.25 ms) before the strongest one whose |c| is at least
//!    [`FIRST_PATH_FRACTION`] of the strongest's (above the m-sequence's side lobes) and whose
//!    own `q` is at least [`FIRST_PATH_QUALITY_MIN`] (above noise), or the strongest itself.
//!    `quality` and `level_db` are those of the reported peak. Two paths less than about one
//!    chip (0.5 ms) apart are one peak, and their sum bends the envelope (step 4 (a)).
//! 4. **Refine** to a fraction of an input sample. With the arrival at input sample n₀ the
//!    correlation is `c[m] = ¼ (−1)^m e^{−j 3π n₀/4} E(12m − n₀) = ¼ e^{−j 3π δ/4} E(−δ)` with
//!    `n₀ = 12m + δ` (as `e^{−j 9π m} = (−1)^m`), E the real envelope
//!    autocorrelation. (a) Coarse: the envelope ratio `ρ = (|c[m*+1]| − |c[m*−1]|) / |c[m*]|`
//!    is inverted through a table of ρ at whole-sample offsets −6..6 computed from the template
//!    itself at configuration (linear interpolation between them): δ̂ with n₀ ≈ 12m* + δ̂,
//!    good to a fraction of a sample. (b) Fine: the carrier phase `ψ = arg(c[m*]) = −3π δ/4
//!    (mod 2π)` (exact whatever the decimation aliases: E is real) fixes n₀ modulo one carrier period (8/3 samples); the value nearest
//!    the coarse one is kept. The phase estimate's noise is `1/(2π f_c √(2 E/N₀))`, the
//!    carrier's precision rather than the envelope's; a coarse error beyond ±4/3 samples
//!    (28 µs) would slip one carrier cycle (56 µs), which the quality threshold keeps rare.
//!
//! The arrival is that of the emission's first sample (t = 0 above) at microphone 0, on the
//! board's input clock, when the speaker's and the board's clocks run at the same rate. When
//! they differ by a relative rate ε (their drifts), the received emission is stretched by ε
//! and the matched filter locks onto its centre: the report is then the arrival of the
//! emission's centre less `LEN / 2` board samples (the first sample's arrival + ε · LEN / 2,
//! 0.15 sample at 100 ppm). A clock model should therefore use `reported + LEN / 2` as the
//! arrival of the emission's centre, which is exact for any drift.
//!
//! Memory: about 10.5 KiB (two 512-point complex buffers, the converted input, the last 32
//! lags for the first-path search); the overlap
//! tail is parked in the caller's scratch during the transform.

use microfft::Complex32;

/// Input sample rate the waveform and detector are defined at, Hz.
pub const SAMPLE_RATE_HZ: u32 = 48_000;
/// Carrier frequency, Hz.
pub const CARRIER_HZ: f32 = 18_000.0;
/// Chips of the m-sequence (2⁷ − 1).
pub const CHIPS: usize = 127;
/// Input samples per chip (2 000 chips/s).
pub const CHIP_SAMPLES: usize = 24;
/// Length of the chip pulse (sin², two chips), input samples.
pub const PULSE_SAMPLES: usize = 2 * CHIP_SAMPLES;
/// Length of one emission, input samples (64 ms).
pub const LEN: usize = (CHIPS - 1) * CHIP_SAMPLES + PULSE_SAMPLES;
/// Name of the sequence as written in site files (`[[beacon]] sequence`).
pub const SEQUENCE_NAME: &str = "aim-beacon-v1";
/// Decimation of the baseband (4 kHz complex).
pub const DECIMATION: usize = 12;
/// Taps of the mixing, chip-matched decimation filter.
pub const TAPS: usize = PULSE_SAMPLES;
/// Template length at the baseband rate.
pub const TEMPLATE_LEN: usize = (LEN - 1 + TAPS - 1) / DECIMATION + 1;
/// Overlap-save transform length.
pub const FFT_LEN: usize = 512;
/// New correlation lags per transform.
pub const HOP: usize = FFT_LEN - TEMPLATE_LEN + 1;
/// Least normalised correlation reported (false alarms on noise alone: see BENCHMARKS.md).
pub const QUALITY_MIN: f32 = 0.4;
/// Baseband samples around a reported peak within which no other peak is reported (one
/// template length, 65 ms).
pub const GUARD: u64 = TEMPLATE_LEN as u64;
/// Scratch floats [`Detector::push`] needs.
pub const SCRATCH_LEN: usize = 2 * (TEMPLATE_LEN - 1) + FFT_LEN;
/// Whole-sample offsets of the coarse table: −OFFSETS..=OFFSETS.
const OFFSETS: usize = DECIMATION / 2;

/// The ±1 chips of the `aim-beacon-v1` m-sequence.
pub const fn chips() -> [i8; CHIPS] {
    let mut out = [0i8; CHIPS];
    let mut state: u8 = 0x7F;
    let mut i = 0;
    while i < CHIPS {
        out[i] = if state & 1 == 1 { 1 } else { -1 };
        // x⁷ + x⁶ + 1: the new bit is s₀ ⊕ s₁, shifted in at the top.
        let bit = (state ^ (state >> 1)) & 1;
        state = (state >> 1) | (bit << 6);
        i += 1;
    }
    out
}

/// The chips as a table.
pub const CHIP_TABLE: [i8; CHIPS] = chips();

/// The beacon waveform at time `t` (48 kHz samples from the emission's first sample; zero
/// outside `[0, LEN)`), peak amplitude 1. See the module docs.
pub fn waveform_at(t: f64) -> f64 {
    if !(t > 0.0 && t < LEN as f64) {
        return 0.0;
    }
    let cs = CHIP_SAMPLES as f64;
    // Chips whose pulse covers t: k with 0 ≤ t − 24k < 48.
    let hi = libm::floor(t / cs) as usize;
    let mut env = 0.0;
    for k in [hi.wrapping_sub(1), hi] {
        if k < CHIPS {
            let u = t - cs * k as f64;
            if (0.0..PULSE_SAMPLES as f64).contains(&u) {
                let s = libm::sin(core::f64::consts::PI * u / PULSE_SAMPLES as f64);
                env += f64::from(CHIP_TABLE[k]) * s * s;
            }
        }
    }
    // 18 kHz at 48 kHz: 3π/4 per sample; t mod 8 keeps the argument small.
    let phase = 0.75 * core::f64::consts::PI * libm::fmod(t, 8.0);
    env * libm::cos(phase)
}

/// sin²(π u / PULSE_SAMPLES), u = 0 .. PULSE_SAMPLES: the chip pulse at whole samples.
static PULSE: [f64; PULSE_SAMPLES] = {
    let mut t = [0.0; PULSE_SAMPLES];
    let mut u = 0;
    while u < PULSE_SAMPLES {
        let s = crate::trig::cos_sin(core::f64::consts::PI * u as f64 / PULSE_SAMPLES as f64).1;
        t[u] = s * s;
        u += 1;
    }
    t
};

/// cos(3π/4 · r), r = 0 .. 8 (the argument reduced to [−π, π]): the 18 kHz carrier at whole
/// 48 kHz samples.
static CARRIER: [f64; 8] = {
    let mut t = [0.0; 8];
    let mut r = 0;
    while r < 8 {
        let k = (3 * r) % 8; // 3π/4 · r = π/4 · k (mod 2π)
        let k = if k > 4 { k as i64 - 8 } else { k as i64 };
        t[r] = crate::trig::cos_sin(core::f64::consts::PI * k as f64 / 4.0).0;
        r += 1;
    }
    t
};

/// `waveform_at(t as f64)` at whole input samples, within 10⁻¹⁵ (peak 1), from [`PULSE`] and
/// [`CARRIER`], built at compile time: two multiplications and an addition per sample instead
/// of software sines (≈ 10 k instructions a sample on the Cortex-M4F, which made
/// [`Detector::configure`] take about 10 s on the chip), and no f64 trigonometry in the image.
fn waveform_at_sample(t: usize) -> f64 {
    if t == 0 || t >= LEN {
        return 0.0;
    }
    let hi = t / CHIP_SAMPLES;
    let mut env = 0.0;
    for k in [hi.wrapping_sub(1), hi] {
        if k < CHIPS {
            let u = t - CHIP_SAMPLES * k;
            if u < PULSE_SAMPLES {
                let p = PULSE[u];
                env += if CHIP_TABLE[k] > 0 { p } else { -p };
            }
        }
    }
    env * CARRIER[t % 8]
}

/// One detected emission.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Beacon {
    /// Integer part of the arrival: the input-clock sample index at which the emission's first
    /// sample reached microphone 0.
    pub sample_index: u64,
    /// Sub-sample part of the arrival, input samples, in [0, 1).
    pub fraction: f32,
    /// Normalised correlation of the received window with the template, 0..1 (1: the beacon
    /// alone, noiseless); at least [`QUALITY_MIN`].
    pub quality: f32,
    /// Received peak amplitude of the waveform at microphone 0, dB re full scale.
    pub level_db: f32,
}

/// A correlation lag: its value and the energy of the received window it covers.
#[derive(Debug, Clone, Copy)]
struct Lag {
    m: u64,
    c: Complex32,
    energy: f32,
}

const ZERO: Complex32 = Complex32::new(0.0, 0.0);
const LAG0: Lag = Lag { m: 0, c: ZERO, energy: 0.0 };

/// Input samples converted per pass of [`Detector::push`] (a multiple of [`DECIMATION`]).
const BLOCK: usize = 8 * DECIMATION;
/// The converted input: `TAPS − 1` samples of history, then up to [`BLOCK`] new ones.
const LIN_LEN: usize = TAPS - 1 + BLOCK;
/// Taps of one half of the symmetric filter (k = 0..=TAPS/2; tap TAPS − k is the conjugate).
const HALF: usize = TAPS / 2 + 1;

/// Lags before the strongest peak searched for an earlier (direct-path) peak: 7.25 ms at the
/// 4 kHz baseband, 2.5 m of extra path for the reflection.
pub const FIRST_PATH_WINDOW: usize = RING - 3;
/// An earlier peak is the direct path if its |c| is at least this fraction of the strongest
/// peak's (the m-sequence's correlation side lobes stay below 0.2 of the main lobe)...
pub const FIRST_PATH_FRACTION: f32 = 0.3;
/// ... and its own normalised correlation at least this (noise alone stays below ≈ 0.2).
pub const FIRST_PATH_QUALITY_MIN: f32 = 0.25;
/// Lags kept for the first-path search: the window and both neighbours of its peaks (a power
/// of two: the ring index is a mask).
const RING: usize = 32;

/// Peak picking over the correlation lags (module docs, step 3 and the first path).
#[derive(Debug, Clone)]
struct Picker {
    /// The last [`RING`] lags, the newest at `newest`.
    ring: [Lag; RING],
    newest: usize,
    lags_seen: u64,
    /// Whether an emission is pending (no `Option`: the firmware's zeroed `Pipeline` static
    /// holds only integers, floats, bools and arrays).
    has_pending: bool,
    /// The peak to report for the pending emission (the first path), with its neighbours.
    pending: [Lag; 3],
    /// Quality of the reported peak.
    pending_q: f32,
    /// The strongest peak of the current emission: its lag and quality.
    best_m: u64,
    best_q: f32,
}

impl Picker {
    const fn new() -> Self {
        Self {
            ring: [LAG0; RING],
            newest: 0,
            lags_seen: 0,
            has_pending: false,
            pending: [LAG0; 3],
            pending_q: 0.0,
            best_m: 0,
            best_q: 0.0,
        }
    }

    /// The lag `back` lags before the newest one.
    fn at(&self, back: usize) -> Lag {
        self.ring[self.newest.wrapping_sub(back) % RING]
    }

    /// Normalised correlation of `l` if it is a local maximum of |c| between `a` and `n` and
    /// reaches `min`. The test is on the squares: the square root (a software routine on the
    /// Cortex-M4F, ≈ 100 instructions) is taken only for a peak that passes, about one local
    /// maximum in a hundred in noise.
    fn peak_quality(a: &Lag, l: &Lag, n: &Lag, template_energy: f32, min: f32) -> Option<f32> {
        let mag = l.c.norm_sqr();
        if mag < a.c.norm_sqr() || mag <= n.c.norm_sqr() || l.energy <= 0.0 {
            return None;
        }
        let q2 = mag / (template_energy * l.energy);
        (q2 >= min * min).then(|| libm::sqrtf(q2)).filter(|&q| q >= min)
    }

    fn take(
        &mut self,
        lag: Lag,
        template_energy: f32,
        ratio: &[f32; 2 * OFFSETS + 1],
        gain: &[f32; 2 * OFFSETS + 1],
        out: &mut impl FnMut(Beacon),
    ) {
        self.newest = (self.newest + 1) % RING;
        self.ring[self.newest] = lag;
        self.lags_seen += 1;
        if self.has_pending && lag.m > self.best_m + GUARD {
            if let Some(d) = refine(&self.pending, template_energy, self.pending_q, ratio, gain) {
                out(d);
            }
            self.has_pending = false;
        }
        if self.lags_seen < 3 {
            return;
        }
        let (a, b) = (self.at(2), self.at(1));
        let Some(q) = Self::peak_quality(&a, &b, &lag, template_energy, QUALITY_MIN) else {
            return;
        };
        if self.has_pending && (q <= self.best_q || b.m > self.best_m + GUARD) {
            return;
        }
        // A new strongest peak: the earliest credible peak up to FIRST_PATH_WINDOW lags before
        // it is the direct path (a stronger reflection follows it).
        self.best_m = b.m;
        self.best_q = q;
        let floor = FIRST_PATH_FRACTION * FIRST_PATH_FRACTION * b.c.norm_sqr();
        let mut first = ([a, b, lag], q);
        let reach = (FIRST_PATH_WINDOW as u64).min(self.lags_seen - 3) as usize;
        for back in (2..reach + 2).rev() {
            let (pa, p, pn) = (self.at(back + 1), self.at(back), self.at(back - 1));
            if p.c.norm_sqr() < floor {
                continue;
            }
            if let Some(pq) =
                Self::peak_quality(&pa, &p, &pn, template_energy, FIRST_PATH_QUALITY_MIN)
            {
                first = ([pa, p, pn], pq);
                break;
            }
        }
        self.has_pending = true;
        self.pending = first.0;
        self.pending_q = first.1;
    }
}

/// The streaming matched-filter detector, fixed memory. See the module docs.
#[derive(Debug, Clone)]
pub struct Detector {
    /// Filter taps k = 0..=TAPS/2 (tap TAPS − k is the conjugate of tap k), real parts.
    taps_re: [f32; HALF],
    /// Imaginary parts.
    taps_im: [f32; HALF],
    /// The input as floats: `lin[i]` is input sample `base + i`.
    lin: [f32; LIN_LEN],
    len: usize,
    base: u64,
    /// Input sample index of the next baseband output (a multiple of DECIMATION).
    next_out: u64,
    /// Baseband samples of the transform being filled.
    buf: [Complex32; FFT_LEN],
    fill: usize,
    /// Template spectrum, scaled by 1/FFT_LEN, in [`crate::fft::dif_512`]'s scrambled order.
    spectrum: [Complex32; FFT_LEN],
    /// Σ|r|² of the template.
    template_energy: f32,
    /// Envelope ratio ρ at offsets −OFFSETS..=OFFSETS.
    ratio: [f32; 2 * OFFSETS + 1],
    /// |c| at lag 0 relative to the aligned one, at the same offsets.
    gain: [f32; 2 * OFFSETS + 1],
    picker: Picker,
}

impl Detector {
    /// A detector that must be [`Detector::configure`]d before use; `const` for statics.
    pub const fn empty() -> Self {
        Self {
            taps_re: [0.0; HALF],
            taps_im: [0.0; HALF],
            lin: [0.0; LIN_LEN],
            len: TAPS - 1,
            base: 0,
            next_out: 0,
            buf: [ZERO; FFT_LEN],
            fill: 0,
            spectrum: [ZERO; FFT_LEN],
            template_energy: 0.0,
            ratio: [0.0; 2 * OFFSETS + 1],
            gain: [0.0; 2 * OFFSETS + 1],
            picker: Picker::new(),
        }
    }

    /// Computes the filter, the template, its spectrum and the refinement tables (about
    /// 0.3 M multiply-adds, once), and restarts at input sample 0.
    #[inline(never)] // once per start; out of line so that its cost can be measured
    pub fn configure(&mut self) {
        let tap = |k: usize| -> (f32, f32) {
            let s = libm::sinf(core::f32::consts::PI * k as f32 / TAPS as f32);
            let w = s * s;
            // e^{j 3πk/4}: the phase repeats every 8 taps.
            let a = 0.75 * core::f32::consts::PI * (k % 8) as f32;
            (w * libm::cosf(a), w * libm::sinf(a))
        };
        for k in 0..HALF {
            (self.taps_re[k], self.taps_im[k]) = tap(k);
        }
        // Exact zeros where the carrier's cosine or sine vanishes (the filter skips them).
        for k in 0..HALF {
            if k % 4 == 2 {
                self.taps_re[k] = 0.0;
            }
            if k % 4 == 0 {
                self.taps_im[k] = 0.0;
            }
        }
        // The template and its offset copies: the filter over the waveform delayed by d. The
        // waveform is read at whole input samples only, from its pulse and carrier tables
        // (`waveform_at_sample`: `waveform_at` without a software sine per sample).
        let (taps_re, taps_im) = (self.taps_re, self.taps_im);
        let filtered = |d: isize, m: isize| -> Complex32 {
            let mut acc = ZERO;
            for k in 1..TAPS {
                let t = DECIMATION as isize * m - k as isize - d;
                if t > 0 && t < LEN as isize {
                    let x = waveform_at_sample(t as usize) as f32;
                    let (re, im) = if k < HALF {
                        (taps_re[k], taps_im[k])
                    } else {
                        (taps_re[TAPS - k], -taps_im[TAPS - k])
                    };
                    acc.re += re * x;
                    acc.im += im * x;
                }
            }
            acc
        };
        let mut energy = 0.0;
        for (m, b) in self.buf.iter_mut().enumerate() {
            *b = if m < TEMPLATE_LEN { filtered(0, m as isize) } else { ZERO };
            energy += b.norm_sqr();
        }
        self.template_energy = energy;
        // Coarse table: |c| at lags −1, 0, 1 for the waveform delayed by d samples. The delayed
        // copy at baseband samples −1 ..= TEMPLATE_LEN is formed once per d (in `spectrum`,
        // free until the end) and read at the three lags.
        let mut mags = [[0.0f32; 3]; 2 * OFFSETS + 1];
        for (i, row) in mags.iter_mut().enumerate() {
            let d = i as isize - OFFSETS as isize;
            let copy = &mut self.spectrum[..TEMPLATE_LEN + 2];
            for (m, c) in copy.iter_mut().enumerate() {
                *c = filtered(d, m as isize - 1);
            }
            for (j, v) in row.iter_mut().enumerate() {
                let mut acc = ZERO;
                for (y, r) in copy[j..].iter().zip(&self.buf[..TEMPLATE_LEN]) {
                    acc += *y * r.conj();
                }
                *v = libm::sqrtf(acc.norm_sqr());
            }
        }
        let aligned = mags[OFFSETS][1];
        for (i, row) in mags.iter().enumerate() {
            self.ratio[i] = (row[2] - row[0]) / row[1];
            self.gain[i] = row[1] / aligned;
        }
        crate::fft::dif_512(&mut self.buf);
        let scale = 1.0 / FFT_LEN as f32;
        for (s, &f) in self.spectrum.iter_mut().zip(self.buf.iter()) {
            *s = f * scale;
        }
        self.restart(0);
    }

    /// Forgets everything heard; the next sample pushed has input index `next`.
    fn restart(&mut self, next: u64) {
        self.lin[..TAPS - 1].fill(0.0);
        self.len = TAPS - 1;
        self.base = next.wrapping_sub(TAPS as u64 - 1);
        self.next_out = next.div_ceil(DECIMATION as u64) * DECIMATION as u64;
        self.fill = 0;
        self.picker = Picker::new();
    }

    /// `lost` input samples were lost before the next one: the detector restarts after them (an
    /// emission in progress is dropped).
    pub fn gap(&mut self, lost: u64) {
        if lost > 0 {
            self.restart(self.next_index() + lost);
        }
    }

    /// Input index of the next sample.
    pub fn next_index(&self) -> u64 {
        self.base.wrapping_add(self.len as u64)
    }

    /// Pushes input words (24-bit samples left-justified in i32, Q31), one every `stride` words
    /// from `words[0]`; `scratch` holds at least [`SCRATCH_LEN`] floats (its contents are
    /// overwritten); detections go to `out`.
    #[inline(never)]
    pub fn push(
        &mut self,
        words: &[i32],
        stride: usize,
        scratch: &mut [f32],
        out: &mut impl FnMut(Beacon),
    ) {
        const Q31: f32 = 1.0 / 2_147_483_648.0;
        let stride = stride.max(1);
        let mut words = words;
        // The taps on the stack: near the stack pointer, not at the pipeline's static address.
        let taps = (self.taps_re, self.taps_im);
        while !words.is_empty() {
            let len = self.len;
            let take = (LIN_LEN - len).min(words.len().div_ceil(stride));
            let dst = &mut self.lin[len..len + take];
            // Whole strides, then the first word of a trailing partial one.
            let whole = take.min(words.len() / stride);
            for (x, w) in dst.iter_mut().zip(words.chunks_exact(stride)) {
                *x = w[0] as f32 * Q31;
            }
            if let (Some(x), Some(&w)) = (dst.get_mut(whole), words.get(whole * stride)) {
                *x = w as f32 * Q31;
            }
            self.len = len + take;
            words = words.get(take * stride..).unwrap_or(&[]);
            // Baseband outputs whose newest input sample has arrived.
            while self.next_out < self.base.wrapping_add(self.len as u64) {
                let newest = self.next_out.wrapping_sub(self.base) as usize;
                let y = filter(&self.lin, newest, &taps);
                self.buf[self.fill] = y;
                self.fill += 1;
                self.next_out += DECIMATION as u64;
                if self.fill == FFT_LEN {
                    self.correlate(scratch, out);
                }
            }
            if self.len == LIN_LEN {
                self.lin.copy_within(LIN_LEN - (TAPS - 1).., 0);
                self.base = self.base.wrapping_add((LIN_LEN - (TAPS - 1)) as u64);
                self.len = TAPS - 1;
            }
        }
    }
}

/// One baseband sample: `y = Σₖ g[k] · x[n − k]` with `x[n]` = `lin[newest]`, as pairs
/// `g[TAPS − k] = conj(g[k])` (k = 1..TAPS/2; g[0] = 0) and without the zero taps.
#[inline(always)]
fn filter(lin: &[f32], newest: usize, taps: &([f32; HALF], [f32; HALF])) -> Complex32 {
    let Some(win) = lin.get(newest + 1 - TAPS..=newest) else { return ZERO };
    let Ok(win) = <&[f32; TAPS]>::try_from(win) else { return ZERO };
    let (wr, wi) = (&taps.0, &taps.1);
    // x[n − k] = win[TAPS − 1 − k]; its partner x[n − TAPS + k] = win[k − 1].
    let mut re = wr[TAPS / 2] * win[TAPS - 1 - TAPS / 2];
    let mut im = 0.0f32;
    macro_rules! pair {
        (both $k:literal) => {{
            let (a, b) = (win[TAPS - 1 - $k], win[$k - 1]);
            re += wr[$k] * (a + b);
            im += wi[$k] * (a - b);
        }};
        (re $k:literal) => {{
            re += wr[$k] * (win[TAPS - 1 - $k] + win[$k - 1]);
        }};
        (im $k:literal) => {{
            im += wi[$k] * (win[TAPS - 1 - $k] - win[$k - 1]);
        }};
    }
    // cos(3πk/4) = 0 for k ≡ 2 (mod 4), sin(3πk/4) = 0 for k ≡ 0 (mod 4).
    pair!(both 1);
    pair!(im 2);
    pair!(both 3);
    pair!(re 4);
    pair!(both 5);
    pair!(im 6);
    pair!(both 7);
    pair!(re 8);
    pair!(both 9);
    pair!(im 10);
    pair!(both 11);
    pair!(re 12);
    pair!(both 13);
    pair!(im 14);
    pair!(both 15);
    pair!(re 16);
    pair!(both 17);
    pair!(im 18);
    pair!(both 19);
    pair!(re 20);
    pair!(both 21);
    pair!(im 22);
    pair!(both 23);
    Complex32::new(re, im)
}

impl Detector {
    /// One overlap-save transform over the full buffer; leaves its tail as the next buffer's
    /// head.
    #[inline(never)]
    fn correlate(&mut self, scratch: &mut [f32], out: &mut impl FnMut(Beacon)) {
        let keep = TEMPLATE_LEN - 1;
        let (tail, power) = scratch.split_at_mut(2 * keep);
        let power = &mut power[..FFT_LEN];
        for ((t, p), b) in tail.chunks_exact_mut(2).zip(power.iter_mut()).zip(&self.buf[HOP..]) {
            t[0] = b.re;
            t[1] = b.im;
            *p = b.norm_sqr();
        }
        for (p, b) in power[keep..].iter_mut().zip(&self.buf[..HOP]) {
            *p = b.norm_sqr();
        }
        // power[keep + j] = |buf[j]|² (j < HOP), power[j] = |buf[HOP + j]|²: window energy of
        // lag j = Σ |buf[j .. j + TEMPLATE_LEN]|².
        let pw = |i: usize, power: &[f32]| if i < HOP { power[keep + i] } else { power[i - HOP] };
        let mut energy: f32 = (0..TEMPLATE_LEN).map(|i| pw(i, power)).sum();
        // Circular correlation: conj(FFT(conj(Y) · R)) / N, both spectra in the scrambled
        // order of the radix-4 DIF, the second transform a DIT taking that order.
        crate::fft::dif_512(&mut self.buf);
        for (y, r) in self.buf.iter_mut().zip(&self.spectrum) {
            *y = y.conj() * r;
        }
        crate::fft::dit_512(&mut self.buf);
        let corr = &self.buf;
        let m0 = self.next_out / DECIMATION as u64 - FFT_LEN as u64;
        for (j, c) in corr[..HOP].iter().enumerate() {
            let lag = Lag { m: m0 + j as u64, c: c.conj(), energy: energy.max(0.0) };
            energy += pw(j + TEMPLATE_LEN, power) - pw(j, power);
            self.picker.take(lag, self.template_energy, &self.ratio, &self.gain, out);
        }
        for (b, t) in self.buf.iter_mut().zip(tail.chunks_exact(2)) {
            *b = Complex32::new(t[0], t[1]);
        }
        self.fill = keep;
    }
}

/// Sub-sample arrival from a peak and its neighbours (module docs, step 4).
fn refine(
    p: &[Lag; 3],
    template_energy: f32,
    q: f32,
    ratio: &[f32; 2 * OFFSETS + 1],
    gain: &[f32; 2 * OFFSETS + 1],
) -> Option<Beacon> {
    let mag = |c: Complex32| libm::sqrtf(c.norm_sqr());
    let (c0, c1, c2) = (mag(p[0].c), mag(p[1].c), mag(p[2].c));
    let rho = (c2 - c0) / c1;
    // ratio[] rises with the offset; invert it by linear interpolation.
    let n = ratio.len();
    let mut delta = if rho <= ratio[0] { -(OFFSETS as f32) } else { OFFSETS as f32 };
    let mut g = 1.0f32;
    for i in 0..n - 1 {
        let (lo, hi) = (ratio[i], ratio[i + 1]);
        if rho >= lo && rho <= hi && hi > lo {
            let f = (rho - lo) / (hi - lo);
            delta = i as f32 - OFFSETS as f32 + f;
            g = gain[i] + f * (gain[i + 1] - gain[i]);
            break;
        }
    }
    // Carrier phase: (−1)^m e^{−j3π n₀/4} = e^{−j3π δ/4} with n₀ = 12m + δ, so
    // arg(c) = −3π δ / 4 (mod 2π).
    let c = p[1].c;
    let period = 8.0 / 3.0;
    let by_phase = -libm::atan2f(c.im, c.re) * (4.0 / (3.0 * core::f32::consts::PI));
    let cycles = libm::roundf((delta - by_phase) / period);
    let offset = by_phase + cycles * period;
    let whole = libm::floorf(offset);
    let start = (p[1].m * DECIMATION as u64) as i64 + whole as i64;
    if start < 0 {
        return None;
    }
    let amplitude = c1 / (template_energy * g.max(0.1));
    Some(Beacon {
        sample_index: start as u64,
        fraction: (offset - whole).clamp(0.0, 0.999_984_7),
        quality: q.min(1.0),
        level_db: 20.0 * libm::log10f(amplitude.max(1e-12)),
    })
}

impl Default for Detector {
    fn default() -> Self {
        Self::empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn waveform_at_sample_is_waveform_at() {
        for t in 0..LEN + 30 {
            let (got, want) = (waveform_at_sample(t), waveform_at(t as f64));
            assert!((got - want).abs() < 1e-15, "t = {t}: {got} vs {want}");
        }
    }

    /// Words of a signal: `amp` · waveform starting at `start` (real), plus white noise of
    /// `noise` rms (fraction of full scale), `len` samples.
    fn signal(len: usize, starts: &[f64], amp: f64, noise: f64, seed: u64) -> Vec<i32> {
        let mut state = seed | 1;
        let mut rand = move || {
            // xorshift64*, uniform in (−0.5, 0.5)
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            (state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        (0..len)
            .map(|n| {
                let s: f64 = starts.iter().map(|&t0| waveform_at(n as f64 - t0)).sum();
                // Sum of 12 uniforms: variance 1.
                let g: f64 = (0..12).map(|_| rand()).sum();
                let v = amp * s + noise * g;
                ((v * 8_388_608.0).round().clamp(-8_388_607.0, 8_388_607.0) as i32) << 8
            })
            .collect()
    }

    fn detect(words: &[i32], chunk: usize) -> Vec<Beacon> {
        let mut d = Detector::empty();
        d.configure();
        let mut scratch = [0.0f32; SCRATCH_LEN];
        let mut found = Vec::new();
        for c in words.chunks(chunk) {
            d.push(c, 1, &mut scratch, &mut |b| found.push(b));
        }
        found
    }

    #[test]
    fn chips_are_an_m_sequence() {
        let c = CHIP_TABLE;
        assert_eq!(c.iter().filter(|&&x| x == 1).count(), 64);
        // Periodic autocorrelation −1 at every non-zero shift.
        for s in 1..CHIPS {
            let r: i32 = (0..CHIPS).map(|i| i32::from(c[i]) * i32::from(c[(i + s) % CHIPS])).sum();
            assert_eq!(r, -1, "shift {s}");
        }
    }

    #[test]
    fn waveform_is_in_band() {
        // DFT power of the waveform: ≥ 99 % between 16 and 20 kHz.
        let x: Vec<f64> = (0..LEN).map(|n| waveform_at(n as f64)).collect();
        let (mut inband, mut total) = (0.0, 0.0);
        for k in 0..LEN / 2 {
            let f = k as f64 * 48_000.0 / LEN as f64;
            let (mut re, mut im) = (0.0, 0.0);
            for (n, &v) in x.iter().enumerate() {
                let a = 2.0 * core::f64::consts::PI * (k * n) as f64 / LEN as f64;
                re += v * a.cos();
                im -= v * a.sin();
            }
            let p = re * re + im * im;
            total += p;
            if (16_000.0..=20_000.0).contains(&f) {
                inband += p;
            }
        }
        assert!(inband / total > 0.99, "in band {}", inband / total);
        assert!(x.iter().all(|v| v.abs() <= 1.0 + 1e-12));
    }

    #[test]
    fn noiseless_arrivals_are_exact_at_any_fraction() {
        // Oracle: the waveform placed at a known real start; the estimate must match it.
        for (i, &start) in [1000.0, 1000.25, 1003.5, 1007.75, 1011.9, 5000.333].iter().enumerate() {
            let words = signal(16_000, &[start], 0.01, 0.0, 1);
            let found = detect(&words, 256 + i * 37);
            assert_eq!(found.len(), 1, "start {start}: {found:?}");
            let b = found[0];
            let got = b.sample_index as f64 + f64::from(b.fraction);
            assert!((got - start).abs() < 0.02, "start {start}: got {got}");
            assert!(b.quality > 0.9, "{b:?}");
            assert!((b.level_db + 40.0).abs() < 0.2, "{b:?}");
        }
    }

    #[test]
    fn noisy_arrival_jitter_matches_the_carrier_bound() {
        // Beacon amplitude 1e-2 (−40 dBFS) in white noise of 1e-2 rms (−40 dBFS), in-band SNR
        // per sample about +3 dB; the carrier-phase bound σ = 1/(2π f_c √(2E/N₀)), with
        // 2E/N₀ = Σ s² / σ² in samples, is ≈ 0.013 sample (0.26 µs) here. Assert the measured
        // sd is within 3× that and the bias small. (At much lower SNR the coarse envelope step
        // slips carrier cycles of 8/3 samples: BENCHMARKS.md.)
        let (amp, noise) = (1e-2, 1e-2);
        let e: f64 = (0..LEN).map(|n| (amp * waveform_at(n as f64)).powi(2)).sum();
        let n0 = noise * noise;
        let bound_samples = 1.0 / (2.0 * core::f64::consts::PI * 0.375 * (e / n0).sqrt());
        let mut errs = Vec::new();
        for seed in 0..12u64 {
            let start = 2000.0 + seed as f64 * 0.37;
            let words = signal(14_000, &[start], amp, noise, seed + 7);
            let found = detect(&words, 1024);
            assert_eq!(found.len(), 1, "seed {seed}: {found:?}");
            let b = found[0];
            errs.push(b.sample_index as f64 + f64::from(b.fraction) - start);
        }
        let mean = errs.iter().sum::<f64>() / errs.len() as f64;
        let sd = (errs.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / errs.len() as f64).sqrt();
        assert!(sd < 3.0 * bound_samples, "sd {sd} bound {bound_samples}");
        assert!(mean.abs() < 3.0 * bound_samples, "mean {mean}");
    }

    /// Words of a direct path at `start` plus a copy `gain` times stronger `delay` samples later.
    fn with_reflection(start: f64, delay: f64, gain: f64, noise: f64, seed: u64) -> Vec<i32> {
        let direct = signal(16_000, &[start], 0.004, noise, seed);
        let echo = signal(16_000, &[start + delay], 0.004 * gain, 0.0, seed);
        direct.iter().zip(&echo).map(|(&a, &b)| a + b).collect()
    }

    #[test]
    fn a_stronger_reflection_does_not_hide_the_direct_path() {
        // Oracle: the direct path's known start. The reflection (1.5 to 2.5 times stronger,
        // 1.3 to 6.9 ms later: zigzag10-los had 1.97 ms; closer copies overlap the main lobe and bend the envelope) is the strongest correlation peak; the
        // report must still be the direct path, as exact as without it.
        for (i, &(delay, gain)) in
            [(94.56, 2.0), (60.3, 1.5), (200.7, 2.5), (330.2, 2.0), (94.56, 1.0)].iter().enumerate()
        {
            let start = 2000.0 + 0.37 * i as f64;
            let found = detect(&with_reflection(start, delay, gain, 0.0, 1), 1024);
            assert_eq!(found.len(), 1, "delay {delay}: {found:?}");
            let got = found[0].sample_index as f64 + f64::from(found[0].fraction);
            assert!((got - start).abs() < 0.05, "delay {delay} gain {gain}: got {got}, {found:?}");
            assert!(found[0].quality >= FIRST_PATH_QUALITY_MIN, "{found:?}");
        }
        // In noise (−48 dBFS, the direct path at −48 dBFS peak): still the direct path.
        for seed in 0..8u64 {
            let start = 3000.0 + 0.29 * seed as f64;
            let found = detect(&with_reflection(start, 94.56, 2.0, 0.004, seed + 11), 1024);
            assert_eq!(found.len(), 1, "seed {seed}: {found:?}");
            let got = found[0].sample_index as f64 + f64::from(found[0].fraction);
            assert!((got - start).abs() < 0.1, "seed {seed}: got {got}, {found:?}");
        }
        // A reflection beyond the window is not searched: the strongest peak is reported.
        let found = detect(&with_reflection(2000.0, 600.0, 2.0, 0.0, 1), 1024);
        assert_eq!(found.len(), 1, "{found:?}");
        let got = found[0].sample_index as f64 + f64::from(found[0].fraction);
        assert!((got - 2600.0).abs() < 0.05, "got {got}");
    }

    #[test]
    fn one_detection_per_emission_and_none_on_noise() {
        let starts = [3000.0, 3000.0 + 48_000.0, 3000.0 + 96_000.5];
        let words = signal(150_000, &starts, 0.003, 0.003, 3);
        let found = detect(&words, 4096);
        assert_eq!(found.len(), 3, "{found:?}");
        let words = signal(480_000, &[], 0.0, 0.01, 5);
        let f = detect(&words, 4096);
        assert!(f.is_empty(), "{} {:?}", f.len(), &f[..f.len().min(5)]);
    }

    #[test]
    fn stride_and_gap_keep_the_input_clock() {
        // Two interleaved channels, the beacon on the first; a gap of 1000 frames first.
        let words = signal(16_000, &[4000.5], 0.01, 0.0, 1);
        let inter: Vec<i32> = words.iter().flat_map(|&w| [w, 0]).collect();
        let mut d = Detector::empty();
        d.configure();
        d.gap(1000);
        let mut scratch = [0.0f32; SCRATCH_LEN];
        let mut found = Vec::new();
        d.push(&inter, 2, &mut scratch, &mut |b| found.push(b));
        assert_eq!(found.len(), 1);
        let got = found[0].sample_index as f64 + f64::from(found[0].fraction);
        assert!((got - 5000.5).abs() < 0.02, "{got}");
    }
}
