//! The streaming pipeline: TDM words in, `Doa` / `Peaks` / `Mfcc` / `Health` out.
//!
//! Output rates with the defaults: one `Doa` per `average_blocks` blocks (48 kHz, 1024-sample
//! blocks, 8 blocks: 5.86 per second; 16 kHz, 512, 5: 6.25 per second), one `Peaks` per
//! 2048 decimated samples (3.9 per second at either rate), one `Mfcc` (identification
//! features of the same analysis window) per `mfcc_interval` `Peaks`, one `Health` per
//! `health_interval_blocks` blocks (about 1 per second at 48 kHz). A `Doa` is left out when
//! fewer than two pairs, spanning the plane, carry a coherent peak (silence, a single tone).
//!
//! Memory is fixed: `size_of::<Pipeline>()` is 117 456 bytes on the Cortex-M4F (the
//! `memory_budget` test keeps it ≤ 128 KiB), all of it in the struct, nothing on the heap and
//! only small temporaries on the stack (992 bytes deep for `push`). The
//! struct is `const`-constructible ([`Pipeline::empty`]) so the firmware can place it in a
//! `static` and [`Pipeline::configure`] it there, without a large stack temporary.
//!
//! Gaps: when the capture loses samples (a DMA overrun, a chunk discarded because the DSP fell
//! behind) the firmware calls [`Pipeline::gap`] with the number of frames lost. The sample
//! index then jumps by that much, so every later stamp stays on the array's real clock, and
//! every output whose span would cross the gap is dropped and counted ([`GapStats`]): the
//! partly filled block, a DoA average in progress, every BPF analysis window that holds
//! samples from before the gap. The filters' memory (DC removal, half-band, the spectral
//! decimator) is kept: a transient of their length (under 1 ms) in the first block after a
//! gap, where a reset would instead cost the DC estimate's much longer settling.

use microfft::Complex32;

use crate::beacon::{self, Detector};
use crate::bpf::{SpectralPath, ANALYSIS_LEN};
use crate::doa::{self, Pair};
use crate::frontend::{self, FrontEnd};
use crate::gcc_phat::{self, DelayEstimate, Twiddles};
use crate::idframe::IdExtractor;
use crate::snippet::{self, Snippet, SNIPPET_LEN};
use crate::{
    Config, ConfigError, Doa, Health, Output, MAX_BAND_BINS, MAX_BLOCK_LEN, MAX_MICS, MAX_PAIRS,
};

/// Discontinuities the pipeline was told about ([`Pipeline::gap`]) and what they cost. Counters
/// count from [`Pipeline::configure`] and wrap.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GapStats {
    /// Gaps reported (calls of [`Pipeline::gap`] with at least one lost frame).
    pub gaps: u32,
    /// Input frames (samples per microphone) lost in them.
    pub frames_lost: u64,
    /// Outputs dropped because their span crossed a gap: DoA averages abandoned (the partial
    /// block included) and BPF analyses whose window held samples from before a gap.
    pub outputs_dropped: u32,
}

/// Most words per TDM frame ([`Config::tdm_slots`]).
const MAX_TDM_SLOTS: usize = 16;

/// Scratch floats: the spatial FFT (first [`MAX_BLOCK_LEN`]) with the unit band spectra of all
/// microphones after it, or the whole BPF transform. Both uses fit exactly.
const SCRATCH_LEN: usize = ANALYSIS_LEN;
const _: () = assert!(MAX_BLOCK_LEN + MAX_MICS * 2 * MAX_BAND_BINS <= SCRATCH_LEN);
const _: () = assert!(beacon::SCRATCH_LEN <= SCRATCH_LEN);

