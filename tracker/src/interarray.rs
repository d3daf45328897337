//! Inter-array delays T_pq from `Snippet` frames (`ALGORITHMS.md` §9 eq. 7, issue 14).
//!
//! Each board sends its mean signal at 8 kHz as a contiguous stream of 32 ms snippets, stamped
//! on its own sample clock ([`aim_wire::Snippet`]). [`SnippetStore`] keeps the recent ones per
//! array; [`SnippetStore::delay`] takes two arrays, their clock maps (board sample index →
//! common time, from the clock model solved on the beacons; any [`ClockMap`]), a time and a
//! prior window for the delay (from the current track), cuts one window of each array's stream
//! that overlap in true time, and returns T_pq = (arrival at p) − (arrival at q) on the common
//! clock by GCC-PHAT ([`gcc_phat_lag`]: PHAT cross spectra averaged over half-overlapping
//! Hann frames, band mask, peak inside the prior window, refined below one sample by Newton
//! steps on the band-limited correlation R(τ) = Σ_k Re(G_k e^{j2πkτ/M})).
//!
//! The drone's sound is a comb of BPF harmonics, so R(τ) repeats every 1/BPF (≈ 3 ms, ≈ 1 m of
//! range difference): the prior window must be narrower than one period (± 1/(2·BPF) about
//! the true delay) for the peak to be the right one. Measured precision and the usable width:
//! BENCHMARKS.md "Snippets for inter-array delays (issue 14)".

use std::collections::{BTreeMap, VecDeque};

use crate::site::Room;

/// Board sample index (input rate, f64 for fractions) → common time, s. Supplied by the clock
/// model (t = a_p + b_p · n); any `Fn(f64) -> f64` is one.
pub trait ClockMap {
    /// Common time of the board's sample `sample_index`, s.
    fn time_s(&self, sample_index: f64) -> f64;
}

impl<F: Fn(f64) -> f64> ClockMap for F {
    fn time_s(&self, sample_index: f64) -> f64 {
        self(sample_index)
    }
}

/// The board sample index at common time `t` (Newton steps on the map; exact for an affine
/// map after the first).
fn index_at(clock: &impl ClockMap, t: f64, near: f64) -> f64 {
    let mut n = near;
    for _ in 0..3 {
        let (t0, t1) = (clock.time_s(n), clock.time_s(n + 48_000.0));
        let slope = (t1 - t0) / 48_000.0;
        if !(slope.is_finite() && slope > 0.0) {
            return f64::NAN;
        }
        n += (t - t0) / slope;
    }
    n
}

/// How [`SnippetStore::delay`] correlates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DelayConfig {
    /// Correlation window, s of array q's stream. Default 0.5.
    pub window_s: f64,
    /// Frame of the averaged cross spectrum, snippet samples (power of two). Default 512
    /// (64 ms at 8 kHz): lags up to ± one frame, 15.6 Hz bins.
    pub frame_len: usize,
    /// Band mask, Hz: the drone's harmonics. Default 150–3000.
    pub band_hz: (f64, f64),
}

impl Default for DelayConfig {
    fn default() -> Self {
        Self { window_s: 0.5, frame_len: 512, band_hz: (150.0, 3000.0) }
    }
}

/// Where the delay is expected: T_pq within `centre_s ± half_width_s` (s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prior {
    /// Predicted T_pq, s (range difference / c from the track).
    pub centre_s: f64,
    /// Half width of the window, s; below half a harmonic period (≈ 1.5 ms) to keep one peak.
    pub half_width_s: f64,
}

/// An inter-array delay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterArrayDelay {
    /// T_pq = arrival at array p − arrival at array q, common clock, s.
    pub delay_s: f64,
    /// Common time of the centre of q's window, s.
    pub time_s: f64,
    /// Peak of the coherence-weighted averaged PHAT correlation, 0..1 ([`LagEstimate::quality`]).
    pub quality: f64,
    /// Peak over the next-highest local maximum inside the prior window (≥ 1; infinite when
    /// there is none): near 1 when two harmonic periods fit the window.
    pub margin: f64,
}

/// One array's recent snippets, oldest first.
#[derive(Debug, Default, Clone)]
struct Stream {
    /// (input-rate index of the first sample, decimation, values as fractions of full scale).
    frames: VecDeque<(u64, u32, Vec<f64>)>,
}

