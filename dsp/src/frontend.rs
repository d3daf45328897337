//! Fixed-point front end: TDM word → Q31 → DC removal → Q15 with a block exponent.
//!
//! A TDM slot carries a 24-bit sample left-justified in 32 bits (`sample << 8`), which read as
//! an `i32` is already Q31 (fraction of full scale). DC is removed per microphone by subtracting
//! a first-order running mean kept with 16 extra fractional bits; its −3 dB corner is about
//! fs / (2π · 2^k) with k = [`dc_shift`] (7.5 Hz at 48 kHz, 5 Hz at 16 kHz). A block is then
//! scaled by one shift common to all microphones (so their relative levels survive) and rounded
//! to Q15: `value = q15 · 2^(exponent − 15)` of full scale, `exponent = −shift`.
//!
//! At 48 kHz the spatial path runs at 24 kHz (its band ends at 6 kHz): each word is taken to
//! Q25 (`>> 6`) and a 7-tap half-band FIR `[−1, 0, 9, 16, 9, 0, −1] / 32` (integer taps, gain 1
//! at DC, −0.5 dB at 6 kHz, ≤ −25 dB above 18 kHz, where aliases would land in the band) keeps
//! every second output, in Q30 (`|y| ≤ 1.125 · 2^30`, no overflow). DC is then removed at
//! 24 kHz, on the Q30 samples (the filter is linear, so the order does not matter; k = 9 keeps
//! the 7.5 Hz corner), half the work of removing it at 48 kHz. The filter is the same for
//! every microphone, so relative delays are untouched; its group delay is 3 input samples.
//! The block exponent then counts from Q30: `exponent = 1 − shift`.

use crate::MAX_MICS;

/// Largest block shift: a block quieter than 2^-16 of full scale is not amplified further.
pub const MAX_BLOCK_SHIFT: u32 = 16;
/// Magnitude at or above which a word counts as clipped (24-bit full scale, left-justified).
pub const CLIP_LEVEL: i32 = 0x7FFF_FF00 - 0x100;
/// Lower bound of `x ^ (x >> 31)` over clipped words `x` (|x| ≥ [`CLIP_LEVEL`]): an OR of
/// these values below it proves that no word was clipped.
const CLIP_SCREEN: u32 = (CLIP_LEVEL - 1) as u32;

/// Running-mean length exponent k for a sample rate: the DC corner sits near 5–8 Hz.
pub fn dc_shift(sample_rate_hz: u32) -> u32 {
    if sample_rate_hz >= 32_000 {
        10
    } else {
        9
    }
}

/// Spatial decimation factor of the front end for a sample rate: 2 at 48 kHz (24 kHz spatial
/// rate), 1 at 16 kHz.
pub fn spatial_decimation(sample_rate_hz: u32) -> usize {
    if sample_rate_hz >= 32_000 {
        2
    } else {
        1
    }
}

/// State of one microphone's half-band decimator (Q25 samples). With the newest input pair
/// (x(n−1), x(n)): `y(n) = 16·x(n−3) + 9·(x(n−2) + x(n−4)) − (x(n) + x(n−6))`, computed as
/// `partial − x(n)` with `partial` formed when the previous pair completed (the same integer:
/// every term and sum stays below 2^31 in magnitude, 36 · 2^25 at most).
#[derive(Debug, Clone, Copy)]
struct HalfBand {
    /// 16·x(n−3) + 9·(x(n−2) + x(n−4)) − x(n−6) for the pair being completed.
    partial: i32,
    /// x(n−2), x(n−4): the second samples of the last two pairs, newest first.
    even: [i32; 2],
    /// The first sample of the pair being completed.
    pending: i32,
}

impl HalfBand {
    const ZERO: Self = Self { partial: 0, even: [0; 2], pending: 0 };
}

/// The half-band output for the pair (`first`, `second`), updating the state in registers.
#[inline(always)]
fn half_band(partial: &mut i32, e: &mut [i32; 2], first: i32, second: i32) -> i32 {
    let y = *partial - second;
    *partial = 16 * first + 9 * (second + e[0]) - e[1];
    *e = [second, e[0]];
    y
}

