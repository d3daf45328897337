//! The frame kinds, their header and payloads, and the physical units of every field.

use serde::{Deserialize, Serialize};

use crate::fixed;

/// Most microphones a `Hello` can describe.
pub const MAX_MICS: usize = 8;
/// Most spectral peaks a `Peaks` frame carries.
pub const MAX_PEAKS: usize = 4;
/// Mel bands in an `Mfcc` frame (aim-dsp `idframe::MEL_BANDS`).
pub const MFCC_MEL_BANDS: usize = 24;
/// Cepstral coefficients (c0 included) in an `Mfcc` frame (aim-dsp `idframe::MFCC_COUNT`).
pub const MFCC_COEFFS: usize = 13;
/// BPF comb features in an `Mfcc` frame (aim-dsp `features::HARMONIC_FEATURES`).
pub const MFCC_HARMONIC: usize = 9;
/// Samples in a `Snippet` frame (aim-dsp `snippet::SNIPPET_LEN`).
pub const SNIPPET_SAMPLES: usize = 256;
/// Most bytes of the panic message a `Hello` carries ([`Hello::panic_message`]).
pub const MAX_PANIC_MESSAGE: usize = 48;
/// Bytes of a chip unique ID ([`Hello::unique_id`]: the STM32's 96-bit UID).
pub const UNIQUE_ID_LEN: usize = 12;

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
    /// [`Mfcc`]: drone-identification features (log-mel, MFCC, BPF comb) of one analysis window.
    Mfcc = 4,
    /// [`Beacon`]: one arrival of the synchronisation beacon (aim-dsp `beacon`).
    Beacon = 5,
    /// [`Snippet`]: 32 ms of the array's mean signal at 8 kHz, for inter-array delays.
    Snippet = 6,
}

/// Kind bytes reserved for planned frames. Never reuse them for anything else; an old host
/// counts such frames as unknown kinds and skips them.
pub mod reserved {
    /// MFCC features (`ALGORITHMS.md` §10): now [`super::Kind::Mfcc`], kept for the record.
    pub const MFCC: u8 = 4;
    /// Beacon arrivals in 16–20 kHz: now [`super::Kind::Beacon`], kept for the record.
    pub const BEACON: u8 = 5;
    /// Band-limited audio snippet for inter-array delays (`ALGORITHMS.md` §9): now
    /// [`super::Kind::Snippet`], kept for the record.
    pub const SNIPPET: u8 = 6;
}

impl Kind {
    /// Every kind this version knows, in discriminant order.
    pub const ALL: [Kind; 7] = [
        Kind::Hello,
        Kind::Doa,
        Kind::Peaks,
        Kind::Health,
        Kind::Mfcc,
        Kind::Beacon,
        Kind::Snippet,
    ];

    /// The kind of a kind byte, or `None` if this version does not know it.
    pub const fn from_byte(byte: u8) -> Option<Kind> {
        match byte {
            0 => Some(Kind::Hello),
            1 => Some(Kind::Doa),
            2 => Some(Kind::Peaks),
            3 => Some(Kind::Health),
            4 => Some(Kind::Mfcc),
            5 => Some(Kind::Beacon),
            6 => Some(Kind::Snippet),
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
            Kind::Mfcc => "mfcc",
            Kind::Beacon => "beacon",
            Kind::Snippet => "snippet",
        }
    }