impl Stream {
    /// `n` consecutive snippet samples from the one taken at or just before input index
    /// `from`: (input index of the first, decimation, values); None if the stream does not
    /// hold them contiguously.
    fn window(&self, from: f64, n: usize) -> Option<(u64, u32, Vec<f64>)> {
        let i = self.frames.iter().rposition(|(s, _, _)| (*s as f64) <= from)?;
        let (start, dec, _) = &self.frames[i];
        let dec = *dec;
        let j = ((from - *start as f64) / f64::from(dec)).floor() as usize;
        let first = start + j as u64 * u64::from(dec);
        let mut out = Vec::with_capacity(n);
        let mut expected = *start;
        let mut skip = j;
        for (s, d, x) in self.frames.iter().skip(i) {
            if *s != expected || *d != dec {
                return None;
            }
            expected = s + (x.len() as u64) * u64::from(dec);
            let take = (x.len().saturating_sub(skip)).min(n - out.len());
            out.extend_from_slice(&x[skip.min(x.len())..skip.min(x.len()) + take]);
            skip = 0;
            if out.len() == n {
                return Some((first, dec, out));
            }
        }
        None
    }
}

/// The recent snippets of every array.
#[derive(Debug, Clone)]
pub struct SnippetStore {
    streams: BTreeMap<u8, Stream>,
    keep: usize,
}

impl SnippetStore {
    /// A store keeping the last `keep_frames` snippets per array (31.25 per second).
    pub fn new(keep_frames: usize) -> Self {
        Self { streams: BTreeMap::new(), keep: keep_frames.max(1) }
    }

    /// Adds a snippet of `array_id` whose header sample index is `sample_index`. A snippet
    /// stamped before the last one (a reboot) clears the array's stream.
    pub fn push(&mut self, array_id: u8, sample_index: u64, snippet: &aim_wire::Snippet) {
        let x = (0..snippet.samples.len()).map(|j| snippet.value(j)).collect();
        self.push_samples(array_id, sample_index, u32::from(snippet.decimation.max(1)), x);
    }

    /// Adds a piece of `array_id`'s stream already in numbers: sample `j` of `values` taken
    /// at input index `sample_index + j · decimation` (other formats than the wire's, for
    /// trade-off studies).
    pub fn push_samples(
        &mut self,
        array_id: u8,
        sample_index: u64,
        decimation: u32,
        values: Vec<f64>,
    ) {
        let s = self.streams.entry(array_id).or_default();
        if s.frames.back().is_some_and(|(last, _, _)| *last >= sample_index) {
            s.frames.clear();
        }
        s.frames.push_back((sample_index, decimation.max(1), values));
        while s.frames.len() > self.keep {
            s.frames.pop_front();
        }
    }

    /// T_pq around common time `time_s`: a window of q's stream centred there, one of p's
    /// shifted by the prior's centre (so the two overlap in true time), GCC-PHAT searched
    /// inside the prior window. None when either stream does not hold its window contiguously
    /// or the band holds no bins.
    #[allow(clippy::too_many_arguments)]
    pub fn delay(
        &self,
        p: u8,
        q: u8,
        clock_p: &impl ClockMap,
        clock_q: &impl ClockMap,
        time_s: f64,
        prior: Prior,
        config: &DelayConfig,
    ) -> Option<InterArrayDelay> {
        self.correlation(p, q, clock_p, clock_q, time_s, prior.centre_s, config)?
            .refine(prior.centre_s, prior.half_width_s)
    }