/// The on-chip processing of one array, in fixed memory. See the module docs for output rates.
#[derive(Debug, Clone)]
pub struct Pipeline {
    config: Config,
    configured: bool,
    mics: usize,
    pair_count: usize,
    first_bin: usize,
    band_bins: usize,
    samples_per_metre: f32,
    pairs: [Pair; MAX_PAIRS],
    delays: [DelayEstimate; MAX_PAIRS],
    twiddles: Twiddles,
    // front end
    front: FrontEnd,
    /// DC-removed (at 48 kHz also decimated) samples of the block being filled, per microphone.
    block: [[i32; MAX_BLOCK_LEN]; MAX_MICS],
    /// The words of a TDM frame split across `push` calls.
    partial: [i32; MAX_TDM_SLOTS],
    slot: usize,
    /// Samples of `block` filled, at the spatial rate.
    fill: usize,
    /// Samples per block at the spatial rate: the spatial FFT length.
    fft_len: usize,
    /// Input samples per spatial sample (1 or 2).
    decimation: usize,
    block_start: u64,
    /// Largest absolute DC-removed sample of the block being filled.
    block_peak: u32,
    blocks: u32,
    last_exponent: i8,
    // spatial path
    window: [f32; MAX_BLOCK_LEN],
    cross: [[Complex32; MAX_BAND_BINS]; MAX_PAIRS],
    averaged: u32,
    average_start: u64,
    // spectral path
    spectral: SpectralPath,
    /// Identification features of the BPF analyses.
    id: IdExtractor,
    /// BPF analyses since the last `Mfcc` output.
    analyses_since_mfcc: u32,
    scratch: [f32; SCRATCH_LEN],
    // health
    health_start: u64,
    health_blocks: u32,
    health_peak: u32,
    /// Per microphone, Σ (x >> 8)² over the first block of the Health interval.
    level_power: [u64; MAX_MICS],
    /// Per microphone, the DC estimate at that block.
    level_dc: [i32; MAX_MICS],
    // gaps
    gap_stats: GapStats,
    /// Real (input-rate) samples skipped by gaps: the spectral path's stamps count only the
    /// samples it was fed, so its stamps plus this are on the array's clock.
    spectral_skipped: u64,
    /// The spectral path's own stamp of its first sample after the last gap; an analysis
    /// window that starts earlier holds samples from before the gap and is dropped.
    spectral_clean_from: u64,
    /// Beacon detector on microphone 0's input-rate words (48 kHz only).
    beacon: Detector,
    beacon_on: bool,
    /// Decimated sample (spectral path's count) where the next snippet starts.
    next_snippet: u64,
}

impl Pipeline {
    /// An unconfigured pipeline (ignores input until [`Pipeline::configure`]); `const` so it
    /// can initialise a `static`.
    pub const fn empty() -> Self {
        Self {
            config: Config::empty(),
            configured: false,
            mics: 0,
            pair_count: 0,
            first_bin: 0,
            band_bins: 0,
            samples_per_metre: 0.0,
            pairs: [Pair { i: 0, j: 0, baseline_m: [0.0; 2], max_lag: 0 }; MAX_PAIRS],
            delays: [DelayEstimate { delay_samples: 0.0, coherence: 0.0, peak_margin: 0.0 };
                MAX_PAIRS],
            twiddles: Twiddles::empty(),
            front: FrontEnd::new(10),
            block: [[0; MAX_BLOCK_LEN]; MAX_MICS],
            partial: [0; MAX_TDM_SLOTS],
            slot: 0,
            fill: 0,
            fft_len: 0,
            decimation: 1,
            block_start: 0,
            block_peak: 0,
            blocks: 0,
            last_exponent: 0,
            window: [0.0; MAX_BLOCK_LEN],
            cross: [[Complex32::new(0.0, 0.0); MAX_BAND_BINS]; MAX_PAIRS],
            averaged: 0,
            average_start: 0,
            spectral: SpectralPath::empty(),
            id: IdExtractor::empty(),
            analyses_since_mfcc: 0,
            scratch: [0.0; SCRATCH_LEN],
            health_start: 0,
            health_blocks: 0,
            health_peak: 0,
            level_power: [0; MAX_MICS],
            level_dc: [0; MAX_MICS],
            gap_stats: GapStats { gaps: 0, frames_lost: 0, outputs_dropped: 0 },
            spectral_skipped: 0,
            spectral_clean_from: 0,
            beacon: Detector::empty(),
            beacon_on: false,
            next_snippet: 0,
        }
    }

    /// A configured pipeline by value (117 456 bytes: prefer [`Pipeline::empty`] +
    /// [`Pipeline::configure`] in place on small stacks).
    pub fn new(config: &Config) -> Result<Self, ConfigError> {
        let mut p = Self::empty();
        p.configure(config)?;
        Ok(p)
    }