    /// Largest postcard payload of this kind, bytes (every varint at its widest).
    pub const fn max_payload_len(self) -> usize {
        match self {
            // version 3 + rate u32 5 + block u16 3 + count 1 + 8 mics x 2 x i16 3
            // + reset cause 1 + boot count u32 5 + unique id 12 + message length 1 + message
            // + chip revision u16 3 + clock source 1 + sysclk u32 5
            Kind::Hello => {
                3 + 5
                    + 3
                    + 1
                    + MAX_MICS * 2 * 3
                    + 1
                    + 5
                    + UNIQUE_ID_LEN
                    + 1
                    + MAX_PANIC_MESSAGE
                    + 3
                    + 1
                    + 5
            }
            // span u32 5 + azimuth i16 3 + zenith u16 3 + residual u16 3 + quality 1 + pairs 1
            Kind::Doa => 5 + 3 + 3 + 3 + 1 + 1,
            // span u32 5 + bpf u32 5 + count 1 + 4 x (hz u32 5 + amplitude i16 3 + harmonicity 1)
            // + detection 1 + count 1 + 4 x quality 1 (appended)
            Kind::Peaks => 5 + 5 + 1 + MAX_PEAKS * (5 + 3 + 1) + 1 + 1 + MAX_PEAKS,
            // blocks, clipped u32 5 each + peak i16 3 + exponent i8 1
            // + cycles, overruns, dropped u32 5 each + queue depth 1 + 9 loss counters u32 5 each
            // + microphone count 1 + 8 x (rms, dc) i16 3 each
            Kind::Health => 5 + 5 + 3 + 1 + 5 * 3 + 1 + 9 * 5 + 1 + MAX_MICS * 2 * 3,
            // span u32 5 + (24 log-mel + 13 MFCC + 9 harmonic) x i16 3
            // + second comb (appended) Option tag 1 + 9 x i16 3
            Kind::Mfcc => {
                5 + (MFCC_MEL_BANDS + MFCC_COEFFS + MFCC_HARMONIC) * 3 + 1 + MFCC_HARMONIC * 3
            }
            // fraction u16 3 + quality 1 + level i16 3
            Kind::Beacon => 3 + 1 + 3,
            // decimation 1 + exponent 1 + length varint 2 + samples 1 each
            Kind::Snippet => 1 + 1 + 2 + SNIPPET_SAMPLES,
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
    /// See [`Mfcc`].
    Mfcc(Mfcc),
    /// See [`Beacon`].
    Beacon(Beacon),
    /// See [`Snippet`].
    Snippet(Snippet),
}

impl Body {
    /// The kind of this payload.
    pub const fn kind(&self) -> Kind {
        match self {
            Body::Hello(_) => Kind::Hello,
            Body::Doa(_) => Kind::Doa,
            Body::Peaks(_) => Kind::Peaks,
            Body::Health(_) => Kind::Health,
            Body::Mfcc(_) => Kind::Mfcc,
            Body::Beacon(_) => Kind::Beacon,
            Body::Snippet(_) => Kind::Snippet,
        }
    }
}

/// Sent at start-up and periodically (default every 5 s): firmware version, the array's
/// sampling and geometry (so a host can check it against its site file), and who the board is
/// and why it started (so a host notices a reboot and two boards claiming one id).
///
/// The fields after `mic_positions_decimm` were appended later (compatibility rule 3): a
/// payload without them (older firmware, the simulator's old recordings) decodes with their
/// defaults: reset cause [`ResetCause::Unknown`], boot count 0, unique ID all zero, no message.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize)]
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
    /// Why the board last started: a [`ResetCause`] code (unknown codes are kept as sent).
    pub reset_cause: u8,
    /// Starts of the firmware since power-on (1 for the first; 0: not reported). It is kept
    /// in RAM that a reset does not clear, so a power cycle starts it again at 1; a host
    /// also sees a reboot as the sample index going back.
    pub boot_count: u32,
    /// The chip's unique ID (STM32: the 96-bit UID, the bytes as the chip stores them; all zero:
    /// not reported, e.g. simulation).
    pub unique_id: [u8; UNIQUE_ID_LEN],
    /// The panic that caused the last reset, as the firmware recorded it before resetting:
    /// `file:line message`, cut to [`MAX_PANIC_MESSAGE`] bytes at a character boundary; empty
    /// when the last reset was not a panic.
    pub panic_message: heapless::String<MAX_PANIC_MESSAGE>,
    /// The chip's silicon revision as the chip reports it (STM32: REV_ID of DBGMCU_IDCODE,
    /// e.g. `0x2003` = revision V, `0x1003` = revision Y; [`stm32h7_revision_name`]); 0: not
    /// reported. Appended after `panic_message` (rule 3) with [`Hello::clock_source`] and
    /// [`Hello::sysclk_hz`]; the three are sent only when one of them is set, so a `Hello`
    /// without them (simulation, older firmware) keeps its bytes. Fields appended after them
    /// later must send them (zeros allowed) first.
    #[serde(skip)]
    pub chip_revision: u16,
    /// Where the core and audio clocks come from: a [`ClockSource`] code (0: not reported).
    #[serde(skip)]
    pub clock_source: u8,
    /// Core clock the firmware runs at, Hz (0: not reported).
    #[serde(skip)]
    pub sysclk_hz: u32,
}

/// The array id a board derives from its chip unique ID when no id was set for it: 1 + the
/// CRC-32 of the 12 ID bytes modulo 255, so 1..=255 (0 is left for "not set"). The same
/// function on the host maps a unique ID in a site file to the id its board will send. Two
/// boards collide with probability 1/255 per pair; a host that sees two unique IDs under one
/// array id reports it (`aim frames`), and such a board is then given an id at build time.
pub fn derived_array_id(unique_id: &[u8; UNIQUE_ID_LEN]) -> u8 {
    // The remainder is below 255, so the sum fits a u8.
    1 + (crate::crc32(unique_id) % 255) as u8
}

/// The part of a [`Hello`] payload every version has.
#[derive(Deserialize)]
struct HelloBase {
    firmware_version: [u8; 3],
    sample_rate_hz: u32,
    block_len: u16,
    mic_positions_decimm: heapless::Vec<[i16; 2], MAX_MICS>,
}

/// The fields appended to [`Hello`] for start-up reporting.
#[derive(Deserialize)]
struct HelloStart {
    reset_cause: u8,
    boot_count: u32,
    unique_id: [u8; UNIQUE_ID_LEN],
    panic_message: heapless::String<MAX_PANIC_MESSAGE>,
}

/// The fields appended to [`Hello`] for the chip and clock report (sent only when set).
#[derive(Serialize, Deserialize)]
pub(crate) struct HelloClock {
    pub(crate) chip_revision: u16,
    pub(crate) clock_source: u8,
    pub(crate) sysclk_hz: u32,
}

/// Where a board's clocks come from, as [`Hello::clock_source`] reports it. The codes are
/// pinned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
#[non_exhaustive]
pub enum ClockSource {
    /// Not reported (older firmware, simulation).
    Unknown = 0,
    /// The external clock in bypass mode (NUCLEO: the ST-LINK's 8 MHz): the sample rate is as
    /// exact as that crystal.
    HseBypass = 1,
    /// The internal RC oscillator, because the external clock did not start: the sample rate
    /// is only as exact as the RC oscillator's trim (a fault to fix, reported so a host knows).
    Hsi = 2,
}

impl ClockSource {
    /// The source of a code, or `None` for a code this version does not know.
    pub fn from_code(code: u8) -> Option<ClockSource> {
        match code {
            0 => Some(ClockSource::Unknown),
            1 => Some(ClockSource::HseBypass),
            2 => Some(ClockSource::Hsi),
            _ => None,
        }
    }