    /// The correlation of p's stream against q's around common time `time_s` as a function of
    /// the delay T_pq: a window of q's stream centred at `time_s`, one of p's shifted by
    /// `centre_s` (the expected T_pq, so that the two overlap in true time). None when either
    /// stream does not hold its window contiguously or the band holds no bins.
    #[allow(clippy::too_many_arguments)]
    pub fn correlation(
        &self,
        p: u8,
        q: u8,
        clock_p: &impl ClockMap,
        clock_q: &impl ClockMap,
        time_s: f64,
        centre_s: f64,
        config: &DelayConfig,
    ) -> Option<PairCorrelation> {
        let (sp, sq) = (self.streams.get(&p)?, self.streams.get(&q)?);
        let near_q = sq.frames.back()?.0 as f64;
        let near_p = sp.frames.back()?.0 as f64;
        let dec_q = f64::from(sq.frames.back()?.1);
        // Snippet-rate samples in the window (rate from q's clock at the window).
        let n_mid_q = index_at(clock_q, time_s, near_q);
        let step_q = clock_q.time_s(n_mid_q + dec_q) - clock_q.time_s(n_mid_q);
        let n = (config.window_s / step_q).round() as usize;
        if n < config.frame_len || !n_mid_q.is_finite() || !centre_s.is_finite() {
            return None;
        }
        let t0 = time_s - 0.5 * n as f64 * step_q;
        let (iq, _, xq) = sq.window(index_at(clock_q, t0, n_mid_q), n)?;
        let (ip, dp, xp) = sp.window(index_at(clock_p, t0 + centre_s, near_p), n)?;
        let (tq0, tp0) = (clock_q.time_s(iq as f64), clock_p.time_s(ip as f64));
        let step_p = clock_p.time_s((ip + u64::from(dp)) as f64) - tp0;
        let spectrum = cross_spectrum(&xp, &xq, 1.0 / step_p, config.frame_len, config.band_hz)?;
        // p's sample n + lag meets q's sample n where tp0 + (n + lag)·step_p − T = tq0 + n·step_q:
        // the lag drifts by n·(step_q − step_p)/step_p along the window; the delay is the
        // one at its centre, n = N/2.
        let half = 0.5 * n as f64;
        Some(PairCorrelation {
            spectrum,
            offset_s: tp0 - tq0 + half * (step_p - step_q),
            step_s: step_p,
            time_s: tq0 + half * step_q,
            table: Vec::new(),
            oversample: 0,
        })
    }
}

/// The correlation of two arrays' streams over one window ([`SnippetStore::correlation`]),
/// as a function of the delay T_pq on the common clock.
#[derive(Debug, Clone, PartialEq)]
pub struct PairCorrelation {
    spectrum: CrossSpectrum,
    /// T_pq at lag 0, s.
    offset_s: f64,
    /// One lag sample, s.
    step_s: f64,
    /// Common time of the centre of q's window, s.
    pub time_s: f64,
    /// R tabulated by [`PairCorrelation::tabulate`] (empty before).
    table: Vec<f64>,
    /// Table entries per lag sample.
    oversample: usize,
}

impl PairCorrelation {
    /// The lag (samples of p's stream) of delay `delay_s` (s).
    fn lag(&self, delay_s: f64) -> f64 {
        (delay_s - self.offset_s) / self.step_s
    }

    /// Tabulates R at 1/`oversample` of a lag sample (a power of two) for
    /// [`PairCorrelation::value`].
    pub fn tabulate(&mut self, oversample: usize) {
        self.table = self.spectrum.table(oversample);
        self.oversample = self.table.len() / self.spectrum.m;
    }

    /// R at delay `delay_s` (s), ≤ 1: from the table (linear between its points) once
    /// tabulated, else evaluated exactly. Delays beyond ± half the transform wrap around.
    pub fn value(&self, delay_s: f64) -> f64 {
        let lag = self.lag(delay_s);
        if self.table.is_empty() {
            return self.spectrum.r(lag).0;
        }
        let len = self.table.len();
        let x = (lag * self.oversample as f64).rem_euclid(len as f64);
        let i = (x.floor() as usize).min(len - 1);
        let f = x - i as f64;
        self.table[i] * (1.0 - f) + self.table[(i + 1) % len] * f
    }

    /// The highest point of R within `centre_s ± half_width_s` (s) as an inter-array delay.
    pub fn refine(&self, centre_s: f64, half_width_s: f64) -> Option<InterArrayDelay> {
        let range = (self.lag(centre_s - half_width_s), self.lag(centre_s + half_width_s));
        let est = self.spectrum.peak(range)?;
        Some(InterArrayDelay {
            delay_s: self.offset_s + est.lag * self.step_s,
            time_s: self.time_s,
            quality: est.quality,
            margin: est.margin,
        })
    }
}

/// Half width of the horizontal search of [`joint_search`], m.
pub const DELAYS_SEARCH_HALF_M: f64 = 2.0;
/// Horizontal step of that search, m (under the half width of a correlation lobe, ≈ 5 cm of
/// range difference at 3 kHz).
pub const DELAYS_SEARCH_STEP_M: f64 = 0.05;
/// Heights searched around the track's, m: ± this in [`DELAYS_SEARCH_STEP_Z_M`] steps.
pub const DELAYS_SEARCH_HALF_Z_M: f64 = 1.0;
/// Vertical step of the search, m.
pub const DELAYS_SEARCH_STEP_Z_M: f64 = 0.25;
/// Distance from the track at which the search's prior costs as much as one pair's peak, m.
pub const DELAYS_SEARCH_PRIOR_M: f64 = 1.5;
/// Half width of the refinement of each pair's delay about the joint point, s (a third of a
/// 330 Hz period).
pub const DELAYS_REFINE_S: f64 = 0.3e-3;
/// Correlation table points per snippet sample ([`PairCorrelation::tabulate`]) (16 µs at 8 kHz ≈ 5 mm).
pub const DELAYS_OVERSAMPLE: usize = 8;

