//! AIM frame format: what an array board sends to the host, and how the host gets it back.
//!
//! Shared by the firmware (encoding) and the host (decoding); `no_std`, no allocation: encoding
//! writes into the caller's buffer, the [`Deframer`] keeps one fixed buffer.
//!
//! # A frame
//!
//! ```text
//! wire:  0x00 | COBS(raw) | 0x00          both delimiters; empty frames (0x00 0x00) are ignored
//!
//! raw:   0      1        2      3        4        6                   6+v          len-4     len
//!        +------+--------+------+--------+--------+-------------------+------------+---------+
//!        | 0xA1 | 0x01   | kind | array  | seq    | sample index      | payload    | CRC-32  |
//!        | magic| version| u8   | id u8  | u16 LE | LEB128 u64, v B   | postcard   | u32 LE  |
//!        +------+--------+------+--------+--------+-------------------+------------+---------+
//!        \___________________ header: 7..=16 bytes ___________________/
//! ```
//!
//! * **COBS** ([`cobs`]) removes every `0x00` from `raw`, so `0x00` marks frame boundaries and a
//!   receiver that starts mid-stream, or loses bytes, resynchronises at the next `0x00`. The
//!   sender puts a delimiter on both sides of every frame: line noise between two frames is
//!   then cut off from both, and costs nothing but itself.
//! * **CRC-32** is CRC-32/ISO-HDLC (the IEEE 802.3 / zlib CRC, check value `0xCBF43926`;
//!   [`crc32`]) over every raw byte before it, appended little-endian.
//! * **Header**: magic `0xA1`, protocol version, kind byte ([`Kind`]), array id, per-array
//!   sequence number (wrapping `u16`), and the sample index of the first sample of the block the
//!   frame describes, in the array's own clock, as a postcard varint (LEB128).
//! * **Payload**: the postcard encoding of the kind's struct ([`Hello`], [`Doa`], [`Peaks`],
//!   [`Health`]). Integers are varints (zig-zag for signed), `u8` is one raw byte.
//!
//! # Field resolution
//!
//! | field | type | unit | range |
//! |---|---|---|---|
//! | `Doa::azimuth_cdeg` | i16 | 0.01° | ±180° |
//! | `Doa::zenith_cdeg` | u16 | 0.01° | 0–180° |
//! | `Doa::residual_csamples` | u16 | 0.01 sample | 0–655.35 |
//! | `Doa::quality`, `Peak::harmonicity` | u8 | 1/255 | 0–1 |
//! | `Peaks::bpf_chz`, `Peak::freq_chz` | u32 | 0.01 Hz | 0–42.9 MHz |
//! | `Peak::amplitude_ddb` | i16 | 0.1 dB | ±3276.7 dB |
//! | `Hello::mic_positions_decimm` | i16 | 0.1 mm | ±3.2767 m |
//! | `Health::peak_ddbfs` | i16 | 0.1 dB | ±3276.7 dBFS |
//! | `Mfcc::log_mel_cdb`, `Mfcc::harmonic[1..]`, `Mfcc::second_harmonic[1..]` | i16 | 0.01 dB | ±327.67 dB |
//! | `Mfcc::mfcc_ddb` | i16 | 0.1 dB | ±3276.7 dB |
//! | `Mfcc::harmonic[0]`, `Mfcc::second_harmonic[0]` (`log2(f0 / 250 Hz)`) | i16 | 0.001 octave | ±32.767 octaves |
//! | `Beacon::fraction` | u16 | 1/65536 sample | 0–1 sample |
//! | `Beacon::quality` | u8 | 1/255 | 0–1 |
//! | `Beacon::level_cdb` | i16 | 0.01 dB | ±327.67 dBFS |
//! | `Snippet::samples` | i8 | `2^exponent` of full scale | −127..=127 |
//! | `span_samples`, `sample_rate_hz`, counters | u32 | 1 | exact |
//! | `Hello::reset_cause` | u8 | [`ResetCause`] code | 0–9 known |
//! | `Hello::unique_id` | 12 × u8 | chip unique ID bytes | all zero: not reported |
//! | `Hello::panic_message` | UTF-8 string | ≤ [`MAX_PANIC_MESSAGE`] bytes | empty: none |
//! | `Hello::chip_revision` | u16 | silicon revision (STM32 REV_ID) | 0: not reported |
//! | `Hello::clock_source` | u8 | [`ClockSource`] code | 0–2 known |
//! | `Hello::sysclk_hz` | u32 | core clock, Hz | 0: not reported |
//! | header `sample_index` | u64 | 1 sample | exact (LEB128 at 48 kHz: 3 bytes to 43 s, 4 to 93 min, 5 to 8 days) |
//!
//! Quantisation rounds half away from zero and saturates ([`Doa::new`], [`Peak::new`], …).
//!
//! # Compatibility rules
//!
//! 1. **The envelope never changes**: delimiters, COBS, the positions of magic, version and
//!    kind, and the CRC trailer. Any host can therefore tell a damaged frame (CRC error) from a
//!    frame it does not understand.
//! 2. **Kind bytes are pinned** ([`Kind`] discriminants, [`reserved`]) and never reused. A host
//!    that meets an unknown kind counts it ([`LinkStats::unknown_kinds`]) and skips it; its
//!    sequence number still counts, so it is not mistaken for a lost frame.
//! 3. **Payloads grow only at the end**, within one protocol version. A decoder ignores
//!    trailing payload bytes it does not know; a decoder that knows a field added later must
//!    accept the payload without it (the field defaults).
//! 4. **Anything else** (reordering, removing or retyping a field, changing a unit, changing the
//!    header) is a breaking change and bumps [`PROTOCOL_VERSION`]. Hosts skip and count frames
//!    of other versions ([`LinkStats::unknown_versions`]).
//!
//! Golden byte snapshots of every kind live in `wire/tests/golden/`; `AIM_WIRE_BLESS=1 cargo
//! test -p aim-wire --test format` rewrites them after an intended change (which rule 4 says is
//! a version bump unless it only appends).
//!
//! # Example
//!
//! ```
//! use aim_wire::{encode, Body, Deframer, Doa, Frame, Header, Kind, MAX_ENCODED_LEN};
//!
//! let frame = Frame {
//!     header: Header { array_id: 2, seq: 7, sample_index: 48_000 },
//!     body: Body::Doa(Doa::new(0.5, 1.2, 0.3, 0.9)),
//! };
//! let mut wire = [0u8; MAX_ENCODED_LEN];
//! let n = encode(&frame, &mut wire).unwrap();
//! assert!(n <= Kind::Doa.max_encoded_len());
//!
//! let mut deframer: Deframer = Deframer::new();
//! let decoded: Vec<_> = deframer.feed(&wire[..n]).collect();
//! assert_eq!(decoded, [Ok(frame)]);
//! assert_eq!(deframer.stats().frames, 1);
//! ```
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod cobs;
mod crc32;
mod deframe;
mod encode;
pub mod fixed;
mod frame;
#[cfg(feature = "dsp")]
pub mod from_dsp;