    /// Validates `config` and (re)starts the pipeline with it; sample index 0 is the next word.
    /// On error the pipeline is left unconfigured.
    pub fn configure(&mut self, config: &Config) -> Result<(), ConfigError> {
        self.configured = false;
        config.validate()?;
        self.config = *config;
        let g = &config.geometry;
        self.mics = g.len();
        let (lo, hi) = config.band_bins();
        self.first_bin = lo;
        self.band_bins = hi - lo;
        self.samples_per_metre = config.sample_rate_hz as f32 / config.speed_of_sound_m_s;
        let p = g.positions();
        let mut n = 0;
        for i in 0..self.mics {
            for j in i + 1..self.mics {
                let b = [p[i][0] - p[j][0], p[i][1] - p[j][1]];
                let lag = libm::hypotf(b[0], b[1]) * self.samples_per_metre + 1.0;
                self.pairs[n] =
                    Pair { i: i as u8, j: j as u8, baseline_m: b, max_lag: libm::ceilf(lag) as u8 };
                n += 1;
            }
        }
        self.pair_count = n;
        self.twiddles = Twiddles::new();
        self.front = FrontEnd::for_rate(config.sample_rate_hz);
        self.decimation = self.front.decimation();
        self.fft_len = config.block_len / self.decimation;
        crate::window::hann(&mut self.window[..self.fft_len]);
        self.spectral.configure(config.sample_rate_hz, self.decimation);
        self.id.configure();
        self.beacon_on = config.sample_rate_hz == beacon::SAMPLE_RATE_HZ;
        if self.beacon_on {
            self.beacon.configure();
        }
        self.reset_stream();
        self.configured = true;
        Ok(())
    }

    fn reset_stream(&mut self) {
        self.slot = 0;
        self.fill = 0;
        self.block_start = 0;
        self.block_peak = 0;
        self.blocks = 0;
        self.averaged = 0;
        self.average_start = 0;
        self.health_start = 0;
        self.health_blocks = 0;
        self.health_peak = 0;
        self.gap_stats = GapStats::default();
        self.spectral_skipped = 0;
        self.spectral_clean_from = 0;
        self.next_snippet = 0;
        self.analyses_since_mfcc = 0;
        self.delays = [DelayEstimate::default(); MAX_PAIRS];
        for c in &mut self.cross {
            c.fill(Complex32::new(0.0, 0.0));
        }
    }

    /// The configuration in force.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The microphone pairs, in the order of [`Pipeline::pair_delays`]: (0,1), (0,2), …, (1,2), ….
    pub fn pairs(&self) -> &[Pair] {
        &self.pairs[..self.pair_count]
    }

    /// The pair delays behind the last `Doa` (or the last averaging period).
    pub fn pair_delays(&self) -> &[DelayEstimate] {
        &self.delays[..self.pair_count]
    }

    /// Interleaved TDM words (frames of `tdm_slots` words; mic i = slot i; 24-bit samples
    /// left-justified in i32), any chunk length: a frame may be split across calls. Results go
    /// to `sink` as their blocks complete. Ignored while unconfigured.
    pub fn push(&mut self, words: &[i32], sink: &mut impl FnMut(Output)) {
        if !self.configured {
            return;
        }
        let slots = self.config.tdm_slots;
        if self.beacon_on {
            // Microphone 0's words of this chunk: the first is where the next frame starts.
            let first = (slots - self.slot) % slots;
            if let Some(mic0) = words.get(first..) {
                self.beacon.push(mic0, slots, &mut self.scratch, &mut |b| sink(Output::Beacon(b)));
            }
        }
        let n = self.fft_len;
        let d = self.decimation;
        let mut words = words;
        while !words.is_empty() {
            // Whole frames in the common case: one tight loop per microphone (per pair of
            // frames when decimating).
            let runs = if self.slot == 0 && !self.front.pair_open() {
                (words.len() / (d * slots)).min(n - self.fill)
            } else {
                0
            };
            if runs > 0 {
                let (now, rest) = words.split_at(runs * d * slots);
                if d != 1 {
                    self.front.count_clipped(now, slots, self.mics);
                }
                for (mic, ch) in self.block[..self.mics].iter_mut().enumerate() {
                    let out = &mut ch[self.fill..self.fill + runs];
                    if d == 1 {
                        self.front.remove_dc_frames(mic, now, slots, out, &mut self.block_peak);
                    } else {
                        self.front.decimate_frames(mic, now, slots, out, &mut self.block_peak);
                    }
                }
                self.fill += runs;
                words = rest;
            } else {
                // A frame split across calls, or an odd frame: gather it, then push it whole.
                let take = (slots - self.slot).min(words.len());
                self.partial[self.slot..self.slot + take].copy_from_slice(&words[..take]);
                words = &words[take..];
                self.slot += take;
                if self.slot < slots {
                    break;
                }
                self.slot = 0;
                let (block, fill) = (&mut self.block, self.fill);
                let produced = self.front.push_frame(
                    &self.partial[..slots],
                    self.mics,
                    &mut self.block_peak,
                    &mut |mic, y| block[mic][fill] = y,
                );
                self.fill += usize::from(produced);
            }
            if self.fill == n {
                self.fill = 0;
                self.process_block(sink);
            }
        }
    }

