//! Frame encoding: header, postcard payload, CRC-32, COBS, delimiters.

use crate::frame::{Body, Frame, Header};
use crate::{cobs, crc32, CRC_LEN, FIXED_HEADER_LEN, MAGIC, MAX_RAW_LEN, PROTOCOL_VERSION};

/// Why a frame could not be encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EncodeError {
    /// The output buffer is shorter than the frame needs ([`crate::MAX_ENCODED_LEN`] always
    /// suffices).
    BufferTooSmall {
        /// Bytes the worst case of this frame needs.
        needed: usize,
        /// Bytes the buffer has.
        available: usize,
    },
    /// The payload did not serialise (cannot happen for the kinds of this version; kept so the
    /// encoder never panics).
    Payload,
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            EncodeError::BufferTooSmall { needed, available } => write!(
                f,
                "output buffer too small for the frame: {available} bytes, {needed} needed"
            ),
            EncodeError::Payload => f.write_str("frame payload did not serialise"),
        }
    }
}

/// Encodes `frame` into `out` as it goes on the wire (`0x00`, COBS bytes, `0x00`); returns the
/// number of bytes written. Uses [`crate::MAX_RAW_LEN`] bytes of stack.
pub fn encode(frame: &Frame, out: &mut [u8]) -> Result<usize, EncodeError> {
    let mut raw = [0u8; MAX_RAW_LEN];
    let raw_len = encode_raw(frame, &mut raw)?;
    let needed = 2 + cobs::max_encoded_len(raw_len);
    if out.len() < needed {
        return Err(EncodeError::BufferTooSmall { needed, available: out.len() });
    }
    out[0] = 0;
    let cobs_len = cobs::encode(&raw[..raw_len], &mut out[1..]).ok_or(EncodeError::Payload)?;
    out[1 + cobs_len] = 0;
    Ok(cobs_len + 2)
}

/// Writes header, payload and CRC (no COBS) into `raw`; returns their length.
fn encode_raw(frame: &Frame, raw: &mut [u8; MAX_RAW_LEN]) -> Result<usize, EncodeError> {
    let Header { array_id, seq, sample_index } = frame.header;
    let [seq_lo, seq_hi] = seq.to_le_bytes();
    raw[..FIXED_HEADER_LEN].copy_from_slice(&[
        MAGIC,
        PROTOCOL_VERSION,
        frame.body.kind().byte(),
        array_id,
        seq_lo,
        seq_hi,
    ]);
    let mut at = FIXED_HEADER_LEN;
    at +=
        postcard::to_slice(&sample_index, &mut raw[at..]).map_err(|_| EncodeError::Payload)?.len();
    // Leave room for the CRC so a payload can never run into it.
    let payload_room = raw.len() - CRC_LEN;
    let payload = &mut raw[at..payload_room];
    let written = match &frame.body {
        Body::Hello(p) => postcard::to_slice(p, payload).map(|s| s.len()).and_then(|n| {
            // The chip and clock report is appended only when set (see `Hello::chip_revision`).
            match p.clock_report() {
                Some(clock) => postcard::to_slice(&clock, &mut payload[n..]).map(|s| n + s.len()),
                None => Ok(n),
            }
        }),
        Body::Doa(p) => postcard::to_slice(p, payload).map(|s| s.len()),
        Body::Peaks(p) => postcard::to_slice(p, payload).map(|s| s.len()),
        Body::Mfcc(p) => postcard::to_slice(p, payload).map(|s| s.len()),
        Body::Beacon(p) => postcard::to_slice(p, payload).map(|s| s.len()),
        Body::Snippet(p) => postcard::to_slice(p, payload).map(|s| s.len()),
        Body::Health(p) => postcard::to_slice(p, payload).map(|s| s.len()).and_then(|n| {
            // The microphone levels are appended only when there are any.
            match p.mic_report() {
                Some(mics) => postcard::to_slice(&mics, &mut payload[n..]).map(|s| n + s.len()),
                None => Ok(n),
            }
        }),
    }
    .map_err(|_| EncodeError::Payload)?;
    at += written;
    let crc = crc32(&raw[..at]);
    raw[at..at + CRC_LEN].copy_from_slice(&crc.to_le_bytes());
    Ok(at + CRC_LEN)
}

/// Stamps frames of one array with consecutive sequence numbers and encodes them: what the
/// firmware (and the simulator, to produce the same bytes) holds per array.
#[derive(Debug, Clone)]
pub struct Encoder {
    array_id: u8,
    next_seq: u16,
}

impl Encoder {
    /// An encoder for array `array_id` whose first frame has sequence number 0.
    pub const fn new(array_id: u8) -> Self {
        Encoder { array_id, next_seq: 0 }
    }

    /// The sequence number the next frame will carry.
    pub const fn next_seq(&self) -> u16 {
        self.next_seq
    }

    /// The frame that [`Encoder::encode`] would write next, without consuming a sequence number.
    pub fn frame(&self, sample_index: u64, body: Body) -> Frame {
        Frame { header: Header { array_id: self.array_id, seq: self.next_seq, sample_index }, body }
    }

    /// Encodes `body` with the next sequence number into `out`; returns the bytes written.
    /// The sequence number advances only when the frame was written, so a frame that could not
    /// be encoded leaves no gap.
    pub fn encode(
        &mut self,
        sample_index: u64,
        body: Body,
        out: &mut [u8],
    ) -> Result<usize, EncodeError> {
        let n = encode(&self.frame(sample_index, body), out)?;
        self.next_seq = self.next_seq.wrapping_add(1);
        Ok(n)
    }
}
