//! PDM microphones → the 48 kHz TDM words of the rest of the pipeline: a fixed-point decimator
//! by 64 (3.072 MHz one-bit pulse-density streams → 48 kHz 24-bit samples).
//!
//! Two stages, integer only (host and target compute the same bits by construction):
//!
//! 1. **CIC, order 2, decimation 64**, `H(z) = ((1 − z⁻⁶⁴) / (1 − z⁻¹))²`: the 127-tap integer
//!    FIR `h[j] = min(j, 126 − j) + 1` (sum 4096), computed byte-wise from lookup tables. An
//!    output period holds 8 bytes of PDM (64 bits); the taps a byte meets depend only on its
//!    position `p` (0..8) in the period, so [`CIC_TABLES`]`[p][byte]` holds, packed into one
//!    `u32`, the byte's partial sums for the output that ends this period (low 16 bits, taps
//!    `h[0..64]`) and for the next one (high 16 bits, taps `h[64..127]`). Per byte: one load of
//!    the byte, one table load, one add; per output: `acc & 0xFFFF` is the finished CIC sum
//!    (0..=4096, exact), `acc >> 16` carries the next output's partial sum. No lane can carry
//!    into the next: a finished sum is at most 4096 < 2¹⁶.
//! 2. **Compensation FIR, 3 taps at 48 kHz**, `[−a, 1 + 2a, −a]` with `a = 3/32`: lifts the
//!    CIC's droop (−0.45 dB at 6 kHz, −0.80 dB at 8 kHz) back to within 0.02 dB of flat over
//!    0–6 kHz and 0.05 dB over 0–8 kHz (the GCC-PHAT band ends at 6 kHz, the BPF harmonics at
//!    4 kHz). It is centred on the previous CIC output, so the decimator delays by one
//!    output sample more than the CIC (group delay 63 input bits + 1 output ≈ 41 µs, the same
//!    for every microphone, so relative delays are untouched).
//!
//! Why a second-order CIC and not a longer filter: the byte-table trick packs the partial sums
//! of the outputs a byte contributes to into one 32-bit word, which is what makes it cheap
//! (about 3 instructions per byte on a Cortex-M4F; the budget `dsp-8mic-pdm` is 8 microphones plus
//! the 8-microphone pipeline within 45 M instructions per second of audio). A third-order CIC
//! spans three output periods and sums to 2¹⁸: three 19-bit lanes need two words per byte,
//! about 5 instructions per byte, over the budget; rounding its taps down to fit three lanes
//! into one word (a sum near 2¹¹) lets the taps' rounding errors pass the modulator's
//! high-frequency noise into the band (≈ 60 dB signal-to-noise against the reference, measured,
//! against ≈ 76 dB for this exact CIC). The price of order 2: aliases of 42–54 kHz (which fold
//! onto 0–6 kHz) are rejected by 34 dB at the band edge (42 kHz), 42 dB at 44 kHz, more than
//! 54 dB within ±2 kHz of 48 kHz; higher alias bands by more.
//!
//! Input: `stride` bytes per PDM byte period (one byte per microphone: microphone `m` at offset
//! `m`, the byte's most significant bit the earliest), 8 byte periods per output frame. This is
//! how the SAI's PDM interface delivers them (one byte of each microphone per 8 PDM clocks).
//! A one bit is positive pressure. Output: the words of [`crate::Pipeline::push`], 24-bit
//! samples left-justified in `i32`, microphone `m` in TDM slot `m`, other slots zero. A
//! full-scale PDM stream (all ones / all zeros) maps to ±2²² (half the 24-bit range,
//! −6.02 dBFS): the headroom takes the compensation FIR's gain above 8 kHz (at most 1 + 4a),
//! so no word can wrap.

use crate::MAX_MICS;

/// Decimation factor: PDM bits per output sample.
pub const DECIMATION: usize = 64;
/// PDM bytes per output sample and microphone.
pub const BYTES_PER_OUTPUT: usize = DECIMATION / 8;
/// CIC taps (order 2, decimation 64): `2 · 64 − 1`.
pub const CIC_TAPS: usize = 2 * DECIMATION - 1;
/// Sum of the CIC taps, the CIC output for an all-ones input: 64².
pub const CIC_GAIN: u32 = (DECIMATION * DECIMATION) as u32;
/// Compensation FIR side tap `a` = 3/32, Q18: a multiple of 2⁸, so that every word's low 8
/// bits are zero, and `2a`, `2(1 + 2a)` in Q18 are single-instruction immediates on Thumb-2.
pub const COMP_SIDE_Q18: i32 = 3 << 13;
/// Compensation FIR centre tap `1 + 2a`, Q18 (DC gain exactly 1).
pub const COMP_CENTRE_Q18: i32 = (1 << 18) + 2 * COMP_SIDE_Q18;
/// Bits the compensated sample is shifted by: a CIC output `y` maps to `(2y − 4096) · 2¹⁸`, so
/// the full PDM range (`y` = 0..=4096) spans ±2³⁰ = ±2²² in 24-bit units.
pub const OUTPUT_Q: u32 = 18;