/// The point within ± [`DELAYS_SEARCH_HALF_M`] (horizontally) and
/// ± [`DELAYS_SEARCH_HALF_Z_M`] (vertically) of `near` whose range differences best fit every
/// pair's correlation at once (`pairs`: array p's centre and its correlation against the array
/// at `q`; `c` the speed of sound, m/s): the sum of the correlations at the point's delays,
/// less a quadratic prior on the distance from `near` (one pair's full peak at
/// [`DELAYS_SEARCH_PRIOR_M`]). Within `room` only, when the site gives one: a wall's image of
/// the drone is a coherent second source whose range differences fit the pairs nearly as
/// well as the drone's, and it lies behind the wall.
pub fn joint_search(
    near: [f64; 3],
    pairs: &[([f64; 3], PairCorrelation)],
    q: [f64; 3],
    c: f64,
    room: Option<&Room>,
) -> [f64; 3] {
    let inside =
        |x: [f64; 3]| room.is_none_or(|r| (0..3).all(|i| (r.min[i]..=r.max[i]).contains(&x[i])));
    let n = (DELAYS_SEARCH_HALF_M / DELAYS_SEARCH_STEP_M).round() as i32;
    let nz = (DELAYS_SEARCH_HALF_Z_M / DELAYS_SEARCH_STEP_Z_M).round() as i32;
    let dist = |a: [f64; 3], b: [f64; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt();
    let mut best = (f64::NEG_INFINITY, near);
    for k in -nz..=nz {
        for i in -n..=n {
            for j in -n..=n {
                let x = [
                    near[0] + f64::from(i) * DELAYS_SEARCH_STEP_M,
                    near[1] + f64::from(j) * DELAYS_SEARCH_STEP_M,
                    near[2] + f64::from(k) * DELAYS_SEARCH_STEP_Z_M,
                ];
                if !inside(x) {
                    continue;
                }
                let prior = (dist(x, near) / DELAYS_SEARCH_PRIOR_M).powi(2);
                let dq = dist(x, q);
                let score =
                    pairs.iter().map(|(p, r)| r.value((dist(x, *p) - dq) / c)).sum::<f64>() - prior;
                if score > best.0 {
                    best = (score, x);
                }
            }
        }
    }
    best.1
}

/// The result of [`gcc_phat_lag`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LagEstimate {
    /// Lag of `xp` behind `xq`, samples: `xp[n + lag] ≈ xq[n]`.
    pub lag: f64,
    /// Peak of R over Σ_k |G_k|² (G the averaged unit cross spectrum, weighted by its
    /// coherence), 0..1: 1 when every coherent bin agrees on the lag.
    pub quality: f64,
    /// Peak over the next local maximum in the searched range (infinite if none).
    pub margin: f64,
}

/// GCC-PHAT lag of `xp` behind `xq` (equal lengths, sampled at `fs` Hz), searched in
/// `range` (samples, inclusive): PHAT cross spectra of half-overlapping Hann frames of
/// `frame_len` (zero-padded to twice that) averaged, bins outside `band_hz` dropped, each bin
/// weighted by its coherence (the averaged unit spectrum's magnitude); the correlation
/// evaluated on a quarter-sample grid, its highest point refined by Newton steps. With
/// different sample spacings (clock drift) the lag drifts along the window: the estimate is
/// the lag at its centre.
///
/// ```
/// use aim_tracker::interarray::gcc_phat_lag;
/// // Eight harmonics of 330 Hz, the second stream 2.3 samples later.
/// let s = |t: f64| (1..=8).map(|h| (2.0 * std::f64::consts::PI * 330.0 * h as f64 * t + h as f64).sin()).sum::<f64>();
/// let xq: Vec<f64> = (0..4000).map(|n| s(n as f64 / 8000.0)).collect();
/// let xp: Vec<f64> = (0..4000).map(|n| s((n as f64 - 2.3) / 8000.0)).collect();
/// let e = gcc_phat_lag(&xp, &xq, 8000.0, 512, (150.0, 3000.0), (-5.0, 5.0)).unwrap();
/// assert!((e.lag - 2.3).abs() < 0.05, "{}", e.lag);
/// ```
pub fn gcc_phat_lag(
    xp: &[f64],
    xq: &[f64],
    fs: f64,
    frame_len: usize,
    band_hz: (f64, f64),
    range: (f64, f64),
) -> Option<LagEstimate> {
    cross_spectrum(xp, xq, fs, frame_len, band_hz)?.peak(range)
}

