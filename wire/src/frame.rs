//! The frame kinds, their header and payloads, and the physical units of every field.

use serde::{Deserialize, Serialize};

use crate::fixed;

/// Most microphones a `Hello` can describe.
pub const MAX_MICS: usize = 8;
/// Most spectral peaks a `Peaks` frame carries.
pub const MAX_PEAKS: usize = 4;

/// Degrees per radian (f32), used by the unit conversions.
const DEG_PER_RAD: f32 = 57.295_78;

/// What a frame carries. The discriminant is the kind byte on the wire and is pinned forever
/// (see the compatibility rules in the crate docs); a test asserts every value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
#[non_exhaustive]
pub enum Kind {
    /// [`Hello`]: who is talking and how it samples.
    Hello = 0,
    /// [`Doa`]: one direction of arrival.
    Doa = 1,
    /// [`Peaks`]: blade-passing frequency and spectral peaks.
    Peaks = 2,
    /// [`Health`]: processing load and loss counters.
    Health = 3,
}

/// Kind bytes reserved for planned frames. Never reuse them for anything else; an old host
/// counts such frames as unknown kinds and skips them.
pub mod reserved {
    /// MFCC features per drone-type band (`ALGORITHMS.md` §9).
    pub const MFCC: u8 = 4;
    /// Ultrasonic beacon detections in 16–20 kHz.
    pub const BEACON: u8 = 5;
    /// Band-limited audio snippet for inter-array delays (`ALGORITHMS.md` §10).
    pub const SNIPPET: u8 = 6;
}

impl Kind {
    /// Every kind this version knows, in discriminant order.
    pub const ALL: [Kind; 4] = [Kind::Hello, Kind::Doa, Kind::Peaks, Kind::Health];

    /// The kind of a kind byte, or `None` if this version does not know it.
    pub const fn from_byte(byte: u8) -> Option<Kind> {
        match byte {
            0 => Some(Kind::Hello),
            1 => Some(Kind::Doa),
            2 => Some(Kind::Peaks),
            3 => Some(Kind::Health),
            _ => None,
        }
    }

    /// The kind byte on the wire.
    pub const fn byte(self) -> u8 {
        self as u8
    }

    /// Lower-case name, as printed by `aim frames`.
    pub const fn name(self) -> &'static str {
        match self {
            Kind::Hello => "hello",
            Kind::Doa => "doa",
            Kind::Peaks => "peaks",
            Kind::Health => "health",
        }
    }

    /// Largest postcard payload of this kind, bytes (every varint at its widest).
    pub const fn max_payload_len(self) -> usize {
        match self {
            // version 3 + rate u32 5 + block u16 3 + count 1 + 8 mics x 2 x i16 3
            Kind::Hello => 3 + 5 + 3 + 1 + MAX_MICS * 2 * 3,
            // span u32 5 + azimuth i16 3 + zenith u16 3 + residual u16 3 + quality 1 + pairs 1
            Kind::Doa => 5 + 3 + 3 + 3 + 1 + 1,
            // span u32 5 + bpf u32 5 + count 1 + 4 x (hz u32 5 + amplitude i16 3 + harmonicity 1)
            // + detection 1 + count 1 + 4 x quality 1 (appended)
            Kind::Peaks => 5 + 5 + 1 + MAX_PEAKS * (5 + 3 + 1) + 1 + 1 + MAX_PEAKS,
            // blocks, clipped u32 5 each + peak i16 3 + exponent i8 1
            // + cycles, overruns, dropped u32 5 each + queue depth 1
            Kind::Health => 5 + 5 + 3 + 1 + 5 * 3 + 1,
        }
    }

    /// Largest frame of this kind before COBS: header, payload and CRC, bytes.
    pub const fn max_raw_len(self) -> usize {
        crate::MAX_HEADER_LEN + self.max_payload_len() + crate::CRC_LEN
    }

    /// Largest frame of this kind on the wire: both delimiters and the COBS overhead, bytes.
    pub const fn max_encoded_len(self) -> usize {
        2 + crate::cobs::max_encoded_len(self.max_raw_len())
    }
}

/// The header every frame starts with (magic, version and kind are implied by the codec).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Header {
    /// Which array sent the frame (site files name arrays by this id).
    pub array_id: u8,
    /// Per-array frame counter, +1 for every frame sent, wrapping at 2^16; gaps mean lost frames.
    pub seq: u16,
    /// Index, in the array's own sample clock, of the first sample of the block the frame
    /// describes (samples since the array started).
    pub sample_index: u64,
}

/// A decoded frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Who sent it, its place in the sequence and its time.
    pub header: Header,
    /// What it says.
    pub body: Body,
}

/// The payload of a frame, one variant per [`Kind`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Body {
    /// See [`Hello`].
    Hello(Hello),
    /// See [`Doa`].
    Doa(Doa),
    /// See [`Peaks`].
    Peaks(Peaks),
    /// See [`Health`].
    Health(Health),
}

impl Body {
    /// The kind of this payload.
    pub const fn kind(&self) -> Kind {
        match self {
            Body::Hello(_) => Kind::Hello,
            Body::Doa(_) => Kind::Doa,
            Body::Peaks(_) => Kind::Peaks,
            Body::Health(_) => Kind::Health,
        }
    }
}