// The largest compensated magnitude: every input at ±4096 with the worst signs.
const _: () = assert!(
    (COMP_CENTRE_Q18 as i64 + 2 * COMP_SIDE_Q18 as i64) * CIC_GAIN as i64 <= i32::MAX as i64
);
// A finished CIC sum fits its 16-bit lane.
const _: () = assert!(CIC_GAIN < 1 << 16);
// Every word is a multiple of 2⁸ (a 24-bit sample left-justified).
const _: () = assert!(COMP_SIDE_Q18 % 256 == 0 && COMP_CENTRE_Q18 % 256 == 0);

/// The CIC's tap `j` (0 = applied to the newest bit): the triangle `min(j, 126 − j) + 1`.
pub const fn cic_tap(j: usize) -> u32 {
    if j >= CIC_TAPS {
        0
    } else if j < DECIMATION {
        (j + 1) as u32
    } else {
        (CIC_TAPS - j) as u32
    }
}

/// Byte tables of the CIC: `CIC_TABLES[p][b]` = the packed partial sums of byte `b` at byte
/// position `p` of an output period (low half: taps for the output that ends this period;
/// high half: taps for the next output). Bit 7 of a byte is the earliest.
pub static CIC_TABLES: [[u32; 256]; BYTES_PER_OUTPUT] = build_tables();

const fn build_tables() -> [[u32; 256]; BYTES_PER_OUTPUT] {
    let mut tables = [[0u32; 256]; BYTES_PER_OUTPUT];
    let mut p = 0;
    while p < BYTES_PER_OUTPUT {
        let mut b = 0;
        while b < 256 {
            let mut now = 0u32;
            let mut next = 0u32;
            let mut k = 0;
            while k < 8 {
                if b & (1 << k) != 0 {
                    // Bit k of byte p is bit i = 8p + 7 − k of the period (time order); the
                    // period's last bit (i = 63) meets tap 0 of this output, tap 64 of the next.
                    let age = DECIMATION - 1 - (8 * p + 7 - k);
                    now += cic_tap(age);
                    next += cic_tap(age + DECIMATION);
                }
                k += 1;
            }
            tables[p][b] = now | (next << 16);
            b += 1;
        }
        p += 1;
    }
    tables
}

/// Why [`PdmDecimator::push`] refused its buffers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PdmError {
    /// The PDM bytes are not a whole number of output periods (`8 · stride` bytes each).
    PartialPeriod {
        /// Bytes given.
        bytes: usize,
        /// Bytes per output period.
        period: usize,
    },
    /// The output has room for fewer frames than the input makes.
    OutputTooSmall {
        /// Words needed.
        needed: usize,
        /// Words given.
        available: usize,
    },
    /// Fewer TDM slots than microphones, or no microphones.
    Slots {
        /// Slots per output frame.
        slots: usize,
        /// Microphones.
        mics: usize,
    },
}

/// The per-microphone state of the decimator.
#[derive(Debug, Clone, Copy)]
struct Channel {
    /// The next output's partial CIC sum, in the high 16 bits.
    carry: u32,
    /// The compensation FIR's state ([`comp_state`] of the last two CIC sums).
    history: [u32; 2],
}

/// A CIC output of silence (density ½): the compensation FIR's history at start.
const MIDSCALE: u32 = CIC_GAIN / 2;

/// PDM → 48 kHz decimator for up to [`MAX_MICS`] microphones (see the module docs).
#[derive(Debug, Clone)]
pub struct PdmDecimator {
    mics: usize,
    stride: usize,
    channels: [Channel; MAX_MICS],
}

impl PdmDecimator {
    /// A decimator for `mics` microphones whose bytes arrive `stride` apart (`mics` is clamped
    /// to `1..=min(stride, MAX_MICS)`).
    pub const fn new(mics: usize, stride: usize) -> Self {
        let stride = if stride == 0 { 1 } else { stride };
        let mut mics = if mics > MAX_MICS { MAX_MICS } else { mics };
        if mics > stride {
            mics = stride;
        }
        if mics == 0 {
            mics = 1;
        }
        let channel = Channel { carry: 0, history: comp_state(MIDSCALE, MIDSCALE) };
        Self { mics, stride, channels: [channel; MAX_MICS] }
    }

