//! Pipeline configuration: geometry, rates, and the tunables with their defaults.

use crate::{ConfigError, Geometry, MAX_BAND_BINS, MAX_HARMONICS, MAX_LAG};

/// Everything the [`crate::Pipeline`] needs to know. Build with [`Config::new`], then adjust
/// tunables; [`crate::Pipeline::configure`] validates the whole.
///
/// ```
/// let mut c = aim_dsp::Config::new(aim_dsp::Geometry::respeaker_6mic(), 48_000);
/// c.average_blocks = 8; // fewer, steadier DoA outputs
/// assert_eq!(c.block_len, 1024);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Config {
    /// Microphone positions; mic i is TDM slot i.
    pub geometry: Geometry,
    /// Sample rate, Hz: 16 000 or 48 000.
    pub sample_rate_hz: u32,
    /// Words per TDM frame (slots); slots past the microphone count are ignored. Default 8.
    pub tdm_slots: usize,
    /// Samples per block and FFT length of the spatial path: 512 or 1024.
    /// Default 1024 at 48 kHz (21.3 ms), 512 at 16 kHz (32 ms).
    pub block_len: usize,
    /// Lower edge of the GCC-PHAT band mask, Hz. Default 200.
    pub band_low_hz: f32,
    /// Upper edge of the GCC-PHAT band mask, Hz. Default 6000.
    pub band_high_hz: f32,
    /// Blocks whose PHAT cross spectra are averaged into one DoA estimate: one `Doa` per
    /// `average_blocks · block_len` samples. Default 8 at 48 kHz (171 ms, 5.9 per second),
    /// 5 at 16 kHz (160 ms, 6.25 per second).
    pub average_blocks: u32,
    /// Speed of sound, m/s. Default 343 (20 °C).
    pub speed_of_sound_m_s: f32,
    /// Lowest blade-passing frequency searched, Hz. Default 140 (indoor drones: 150–700 Hz;
    /// desk and ceiling fans, whose steady five-blade combs are rotors too, 50–120 Hz; lower
    /// it for large propellers).
    pub bpf_min_hz: f32,
    /// Highest blade-passing frequency searched, Hz. Default 1000.
    pub bpf_max_hz: f32,
    /// Harmonics (including the fundamental) used per BPF peak group. Default 8.
    pub harmonics: usize,
    /// A BPF candidate line must stand this many times above the local noise floor (the
    /// whitened spectrum, [`crate::comb`]). Default 4 (was 5; chosen with
    /// [`crate::comb::MIN_AGE`] 4, BENCHMARKS.md issue 19, session 43).
    pub peak_floor_ratio: f32,
    /// A further peak group must reach this fraction of the strongest group's harmonic
    /// score. Default 0.1.
    pub peak_relative_score: f32,
    /// Lowest detection quality of a reported rotor group, 0–1 ([`crate::Peak::quality`]).
    /// Default 0.2 (was 0.3, chosen in session 9 with [`crate::comb::LINE_RATIO`] 2.5; 0.2 with
    /// [`crate::comb::MIN_AGE`] 4 on the BPF bench's tuning seeds 1–16, BENCHMARKS.md issue 19,
    /// session 43: with the four-analysis start, non-drone frames with a BPF 0.53 % there, 0.80 %
    /// on fresh seeds 1101–1108, 1.18 % on 301–304).
    pub bpf_min_quality: f32,
    /// Fastest relative change of a rotor's BPF between analyses that still continues a group,
    /// per second. Default 0.1 (10 %/s: 2.6 % per 0.256 s hop, under a semitone's 6 %: a
    /// melody's steps do not continue a group).
    pub bpf_max_rate_per_s: f32,
    /// Blocks between two `Health` outputs. Default 48 (about 1 s at 48 kHz / 1024).
    pub health_interval_blocks: u32,
    /// BPF analyses (one per 0.256 s) between two `Mfcc` outputs ([`crate::idframe`]); 0: no
    /// `Mfcc` outputs. Default 1 (3.9 per second).
    pub mfcc_interval: u32,
    /// Send the array's mean signal as a contiguous stream of [`crate::snippet::Snippet`]s
    /// (8 kHz, 32 ms each, 31.25 per second; about 9 % of a 921 600 Bd link) for inter-array
    /// delays. Default true: there is no downlink to ask for them, and a board in a
    /// multi-array site must send them from the start; a single-array site may turn them off.
    pub snippets: bool,
}

impl Config {
    /// Defaults for `geometry` at `sample_rate_hz` (see each field); `tdm_slots` = 8.
    pub fn new(geometry: Geometry, sample_rate_hz: u32) -> Self {
        Self {
            geometry,
            sample_rate_hz,
            block_len: if sample_rate_hz <= 16_000 { 512 } else { 1024 },
            average_blocks: if sample_rate_hz <= 16_000 { 5 } else { 8 },
            ..Self::empty()
        }
    }