    /// Tells the pipeline that `lost_frames` TDM frames were lost before the next word pushed:
    /// the next word starts a frame whose sample index is that of the frame that would have
    /// come next, plus `lost_frames`. A frame left incomplete by the last push is dropped (its
    /// index counts as used). Outputs whose span would cross the gap are dropped and counted in
    /// [`Pipeline::gap_stats`]. `lost_frames` = 0 does nothing.
    pub fn gap(&mut self, lost_frames: u64) {
        if !self.configured || lost_frames == 0 {
            return;
        }
        let d = self.decimation as u64;
        // An incomplete frame: its words are dropped, its index is used.
        let partial = u64::from(self.slot != 0);
        self.slot = 0;
        let open = self.front.pair_open();
        // The input frames of the block being filled (an open decimation pair included).
        let consumed = self.fill as u64 * d + u64::from(open);
        if open {
            // Close the decimation pair with a silent frame standing for the first lost frame,
            // so that the next frame starts a pair; its output is discarded with the block.
            let zeros = [0i32; MAX_TDM_SLOTS];
            let mut ignored = 0;
            let (block, fill) = (&mut self.block, self.fill);
            self.front.push_frame(
                &zeros[..self.config.tdm_slots],
                self.mics,
                &mut ignored,
                &mut |mic, y| block[mic][fill] = y,
            );
        }
        let next = self.block_start + consumed + partial + lost_frames;
        if self.beacon_on {
            // The detector has seen mic 0 of every frame begun so far.
            debug_assert_eq!(self.beacon.next_index() + lost_frames, next);
            self.beacon.gap(lost_frames);
        }
        // The partial block and a DoA average in progress would span the gap.
        if self.fill > 0 || open || partial > 0 || self.averaged > 0 {
            self.gap_stats.outputs_dropped = self.gap_stats.outputs_dropped.wrapping_add(1);
        }
        self.health_peak = self.health_peak.max(core::mem::take(&mut self.block_peak));
        self.fill = 0;
        self.averaged = 0;
        for c in &mut self.cross[..self.pair_count] {
            c.fill(Complex32::new(0.0, 0.0));
        }
        // The spectral path was fed whole blocks up to `block_start`; it goes on from there.
        let spectral_next = self.block_start - self.spectral_skipped;
        self.spectral_skipped = next - spectral_next;
        self.spectral_clean_from = spectral_next;
        self.block_start = next;
        self.gap_stats.gaps = self.gap_stats.gaps.wrapping_add(1);
        self.gap_stats.frames_lost = self.gap_stats.frames_lost.wrapping_add(lost_frames);
    }

    /// Gaps reported since [`Pipeline::configure`] and the outputs they cost.
    pub fn gap_stats(&self) -> GapStats {
        self.gap_stats
    }

    fn process_block(&mut self, sink: &mut impl FnMut(Output)) {
        let n = self.config.block_len;
        let peak = core::mem::take(&mut self.block_peak);
        let shift = frontend::block_shift(peak);
        self.last_exponent = self.q_exponent() - shift as i8;
        self.health_peak = self.health_peak.max(peak);
        if self.health_blocks == 0 {
            self.probe_levels();
        }

        self.spatial_block(shift);
        if self.averaged == 0 {
            self.average_start = self.block_start;
        }
        self.averaged += 1;
        if self.averaged == self.config.average_blocks {
            self.averaged = 0;
            if let Some(doa) = self.estimate_direction() {
                sink(Output::Doa(doa));
            }
        }
        self.spectral_block(shift, sink);

        self.blocks = self.blocks.wrapping_add(1);
        self.health_blocks += 1;
        self.block_start += n as u64;
        if self.health_blocks == self.config.health_interval_blocks {
            sink(Output::Health(self.take_health()));
        }
    }