/// DC running-mean exponent k of a decimating front end (at the 24 kHz spatial rate: 7.5 Hz);
/// a constant so the decimating loops keep it out of a register.
const DECIMATED_DC_SHIFT: u32 = 9;

/// One microphone's decimating front end in registers: half-band, DC removal, peak.
struct Lane {
    partial: i32,
    even: [i32; 2],
    dc: i32,
    /// The largest zigzag code `2|y| − (y < 0)` of the outputs (and of the peak before):
    /// two instructions per output where `unsigned_abs` takes three or four, the same order
    /// on |y|.
    z: u32,
}

impl Lane {
    #[inline(always)]
    fn load(front: &FrontEnd, mic: usize, peak: u32) -> Self {
        let HalfBand { partial, even, .. } = front.half_band[mic];
        Self { partial, even, dc: front.dc[mic], z: zigzag_of_abs(peak) }
    }

    /// The output of the pair (`a`, `b`) of TDM words.
    #[inline(always)]
    fn push(&mut self, a: i32, b: i32) -> i32 {
        let y = half_band(&mut self.partial, &mut self.even, a >> 6, b >> 6);
        let y = FrontEnd::step(&mut self.dc, DECIMATED_DC_SHIFT - 1, y);
        self.z = self.z.max(((y << 1) ^ (y >> 31)) as u32);
        y
    }

    /// Writes the state back; returns the peak.
    #[inline(always)]
    fn store(self, front: &mut FrontEnd, mic: usize) -> u32 {
        front.dc[mic] = self.dc;
        front.half_band[mic].partial = self.partial;
        front.half_band[mic].even = self.even;
        (self.z >> 1) + (self.z & 1)
    }
}

/// Per-microphone DC removal (and spatial decimation) state and the clip counter.
///
/// The DC estimate is kept in Q31 and updated as `dc += (x/2 − dc/2) >> (k − 1)`: all in 32 bits
/// (one cycle per operation on the Cortex-M), never overflowing; its truncation leaves at most
/// 2^k LSB of Q31 (−126 dBFS at k = 10) of DC behind.
#[derive(Debug, Clone)]
pub struct FrontEnd {
    dc: [i32; MAX_MICS],
    half_band: [HalfBand; MAX_MICS],
    /// 1 while the first sample of a half-band pair has been taken and its second is due.
    phase: u8,
    decimation: u8,
    shift: u32,
    /// Words at full scale since the counter was last taken.
    pub clipped: u32,
}

impl FrontEnd {
    /// A front end with zero DC estimates; `shift` from [`dc_shift`] (1..=30); no decimation.
    pub const fn new(shift: u32) -> Self {
        Self {
            dc: [0; MAX_MICS],
            half_band: [HalfBand::ZERO; MAX_MICS],
            phase: 0,
            decimation: 1,
            shift,
            clipped: 0,
        }
    }

    /// A front end for `sample_rate_hz`: decimation from [`spatial_decimation`], DC removal at
    /// the decimated rate with k = 9.
    pub const fn for_rate(sample_rate_hz: u32) -> Self {
        // DC removal runs at 24 kHz when decimating, at 16 kHz otherwise: k = 9 either way
        // (7.5 Hz, resp. 5 Hz).
        let mut f = Self::new(DECIMATED_DC_SHIFT);
        f.decimation = if sample_rate_hz >= 32_000 { 2 } else { 1 };
        f
    }

    /// DC estimate of microphone `mic`, in the scale of the samples it is subtracted from (Q31,
    /// or Q30 after the half-band decimator).
    pub fn dc(&self, mic: usize) -> i32 {
        self.dc[mic]
    }

    /// Input samples per output sample (1 or 2).
    pub fn decimation(&self) -> usize {
        self.decimation as usize
    }

    /// True when the next frame completes a half-band pair (or there is no decimation).
    pub fn pair_open(&self) -> bool {
        self.phase != 0
    }