    /// The code on the wire.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// Lower-case name, as printed by `aim frames`.
    pub const fn name(self) -> &'static str {
        match self {
            ClockSource::Unknown => "unknown",
            ClockSource::HseBypass => "hse-bypass",
            ClockSource::Hsi => "hsi",
        }
    }
}

/// The STM32H742/743/750/753 revision letter of a DBGMCU_IDCODE REV_ID (ST errata sheet
/// ES0392: `0x1001` Z, `0x1003` Y, `0x2001` X, `0x2003` V), or `None` for another value.
/// Revision V is the one that runs at 480 MHz; the earlier ones stop at 400 MHz.
pub const fn stm32h7_revision_name(rev_id: u16) -> Option<&'static str> {
    match rev_id {
        0x1001 => Some("Z"),
        0x1003 => Some("Y"),
        0x2001 => Some("X"),
        0x2003 => Some("V"),
        _ => None,
    }
}

/// Why a board started, as [`Hello::reset_cause`] reports it. The codes are pinned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
#[non_exhaustive]
pub enum ResetCause {
    /// Not reported (older firmware, simulation) or no flag set.
    Unknown = 0,
    /// Power-on reset.
    PowerOn = 1,
    /// The reset pin (NRST), e.g. the reset button or a debugger.
    Pin = 2,
    /// Brown-out: the supply dipped.
    BrownOut = 3,
    /// A software reset the firmware did not attribute to a panic or a fault.
    Software = 4,
    /// The independent watchdog: the processing loop stopped feeding it.
    Watchdog = 5,
    /// The window watchdog.
    WindowWatchdog = 6,
    /// An illegal low-power entry.
    LowPower = 7,
    /// A panic: the firmware logged it, kept its message ([`Hello::panic_message`]) and reset.
    Panic = 8,
    /// A CPU fault (hard fault, stack overflow into the guard region): recorded, then reset.
    Fault = 9,
}