    /// Exponent of the block samples before the block shift: 0 for Q31, 1 for the Q30 of the
    /// half-band decimator.
    fn q_exponent(&self) -> i8 {
        i8::from(self.decimation == 2)
    }

    /// Q15 conversion, window, FFT and PHAT band of every microphone, then every pair's cross
    /// spectrum. Leaves the sum of the microphones' Q15 samples in `block[0]` (the mono signal
    /// of the spectral path).
    fn spatial_block(&mut self, shift: u32) {
        let n = self.fft_len;
        let nb = self.band_bins;
        let (fft_buf, units) = self.scratch.split_at_mut(MAX_BLOCK_LEN);
        let [mono, others @ ..] = &mut self.block;
        // Out of line, on opaque slices: compiled inline (or with the slices' addresses known),
        // the loops addressed the pipeline's fields from its static address and rebuilt the
        // addresses every sample (QEMU cost, fft stage).
        #[inline(never)]
        fn first(fft_buf: &mut [f32], mono: &mut [i32], window: &[f32], shift: u32) {
            let (fft_buf, mono, window) = core::hint::black_box((fft_buf, mono, window));
            for ((x, s), &w) in fft_buf.iter_mut().zip(mono).zip(window) {
                let q = frontend::to_q15(*s, shift);
                *x = f32::from(q) * w;
                *s = i32::from(q);
            }
        }
        #[inline(never)]
        fn other(fft_buf: &mut [f32], ch: &[i32], mono: &mut [i32], window: &[f32], shift: u32) {
            let (fft_buf, ch, mono, window) = core::hint::black_box((fft_buf, ch, mono, window));
            for (((x, &s), m), &w) in fft_buf.iter_mut().zip(ch).zip(mono).zip(window) {
                let q = frontend::to_q15(s, shift);
                *x = f32::from(q) * w;
                *m += i32::from(q);
            }
        }
        for mic in 0..self.mics {
            let window = &self.window[..n];
            if mic == 0 {
                first(&mut fft_buf[..n], &mut mono[..n], window, shift);
            } else {
                other(&mut fft_buf[..n], &others[mic - 1][..n], &mut mono[..n], window, shift);
            }
            let unit = &mut units[mic * 2 * MAX_BAND_BINS..][..2 * nb];
            if n == 1024 {
                if let Some(buf) = fft_buf.first_chunk_mut::<1024>() {
                    gcc_phat::phat_band(microfft::real::rfft_1024(buf), self.first_bin, unit);
                }
            } else if n == 512 {
                if let Some(buf) = fft_buf.first_chunk_mut::<512>() {
                    // The band only, each bin PHAT-weighted as it is formed.
                    let mut out = unit.chunks_exact_mut(2);
                    crate::fft::rfft_512_bins(buf, self.first_bin, nb, |x| {
                        if let Some(o) = out.next() {
                            gcc_phat::phat_unit(x, o);
                        }
                    });
                }
            } else if let Some(buf) = fft_buf.first_chunk_mut::<256>() {
                gcc_phat::phat_band(microfft::real::rfft_256(buf), self.first_bin, unit);
            }
        }
        // Pairs come as (0,1), (0,2), …: two neighbours sharing i are accumulated together.
        let unit = |mic: u8| &units[mic as usize * 2 * MAX_BAND_BINS..][..2 * nb];
        let mut p = 0;
        while p < self.pair_count {
            let pair = self.pairs[p];
            let (ui, uj) = (unit(pair.i), unit(pair.j));
            if p + 1 < self.pair_count && self.pairs[p + 1].i == pair.i {
                let uk = unit(self.pairs[p + 1].j);
                let (head, tail) = self.cross.split_at_mut(p + 1);
                gcc_phat::accumulate_cross_two(&mut head[p][..nb], &mut tail[0][..nb], ui, uj, uk);
                p += 2;
            } else {
                gcc_phat::accumulate_cross(&mut self.cross[p][..nb], ui, uj);
                p += 1;
            }
        }
    }