    /// Microphones decimated.
    pub const fn mics(&self) -> usize {
        self.mics
    }

    /// PDM bytes per output frame: `8 · stride`.
    pub const fn period_bytes(&self) -> usize {
        BYTES_PER_OUTPUT * self.stride
    }

    /// Decimates `pdm` (whole output periods) into `out`, `tdm_slots` words per frame;
    /// returns the frames written. Slots from `mics` on are zeroed.
    pub fn push(
        &mut self,
        pdm: &[u8],
        out: &mut [i32],
        tdm_slots: usize,
    ) -> Result<usize, PdmError> {
        let period = self.period_bytes();
        if !pdm.len().is_multiple_of(period) {
            return Err(PdmError::PartialPeriod { bytes: pdm.len(), period });
        }
        if tdm_slots < self.mics {
            return Err(PdmError::Slots { slots: tdm_slots, mics: self.mics });
        }
        let frames = pdm.len() / period;
        let needed = frames * tdm_slots;
        if out.len() < needed {
            return Err(PdmError::OutputTooSmall { needed, available: out.len() });
        }
        if frames == 0 {
            return Ok(0);
        }
        let out = &mut out[..needed];
        if tdm_slots > self.mics {
            for frame in out.chunks_exact_mut(tdm_slots) {
                frame[self.mics..].fill(0);
            }
        }
        // Per microphone, two passes, each with few enough live values to stay in registers:
        // the CIC writes each period's packed accumulator into the microphone's slot, then the
        // compensation FIR turns them into words in place. Fast paths for TDM frames of 8
        // slots (the firmware's and the golden checks') with the layout known at compile time.
        let (mics, stride) = (self.mics, self.stride);
        let fast = tdm_slots == 8
            && self.channels[..mics].iter_mut().enumerate().all(|(m, channel)| match stride {
                8 => decimate_mic::<8>(channel, pdm, m, out),
                6 => decimate_mic::<6>(channel, pdm, m, out),
                4 => decimate_mic::<4>(channel, pdm, m, out),
                _ => false,
            });
        if !fast {
            for (m, channel) in self.channels[..mics].iter_mut().enumerate() {
                let words = out[m..].iter_mut().step_by(tdm_slots);
                cic_any(&mut channel.carry, pdm, stride, m, words);
                compensate(&mut channel.history, out[m..].iter_mut().step_by(tdm_slots));
            }
        }
        Ok(frames)
    }
}

/// Microphone `m` whose bytes are `STRIDE` apart (byte `p` of a period is
/// `period[p · STRIDE + m]`) into slot `m` of frames of 8 slots: [`cic_pass`], then
/// [`compensate_slot`]. `false` (nothing done) if the layout does not fit.
#[inline(always)]
fn decimate_mic<const STRIDE: usize>(
    channel: &mut Channel,
    pdm: &[u8],
    m: usize,
    out: &mut [i32],
) -> bool {
    if m >= STRIDE || m >= 8 {
        return false;
    }
    let (rows, _) = pdm.as_chunks::<STRIDE>();
    let (periods, _) = rows.as_chunks::<BYTES_PER_OUTPUT>();
    let (frames, _) = out.as_chunks_mut::<8>();
    channel.carry = cic_pass(channel.carry, periods, frames, m);
    // Second pass, the compensation FIR, with the slot known at compile time.
    let state = &mut channel.history;
    match m {
        0 => compensate_slot::<0>(state, frames_again(out)),
        1 => compensate_slot::<1>(state, frames_again(out)),
        2 => compensate_slot::<2>(state, frames_again(out)),
        3 => compensate_slot::<3>(state, frames_again(out)),
        4 => compensate_slot::<4>(state, frames_again(out)),
        5 => compensate_slot::<5>(state, frames_again(out)),
        6 => compensate_slot::<6>(state, frames_again(out)),
        _ => compensate_slot::<7>(state, frames_again(out)),
    }
    true
}

