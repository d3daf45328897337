//! The board's array configuration, in one place: which microphones, which array, which rates.
//!
//! Everything the host must know about this array (its id, geometry, sample rate, firmware
//! version) is taken from here and reported in the `Hello` frame, so a host never has to guess
//! how a board was built.
//!
//! - Geometry: one cargo feature, `mics-8` (default, 8-mic circle), `mics-6` (ReSpeaker 6-mic
//!   circle) or `mics-4` (ReSpeaker 4-mic square).
//! - Array id: at run time, derived from the chip's unique ID ([`array_id`],
//!   `aim_wire::derived_array_id`), so one image serves every board; `aim frames` shows each
//!   board's id and unique ID for the site file. `AIM_ARRAY_ID` at build time (decimal,
//!   0..=255) overrides it, for a board whose derived id collides with another's.

#[cfg(not(any(feature = "mics-8", feature = "mics-6", feature = "mics-4")))]
compile_error!("choose the array: enable one of the features `mics-8`, `mics-6`, `mics-4`");
#[cfg(any(
    all(feature = "mics-8", feature = "mics-6"),
    all(feature = "mics-8", feature = "mics-4"),
    all(feature = "mics-6", feature = "mics-4"),
))]
compile_error!("enable exactly one of `mics-8`, `mics-6`, `mics-4` (use --no-default-features)");

/// The array id set at build time (`AIM_ARRAY_ID`), if any.
pub const BUILD_ARRAY_ID: Option<u8> = match option_env!("AIM_ARRAY_ID") {
    Some(text) => Some(parse_array_id(text)),
    None => None,
};

/// The array id in every frame header: [`BUILD_ARRAY_ID`] if set, else derived from the chip's
/// unique ID (1..=255, `aim_wire::derived_array_id`).
///
/// Why derived rather than stored in flash and set over the serial link: the link is
/// transmit-only today, a flash write needs its own sector (128 KB on this part) and a
/// command protocol, and a stored id can be lost or copied with an image; the unique ID comes
/// with the silicon, needs no state, and the host can map it (the site file's unique IDs give
/// the ids the boards will send). A collision (1 in 255 per pair of boards) is reported by the
/// host, which sees two unique IDs under one id; that board then gets `AIM_ARRAY_ID`.
pub fn array_id(unique_id: &[u8; aim_wire::UNIQUE_ID_LEN]) -> u8 {
    match BUILD_ARRAY_ID {
        Some(id) => id,
        None => aim_wire::derived_array_id(unique_id),
    }
}

/// Number of microphones; microphone `i` is TDM slot `i`.
#[cfg(feature = "mics-8")]
pub const MIC_COUNT: usize = 8;
/// Number of microphones; microphone `i` is TDM slot `i`.
#[cfg(all(feature = "mics-6", not(feature = "mics-8")))]
pub const MIC_COUNT: usize = 6;
/// Number of microphones; microphone `i` is TDM slot `i`.
#[cfg(all(feature = "mics-4", not(any(feature = "mics-8", feature = "mics-6"))))]
pub const MIC_COUNT: usize = 4;

/// The array geometry (microphone positions in metres, array frame) for the DSP and `Hello`.
pub fn geometry() -> aim_dsp::Geometry {
    #[cfg(feature = "mics-8")]
    return aim_dsp::Geometry::circle_8mic();
    #[cfg(all(feature = "mics-6", not(feature = "mics-8")))]
    return aim_dsp::Geometry::respeaker_6mic();
    #[cfg(all(feature = "mics-4", not(any(feature = "mics-8", feature = "mics-6"))))]
    return aim_dsp::Geometry::respeaker_4mic();
}

/// Audio sample rate, Hz (exact: see `clocks`).
pub const SAMPLE_RATE_HZ: u32 = 48_000;
/// TDM slots per frame on SAI1 block A (always 8; unused slots carry no microphone).
pub const TDM_SLOTS: usize = 8;
/// Bits per TDM slot.
pub const SLOT_BITS: u32 = 32;

/// Audio frames (one word per slot) per capture chunk, i.e. per DMA half-buffer: 5.33 ms.
///
/// The DSP block (1024 frames) is assembled by the `Pipeline` from several chunks; small chunks
/// keep the DMA ring small and let the capture queue absorb the long FFT work of a block.
pub const CHUNK_FRAMES: usize = 256;
/// 32-bit words per capture chunk.
pub const CHUNK_WORDS: usize = CHUNK_FRAMES * TDM_SLOTS;
/// Chunks the capture task can queue for the DSP task: 8 × 5.33 ms = 42.7 ms, two DSP blocks.
///
/// The DSP load is bursty: every `average_blocks`-th block also averages the cross spectra and
/// estimates a direction, and that one push can take longer than a chunk period. The queue
/// absorbs it (64 KB of AXI SRAM); `tests/hil` `dsp_time` checks the longest push fits.
pub const CAPTURE_QUEUE_CHUNKS: usize = 8;

/// Uplink baud rate on USART3 (the ST-LINK virtual COM port).
pub const UPLINK_BAUD: u32 = 921_600;
/// Encoded frames the uplink queue holds; when full, the oldest is dropped and counted.
pub const UPLINK_QUEUE_FRAMES: usize = 16;
/// A `Hello` frame is repeated every this many samples of the array clock (5 s), so a host that
/// attaches late learns the geometry.
pub const HELLO_INTERVAL_SAMPLES: u64 = 5 * SAMPLE_RATE_HZ as u64;
/// A firmware `Health` frame is sent every this many samples of the array clock (1 s).
pub const HEALTH_INTERVAL_SAMPLES: u64 = SAMPLE_RATE_HZ as u64;

/// Independent watchdog timeout, µs. The DSP loop feeds it once per chunk (every 5.33 ms);
/// 500 ms survives a long block with margin and still resets a hung loop quickly.
pub const WATCHDOG_TIMEOUT_US: u32 = 500_000;

/// Firmware version reported in `Hello`: (major, minor, patch) of this crate.
pub const FIRMWARE_VERSION: (u8, u8, u8) = (
    parse_u8(env!("CARGO_PKG_VERSION_MAJOR")),
    parse_u8(env!("CARGO_PKG_VERSION_MINOR")),
    parse_u8(env!("CARGO_PKG_VERSION_PATCH")),
);

const fn parse_array_id(text: &str) -> u8 {
    let bytes = text.as_bytes();
    if bytes.is_empty() {
        panic!("AIM_ARRAY_ID is empty: give a decimal number 0..=255");
    }
    parse_u8(text)
}

/// Parses a decimal `u8` at compile time; a bad value stops the build with a message.
const fn parse_u8(text: &str) -> u8 {
    let bytes = text.as_bytes();
    let mut value: u32 = 0;
    let mut i = 0;
    while i < bytes.len() {
        let digit = bytes[i];
        if !digit.is_ascii_digit() {
            panic!("not a decimal number (AIM_ARRAY_ID or the crate version)");
        }
        value = value * 10 + (digit - b'0') as u32;
        if value > 255 {
            panic!("number out of range 0..=255 (AIM_ARRAY_ID or the crate version)");
        }
        i += 1;
    }
    value as u8
}

const _: () = assert!(MIC_COUNT <= TDM_SLOTS);
const _: () = assert!(CHUNK_FRAMES.is_power_of_two());