impl ResetCause {
    /// Every cause, in code order.
    pub const ALL: [ResetCause; 10] = [
        ResetCause::Unknown,
        ResetCause::PowerOn,
        ResetCause::Pin,
        ResetCause::BrownOut,
        ResetCause::Software,
        ResetCause::Watchdog,
        ResetCause::WindowWatchdog,
        ResetCause::LowPower,
        ResetCause::Panic,
        ResetCause::Fault,
    ];

    /// The cause of a code, or `None` for a code this version does not know.
    pub fn from_code(code: u8) -> Option<ResetCause> {
        ResetCause::ALL.get(usize::from(code)).copied()
    }

    /// The code on the wire.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// Lower-case name, as printed by `aim frames`.
    pub const fn name(self) -> &'static str {
        match self {
            ResetCause::Unknown => "unknown",
            ResetCause::PowerOn => "power-on",
            ResetCause::Pin => "pin",
            ResetCause::BrownOut => "brown-out",
            ResetCause::Software => "software",
            ResetCause::Watchdog => "watchdog",
            ResetCause::WindowWatchdog => "window-watchdog",
            ResetCause::LowPower => "low-power",
            ResetCause::Panic => "panic",
            ResetCause::Fault => "fault",
        }
    }
}

/// Decodes a payload of fields every version has, then, if bytes follow, the appended fields
/// `E`; a payload that ends after the base gives `E::default()`. Returns both and the bytes
/// after them (fields appended by a later version).
fn base_and_appended<B, E>(payload: &[u8]) -> postcard::Result<(B, Option<E>, &[u8])>
where
    B: serde::de::DeserializeOwned,
    E: serde::de::DeserializeOwned,
{
    let (base, rest) = postcard::take_from_bytes::<B>(payload)?;
    if rest.is_empty() {
        return Ok((base, None, rest));
    }
    let (appended, rest) = postcard::take_from_bytes::<E>(rest)?;
    Ok((base, Some(appended), rest))
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
        Hello {
            firmware_version,
            sample_rate_hz,
            block_len,
            mic_positions_decimm,
            ..Hello::default()
        }
    }

    /// Decodes a payload; the start-up fields and the chip and clock report default when
    /// absent (older firmware, simulation).
    pub(crate) fn from_payload(payload: &[u8]) -> postcard::Result<Hello> {
        let (base, start, rest) = base_and_appended::<HelloBase, HelloStart>(payload)?;
        let mut hello = Hello {
            firmware_version: base.firmware_version,
            sample_rate_hz: base.sample_rate_hz,
            block_len: base.block_len,
            mic_positions_decimm: base.mic_positions_decimm,
            ..Hello::default()
        };
        if let Some(s) = start {
            hello.reset_cause = s.reset_cause;
            hello.boot_count = s.boot_count;
            hello.unique_id = s.unique_id;
            hello.panic_message = s.panic_message;
        }
        if !rest.is_empty() {
            let (clock, _) = postcard::take_from_bytes::<HelloClock>(rest)?;
            hello.chip_revision = clock.chip_revision;
            hello.clock_source = clock.clock_source;
            hello.sysclk_hz = clock.sysclk_hz;
        }
        Ok(hello)
    }

    /// The chip and clock report, when it is to be sent (any of its fields set).
    pub(crate) fn clock_report(&self) -> Option<HelloClock> {
        (self.chip_revision != 0 || self.clock_source != 0 || self.sysclk_hz != 0).then_some(
            HelloClock {
                chip_revision: self.chip_revision,
                clock_source: self.clock_source,
                sysclk_hz: self.sysclk_hz,
            },
        )
    }

    /// The clock source, or `None` for a code this version does not know.
    pub fn clock_source(&self) -> Option<ClockSource> {
        ClockSource::from_code(self.clock_source)
    }

    /// The reset cause, or `None` for a code this version does not know.
    pub fn reset_cause(&self) -> Option<ResetCause> {
        ResetCause::from_code(self.reset_cause)
    }

    /// Sets the panic message, cut to [`MAX_PANIC_MESSAGE`] bytes at a character boundary.
    pub fn set_panic_message(&mut self, message: &str) {
        let mut end = message.len().min(MAX_PANIC_MESSAGE);
        while !message.is_char_boundary(end) {
            end -= 1;
        }
        self.panic_message.clear();
        // Cannot fail: at most MAX_PANIC_MESSAGE bytes.
        let _ = self.panic_message.push_str(&message[..end]);
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
    /// Level of the group (root-sum-square amplitude of its harmonic lines; older firmware: the
    /// fundamental's amplitude), units of 0.1 dB relative to microphone full scale
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
    /// Up to [`MAX_PEAKS`] peaks in the detector's order (aim-dsp: groups continuing a
    /// reported comb first, each set strongest first).
    pub peaks: heapless::Vec<Peak, MAX_PEAKS>,
    /// Rotor signature or not (appended; absent in older frames).
    pub detection: Detection,
    /// Detection quality of each peak group in [0, 1], units of 1/255, in the order of
    /// `peaks` (appended; empty in older frames).
    pub quality: heapless::Vec<u8, MAX_PEAKS>,
}