/// The averaged PHAT cross spectrum of `xp` against `xq` (equal lengths, sampled at `fs` Hz)
/// that [`gcc_phat_lag`] searches: half-overlapping Hann frames of `frame_len` (a power of
/// two, zero-padded to twice that), bins outside `band_hz` dropped, each bin weighted by its
/// coherence. None if the streams are shorter than a frame or the band holds no bin.
pub fn cross_spectrum(
    xp: &[f64],
    xq: &[f64],
    fs: f64,
    frame_len: usize,
    band_hz: (f64, f64),
) -> Option<CrossSpectrum> {
    let l = frame_len;
    let m = 2 * l;
    let n = xp.len().min(xq.len());
    if !l.is_power_of_two() || n < l {
        return None;
    }
    let k_lo = ((band_hz.0 / fs * m as f64).ceil() as usize).max(1);
    let k_hi = ((band_hz.1 / fs * m as f64).floor() as usize).min(m / 2 - 1);
    if k_hi < k_lo {
        return None;
    }
    let hann: Vec<f64> = (0..l)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / l as f64).cos())
        .collect();
    let mut g = vec![(0.0f64, 0.0f64); k_hi + 1];
    let mut frames = 0usize;
    let (mut bp, mut bq) = (vec![(0.0, 0.0); m], vec![(0.0, 0.0); m]);
    let mut start = 0;
    while start + l <= n {
        for i in 0..m {
            let w = if i < l { hann[i] } else { 0.0 };
            bp[i] = (if i < l { xp[start + i] * w } else { 0.0 }, 0.0);
            bq[i] = (if i < l { xq[start + i] * w } else { 0.0 }, 0.0);
        }
        fft(&mut bp);
        fft(&mut bq);
        for k in k_lo..=k_hi {
            let (a, b) = (bp[k], bq[k]);
            // a · conj(b), normalised.
            let (re, im) = (a.0 * b.0 + a.1 * b.1, a.1 * b.0 - a.0 * b.1);
            let mag = re.hypot(im);
            if mag > 0.0 {
                g[k].0 += re / mag;
                g[k].1 += im / mag;
            }
        }
        frames += 1;
        start += l / 2;
    }
    // Coherence weighting: the averaged unit spectrum's magnitude (near 1 on the harmonics,
    // ~1/√frames on bins of incoherent noise) weights each bin once more, as the chip does
    // (`gcc_phat::weight_by_coherence`); R is then normalised by Σ |G_k|², so R ≤ 1.
    let mut total = 0.0;
    for v in &mut g[k_lo..] {
        let mag = v.0.hypot(v.1) / frames as f64;
        *v = (v.0 * mag, v.1 * mag);
        total += mag * mag * frames as f64;
    }
    if total <= 0.0 {
        return None;
    }
    Some(CrossSpectrum { g, k_lo, m, scale: 1.0 / total })
}

/// The averaged, coherence-weighted PHAT cross spectrum of two streams
/// ([`cross_spectrum`]): the correlation R(τ) at any lag τ (samples of the first stream),
/// normalised so that R ≤ 1.
#[derive(Debug, Clone, PartialEq)]
pub struct CrossSpectrum {
    /// Weighted spectrum per bin (bins below `k_lo` are zero).
    g: Vec<(f64, f64)>,
    /// First bin of the band.
    k_lo: usize,
    /// Transform length (twice the frame), samples.
    m: usize,
    /// 1 / Σ |G_k|².
    scale: f64,
}

impl CrossSpectrum {
    /// R(τ), R'(τ), R''(τ) at lag `tau` (samples): R ≤ 1.
    pub fn r(&self, tau: f64) -> (f64, f64, f64) {
        let w0 = 2.0 * std::f64::consts::PI / self.m as f64;
        let (mut r0, mut r1, mut r2) = (0.0, 0.0, 0.0);
        for (k, &(gr, gi)) in self.g.iter().enumerate().skip(self.k_lo) {
            let w = w0 * k as f64;
            let (s, c) = (w * tau).sin_cos();
            let re = gr * c - gi * s;
            let im = gr * s + gi * c;
            r0 += re;
            r1 -= w * im;
            r2 -= w * w * re;
        }
        (r0 * self.scale, r1 * self.scale, r2 * self.scale)
    }