    /// A placeholder for `const` construction; refused by validation.
    pub(crate) const fn empty() -> Self {
        Self {
            geometry: Geometry::empty(),
            sample_rate_hz: 0,
            tdm_slots: 8,
            block_len: 1024,
            band_low_hz: 200.0,
            band_high_hz: 6000.0,
            average_blocks: 8,
            speed_of_sound_m_s: 343.0,
            bpf_min_hz: 140.0,
            bpf_max_hz: 1000.0,
            harmonics: 8,
            peak_floor_ratio: 4.0,
            peak_relative_score: 0.1,
            bpf_min_quality: 0.2,
            bpf_max_rate_per_s: 0.1,
            health_interval_blocks: 48,
            mfcc_interval: 1,
            snippets: true,
        }
    }

    /// FFT bin spacing of the spatial path, Hz.
    pub fn bin_hz(&self) -> f32 {
        self.sample_rate_hz as f32 / self.block_len as f32
    }

    /// Sample rate of the spatial path (GCC-PHAT), Hz: the front end halves 48 kHz
    /// ([`crate::frontend::FrontEnd`]'s half-band), 16 kHz is kept.
    pub fn spatial_rate_hz(&self) -> u32 {
        self.sample_rate_hz / crate::frontend::spatial_decimation(self.sample_rate_hz) as u32
    }

    /// First and one-past-last FFT bin of the GCC-PHAT band.
    pub(crate) fn band_bins(&self) -> (usize, usize) {
        let lo = libm::ceilf(self.band_low_hz / self.bin_hz()) as usize;
        let hi = libm::floorf(self.band_high_hz / self.bin_hz()) as usize + 1;
        (lo.max(1), hi)
    }

    /// Checks every field; the pipeline runs only validated configurations.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let g = Geometry::from_positions(self.geometry.positions())?;
        if self.sample_rate_hz != 16_000 && self.sample_rate_hz != 48_000 {
            return Err(ConfigError::SampleRate(self.sample_rate_hz));
        }
        if self.block_len != 512 && self.block_len != 1024 {
            return Err(ConfigError::BlockLen(self.block_len));
        }
        if self.tdm_slots < g.len() || self.tdm_slots > 16 {
            return Err(ConfigError::TdmSlots { slots: self.tdm_slots, mics: g.len() });
        }
        if !(300.0..=400.0).contains(&self.speed_of_sound_m_s) {
            return Err(ConfigError::SpeedOfSound(self.speed_of_sound_m_s));
        }
        let max_lag = g.aperture_m() / self.speed_of_sound_m_s * self.sample_rate_hz as f32 + 1.0;
        if max_lag > MAX_LAG as f32 {
            return Err(ConfigError::ApertureTooLarge { aperture_m: g.aperture_m() });
        }
        // The spatial path runs at the front end's output rate (48 kHz is halved): its band
        // must end below that rate's Nyquist frequency, so that every band bin is one of the
        // real FFT's bins 1 … N/2 − 1 (bin N/2, packed with DC, is not a band bin).
        let nyquist = self.spatial_rate_hz() as f32 / 2.0;
        let band_ok = self.band_low_hz.is_finite()
            && self.band_high_hz.is_finite()
            && self.band_low_hz > 0.0
            && self.band_high_hz < nyquist
            && self.band_high_hz - self.band_low_hz >= 4.0 * self.bin_hz();
        if !band_ok {
            return Err(ConfigError::Band { low_hz: self.band_low_hz, high_hz: self.band_high_hz });
        }
        let (lo, hi) = self.band_bins();
        if hi - lo > MAX_BAND_BINS {
            return Err(ConfigError::BandTooWide { bins: hi - lo });
        }
        if self.average_blocks == 0 || self.average_blocks > 64 {
            return Err(ConfigError::AverageBlocks(self.average_blocks));
        }
        let bpf_ok = self.bpf_min_hz.is_finite()
            && self.bpf_max_hz.is_finite()
            && self.bpf_min_hz >= 50.0
            && self.bpf_max_hz <= 1500.0
            && self.bpf_max_hz > self.bpf_min_hz;
        if !bpf_ok {
            return Err(ConfigError::BpfRange { min_hz: self.bpf_min_hz, max_hz: self.bpf_max_hz });
        }
        if self.harmonics == 0 || self.harmonics > MAX_HARMONICS {
            return Err(ConfigError::Harmonics(self.harmonics));
        }
        if !(self.peak_floor_ratio.is_finite() && self.peak_floor_ratio > 0.0) {
            return Err(ConfigError::Tunable("peak_floor_ratio"));
        }
        if !(self.peak_relative_score.is_finite() && self.peak_relative_score > 0.0) {
            return Err(ConfigError::Tunable("peak_relative_score"));
        }
        if !(self.bpf_min_quality.is_finite() && (0.0..=1.0).contains(&self.bpf_min_quality)) {
            return Err(ConfigError::Tunable("bpf_min_quality"));
        }
        if !(self.bpf_max_rate_per_s.is_finite() && self.bpf_max_rate_per_s > 0.0) {
            return Err(ConfigError::Tunable("bpf_max_rate_per_s"));
        }
        if self.health_interval_blocks == 0 {
            return Err(ConfigError::Tunable("health_interval_blocks"));
        }
        if self.mfcc_interval > 64 {
            return Err(ConfigError::Tunable("mfcc_interval"));
        }
        Ok(())
    }
}
