//! Configuration errors: every way a [`crate::Config`] or [`crate::Geometry`] can be refused.

use core::fmt;

/// Why a geometry or configuration was refused. Each variant names the offending value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ConfigError {
    /// Fewer than [`crate::MIN_MICS`] or more than [`crate::MAX_MICS`] microphones.
    MicCount(usize),
    /// A microphone coordinate is NaN or infinite (index of the microphone).
    NonFinitePosition(usize),
    /// Two microphones closer than 1 mm to each other (their indices).
    CoincidentMics(usize, usize),
    /// All microphones lie on (or very near) one line: the azimuth is ambiguous.
    CollinearMics,
    /// The array is too large: the pair lag range exceeds [`crate::MAX_LAG`] samples.
    ApertureTooLarge {
        /// Largest distance between two microphones, metres.
        aperture_m: f32,
    },
    /// Sample rate other than 16 000 or 48 000 Hz.
    SampleRate(u32),
    /// Block length other than 512 or 1024 samples.
    BlockLen(usize),
    /// Fewer TDM slots per frame than microphones, or more than 16.
    TdmSlots {
        /// Slots per TDM frame requested.
        slots: usize,
        /// Microphones in the geometry.
        mics: usize,
    },
    /// The GCC-PHAT band is empty, inverted, or reaches past the Nyquist frequency.
    Band {
        /// Lower band edge, Hz.
        low_hz: f32,
        /// Upper band edge, Hz.
        high_hz: f32,
    },
    /// The GCC-PHAT band holds more FFT bins than [`crate::MAX_BAND_BINS`].
    BandTooWide {
        /// Bins the band would need.
        bins: usize,
    },
    /// `average_blocks` is 0 or larger than 64.
    AverageBlocks(u32),
    /// The BPF search range is empty or outside what the spectral path sees (50–1500 Hz).
    BpfRange {
        /// Lower end of the fundamental search range, Hz.
        min_hz: f32,
        /// Upper end of the fundamental search range, Hz.
        max_hz: f32,
    },
    /// `harmonics` is 0 or larger than [`crate::MAX_HARMONICS`].
    Harmonics(usize),
    /// Speed of sound outside 300–400 m/s.
    SpeedOfSound(f32),
    /// A threshold or interval is not a positive finite number (its name).
    Tunable(&'static str),
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::MicCount(n) => write!(
                f,
                "{n} microphones: the array needs {} to {}",
                crate::MIN_MICS,
                crate::MAX_MICS
            ),
            Self::NonFinitePosition(i) => write!(f, "microphone {i} has a non-finite position"),
            Self::CoincidentMics(i, j) => {
                write!(f, "microphones {i} and {j} are less than 1 mm apart")
            }
            Self::CollinearMics => write!(
                f,
                "the microphones lie on or near one line (their spread across it is under a \
                 twentieth of that along it; a microphone far from the others does that too)"
            ),
            Self::ApertureTooLarge { aperture_m } => write!(
                f,
                "array aperture {aperture_m} m exceeds the {} sample lag range",
                crate::MAX_LAG
            ),
            Self::SampleRate(r) => write!(f, "sample rate {r} Hz: supported are 16000 and 48000"),
            Self::BlockLen(n) => write!(f, "block length {n}: supported are 512 and 1024"),
            Self::TdmSlots { slots, mics } => {
                write!(f, "{slots} TDM slots cannot carry {mics} microphones (max 16 slots)")
            }
            Self::Band { low_hz, high_hz } => {
                write!(f, "GCC-PHAT band {low_hz}-{high_hz} Hz is empty or beyond Nyquist")
            }
            Self::BandTooWide { bins } => {
                write!(f, "GCC-PHAT band needs {bins} bins, at most {} fit", crate::MAX_BAND_BINS)
            }
            Self::AverageBlocks(n) => write!(f, "average_blocks = {n}: must be 1 to 64"),
            Self::BpfRange { min_hz, max_hz } => {
                write!(f, "BPF search range {min_hz}-{max_hz} Hz must lie within 50-1500 Hz")
            }
            Self::Harmonics(n) => {
                write!(f, "harmonics = {n}: must be 1 to {}", crate::MAX_HARMONICS)
            }
            Self::SpeedOfSound(c) => write!(f, "speed of sound {c} m/s outside 300-400 m/s"),
            Self::Tunable(name) => write!(f, "{name} must be a positive finite number"),
        }
    }
}

#[cfg(any(test, feature = "std"))]
impl std::error::Error for ConfigError {}