    /// One whole TDM frame (`frame[mic]` for mic < `mics`): DC removal for every microphone and,
    /// when an output sample is due, `out(mic, sample)` for each. Returns whether outputs were
    /// written; raises `peak` to their largest absolute value.
    pub fn push_frame(
        &mut self,
        frame: &[i32],
        mics: usize,
        peak: &mut u32,
        out: &mut impl FnMut(usize, i32),
    ) -> bool {
        if self.decimation == 1 {
            for (mic, &x) in frame[..mics].iter().enumerate() {
                let y = self.remove_dc_one(mic, x, peak);
                out(mic, y);
            }
            return true;
        }
        let k1 = DECIMATED_DC_SHIFT - 1;
        let second = self.phase != 0;
        for (mic, &x) in frame[..mics].iter().enumerate() {
            if x >= CLIP_LEVEL || x <= -CLIP_LEVEL {
                self.clipped = self.clipped.saturating_add(1);
            }
            let h = &mut self.half_band[mic];
            if second {
                let y = half_band(&mut h.partial, &mut h.even, h.pending, x >> 6);
                let y = Self::step(&mut self.dc[mic], k1, y);
                *peak = (*peak).max(y.unsigned_abs());
                out(mic, y);
            } else {
                h.pending = x >> 6;
            }
        }
        self.phase ^= 1;
        second
    }

    /// Counts the clipped words of microphones `0..mics` in whole TDM frames (`frames`, `slots`
    /// words each) into [`Self::clipped`]. [`Self::decimate_frames`] leaves this to the caller,
    /// once per run of frames.
    ///
    /// One contiguous pass ORs every word's ones'-complement magnitude `x ^ (x >> 31)`: below
    /// [`CLIP_LEVEL`] − 1 no word was clipped (2 instructions per word, where counting takes 4).
    /// Only otherwise (a word near full scale, or a loud run whose magnitudes happen to OR up to
    /// it) are the words counted one by one.
    pub fn count_clipped(&mut self, frames: &[i32], slots: usize, mics: usize) {
        let magnitude = |x: i32| (x ^ (x >> 31)) as u32;
        let (eights, rest) = frames.as_chunks::<8>();
        let screen = eights.iter().fold(0u32, |acc, w| {
            let a = (magnitude(w[0]) | magnitude(w[1])) | (magnitude(w[2]) | magnitude(w[3]));
            let b = (magnitude(w[4]) | magnitude(w[5])) | (magnitude(w[6]) | magnitude(w[7]));
            acc | a | b
        });
        let screen = rest.iter().fold(screen, |acc, &x| acc | magnitude(x));
        if screen < CLIP_SCREEN || slots == 0 {
            return;
        }
        // About 5 instructions per word when every slot is a microphone (as with 8 on 8 slots):
        // a loud run that passes the screen costs about what counting alone cost before.
        let is_clipped = |x: i32| u32::from(x >= CLIP_LEVEL || x <= -CLIP_LEVEL);
        let whole = frames.len() - frames.len() % slots;
        let clipped = if mics >= slots {
            frames[..whole].iter().map(|&x| is_clipped(x)).sum::<u32>()
        } else {
            let frames = frames.chunks_exact(slots);
            frames.map(|f| f[..mics].iter().map(|&x| is_clipped(x)).sum::<u32>()).sum()
        };
        self.clipped = self.clipped.saturating_add(clipped);
    }