    /// R on a grid of 1/`oversample` samples over one period of the transform (`m` samples):
    /// entry `i` is R(i / oversample), lags past m/2 standing for negative ones (circular).
    /// One zero-padded inverse transform; `oversample` a power of two.
    pub fn table(&self, oversample: usize) -> Vec<f64> {
        let len = self.m * oversample.max(1).next_power_of_two();
        let mut x = vec![(0.0, 0.0); len];
        for (k, &(gr, gi)) in self.g.iter().enumerate().skip(self.k_lo) {
            // Inverse transform as the forward one of the conjugate (real part unchanged).
            x[k] = (gr, -gi);
        }
        fft(&mut x);
        x.iter().map(|v| v.0 * self.scale).collect()
    }

    /// The highest point of R inside `range` (samples, inclusive): a quarter-sample grid,
    /// then Newton steps; with the margin over the next local maximum.
    pub fn peak(&self, range: (f64, f64)) -> Option<LagEstimate> {
        if range.0.is_nan() || range.1.is_nan() || range.0 > range.1 {
            return None;
        }
        let steps = (((range.1 - range.0) * 4.0).ceil() as usize).max(1);
        let grid: Vec<(f64, f64)> = (0..=steps)
            .map(|i| {
                let tau = range.0 + (range.1 - range.0) * i as f64 / steps as f64;
                (tau, self.r(tau).0)
            })
            .collect();
        let (best, _) = grid.iter().enumerate().max_by(|a, b| a.1 .1.total_cmp(&b.1 .1))?;
        let mut tau = grid[best].0;
        for _ in 0..6 {
            let (_, d1, d2) = self.r(tau);
            if d2 >= 0.0 {
                break;
            }
            let next = (tau - d1 / d2).clamp(tau - 0.5, tau + 0.5);
            tau = next.clamp(range.0, range.1);
        }
        let peak = self.r(tau).0;
        // The next local maximum of the grid, away from the peak's own lobe (> 1 sample off).
        let second = (1..grid.len().saturating_sub(1))
            .filter(|&i| grid[i].1 >= grid[i - 1].1 && grid[i].1 >= grid[i + 1].1)
            .filter(|&i| (grid[i].0 - tau).abs() > 1.0)
            .map(|i| grid[i].1)
            .fold(f64::NEG_INFINITY, f64::max);
        let margin = if second > 0.0 { peak / second } else { f64::INFINITY };
        Some(LagEstimate { lag: tau, quality: peak.clamp(0.0, 1.0), margin })
    }
}