pub use crc32::crc32;
pub use deframe::{decode, DecodeError, Deframer, Feed, LinkStats, DEFAULT_CAPACITY};
pub use encode::{encode, EncodeError, Encoder};
pub use frame::{
    derived_array_id, reserved, stm32h7_revision_name, Beacon, Body, ClockSource, Detection, Doa,
    Frame, Header, Health, Hello, Kind, Mfcc, MicLevels, Peak, Peaks, ResetCause, Snippet,
    MAX_MICS, MAX_PANIC_MESSAGE, MAX_PEAKS, MFCC_COEFFS, MFCC_HARMONIC, MFCC_MEL_BANDS,
    SNIPPET_SAMPLES, UNIQUE_ID_LEN,
};

/// First byte of every raw frame.
pub const MAGIC: u8 = 0xA1;
/// Protocol version this crate writes and reads (bumped only for breaking changes).
pub const PROTOCOL_VERSION: u8 = 1;
/// Bytes of the fixed part of the header: magic, version, kind, array id, sequence number.
pub const FIXED_HEADER_LEN: usize = 6;
/// Largest header: the fixed part and a 10-byte varint sample index.
pub const MAX_HEADER_LEN: usize = FIXED_HEADER_LEN + 10;
/// Bytes of the CRC-32 trailer.
pub const CRC_LEN: usize = 4;
/// Smallest valid raw frame: fixed header, 1-byte sample index, empty payload, CRC.
pub const MIN_RAW_LEN: usize = FIXED_HEADER_LEN + 1 + CRC_LEN;

const fn max_raw_len() -> usize {
    let mut max = 0;
    let mut i = 0;
    while i < Kind::ALL.len() {
        let n = Kind::ALL[i].max_raw_len();
        if n > max {
            max = n;
        }
        i += 1;
    }
    max
}

/// Largest raw frame (before COBS) of any kind this version writes, bytes.
pub const MAX_RAW_LEN: usize = max_raw_len();
/// Largest frame on the wire of any kind this version writes, bytes: a buffer this long always
/// fits [`encode`]'s output.
pub const MAX_ENCODED_LEN: usize = 2 + cobs::max_encoded_len(MAX_RAW_LEN);