    /// De-interleaves microphone `mic` from an even number of whole TDM frames (`frames`,
    /// `slots` words each, starting a half-band pair) into `out` (one sample per two frames),
    /// decimating and removing DC; raises `peak` to the largest absolute output. Clipping is
    /// not counted here: see [`Self::count_clipped`].
    pub fn decimate_frames(
        &mut self,
        mic: usize,
        frames: &[i32],
        slots: usize,
        out: &mut [i32],
        peak: &mut u32,
    ) {
        if mic >= slots || mic >= MAX_MICS {
            return;
        }
        let mut lane = Lane::load(self, mic, *peak);
        if slots == 8 {
            // The firmware's layout (8-slot frames): constant offsets, two outputs per step
            // (after two pairs the half-band state is all new values: no register moves).
            let n = out.len().min(frames.len() / 16);
            let (out, _) = out.split_at_mut(n);
            let (quads, _) = frames.as_chunks::<32>();
            let (twos, tail) = out.as_chunks_mut::<2>();
            for (o, w) in twos.iter_mut().zip(quads) {
                o[0] = lane.push(w[mic], w[8 + mic]);
                o[1] = lane.push(w[16 + mic], w[24 + mic]);
            }
            if let ([o], Some(w)) = (tail, frames.get((n.max(1) - 1) * 16..)) {
                *o = lane.push(w[mic], w[8 + mic]);
            }
        } else {
            for (o, p) in out.iter_mut().zip(frames.chunks_exact(2 * slots)) {
                *o = lane.push(p[mic], p[slots + mic]);
            }
        }
        *peak = lane.store(self, mic);
    }

    #[inline(always)]
    fn step(dc: &mut i32, k1: u32, x: i32) -> i32 {
        *dc += ((x >> 1) - (*dc >> 1)) >> k1;
        x.saturating_sub(*dc)
    }

    /// One TDM word of microphone `mic` → DC-removed Q31 sample (saturated).
    ///
    /// ```
    /// let mut fe = aim_dsp::frontend::FrontEnd::new(10);
    /// // a constant input decays towards zero at the output
    /// let mut y = 0;
    /// for _ in 0..20_000 { y = fe.remove_dc(0, 0x1000_0000); }
    /// assert!(y.abs() < 0x0010_0000);
    /// ```
    pub fn remove_dc(&mut self, mic: usize, word: i32) -> i32 {
        let mut one = [word];
        self.remove_dc_block(mic, &mut one);
        one[0]
    }

    /// Removes DC in place from consecutive Q31 samples of microphone `mic`, counts clipped
    /// words, and returns the largest absolute output.
    pub fn remove_dc_block(&mut self, mic: usize, samples: &mut [i32]) -> u32 {
        let mut peak = 0u32;
        for s in samples {
            *s = self.remove_dc_one(mic, *s, &mut peak);
        }
        peak
    }

    /// De-interleaves microphone `mic` from whole TDM frames (`frames`, `slots` words each) into
    /// `out`, removing DC on the way; counts clipped words and raises `peak` to the largest
    /// absolute output.
    pub fn remove_dc_frames(
        &mut self,
        mic: usize,
        frames: &[i32],
        slots: usize,
        out: &mut [i32],
        peak: &mut u32,
    ) {
        let k1 = self.shift.clamp(1, 30) - 1;
        let mut dc = self.dc[mic];
        let (mut p, mut clipped) = (*peak, 0u32);
        if mic >= slots {
            return;
        }
        for (o, frame) in out.iter_mut().zip(frames.chunks_exact(slots)) {
            let x = frame[mic];
            clipped += u32::from(x >= CLIP_LEVEL || x <= -CLIP_LEVEL);
            let y = Self::step(&mut dc, k1, x);
            p = p.max(y.unsigned_abs());
            *o = y;
        }
        self.dc[mic] = dc;
        self.clipped = self.clipped.saturating_add(clipped);
        *peak = p;
    }

    /// One word of microphone `mic` → DC-removed sample; counts clipping, raises `peak`.
    #[inline]
    pub fn remove_dc_one(&mut self, mic: usize, x: i32, peak: &mut u32) -> i32 {
        let k1 = self.shift.clamp(1, 30) - 1;
        if x >= CLIP_LEVEL || x <= -CLIP_LEVEL {
            self.clipped = self.clipped.saturating_add(1);
        }
        let y = Self::step(&mut self.dc[mic], k1, x);
        *peak = (*peak).max(y.unsigned_abs());
        y
    }
}

/// The zigzag code `2|y| − (y < 0)` of the largest of the magnitudes `peak` (0 for 0): its
/// `(z >> 1) + (z & 1)` is `peak` again, for every `peak` up to 2^31.
#[inline(always)]
fn zigzag_of_abs(peak: u32) -> u32 {
    // A positive y = peak codes as 2·peak; peak = 2^31 (only −2^31) as 2^32 − 1.
    peak.wrapping_mul(2).wrapping_sub(u32::from(peak == 1 << 31))
}