/// The fields of [`Peaks`] before the appended ones: what older frames carry.
#[derive(Deserialize)]
struct PeaksBase {
    pub span_samples: u32,
    pub bpf_chz: u32,
    pub peaks: heapless::Vec<Peak, MAX_PEAKS>,
}

/// The appended fields of [`Peaks`].
#[derive(Deserialize)]
struct PeaksAppended {
    pub detection: Detection,
    pub quality: heapless::Vec<u8, MAX_PEAKS>,
}

impl Peaks {
    /// Decodes a payload; the appended detection and qualities default when absent (older
    /// firmware: [`Detection::Unstated`], no qualities).
    pub(crate) fn from_payload(payload: &[u8]) -> postcard::Result<Peaks> {
        let (base, appended, _) = base_and_appended::<PeaksBase, PeaksAppended>(payload)?;
        let (detection, quality) =
            appended.map_or_else(Default::default, |a| (a.detection, a.quality));
        Ok(Peaks {
            span_samples: base.span_samples,
            bpf_chz: base.bpf_chz,
            peaks: base.peaks,
            detection,
            quality,
        })
    }

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
///
/// The fields after `queue_depth` were appended later (compatibility rule 3): a payload
/// without them decodes with them at 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
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
    /// Audio DMA ring overruns since start-up: the ring wrapped before the capture task read
    /// it (each one restarted capture; the lost samples are a gap).
    pub dma_overruns: u32,
    /// Frames dropped since start-up because the uplink queue was full.
    pub dropped_frames: u32,
    /// Frames waiting in the uplink queue when this one was queued.
    pub queue_depth: u8,
    /// Capture chunks discarded because the DSP had not freed a queue slot in time (DSP
    /// overload; each is a gap of one chunk).
    pub dsp_overloads: u32,
    /// Overruns of the SAI's own FIFO (its overrun flag; each one restarted capture).
    pub sai_overruns: u32,
    /// Gaps in the sample clock handed to the DSP (whatever their cause).
    pub gaps: u32,
    /// Audio frames (samples per microphone) lost in those gaps.
    pub frames_lost: u32,
    /// DSP outputs dropped because their span crossed a gap.
    pub outputs_dropped: u32,
    /// DSP outputs dropped because one chunk produced more than the firmware buffers.
    pub outputs_overflowed: u32,
    /// Uplink UART transmit errors.
    pub uart_errors: u32,
    /// Frames that could not be encoded (too large for the buffer, payload error).
    pub frames_unencodable: u32,
    /// Capture chunks handed to the DSP.
    pub chunks_captured: u32,
    /// Per-microphone levels (appended after `chunks_captured`, rule 3; sent only when
    /// `mic_levels.count > 0`, so a `Health` without them keeps its bytes).
    #[serde(skip)]
    pub mic_levels: MicLevels,
}