/// Sent at start-up and periodically (default every 5 s): firmware version and the array's
/// sampling and geometry, so a host can check it against its site file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Hello {
    /// Firmware version `[major, minor, patch]`.
    pub firmware_version: [u8; 3],
    /// Sample rate, Hz.
    pub sample_rate_hz: u32,
    /// Samples per processing block (the step of `sample_index` between blocks).
    pub block_len: u16,
    /// Microphone positions `[x, y]` in the array frame (x right, y forward), units of 0.1 mm
    /// (range ±3.2767 m), in slot order.
    pub mic_positions_decimm: heapless::Vec<[i16; 2], MAX_MICS>,
}

impl Hello {
    /// Quantises positions in metres (at most [`MAX_MICS`]; extra ones are dropped).
    pub fn new(
        firmware_version: [u8; 3],
        sample_rate_hz: u32,
        block_len: u16,
        positions_m: &[[f32; 2]],
    ) -> Self {
        let mut mic_positions_decimm = heapless::Vec::new();
        for p in positions_m.iter().take(MAX_MICS) {
            // Cannot fail: at most MAX_MICS are taken.
            let _ =
                mic_positions_decimm.push([fixed::to_i16(p[0], 1.0e4), fixed::to_i16(p[1], 1.0e4)]);
        }
        Hello { firmware_version, sample_rate_hz, block_len, mic_positions_decimm }
    }

    /// Microphone `i` position in metres, or `None` past the last microphone.
    pub fn mic_position_m(&self, i: usize) -> Option<[f32; 2]> {
        self.mic_positions_decimm
            .get(i)
            .map(|p| [f32::from(p[0]) * 1.0e-4, f32::from(p[1]) * 1.0e-4])
    }
}

/// One direction-of-arrival estimate (aim-dsp defaults: one per 4 blocks of 1024 samples at
/// 48 kHz, 11.7/s). The header's sample index is the first sample of the first averaged block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Doa {
    /// Samples covered by the estimate, from the header's sample index on.
    pub span_samples: u32,
    /// Azimuth from +x towards +y, units of 0.01° (resolution 1.7e-4 rad), in [-18000, 18000].
    pub azimuth_cdeg: i16,
    /// Zenith angle from +z (the array normal), units of 0.01°, in [0, 18000].
    pub zenith_cdeg: u16,
    /// Residual of the least-squares fit, RMS lag error, units of 0.01 samples (range 0–655.35;
    /// larger values saturate).
    pub residual_csamples: u16,
    /// Quality in [0, 1], units of 1/255 (resolution 0.0039).
    pub quality: u8,
    /// Microphone pairs that carried weight in the fit.
    pub pairs_used: u8,
}

impl Doa {
    /// Quantises angles in radians, the residual in samples and the quality in [0, 1];
    /// `span_samples` and `pairs_used` start at 0 (set them with struct update syntax).
    pub fn new(azimuth_rad: f32, zenith_rad: f32, residual_samples: f32, quality: f32) -> Self {
        let azimuth_deg = wrap_degrees(azimuth_rad * DEG_PER_RAD);
        Doa {
            span_samples: 0,
            pairs_used: 0,
            azimuth_cdeg: fixed::to_i16(azimuth_deg, 100.0),
            zenith_cdeg: fixed::to_u16(zenith_rad * DEG_PER_RAD, 100.0),
            residual_csamples: fixed::to_u16(residual_samples, 100.0),
            quality: fixed::to_u8(quality, 255.0),
        }
    }

    /// Azimuth, degrees.
    pub fn azimuth_deg(&self) -> f32 {
        f32::from(self.azimuth_cdeg) * 0.01
    }

    /// Zenith, degrees.
    pub fn zenith_deg(&self) -> f32 {
        f32::from(self.zenith_cdeg) * 0.01
    }

    /// Azimuth, radians.
    pub fn azimuth_rad(&self) -> f32 {
        self.azimuth_deg() / DEG_PER_RAD
    }

    /// Zenith, radians.
    pub fn zenith_rad(&self) -> f32 {
        self.zenith_deg() / DEG_PER_RAD
    }

    /// Fit residual, samples.
    pub fn residual_samples(&self) -> f32 {
        f32::from(self.residual_csamples) * 0.01
    }

    /// Quality in [0, 1].
    pub fn quality(&self) -> f32 {
        f32::from(self.quality) / 255.0
    }
}

/// Wraps degrees into [-180, 180] without std maths.
fn wrap_degrees(deg: f32) -> f32 {
    if !deg.is_finite() {
        return 0.0;
    }
    let turns = (deg / 360.0) as i64 as f32;
    let mut d = deg - 360.0 * turns;
    if d > 180.0 {
        d -= 360.0;
    } else if d < -180.0 {
        d += 360.0;
    }
    d
}