/// Block shift for the largest absolute Q31 sample of a block: the left shift that puts the
/// peak just below full scale, at most [`MAX_BLOCK_SHIFT`].
///
/// ```
/// assert_eq!(aim_dsp::frontend::block_shift(0x4000_0000), 0);
/// assert_eq!(aim_dsp::frontend::block_shift(0x0100_0000), 6);
/// assert_eq!(aim_dsp::frontend::block_shift(0), 16);
/// ```
pub fn block_shift(max_abs: u32) -> u32 {
    if max_abs == 0 {
        return MAX_BLOCK_SHIFT;
    }
    (max_abs.leading_zeros().saturating_sub(1)).min(MAX_BLOCK_SHIFT)
}

/// Q31 sample → Q15 after the block shift, rounded to nearest (ties up) and saturated.
///
/// `shift` must not exceed `block_shift(|q31|)` (true for every sample of the block the shift
/// was computed from), so the shifted value fits in 32 bits.
#[inline(always)]
pub fn to_q15(q31: i32, shift: u32) -> i16 {
    let v = q31 << shift;
    // floor((v + 2^15) / 2^16): the saturating add (one QADD on the Cortex-M4) clips the one
    // value that would round up past i16::MAX.
    (v.saturating_add(1 << 15) >> 16) as i16
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clip_screen_and_zigzag_peak_are_exact_at_the_edges() {
        // Every clipped word's ones'-complement magnitude reaches the screen; words two LSB
        // inside the clip level stay below it (CLIP_LEVEL − 1 itself passes the screen and is
        // then counted, exactly, as not clipped).
        for x in [CLIP_LEVEL, -CLIP_LEVEL, i32::MAX, i32::MIN, i32::MIN + 1, -CLIP_LEVEL - 1] {
            assert!((x ^ (x >> 31)) as u32 >= CLIP_SCREEN, "{x:#x}");
        }
        for x in [CLIP_LEVEL - 2, -(CLIP_LEVEL - 2), 0, -1] {
            assert!(((x ^ (x >> 31)) as u32) < CLIP_SCREEN, "{x:#x}");
        }
        // The zigzag code orders |y| and decodes to it, from either a sample or a peak.
        let zigzag = |y: i32| ((y << 1) ^ (y >> 31)) as u32;
        let decode = |z: u32| (z >> 1) + (z & 1);
        for y in [0, 1, -1, 2, -2, 0x4000_0000, -0x4000_0000, i32::MAX, i32::MIN, i32::MIN + 1] {
            assert_eq!(decode(zigzag(y)), y.unsigned_abs(), "{y:#x}");
            assert_eq!(decode(zigzag_of_abs(y.unsigned_abs())), y.unsigned_abs(), "{y:#x}");
            assert!(zigzag(y) <= zigzag_of_abs(y.unsigned_abs()), "{y:#x}");
            assert!(zigzag(-y.saturating_abs()) <= zigzag(y.saturating_abs()), "{y:#x}");
        }
    }

    #[test]
    fn q15_round_trip_keeps_relative_level() {
        // A block whose peak is 2^-8 of full scale gets shift 7 and keeps ~15 bits.
        let x: i32 = 1 << 23; // 2^-8 of full scale
        let s = block_shift(x as u32);
        assert_eq!(s, 7);
        let q = to_q15(x, s);
        assert_eq!(q, 1 << 14); // 0.5 in Q15, exponent −7 → 2^-8
        assert_eq!(to_q15(i32::MIN, 0), i16::MIN);
        assert_eq!(to_q15(-(1 << 15), 0), 0); // −0.5 LSB: ties round up
        assert_eq!(to_q15(3 << 15, 0), 2); // 1.5 LSB rounds up
        assert_eq!(to_q15(i32::MAX, 0), i16::MAX);
    }

    #[test]
    fn q15_rounding_is_round_half_up_with_saturation() {
        // The reference: ((v >> 15) + 1) >> 1, saturated to i16::MAX.
        let mut v = 0x1234_5678i32;
        for _ in 0..200_000 {
            v = v.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            for x in [v, v >> 7, i32::MAX - (v & 0xFFFF), i32::MIN + (v & 0xFFFF)] {
                let reference = (((x >> 15) + 1) >> 1).min(i16::MAX as i32) as i16;
                assert_eq!(to_q15(x, 0), reference, "{x:#x}");
            }
        }
    }

    #[test]
    fn decimating_front_end_removes_dc_and_agrees_frame_by_frame() {
        // 2 mics in 3-slot frames at 48 kHz: mic 0 an offset of 10 % full scale plus a 1 kHz
        // tone, mic 1 the tone alone. After settling both outputs (Q30, 24 kHz) carry the tone
        // at the half-band's gain (0.9984 at 1 kHz: (16 + 18 cos ω − 2 cos 3ω) / 32) and no DC;
        // whole-pair and frame-by-frame paths give the same bits.
        let amp = 0.2 * (1u64 << 31) as f64;
        let words: Vec<i32> = (0..96_000)
            .flat_map(|n| {
                let tone = amp * (2.0 * std::f64::consts::PI * 1000.0 * n as f64 / 48_000.0).sin();
                [(0.1 * (1u64 << 31) as f64 + tone) as i32, tone as i32, 0]
            })
            .collect();
        let (mut a, mut b) = (FrontEnd::for_rate(48_000), FrontEnd::for_rate(48_000));
        assert_eq!(a.decimation(), 2);
        let mut out_a = vec![vec![0i32; 48_000]; 2];
        let mut peak = 0;
        for (mic, out) in out_a.iter_mut().enumerate() {
            a.decimate_frames(mic, &words, 3, out, &mut peak);
        }
        let mut out_b = vec![Vec::new(); 2];
        let mut peak_b = 0;
        for frame in words.chunks_exact(3) {
            b.push_frame(frame, 2, &mut peak_b, &mut |mic, y| out_b[mic].push(y));
        }
        assert_eq!(out_a, out_b);
        assert_eq!(peak, peak_b);
        let w = 2.0 * std::f64::consts::PI * 1000.0 / 48_000.0;
        let gain = (16.0 + 18.0 * w.cos() - 2.0 * (3.0 * w).cos()) / 32.0;
        for out in &out_a {
            let tail = &out[24_000..];
            let mean = tail.iter().map(|&y| y as f64).sum::<f64>() / tail.len() as f64;
            let top = tail.iter().map(|&y| (y as f64).abs()).fold(0.0, f64::max);
            assert!(mean.abs() < 1e-4 * amp, "residual DC {mean}");
            assert!((top / (0.5 * amp * gain) - 1.0).abs() < 2e-3, "tone gain {}", top / amp);
        }
    }

    #[test]
    fn dc_is_removed_and_tones_pass() {
        // Offset of 10 % full scale plus a 1 kHz tone at 48 kHz: after settling the output mean
        // is near zero and the tone amplitude is kept within 0.1 %.
        let mut fe = FrontEnd::new(dc_shift(48_000));
        let amp = 0.2 * (1u64 << 31) as f64;
        let mut sum = 0.0;
        let mut peak: f64 = 0.0;
        for n in 0..96_000 {
            let t = n as f64 / 48_000.0;
            let x =
                0.1 * (1u64 << 31) as f64 + amp * (2.0 * std::f64::consts::PI * 1000.0 * t).sin();
            let y = fe.remove_dc(3, x as i32) as f64;
            if n >= 48_000 {
                sum += y;
                peak = peak.max(y.abs());
            }
        }
        assert!((sum / 48_000.0).abs() < 1e-4 * amp, "residual DC {}", sum / 48_000.0);
        assert!((peak / amp - 1.0).abs() < 1e-3, "tone gain {}", peak / amp);
        assert_eq!(fe.clipped, 0);
        fe.remove_dc(0, i32::MAX);
        fe.remove_dc(0, i32::MIN + 1);
        assert_eq!(fe.clipped, 2);
    }
}