/// Each microphone's level in the first block of a [`Health`] interval, from the DSP front end:
/// what tells a dead or stuck microphone from a working one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MicLevels {
    /// Microphones reported (0: none; at most [`MAX_MICS`]).
    pub count: u8,
    /// RMS of each microphone's DC-removed signal, units of 0.1 dBFS (−2000: all zero).
    pub rms_ddbfs: [i16; MAX_MICS],
    /// Each microphone's DC level, units of 0.1 dBFS (−2000: zero).
    pub dc_ddbfs: [i16; MAX_MICS],
}

impl MicLevels {
    /// `(rms, dc)` of microphone `mic` in dBFS, or `None` past `count`.
    pub fn level_dbfs(&self, mic: usize) -> Option<(f32, f32)> {
        (mic < usize::from(self.count).min(MAX_MICS))
            .then(|| (f32::from(self.rms_ddbfs[mic]) * 0.1, f32::from(self.dc_ddbfs[mic]) * 0.1))
    }
}

/// The per-microphone levels appended to [`Health`] (sent only when there are any).
#[derive(Serialize, Deserialize)]
pub(crate) struct HealthMics {
    /// `[rms, dc]` per microphone, units of 0.1 dBFS.
    pub(crate) levels: heapless::Vec<[i16; 2], MAX_MICS>,
}

/// The part of a [`Health`] payload every version has.
#[derive(Deserialize)]
struct HealthBase {
    blocks: u32,
    clipped_samples: u32,
    peak_ddbfs: i16,
    block_exponent: i8,
    cycles_per_block: u32,
    dma_overruns: u32,
    dropped_frames: u32,
    queue_depth: u8,
}

/// The loss counters appended to [`Health`].
#[derive(Deserialize)]
struct HealthLosses {
    dsp_overloads: u32,
    sai_overruns: u32,
    gaps: u32,
    frames_lost: u32,
    outputs_dropped: u32,
    outputs_overflowed: u32,
    uart_errors: u32,
    frames_unencodable: u32,
    chunks_captured: u32,
}

impl Health {
    /// Decodes a payload; the appended counters are 0 when absent (older firmware).
    pub(crate) fn from_payload(payload: &[u8]) -> postcard::Result<Health> {
        let (b, losses, rest) = base_and_appended::<HealthBase, HealthLosses>(payload)?;
        let mut health = Health {
            blocks: b.blocks,
            clipped_samples: b.clipped_samples,
            peak_ddbfs: b.peak_ddbfs,
            block_exponent: b.block_exponent,
            cycles_per_block: b.cycles_per_block,
            dma_overruns: b.dma_overruns,
            dropped_frames: b.dropped_frames,
            queue_depth: b.queue_depth,
            ..Health::default()
        };
        if let Some(l) = losses {
            health.dsp_overloads = l.dsp_overloads;
            health.sai_overruns = l.sai_overruns;
            health.gaps = l.gaps;
            health.frames_lost = l.frames_lost;
            health.outputs_dropped = l.outputs_dropped;
            health.outputs_overflowed = l.outputs_overflowed;
            health.uart_errors = l.uart_errors;
            health.frames_unencodable = l.frames_unencodable;
            health.chunks_captured = l.chunks_captured;
        }
        if !rest.is_empty() {
            let (mics, _) = postcard::take_from_bytes::<HealthMics>(rest)?;
            let levels = &mut health.mic_levels;
            levels.count = mics.levels.len() as u8;
            for (i, [rms, dc]) in mics.levels.iter().enumerate() {
                levels.rms_ddbfs[i] = *rms;
                levels.dc_ddbfs[i] = *dc;
            }
        }
        Ok(health)
    }

    /// The per-microphone levels, when they are to be sent.
    pub(crate) fn mic_report(&self) -> Option<HealthMics> {
        let n = usize::from(self.mic_levels.count).min(MAX_MICS);
        (n > 0).then(|| HealthMics {
            levels: (0..n)
                .map(|i| [self.mic_levels.rms_ddbfs[i], self.mic_levels.dc_ddbfs[i]])
                .collect(),
        })
    }
}