    fn estimate_direction(&mut self) -> Option<Doa> {
        let nb = self.band_bins;
        for ((pair, acc), d) in
            self.pairs[..self.pair_count].iter().zip(&mut self.cross).zip(&mut self.delays)
        {
            gcc_phat::weight_by_coherence(&mut acc[..nb], self.config.average_blocks);
            // The search runs at the spatial rate; the delay is reported in input samples.
            *d = gcc_phat::estimate_delay(
                &acc[..nb],
                self.first_bin,
                self.fft_len,
                (pair.max_lag as usize).div_ceil(self.decimation),
                self.config.average_blocks,
                &self.twiddles,
            );
            d.delay_samples *= self.decimation as f32;
            acc[..nb].fill(Complex32::new(0.0, 0.0));
        }
        let delays = &self.delays[..self.pair_count];
        let fit = doa::fit(&self.pairs[..self.pair_count], delays, self.samples_per_metre)?;
        // Mean pair quality, times the share of it the robust fit kept: low when the pairs do
        // not agree on one plane wave (reflections, obstruction).
        let quality = delays.iter().map(|d| d.quality()).sum::<f32>() / self.pair_count as f32
            * fit.kept_weight;
        Some(Doa {
            sample_index: self.average_start,
            span_samples: self.config.average_blocks * self.config.block_len as u32,
            azimuth_rad: fit.azimuth_rad,
            zenith_rad: fit.zenith_rad,
            residual: fit.residual_samples,
            quality,
            pairs_used: fit.pairs_used,
        })
    }

    /// Mono mean of the Q15 block (`block[0]` after [`Self::spatial_block`], as a fraction of
    /// full scale) into the decimator; BPF analysis
    /// when one is due.
    fn spectral_block(&mut self, shift: u32, sink: &mut impl FnMut(Output)) {
        let bits = shift + 15 - self.q_exponent() as u32;
        let scale = 1.0 / ((1u64 << bits) as f32 * self.mics as f32);
        let due = self.spectral.push_block(&self.block[0][..self.fft_len], scale);
        if self.config.snippets {
            self.emit_snippets(sink);
        }
        if due {
            if self.spectral.window_start_sample() < self.spectral_clean_from {
                // The window holds samples from before a gap.
                self.gap_stats.outputs_dropped = self.gap_stats.outputs_dropped.wrapping_add(1);
                return;
            }
            let mut peaks = self.spectral.analyze(&self.config, &mut self.scratch, &self.twiddles);
            peaks.sample_index += self.spectral_skipped;
            sink(Output::Peaks(peaks));
            if self.config.mfcc_interval > 0 {
                self.analyses_since_mfcc += 1;
                if self.analyses_since_mfcc >= self.config.mfcc_interval {
                    self.analyses_since_mfcc = 0;
                    // `analyze` left the magnitude spectrum and the whitened one in scratch.
                    let (mags, white) = self.scratch.split_at(ANALYSIS_LEN / 2);
                    let mut f = self.id.compute(mags, white, &self.config);
                    f.sample_index = peaks.sample_index;
                    f.span_samples = peaks.span_samples;
                    sink(Output::Mfcc(f));
                }
            }
        }
    }

    /// Every whole [`SNIPPET_LEN`] of decimated samples the spectral path has made since the
    /// last snippet, quantised ([`crate::snippet`]); one that holds samples from before a gap
    /// is dropped (and counted), so the stream stays contiguous between gaps.
    fn emit_snippets(&mut self, sink: &mut impl FnMut(Output)) {
        let factor = self.spectral.input_per_output() as u64;
        while self.spectral.produced() >= self.next_snippet + SNIPPET_LEN as u64 {
            let first = self.next_snippet;
            self.next_snippet += SNIPPET_LEN as u64;
            let Some(x) = self.spectral.recent(first, SNIPPET_LEN) else { continue };
            if first * factor < self.spectral_clean_from {
                self.gap_stats.outputs_dropped = self.gap_stats.outputs_dropped.wrapping_add(1);
                continue;
            }
            let mut s = Snippet {
                sample_index: first * factor + self.spectral_skipped,
                decimation: factor as u8,
                ..Snippet::default()
            };
            s.exponent = snippet::quantize(x, &mut s.samples);
            sink(Output::Snippet(s));
        }
    }

    /// Measures each microphone's level in the block just filled (once per Health interval:
    /// about 0.1 % of the samples, so its cost is negligible).
    fn probe_levels(&mut self) {
        let n = self.fft_len;
        for mic in 0..self.mics {
            // (x >> 8)² < 2^46, so 1024 of them fit a u64.
            let power = self.block[mic][..n]
                .iter()
                .map(|&x| (i64::from(x >> 8) * i64::from(x >> 8)) as u64);
            self.level_power[mic] = power.fold(0u64, u64::wrapping_add);
            self.level_dc[mic] = self.front.dc(mic);
        }
    }