/// The CIC of microphone `m` (first pass of [`decimate_mic`]): each period's packed accumulator
/// into slot `m`; returns the last accumulator. Per byte: one load of the byte, one table load
/// (`ldr r, [base, index, lsl #2]`), one add; four table bases, each covering tables `p` and
/// `p + 4` (1024 entries further: bytes 4–7 index with `byte + 1024`, one more add), because
/// eight bases next to the loop's other values make LLVM spill and reload them. Not inlined
/// for the same reason (fewer live values). Left to itself, LLVM also rebuilds each constant
/// table address per load; `black_box` makes the bases opaque values, nothing else.
/// Measured on the Cortex-M4F model: BENCHMARKS.md, "PDM microphones".
#[inline(never)]
fn cic_pass<const STRIDE: usize>(
    mut acc: u32,
    periods: &[[[u8; STRIDE]; BYTES_PER_OUTPUT]],
    frames: &mut [[i32; 8]],
    m: usize,
) -> u32 {
    if m >= STRIDE || m >= 8 {
        return acc;
    }
    let flat = CIC_TABLES.as_flattened();
    let window =
        |q: usize| -> Option<&[u32; 1280]> { flat.get(q * 256..q * 256 + 1280)?.try_into().ok() };
    let (Some(t0), Some(t1), Some(t2), Some(t3)) = (window(0), window(1), window(2), window(3))
    else {
        return acc;
    };
    let [t0, t1, t2, t3] = core::hint::black_box([t0, t1, t2, t3]);
    for (period, frame) in periods.iter().zip(frames) {
        let byte = |p: usize| usize::from(period[p][m]);
        acc = (acc >> 16)
            + t0[byte(0)]
            + t1[byte(1)]
            + t2[byte(2)]
            + t3[byte(3)]
            + t0[byte(4) + 1024]
            + t1[byte(5) + 1024]
            + t2[byte(6) + 1024]
            + t3[byte(7) + 1024];
        frame[m] = acc as i32;
    }
    acc
}

/// `out` as frames of 8 slots.
#[inline(always)]
fn frames_again(out: &mut [i32]) -> &mut [[i32; 8]] {
    out.as_chunks_mut::<8>().0
}

/// [`compensate`] on slot `M` of every frame (not inlined, like [`cic_pass`]: fewer live values).
#[inline(never)]
fn compensate_slot<const M: usize>(state: &mut [u32; 2], frames: &mut [[i32; 8]]) {
    let [mut q, mut y1] = *state;
    for frame in frames {
        let y0 = u32::from(frame[M] as u16);
        frame[M] = q.wrapping_sub(K_SIDE.wrapping_mul(y0)) as i32;
        [q, y1] = comp_state(y0, y1);
    }
    *state = [q, y1];
}

/// The CIC of microphone `m` whose bytes are `stride` apart, for layouts without a fast path:
/// writes each period's packed accumulator (the sum in the low 16 bits) to `out`.
fn cic_any<'a>(
    carry: &mut u32,
    pdm: &[u8],
    stride: usize,
    m: usize,
    out: impl Iterator<Item = &'a mut i32>,
) {
    let mut acc = *carry;
    for (period, word) in pdm.chunks_exact(BYTES_PER_OUTPUT * stride).zip(out) {
        acc >>= 16;
        for (p, table) in CIC_TABLES.iter().enumerate() {
            acc += table[usize::from(period.get(p * stride + m).copied().unwrap_or(0))];
        }
        *word = acc as i32;
    }
    *carry = acc;
}

/// Compensation FIR coefficient `2C` (`C = 1 + 2a`, Q18) for CIC sums `y` (0..=4096).
const K_CENTRE: u32 = 2 * COMP_CENTRE_Q18 as u32;
/// Compensation FIR coefficient `2a` (Q18) for CIC sums `y`.
const K_SIDE: u32 = 2 * COMP_SIDE_Q18 as u32;
/// The offset of the centred samples: `C · 4096 − 2a · 4096 = 2³⁰`.
const K_OFFSET: u32 = 1 << 30;

/// The compensation FIR's state after two CIC sums `y1` (newer) and `y2`:
/// `[2C·y1 − 2a·y2 − 2³⁰, y1]` (wrapping).
const fn comp_state(y1: u32, y2: u32) -> [u32; 2] {
    [K_CENTRE.wrapping_mul(y1).wrapping_sub(K_SIDE.wrapping_mul(y2)).wrapping_sub(K_OFFSET), y1]
}