/// Drone-identification features of one BPF analysis window (aim-dsp `idframe`: 0.512 s at
/// 8 kHz, one per `mfcc_interval` analyses; default one per 2048 decimated samples, 3.9/s, the
/// same windows as the `Peaks` frames). The header's sample index is where the window starts.
/// The host's drone classifier reads these numbers as they are (`aim id`, `aim track`), so a
/// model trained on simulated recordings run through the same pipeline sees the same values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Mfcc {
    /// Input-rate samples covered by the analysis window.
    pub span_samples: u32,
    /// Mel band energies, units of 0.01 dB relative to a full-scale sine at the band's centre
    /// (±327.67 dB), [`MFCC_MEL_BANDS`] bands from 60 Hz to 3.5 kHz.
    pub log_mel_cdb: [i16; MFCC_MEL_BANDS],
    /// MFCC c0..c12 (orthonormal DCT-II of the log-mel vector), units of 0.1 dB (±3276.7 dB).
    pub mfcc_ddb: [i16; MFCC_COEFFS],
    /// Comb features: `log2(f0 / 250 Hz)` in units of 0.001 octave, then salience, half-way
    /// level, third-way level and harmonics 2..=6 relative to the first, units of 0.01 dB.
    pub harmonic: [i16; MFCC_HARMONIC],
    /// The same comb features for the strongest comb that is not the first source's (aim-dsp
    /// `IdFeatures::second`: outside the rotor cluster of the first fundamental's octaves and
    /// off its harmonics and shaft lines), same units; all 0 when no candidate was left.
    /// Appended: `None` in frames of older firmware, which did not compute it.
    pub second_harmonic: Option<[i16; MFCC_HARMONIC]>,
}

/// The fields of [`Mfcc`] before the appended ones: what older frames carry.
#[derive(Deserialize)]
struct MfccBase {
    span_samples: u32,
    log_mel_cdb: [i16; MFCC_MEL_BANDS],
    mfcc_ddb: [i16; MFCC_COEFFS],
    harmonic: [i16; MFCC_HARMONIC],
}

/// The appended fields of [`Mfcc`].
#[derive(Deserialize)]
struct MfccAppended {
    second_harmonic: Option<[i16; MFCC_HARMONIC]>,
}

impl Mfcc {
    /// Decodes a payload; the appended second comb is `None` when absent (older firmware).
    pub(crate) fn from_payload(payload: &[u8]) -> postcard::Result<Mfcc> {
        let (base, appended, _) = base_and_appended::<MfccBase, MfccAppended>(payload)?;
        Ok(Mfcc {
            span_samples: base.span_samples,
            log_mel_cdb: base.log_mel_cdb,
            mfcc_ddb: base.mfcc_ddb,
            harmonic: base.harmonic,
            second_harmonic: appended.and_then(|a| a.second_harmonic),
        })
    }

    /// Log-mel band `b`, dB.
    pub fn log_mel_db(&self, b: usize) -> f32 {
        f32::from(self.log_mel_cdb[b]) * 0.01
    }

    /// MFCC `c`, dB.
    pub fn mfcc_db(&self, c: usize) -> f32 {
        f32::from(self.mfcc_ddb[c]) * 0.1
    }

    /// The comb features in physical units: `log2(f0 / 250 Hz)` (octaves), then dB.
    pub fn harmonic_values(&self) -> [f32; MFCC_HARMONIC] {
        comb_values(&self.harmonic)
    }

    /// The second comb's features in physical units, as [`Mfcc::harmonic_values`]; `None`
    /// from older firmware.
    pub fn second_harmonic_values(&self) -> Option<[f32; MFCC_HARMONIC]> {
        self.second_harmonic.as_ref().map(comb_values)
    }
}

