//! What the pipeline emits: direction of arrival, BPF peaks, identification features, health and
//! beacon arrivals, each stamped with the
//! sample index (the array's own clock) of the first sample it describes.

/// One result of the streaming [`crate::Pipeline`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Output {
    /// Direction of arrival from the averaged GCC-PHAT pair delays.
    Doa(Doa),
    /// Blade-passing-frequency peak groups from the long mono spectrum.
    Peaks(Peaks),
    /// Front-end statistics for the last interval.
    Health(Health),
    /// Drone-identification features of a BPF analysis window ([`crate::idframe`]).
    Mfcc(crate::idframe::IdFeatures),
    /// A synchronisation beacon's arrival at microphone 0 ([`crate::beacon`]), at 48 kHz only.
    Beacon(crate::beacon::Beacon),
    /// 32 ms of the array's mean signal at 8 kHz, for inter-array delays ([`crate::snippet`]).
    Snippet(crate::snippet::Snippet),
}

/// Direction of arrival, far field, planar array (source on the +z side).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Doa {
    /// Index of the first sample of the first block averaged into this estimate.
    pub sample_index: u64,
    /// Samples covered (`average_blocks · block_len`).
    pub span_samples: u32,
    /// Azimuth, radians, from +x towards +y, in (−π, π].
    pub azimuth_rad: f32,
    /// Zenith angle from the array normal (+z), radians, in [0, π/2].
    pub zenith_rad: f32,
    /// Weighted RMS misfit of the pair delays to the plane-wave model, samples.
    pub residual: f32,
    /// Mean pair quality times the share of it the robust direction fit kept
    /// ([`crate::doa::Direction::kept_weight`]): 0 (no coherent peak) to 1 (one clean peak in
    /// every pair, all pairs on one plane wave). Low when pairs lock onto reflections: a
    /// reverberation- or obstruction-dominated frame.
    pub quality: f32,
    /// Pairs with non-zero weight in the fit.
    pub pairs_used: u8,
}

/// One BPF peak group: a fundamental with its harmonics.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Peak {
    /// Fundamental frequency: amplitude-weighted mean of (harmonic frequency / harmonic number), Hz.
    pub hz: f32,
    /// Level of the group: root-sum-square of the amplitudes of its harmonic lines found in the
    /// spectrum ([`crate::comb`]), fraction of microphone full scale (mean over microphones).
    pub amplitude: f32,
    /// Fraction of the expected harmonics (within the analysed band) found as spectral peaks, 0–1.
    pub harmonicity: f32,
    /// Detection quality, 0–1: harmonicity · score / (score + 30), score the sum of the found
    /// lines' levels over the local noise floor (each capped at 40); see [`crate::comb`].
    pub quality: f32,
}

/// Up to four BPF peak groups, or "no rotor signature". Groups continuing one reported in the
/// previous analysis come first, then the others; within each, strongest harmonic score first
/// ([`crate::comb`], point 6).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Peaks {
    /// A rotor signature passed the detection test (`count` > 0); false: no rotor signature,
    /// no BPF, no groups.
    pub rotor: bool,
    /// Index of the (input-rate) sample at which the analysis window starts.
    pub sample_index: u64,
    /// Input-rate samples covered by the analysis window.
    pub span_samples: u32,
    /// The first group's fundamental, Hz (0 when `count` = 0): the strongest of those
    /// continuing a reported comb, else the strongest.
    pub bpf_hz: f32,
    /// Valid entries in `peaks`.
    pub count: u8,
    /// Peak groups (one per resolvable rotor speed); entries past `count` are zero.
    pub peaks: [Peak; 4],
}

/// Front-end statistics over the last `health_interval_blocks` blocks.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Health {
    /// Index of the first sample of the interval.
    pub sample_index: u64,
    /// Blocks processed since the pipeline was configured.
    pub blocks: u32,
    /// Samples at 24-bit full scale in the interval (all microphones).
    pub clipped_samples: u32,
    /// Largest absolute DC-removed sample in the interval, dB relative to full scale.
    pub peak_dbfs: f32,
    /// Block exponent of the last block: Q15 value · 2^(exponent − 15) = fraction of full scale.
    pub block_exponent: i8,
    /// Microphones measured in `mic_rms_dbfs` and `mic_dc_dbfs` (the array's count).
    pub mics: u8,
    /// Per microphone, the RMS level of its DC-removed signal in the interval's first block,
    /// dB relative to full scale (−200 for an all-zero block): a dead or stuck microphone is
    /// far below its neighbours.
    pub mic_rms_dbfs: [f32; crate::MAX_MICS],
    /// Per microphone, the front end's DC estimate at the same block, dB relative to full
    /// scale (−200 for zero): a microphone stuck at a constant word shows a large DC and no
    /// RMS, a dead (silent, all-zero) one neither.
    pub mic_dc_dbfs: [f32; crate::MAX_MICS],
}