/// The compensation FIR in place: each word holds a packed CIC accumulator (sum `y` in the low
/// 16 bits) and becomes `C·(2y(n−1) − 4096) − a·(2y(n) − 4096 + 2y(n−2) − 4096)` in Q18, i.e.
/// `2C·y(n−1) − 2a·(y(n) + y(n−2)) − 2³⁰` = `q − 2a·y(n)` with `q` from [`comp_state`] of the
/// two previous sums. The products may exceed `i32`, the result never does (see the
/// assertion above), so wrapping arithmetic is exact. Both coefficients are multiples of 2⁸:
/// the low 8 bits of every word are zero, as in a TDM slot.
#[inline(always)]
fn compensate<'a>(state: &mut [u32; 2], words: impl Iterator<Item = &'a mut i32>) {
    let [mut q, mut y1] = *state;
    for word in words {
        let y0 = u32::from(*word as u16);
        *word = q.wrapping_sub(K_SIDE.wrapping_mul(y0)) as i32;
        [q, y1] = comp_state(y0, y1);
    }
    *state = [q, y1];
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// PDM bit rate of the tests, Hz.
    const FS: f64 = 3_072_000.0;
    /// Output rate, Hz.
    const FO: f64 = 48_000.0;

    /// A 4th-order one-bit sigma-delta modulator (error feedback, NTF = (1 − z⁻¹)⁴ / A(z) with
    /// A the denominator of a 4th-order Butterworth high-pass at 0.1 · fs/2, ‖NTF‖∞ ≈ 1.51,
    /// STF = 1): the noise shaping of a MEMS microphone's modulator. Returns one bit per
    /// sample of `input` (in −1..1), true = +1.
    fn modulate(input: impl Iterator<Item = f64>) -> Vec<bool> {
        const A: [f64; 5] = [1.0, -3.180_638_55, 3.861_194_35, -2.112_155_36, 0.438_265_14];
        const B: [f64; 5] = [1.0, -4.0, 6.0, -4.0, 1.0];
        let (mut e, mut s) = ([0f64; 4], [0f64; 4]);
        input
            .map(|u| {
                let mut f = 0.0;
                for k in 0..4 {
                    f += (B[k + 1] - A[k + 1]) * e[k] - A[k + 1] * s[k];
                }
                let v = u + f;
                let q = if v >= 0.0 { 1.0 } else { -1.0 };
                e.rotate_right(1);
                s.rotate_right(1);
                e[0] = q - v;
                s[0] = f;
                q > 0.0
            })
            .collect()
    }

    /// Packs bits (time order) into bytes, the earliest bit in the MSB.
    fn pack(bits: &[bool]) -> Vec<u8> {
        bits.chunks_exact(8)
            .map(|b| b.iter().fold(0u8, |byte, &bit| (byte << 1) | u8::from(bit)))
            .collect()
    }

    /// `seconds` of a sine (amplitude `amp` of the PDM range, frequency `hz`) as PDM bytes.
    fn tone(hz: f64, amp: f64, seconds: f64) -> (Vec<bool>, Vec<u8>) {
        let n = (seconds * FO) as usize * DECIMATION;
        let bits = modulate((0..n).map(|i| amp * (2.0 * PI * hz * i as f64 / FS).sin()));
        let bytes = pack(&bits);
        (bits, bytes)
    }

    /// The decimator's output for one microphone, as f64 in units of the PDM range (±1).
    fn decimate(bytes: &[u8]) -> Vec<f64> {
        let mut d = PdmDecimator::new(1, 1);
        let mut out = vec![0i32; bytes.len() / BYTES_PER_OUTPUT];
        assert_eq!(d.push(bytes, &mut out, 1), Ok(out.len()));
        out.iter().map(|&w| f64::from(w) / f64::from(1 << 30)).collect()
    }

    /// Least-squares amplitude of a sine at `hz` in `x` (sample rate FO), with a DC term.
    fn amplitude(x: &[f64], hz: f64) -> f64 {
        let (mut cc, mut ss, mut cs, mut c1, mut s1, mut xc, mut xs, mut x1) =
            (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let n = x.len() as f64;
        for (i, &v) in x.iter().enumerate() {
            let (s, c) = (2.0 * PI * hz * i as f64 / FO).sin_cos();
            cc += c * c;
            ss += s * s;
            cs += c * s;
            c1 += c;
            s1 += s;
            xc += v * c;
            xs += v * s;
            x1 += v;
        }
        // Normal equations of [c s 1] · [a b d]ᵀ ≈ x (3 × 3, Cramer's rule).
        let m = [[cc, cs, c1], [cs, ss, s1], [c1, s1, n]];
        let r = [xc, xs, x1];
        let det = |m: [[f64; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let d = det(m);
        let col = |k: usize| {
            let mut mk = m;
            for row in 0..3 {
                mk[row][k] = r[row];
            }
            det(mk) / d
        };
        col(0).hypot(col(1))
    }

    fn db(x: f64) -> f64 {
        20.0 * x.log10()
    }

    /// Skipped outputs at the start (filters filling), and the analysed length: 0.1 s.
    const SKIP: usize = 200;

    #[test]
    fn tables_compute_the_cic_and_the_compensation_exactly() {
        // Oracle: the CIC as a direct convolution of the bits with its taps, then the
        // compensation FIR, in plain integers; several microphones interleaved.
        let mut noise = 0x1234_5678u32;
        let mut next = || {
            noise ^= noise << 13;
            noise ^= noise >> 17;
            noise ^= noise << 5;
            noise
        };
        // The fast path (6 microphones, 8-byte periods) and the general one (3 in 5).
        for (mics, stride) in [(6, 8), (3, 5), (8, 8)] {
            let frames = 300;
            let bytes: Vec<u8> =
                (0..frames * BYTES_PER_OUTPUT * stride).map(|_| next() as u8).collect();
            let mut d = PdmDecimator::new(mics, stride);
            let slots = 8;
            let mut out = vec![-1i32; frames * slots];
            // Two pushes with a split inside the stream: the state carries over.
            let half = frames / 3 * BYTES_PER_OUTPUT * stride;
            let first = d.push(&bytes[..half], &mut out, slots).unwrap();
            let second = d.push(&bytes[half..], &mut out[first * slots..], slots).unwrap();
            assert_eq!(first + second, frames);
            for m in 0..slots {
                let bits: Vec<i64> = bytes
                    .iter()
                    .skip(m)
                    .step_by(stride)
                    .flat_map(|&b| (0..8).rev().map(move |k| i64::from((b >> k) & 1)))
                    .collect();
                let mut s = [0i64; 3];
                for n in 0..frames {
                    if m >= mics {
                        assert_eq!(out[n * slots + m], 0, "unused slot {m}");
                        continue;
                    }
                    let last = DECIMATION * n + DECIMATION - 1;
                    let y: i64 = (0..CIC_TAPS)
                        .filter(|&j| j <= last)
                        .map(|j| i64::from(cic_tap(j)) * bits[last - j])
                        .sum();
                    s = [2 * y - i64::from(CIC_GAIN), s[0], s[1]];
                    let z = i64::from(COMP_CENTRE_Q18) * s[1]
                        - i64::from(COMP_SIDE_Q18) * (s[0] + s[2]);
                    assert_eq!(i64::from(out[n * slots + m]), z & !0xFF, "mic {m} frame {n}");
                }
            }
        }
        // Full scale: all ones gives +2^30 (after the filters fill), all zeros −2^30.
        for (byte, word) in [(0xFFu8, 1i32 << 30), (0x00, -(1 << 30))] {
            let mut d = PdmDecimator::new(1, 1);
            let mut out = [0i32; 8];
            d.push(&[byte; 64], &mut out, 1).unwrap();
            assert_eq!(out[7], word);
        }
    }

    #[test]
    fn passband_is_flat_within_the_design_ripple() {
        // Design (taps and compensation, computed from the frequency response): within
        // 0.03 dB over 0–8 kHz; measured here through the modulator with a sine fit.
        let mut gains = Vec::new();
        for hz in [100.0, 500.0, 1000.0, 2000.0, 3000.0, 4000.0, 5000.0, 6000.0, 7000.0, 8000.0] {
            let (_, bytes) = tone(hz, 0.5, 0.1);
            let y = decimate(&bytes);
            gains.push(db(amplitude(&y[SKIP..], hz) / 0.5));
        }
        let max = gains.iter().copied().fold(f64::MIN, f64::max);
        let min = gains.iter().copied().fold(f64::MAX, f64::min);
        eprintln!("passband gains 0.1–8 kHz, dB: {gains:.4?}; ripple {:.4} dB", max - min);
        assert!(max - min < 0.06, "ripple {:.3} dB: {gains:.3?}", max - min);
        // Gain 1 (the modulator's signal transfer is 1): ±1 of PDM range ↔ ±2^30.
        assert!(max.abs() < 0.05 && min.abs() < 0.05, "{gains:.3?}");
    }

    #[test]
    fn aliases_of_the_band_are_rejected_as_designed() {
        // Tones above 24 kHz that fold onto the 0–6 kHz band; design rejection of the CIC
        // (order 2) at each, dB, asserted with a 1.5 dB margin.
        for (hz, design_db) in [
            (42_000.0, 34.2),
            (44_000.0, 41.8),
            (46_000.0, 54.5),
            (50_000.0, 56.0),
            (52_000.0, 44.7),
            (54_000.0, 38.6),
            (90_000.0, 47.5),
            (102_000.0, 49.6),
        ] {
            let folded = (hz - FO * (hz / FO).round()).abs();
            let (_, bytes) = tone(hz, 0.5, 0.1);
            let y = decimate(&bytes);
            let rejection = -db(amplitude(&y[SKIP..], folded) / 0.5);
            eprintln!(
                "alias {hz} Hz → {folded} Hz: rejection {rejection:.1} dB (design {design_db})"
            );
            assert!(
                rejection > design_db - 1.5,
                "{hz} Hz → {folded} Hz: {rejection:.1} dB, design {design_db} dB"
            );
        }
    }

    /// Floating-point reference decimator: a 2175-tap Blackman-windowed sinc low-pass (cut-off
    /// 14 kHz, stop band ≥ 74 dB from about 22 kHz) on the ±1 bits, every 64th output. Its
    /// delay, 1087 bits, is the CIC's 63 plus 16 outputs.
    fn reference(bits: &[bool]) -> Vec<f64> {
        const N: usize = CIC_TAPS + 16 * 2 * DECIMATION;
        let fc = 14_000.0 / FS;
        let mid = (N - 1) as f64 / 2.0;
        let mut h: Vec<f64> = (0..N)
            .map(|j| {
                let t = j as f64 - mid;
                let sinc = if t == 0.0 { 2.0 * fc } else { (2.0 * PI * fc * t).sin() / (PI * t) };
                let w = 2.0 * PI * j as f64 / (N - 1) as f64;
                sinc * (0.42 - 0.5 * w.cos() + 0.08 * (2.0 * w).cos())
            })
            .collect();
        let sum: f64 = h.iter().sum();
        h.iter_mut().for_each(|v| *v /= sum);
        let x: Vec<f64> = bits.iter().map(|&b| if b { 1.0 } else { -1.0 }).collect();
        (0..x.len() / DECIMATION)
            .map(|n| {
                let last = DECIMATION * n + DECIMATION - 1;
                h.iter().enumerate().filter(|(j, _)| *j <= last).map(|(j, v)| v * x[last - j]).sum()
            })
            .collect()
    }

    /// The common analysis band: a 63-tap Blackman-windowed sinc low-pass at 8 kHz (48 kHz),
    /// after removing the mean.
    fn band(x: &[f64]) -> Vec<f64> {
        let n = 63;
        let fc = 8_000.0 / FO;
        let mid = (n - 1) as f64 / 2.0;
        let h: Vec<f64> = (0..n)
            .map(|j| {
                let t = j as f64 - mid;
                let sinc = if t == 0.0 { 2.0 * fc } else { (2.0 * PI * fc * t).sin() / (PI * t) };
                let w = 2.0 * PI * j as f64 / (n - 1) as f64;
                sinc * (0.42 - 0.5 * w.cos() + 0.08 * (2.0 * w).cos())
            })
            .collect();
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        (0..x.len() - n).map(|i| h.iter().zip(&x[i..]).map(|(a, b)| a * (b - mean)).sum()).collect()
    }

    #[test]
    fn signal_to_noise_against_the_floating_point_reference() {
        // SNR of the decimator's output against the reference decimator's, both band-limited
        // to 0–8 kHz, after the least-squares gain: what the fixed-point decimator adds
        // (modulator noise aliased by the CIC's side lobes, droop left after compensation).
        // Measured at design time (numpy model of this decimator): 75–76 dB at −6 dB of PDM
        // full scale; asserted ≥ 70 dB.
        for hz in [1000.0, 5000.0] {
            let (bits, bytes) = tone(hz, 0.5, 0.1);
            let ours = decimate(&bytes);
            let reference = reference(&bits);
            // ours[n] is the CIC output n − 1; reference[n + 15] is centred on the same bit.
            let ours = band(&ours[SKIP..ours.len() - 15]);
            let reference = band(&reference[SKIP + 15..]);
            let gain = ours.iter().zip(&reference).map(|(a, b)| a * b).sum::<f64>()
                / ours.iter().map(|a| a * a).sum::<f64>();
            let signal: f64 = reference.iter().map(|r| r * r).sum();
            let error: f64 = ours.iter().zip(&reference).map(|(a, r)| (r - gain * a).powi(2)).sum();
            let snr = 10.0 * (signal / error).log10();
            eprintln!("{hz} Hz: SNR against the reference {snr:.1} dB, gain {gain:.5}");
            assert!(snr > 70.0, "{hz} Hz: SNR against the reference {snr:.1} dB");
            assert!((gain - 1.0).abs() < 0.01, "{hz} Hz: gain {gain}");
        }
    }

    #[test]
    fn eight_interleaved_microphones_each_match_the_reference_and_do_not_leak() {
        // The firmware's layout at 8 microphones: byte p of microphone m at p · 8 + m, words in
        // slot m of 8-slot frames (the fast path `decimate_mic::<8>`). Each microphone carries
        // its own tone from its own modulator. Oracles: (1) every slot equals the one-microphone
        // decimator on that microphone's bytes alone, bit for bit; (2) its SNR against the
        // floating-point reference is > 70 dB, as for one microphone; (3) the other seven
        // tones are absent from it (below −70 dB of its own), so no byte reaches a wrong slot.
        const MICS: usize = 8;
        // Whole numbers of cycles in the analysed 0.1 s − SKIP (4 600 outputs), so the
        // least-squares amplitude of one tone sees none of another: 700 Hz + 900 Hz · m, rounded.
        let analysed = FO * 0.1 - SKIP as f64;
        let tones: [f64; MICS] = core::array::from_fn(|m| {
            ((700.0 + 900.0 * m as f64) * analysed / FO).round() * FO / analysed
        });
        let streams: Vec<(Vec<bool>, Vec<u8>)> =
            tones.iter().map(|&hz| tone(hz, 0.5, 0.1)).collect();
        let periods = streams[0].1.len();
        let mut interleaved = vec![0u8; periods * MICS];
        for (m, (_, bytes)) in streams.iter().enumerate() {
            for (p, &b) in bytes.iter().enumerate() {
                interleaved[p * MICS + m] = b;
            }
        }
        let mut d = PdmDecimator::new(MICS, MICS);
        let frames = periods / BYTES_PER_OUTPUT;
        let mut out = vec![0i32; frames * MICS];
        assert_eq!(d.push(&interleaved, &mut out, MICS), Ok(frames));
        for (m, (bits, bytes)) in streams.iter().enumerate() {
            let slot: Vec<f64> = out
                .iter()
                .skip(m)
                .step_by(MICS)
                .map(|&w| f64::from(w) / f64::from(1 << 30))
                .collect();
            assert_eq!(slot, decimate(bytes), "microphone {m}: not the one-microphone output");
            let ours = band(&slot[SKIP..slot.len() - 15]);
            let reference = band(&reference(bits)[SKIP + 15..]);
            let gain = ours.iter().zip(&reference).map(|(a, b)| a * b).sum::<f64>()
                / ours.iter().map(|a| a * a).sum::<f64>();
            let signal: f64 = reference.iter().map(|r| r * r).sum();
            let error: f64 = ours.iter().zip(&reference).map(|(a, r)| (r - gain * a).powi(2)).sum();
            let snr = 10.0 * (signal / error).log10();
            let own = amplitude(&slot[SKIP..], tones[m]);
            let leak = tones
                .iter()
                .enumerate()
                .filter(|&(k, _)| k != m)
                .map(|(_, &hz)| db(amplitude(&slot[SKIP..], hz) / own))
                .fold(f64::NEG_INFINITY, f64::max);
            eprintln!(
                "microphone {m} ({:.1} Hz): SNR against the reference {snr:.1} dB, largest other tone {leak:.1} dB",
                tones[m]
            );
            assert!(snr > 70.0, "microphone {m}: SNR {snr:.1} dB");
            assert!(leak < -70.0, "microphone {m}: another microphone's tone at {leak:.1} dB");
        }
    }

    #[test]
    fn bad_buffers_are_refused_with_the_reason() {
        let mut d = PdmDecimator::new(4, 8);
        let mut out = [0i32; 16];
        assert_eq!(
            d.push(&[0; 65], &mut out, 8),
            Err(PdmError::PartialPeriod { bytes: 65, period: 64 })
        );
        assert_eq!(d.push(&[0; 64], &mut out, 3), Err(PdmError::Slots { slots: 3, mics: 4 }));
        assert_eq!(
            d.push(&[0; 192], &mut out, 8),
            Err(PdmError::OutputTooSmall { needed: 24, available: 16 })
        );
        assert_eq!(d.push(&[], &mut out, 8), Ok(0));
        assert_eq!(PdmDecimator::new(12, 8).mics(), 8);
        assert_eq!(PdmDecimator::new(6, 4).mics(), 4);
    }
}