/// Comb features from their wire units: `log2(f0 / 250 Hz)` in 0.001 octave, then 0.01 dB.
fn comb_values(q: &[i16; MFCC_HARMONIC]) -> [f32; MFCC_HARMONIC] {
    let mut v = [0.0f32; MFCC_HARMONIC];
    for (i, (o, &q)) in v.iter_mut().zip(q).enumerate() {
        *o = f32::from(q) * if i == 0 { 0.001 } else { 0.01 };
    }
    v
}

/// One arrival of the synchronisation beacon (aim-dsp `beacon`, sequence `aim-beacon-v1`), at
/// most one per emission (default one per second). The header's sample index is the integer
/// part of the arrival: the input-clock sample (48 kHz) at which the emission's first sample
/// reached the array's microphone 0 (slot 0; its position is in [`Hello`] and the site file);
/// the arrival is `sample_index + fraction / 65536` samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Beacon {
    /// Sub-sample part of the arrival, units of 1/65536 sample (resolution 0.3 ns at 48 kHz).
    pub fraction: u16,
    /// Normalised correlation of the received window with the beacon template, units of 1/255
    /// (0–1; the chip reports only ≥ 0.4).
    pub quality: u8,
    /// Received peak amplitude of the beacon at microphone 0, units of 0.01 dB re full scale.
    pub level_cdb: i16,
}

impl Beacon {
    /// Quantises a fraction of a sample in [0, 1), a quality in [0, 1] and a level in dBFS.
    pub fn new(fraction: f32, quality: f32, level_db: f32) -> Self {
        Beacon {
            // Rounding may reach 65536: saturate just below 1.
            fraction: fixed::to_u32(fraction, 65_536.0).min(u32::from(u16::MAX)) as u16,
            quality: fixed::to_u8(quality, 255.0),
            level_cdb: fixed::to_i16(level_db, 100.0),
        }
    }

    /// The sub-sample part of the arrival, samples, in [0, 1).
    pub fn fraction_samples(&self) -> f64 {
        f64::from(self.fraction) / 65_536.0
    }

    /// The arrival in samples of the board's input clock, given the header's sample index.
    pub fn arrival_samples(&self, sample_index: u64) -> f64 {
        sample_index as f64 + self.fraction_samples()
    }

    /// Quality in [0, 1].
    pub fn quality_f32(&self) -> f32 {
        f32::from(self.quality) / 255.0
    }

    /// Received level, dB re full scale.
    pub fn level_db(&self) -> f32 {
        f32::from(self.level_cdb) / 100.0
    }
}

/// 32 ms of one array's sound for inter-array delays (`ALGORITHMS.md` §9): the mean of all
/// microphones, low-passed at 3.5 kHz and decimated to 8 kHz on the chip (aim-dsp
/// `snippet`), as a contiguous stream (31.25 frames per second; a gap in the capture drops the
/// frames that would span it). The header's sample index is the input-rate sample of
/// `samples[0]`; sample `j` was taken at `sample_index + j · decimation`, and its content lags
/// that by the chip's filters (45 input samples at 48 kHz, the same on every array).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Snippet {
    /// Input samples per snippet sample (6 at 48 kHz, 2 at 16 kHz: 8 kHz snippets).
    pub decimation: u8,
    /// Block exponent: sample `j` is `samples[j] · 2^exponent` of microphone full scale.
    pub exponent: i8,
    /// Mantissas, −127..=127, at most [`SNIPPET_SAMPLES`] (always that many from the chip).
    pub samples: heapless::Vec<i8, SNIPPET_SAMPLES>,
}

impl Snippet {
    /// `2^exponent`: the value of one mantissa step, fraction of full scale.
    pub fn step(&self) -> f64 {
        // Every i8 exponent is a normal f64: build the power of two from its bits.
        f64::from_bits(((1023 + i64::from(self.exponent)) as u64) << 52)
    }

    /// Sample `j` as a fraction of microphone full scale (0 past the end).
    pub fn value(&self, j: usize) -> f64 {
        f64::from(self.samples.get(j).copied().unwrap_or(0)) * self.step()
    }

    /// Sample rate of the snippet for the array's input rate (`Hello::sample_rate_hz`), Hz.
    pub fn rate_hz(&self, input_rate_hz: u32) -> f64 {
        f64::from(input_rate_hz) / f64::from(self.decimation.max(1))
    }
}