/// One spectral peak.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Peak {
    /// Frequency, units of 0.01 Hz.
    pub freq_chz: u32,
    /// Amplitude of the fundamental, units of 0.1 dB relative to microphone full scale
    /// (dBFS; -3276.8 dB stands for silence).
    pub amplitude_ddb: i16,
    /// Harmonicity in [0, 1], units of 1/255.
    pub harmonicity: u8,
}

impl Peak {
    /// Quantises a frequency in Hz, an amplitude in dB and a harmonicity in [0, 1].
    pub fn new(freq_hz: f32, amplitude_db: f32, harmonicity: f32) -> Self {
        Peak {
            freq_chz: fixed::to_u32(freq_hz, 100.0),
            amplitude_ddb: fixed::to_i16(amplitude_db, 10.0),
            harmonicity: fixed::to_u8(harmonicity, 255.0),
        }
    }

    /// Frequency, Hz.
    pub fn freq_hz(&self) -> f32 {
        self.freq_chz as f32 * 0.01
    }

    /// Amplitude, dB.
    pub fn amplitude_db(&self) -> f32 {
        f32::from(self.amplitude_ddb) * 0.1
    }

    /// Harmonicity in [0, 1].
    pub fn harmonicity(&self) -> f32 {
        f32::from(self.harmonicity) / 255.0
    }
}

/// The chip's rotor-signature decision in a [`Peaks`] frame (appended field: frames of
/// firmware that did not decide carry none and decode as [`Detection::Unstated`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Detection {
    /// The frame does not say (written before the detection test existed): `bpf_chz` and
    /// `peaks` are whatever the old estimator found.
    #[default]
    Unstated,
    /// No rotor signature passed the detection test: no BPF, no groups.
    NoRotor,
    /// A rotor signature passed the test: `bpf_chz` and `peaks` are its groups.
    Rotor,
}

/// Blade-passing frequency estimate and the strongest peak groups (aim-dsp defaults: one per
/// 2048 samples decimated to 8 kHz, 3.9/s). The header's sample index is where the analysis
/// window starts.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Peaks {
    /// Input-rate samples covered by the analysis window.
    pub span_samples: u32,
    /// Blade-passing frequency, units of 0.01 Hz; 0 when none was found.
    pub bpf_chz: u32,
    /// Up to [`MAX_PEAKS`] peaks, strongest first.
    pub peaks: heapless::Vec<Peak, MAX_PEAKS>,
    /// Rotor signature or not (appended; absent in older frames).
    pub detection: Detection,
    /// Detection quality of each peak group in [0, 1], units of 1/255, in the order of
    /// `peaks` (appended; empty in older frames).
    pub quality: heapless::Vec<u8, MAX_PEAKS>,
}

/// The fields of [`Peaks`] before the appended ones: what older frames carry.
#[derive(Deserialize)]
pub(crate) struct PeaksBase {
    pub span_samples: u32,
    pub bpf_chz: u32,
    pub peaks: heapless::Vec<Peak, MAX_PEAKS>,
}

/// The appended fields of [`Peaks`].
#[derive(Deserialize)]
pub(crate) struct PeaksAppended {
    pub detection: Detection,
    pub quality: heapless::Vec<u8, MAX_PEAKS>,
}

impl Peaks {
    /// A frame of the current layout with no groups: "no rotor signature".
    pub fn no_rotor(span_samples: u32) -> Self {
        Peaks {
            span_samples,
            bpf_chz: 0,
            peaks: heapless::Vec::new(),
            detection: Detection::NoRotor,
            quality: heapless::Vec::new(),
        }
    }

    /// Blade-passing frequency, Hz (0 when none was found).
    pub fn bpf_hz(&self) -> f32 {
        self.bpf_chz as f32 * 0.01
    }

    /// Detection quality of group `i` in [0, 1], if the frame carries it.
    pub fn quality_of(&self, i: usize) -> Option<f32> {
        self.quality.get(i).map(|&q| f32::from(q) / 255.0)
    }

    /// Whether the frame reports a rotor: [`Detection::Rotor`], or an older frame with a BPF.
    pub fn is_rotor(&self) -> bool {
        match self.detection {
            Detection::Rotor => true,
            Detection::NoRotor => false,
            Detection::Unstated => self.bpf_chz > 0,
        }
    }
}

/// Processing load and loss counters (aim-dsp default: every 48 blocks, about 1/s). Counters
/// count from start-up and wrap; a host differences consecutive frames. The first four fields
/// come from the DSP, the rest from the firmware (0 in simulation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Health {
    /// Blocks processed since start-up.
    pub blocks: u32,
    /// Samples at 24-bit full scale in the interval (all microphones).
    pub clipped_samples: u32,
    /// Largest absolute sample in the interval, units of 0.1 dBFS.
    pub peak_ddbfs: i16,
    /// Block exponent of the front end's last block.
    pub block_exponent: i8,
    /// CPU cycles spent on the last block (0 when not measured).
    pub cycles_per_block: u32,
    /// Audio DMA overruns since start-up (blocks lost before processing).
    pub dma_overruns: u32,
    /// Frames dropped since start-up because the uplink queue was full.
    pub dropped_frames: u32,
    /// Frames waiting in the uplink queue when this one was queued.
    pub queue_depth: u8,
}