    fn take_health(&mut self) -> Health {
        let full_scale = (1u64 << (31 - self.q_exponent())) as f32;
        let peak = self.health_peak as f32 / full_scale;
        let db = |ratio: f32| if ratio > 0.0 { 20.0 * libm::log10f(ratio) } else { -200.0 };
        let mut mic_rms_dbfs = [-200.0f32; MAX_MICS];
        let mut mic_dc_dbfs = [-200.0f32; MAX_MICS];
        for mic in 0..self.mics {
            let mean_square = self.level_power[mic] as f32 / self.fft_len as f32;
            mic_rms_dbfs[mic] = db(libm::sqrtf(mean_square) * 256.0 / full_scale);
            mic_dc_dbfs[mic] = db(self.level_dc[mic].unsigned_abs() as f32 / full_scale);
        }
        let h = Health {
            sample_index: self.health_start,
            blocks: self.blocks,
            clipped_samples: self.front.clipped,
            peak_dbfs: db(peak),
            block_exponent: self.last_exponent,
            mics: self.mics as u8,
            mic_rms_dbfs,
            mic_dc_dbfs,
        };
        self.front.clipped = 0;
        self.health_peak = 0;
        self.health_blocks = 0;
        self.health_start = self.block_start;
        h
    }
}

impl Default for Pipeline {
    fn default() -> Self {
        Self::empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Geometry;

    #[test]
    fn memory_budget() {
        let size = core::mem::size_of::<Pipeline>();
        assert!(size <= 128 * 1024, "Pipeline is {size} bytes");
    }

    #[test]
    fn beacon_on_mic_0_is_reported_on_the_input_clock() {
        // Oracle: the beacon waveform placed at a known real start on slot 0 (other slots a
        // quiet tone); pushed in odd chunks that split frames, with a gap before it.
        let config = Config::new(Geometry::respeaker_6mic(), 48_000);
        let mut p = Pipeline::new(&config).unwrap();
        let (start, frames, slots) = (20_000.37f64, 40_000usize, config.tdm_slots);
        let mut words = vec![0i32; frames * slots];
        for (n, frame) in words.chunks_exact_mut(slots).enumerate() {
            let b = 0.01 * beacon::waveform_at(n as f64 + 651.0 - start);
            frame[0] = ((b * 8_388_608.0).round() as i32) << 8;
            for (mic, w) in frame[1..6].iter_mut().enumerate() {
                let t = libm::sin(0.05 * (n + mic) as f64);
                *w = ((0.001 * t * 8_388_608.0) as i32) << 8;
            }
        }
        let mut found = Vec::new();
        let mut sink = |o: Output| {
            if let Output::Beacon(b) = o {
                found.push(b)
            }
        };
        p.push(&words[..1003], &mut sink);
        // Frame 125 was begun (its index is used); frame 126 is board sample 126 + 651.
        p.gap(651);
        for chunk in words[126 * slots..].chunks(997) {
            p.push(chunk, &mut sink);
        }
        assert_eq!(found.len(), 1, "{found:?}");
        let got = found[0].sample_index as f64 + f64::from(found[0].fraction);
        assert!((got - start).abs() < 0.02, "{got} vs {start}");
    }

    #[test]
    fn bad_config_is_refused_and_leaves_pipeline_inert() {
        let mut c = Config::new(Geometry::respeaker_6mic(), 44_100);
        assert_eq!(Pipeline::new(&c).err(), Some(ConfigError::SampleRate(44_100)));
        c.sample_rate_hz = 48_000;
        c.tdm_slots = 4;
        assert_eq!(Pipeline::new(&c).err(), Some(ConfigError::TdmSlots { slots: 4, mics: 6 }));
        c.tdm_slots = 8;
        c.band_high_hz = 12_000.0; // the spatial path's Nyquist frequency at 48 kHz
        assert_eq!(
            Pipeline::new(&c).err(),
            Some(ConfigError::Band { low_hz: c.band_low_hz, high_hz: 12_000.0 })
        );
        c.band_high_hz = 11_900.0;
        assert_eq!(Pipeline::new(&c).err(), Some(ConfigError::BandTooWide { bins: 249 }));
        let mut p = Pipeline::empty();
        let mut n = 0;
        p.push(&[1 << 20; 8 * 4096], &mut |_| n += 1);
        assert_eq!(n, 0);
    }
}