/// In-place radix-2 complex FFT (forward, e^{−j2πkn/N}); `x.len()` a power of two.
pub fn fft(x: &mut [(f64, f64)]) {
    let n = x.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            x.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = -2.0 * std::f64::consts::PI / len as f64;
        for start in (0..n).step_by(len) {
            for k in 0..len / 2 {
                let (s, c) = (ang * k as f64).sin_cos();
                let (a, b) = (x[start + k], x[start + k + len / 2]);
                let t = (b.0 * c - b.1 * s, b.0 * s + b.1 * c);
                x[start + k] = (a.0 + t.0, a.1 + t.1);
                x[start + k + len / 2] = (a.0 - t.0, a.1 - t.1);
            }
        }
        len <<= 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn fft_matches_a_naive_dft() {
        let x: Vec<(f64, f64)> =
            (0..64).map(|n| (((n * 37) % 11) as f64 - 5.0, ((n * 13) % 7) as f64)).collect();
        let mut y = x.clone();
        fft(&mut y);
        for (k, &(yr, yi)) in y.iter().enumerate() {
            let (mut re, mut im) = (0.0, 0.0);
            for (i, &(a, b)) in x.iter().enumerate() {
                let w = -2.0 * PI * (k * i) as f64 / 64.0;
                re += a * w.cos() - b * w.sin();
                im += a * w.sin() + b * w.cos();
            }
            assert!((re - yr).abs() < 1e-9 && (im - yi).abs() < 1e-9, "bin {k}");
        }
    }

    /// xorshift: deterministic noise.
    struct Rng(u64);
    impl Rng {
        fn gauss(&mut self) -> f64 {
            let mut u = || {
                self.0 ^= self.0 << 13;
                self.0 ^= self.0 >> 7;
                self.0 ^= self.0 << 17;
                (self.0 >> 11) as f64 / (1u64 << 53) as f64
            };
            let (a, b) = (u().max(1e-300), u());
            (-2.0 * a.ln()).sqrt() * (2.0 * PI * b).cos()
        }
    }

    /// A drone-like source heard at true time t: 10 harmonics of 330 Hz with fixed phases.
    fn source(t: f64) -> f64 {
        (1..=10)
            .map(|h| (2.0 * PI * 330.0 * h as f64 * t + 0.7 * (h * h) as f64).sin() / h as f64)
            .sum()
    }

    /// Array clock: common time of input sample n = offset + n / (48 kHz · (1 + ppm·1e-6)).
    fn clock(offset: f64, ppm: f64) -> impl Fn(f64) -> f64 {
        move |n: f64| offset + n / (48_000.0 * (1.0 + ppm * 1e-6))
    }

    /// Snippets (through the chip's quantiser and the wire type) of the source heard with
    /// `lag_s` on an array with `clock`, sample j of a snippet taken at input index
    /// `start + 6 j`, plus white noise at `noise` rms.
    fn stream(
        store: &mut SnippetStore,
        id: u8,
        clock: &impl Fn(f64) -> f64,
        lag_s: f64,
        noise: f64,
        seed: u64,
        skip: Option<u64>,
    ) {
        let mut rng = Rng(seed | 1);
        for f in (0..120u64).filter(|&f| Some(f) != skip) {
            let start = 3_000 + f * 1536;
            let x: Vec<f32> = (0..256)
                .map(|j| {
                    let t = clock((start + 6 * j) as f64);
                    (0.01 * (source(t - lag_s) + noise * rng.gauss())) as f32
                })
                .collect();
            let mut q = [0i8; 256];
            let exponent = aim_dsp::snippet::quantize(&x, &mut q);
            let s = aim_wire::Snippet {
                decimation: 6,
                exponent,
                samples: heapless::Vec::from_slice(&q).unwrap(),
            };
            store.push(id, start, &s);
        }
    }

    #[test]
    fn the_delay_between_two_clocks_is_found_to_microseconds() {
        // Array p 7.3 m farther than q minus 4 m: T_pq = (7.3 − 4.0)/343 = 9.62 ms; clocks
        // 0.35 s apart with ±25 ppm. The oracle is the generating delay.
        let (cp, cq) = (clock(0.35, 25.0), clock(-0.02, -20.0));
        let (tp, tq) = (7.3 / 343.0, 4.0 / 343.0);
        let mut store = SnippetStore::new(200);
        stream(&mut store, 2, &cp, tp, 0.1, 7, None);
        stream(&mut store, 5, &cq, tq, 0.1, 11, None);
        let truth = tp - tq;
        let config = DelayConfig::default();
        for (prior_off, half) in [(0.0, 1.2e-3), (1.0e-3, 1.4e-3), (-1.2e-3, 1.4e-3)] {
            let prior = Prior { centre_s: truth + prior_off, half_width_s: half };
            let d = store.delay(2, 5, &cp, &cq, 2.0, prior, &config).unwrap();
            assert!(
                (d.delay_s - truth).abs() < 5e-6,
                "{prior_off}: {:.2} µs",
                (d.delay_s - truth) * 1e6
            );
            assert!(d.quality > 0.5, "{d:?}");
            assert!((d.time_s - 2.0).abs() < 1e-3);
        }
        // The comb repeats every 1/330 s: a prior centred a period off finds the wrong peak,
        // which is why the window must stay within half a period.
        let wrong = Prior { centre_s: truth + 1.0 / 330.0, half_width_s: 1.0e-3 };
        let d = store.delay(2, 5, &cp, &cq, 2.0, wrong, &config).unwrap();
        assert!((d.delay_s - truth - 1.0 / 330.0).abs() < 2e-5, "{d:?}");
        // And the other way round: T_qp = −T_pq.
        let prior = Prior { centre_s: -truth, half_width_s: 1.2e-3 };
        let d = store.delay(5, 2, &cq, &cp, 2.0, prior, &config).unwrap();
        assert!((d.delay_s + truth).abs() < 5e-6, "{d:?}");
    }

    #[test]
    fn a_hole_in_a_stream_gives_no_delay() {
        let (cp, cq) = (clock(0.0, 0.0), clock(0.0, 0.0));
        let mut store = SnippetStore::new(200);
        stream(&mut store, 1, &cp, 0.0, 0.1, 3, None);
        // Array 2: the same, but frame 40 (1.28–1.31 s) lost.
        stream(&mut store, 2, &cq, 0.0, 0.1, 5, Some(40));
        let prior = Prior { centre_s: 0.0, half_width_s: 1e-3 };
        let config = DelayConfig::default();
        assert!(store.delay(1, 2, &cp, &cq, 1.3, prior, &config).is_none());
        assert!(store.delay(1, 2, &cp, &cq, 3.0, prior, &config).is_some());
    }

    #[test]
    fn the_table_matches_the_exact_correlation() {
        let (cp, cq) = (clock(0.0, 0.0), clock(0.0, 0.0));
        let mut store = SnippetStore::new(200);
        stream(&mut store, 1, &cp, 3.0 / 343.0, 0.3, 3, None);
        stream(&mut store, 2, &cq, 1.0 / 343.0, 0.3, 5, None);
        let mut corr =
            store.correlation(1, 2, &cp, &cq, 2.0, 2.0 / 343.0, &DelayConfig::default()).unwrap();
        let exact: Vec<f64> = (-400..400).map(|i| corr.value(f64::from(i) * 1e-5)).collect();
        corr.tabulate(DELAYS_OVERSAMPLE);
        for (i, e) in (-400..400).zip(exact) {
            // Linear between points 1/64 ms apart: within 1 % of the peak.
            let v = corr.value(f64::from(i) * 1e-5);
            assert!((v - e).abs() < 0.01, "{i}: {v} against {e}");
        }
    }

    #[test]
    fn the_joint_search_picks_the_peak_every_pair_agrees_on() {
        // A drone-like comb (330 Hz: its correlation repeats every 1.04 m of range difference)
        // heard by four arrays; the track is 0.8 m off. Oracle: the generating geometry.
        let c = 343.0;
        let drone = [4.0, 3.0, 2.0];
        let q = [0.0, 0.0, 0.0];
        let ps = [[10.0, 0.0, 0.0], [0.0, 10.0, 0.5], [10.0, 10.0, 0.0]];
        let dist =
            |a: [f64; 3], b: [f64; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt();
        let clocks = [clock(0.1, 20.0), clock(-0.3, -50.0), clock(0.02, 90.0), clock(0.0, 0.0)];
        let mut store = SnippetStore::new(200);
        for (i, p) in ps.iter().chain([&q]).enumerate() {
            stream(&mut store, i as u8, &clocks[i], dist(drone, *p) / c, 0.3, 17 + i as u64, None);
        }
        let near = [drone[0] + 0.7, drone[1] - 0.4, drone[2] + 0.2];
        let config = DelayConfig { window_s: 0.25, ..DelayConfig::default() };
        let pairs: Vec<([f64; 3], PairCorrelation)> = ps
            .iter()
            .enumerate()
            .map(|(i, &p)| {
                let predicted = (dist(near, p) - dist(near, q)) / c;
                let mut corr = store
                    .correlation(i as u8, 3, &clocks[i], &clocks[3], 2.0, predicted, &config)
                    .unwrap();
                corr.tabulate(DELAYS_OVERSAMPLE);
                (p, corr)
            })
            .collect();
        let truth = |p: [f64; 3]| (dist(drone, p) - dist(drone, q)) / c;
        // Alone, each pair searched half a period about the track's prediction: at least one
        // takes a neighbouring peak.
        let wrong = pairs
            .iter()
            .filter(|(p, corr)| {
                let predicted = (dist(near, *p) - dist(near, q)) / c;
                let d = corr.refine(predicted, 1.2e-3).unwrap();
                (d.delay_s - truth(*p)).abs() * c > 0.5
            })
            .count();
        assert!(wrong >= 1, "the track's error should fool a pair on its own");
        // Together they find the drone's peak in every pair.
        let at = joint_search(near, &pairs, q, c, None);
        for (p, corr) in &pairs {
            let predicted = (dist(at, *p) - dist(at, q)) / c;
            let d = corr.refine(predicted, DELAYS_REFINE_S).unwrap();
            let error_m = (d.delay_s - truth(*p)) * c;
            assert!(error_m.abs() < 0.02, "{p:?}: {error_m:.3} m");
        }
    }
}
