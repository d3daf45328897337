//! The streaming deframer: bytes in, frames and link statistics out, never a panic.

use crate::cobs::{self, CobsError};
use crate::frame::{Body, Frame, Header, Kind};
use crate::{crc32, CRC_LEN, FIXED_HEADER_LEN, MAGIC, MIN_RAW_LEN, PROTOCOL_VERSION};

/// Default capacity of a [`Deframer`]'s buffer, bytes of COBS data per frame. Larger than any
/// frame of this version ([`crate::MAX_ENCODED_LEN`]) to leave room for larger kinds of later
/// versions (which it then counts as unknown kinds rather than oversize frames).
pub const DEFAULT_CAPACITY: usize = 512;

/// Why a chunk of the byte stream between two delimiters did not yield a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DecodeError {
    /// More bytes than the deframer's capacity arrived without a delimiter.
    Oversize,
    /// The bytes are not valid COBS.
    Framing(CobsError),
    /// Shorter than the smallest frame ([`crate::MIN_RAW_LEN`] bytes after COBS).
    TooShort(usize),
    /// The CRC-32 trailer does not match the bytes before it.
    Crc {
        /// The CRC in the trailer.
        received: u32,
        /// The CRC of the received bytes.
        computed: u32,
    },
    /// The CRC matched but the first byte is not [`crate::MAGIC`]: not an AIM frame.
    BadMagic(u8),
    /// A protocol version this crate does not read.
    UnknownVersion(u8),
    /// A kind byte this version does not know (from newer firmware): skipped.
    UnknownKind(u8),
    /// The header's sample index or the payload does not decode.
    Payload(Option<Kind>),
    /// The stream ended inside a frame.
    Truncated,
}

impl core::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DecodeError::Oversize => f.write_str("frame longer than the deframer buffer"),
            DecodeError::Framing(CobsError::ZeroCode) => f.write_str("COBS code byte of zero"),
            DecodeError::Framing(CobsError::Truncated) => f.write_str("COBS run past the end"),
            DecodeError::TooShort(n) => write!(f, "frame of {n} bytes is too short"),
            DecodeError::Crc { received, computed } => {
                write!(f, "CRC mismatch: trailer {received:#010x}, computed {computed:#010x}")
            }
            DecodeError::BadMagic(m) => write!(f, "bad magic byte {m:#04x}"),
            DecodeError::UnknownVersion(v) => write!(f, "unknown protocol version {v}"),
            DecodeError::UnknownKind(k) => write!(f, "unknown frame kind {k}"),
            DecodeError::Payload(Some(k)) => write!(f, "{} payload does not decode", k.name()),
            DecodeError::Payload(None) => f.write_str("header does not decode"),
            DecodeError::Truncated => f.write_str("stream ended inside a frame"),
        }
    }
}

/// Counters of everything a [`Deframer`] has seen. Every chunk between delimiters lands in
/// exactly one of `frames` or an error counter; `seq_gaps`/`frames_missed` and `seq_resets`
/// come on top.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkStats {
    /// Bytes fed in.
    pub bytes: u64,
    /// Frames decoded.
    pub frames: u64,
    /// Frames decoded, per kind, in [`Kind::ALL`] order.
    pub frames_by_kind: [u64; Kind::ALL.len()],
    /// Frames whose CRC did not match (line errors).
    pub crc_errors: u64,
    /// Chunks that were not valid COBS or too short to be a frame (line errors, mostly).
    pub framing_errors: u64,
    /// Chunks longer than the deframer buffer.
    pub oversize: u64,
    /// Frames of a protocol version this host does not read.
    pub unknown_versions: u64,
    /// Frames of a kind this host does not know (skipped, see the compatibility rules).
    pub unknown_kinds: u64,
    /// Frames with a valid CRC that still did not decode (bad magic, bad payload).
    pub malformed: u64,
    /// A frame cut off by the end of the stream.
    pub truncated: u64,
    /// Times the sequence number of an array jumped forward by more than one.
    pub seq_gaps: u64,
    /// Frames missing according to those jumps.
    pub frames_missed: u64,
    /// Times the sequence number repeated or went backwards (an array restart, most likely;
    /// jumps of 2^15 or more count here too).
    pub seq_resets: u64,
}

impl LinkStats {
    /// Chunks that did not yield a frame, all causes together.
    pub fn errors(&self) -> u64 {
        self.crc_errors
            + self.framing_errors
            + self.oversize
            + self.unknown_versions
            + self.unknown_kinds
            + self.malformed
            + self.truncated
    }

    fn count(&mut self, result: &Result<Frame, DecodeError>) {
        match result {
            Ok(frame) => {
                self.frames += 1;
                let kind = frame.body.kind();
                let k = Kind::ALL.iter().position(|&x| x == kind);
                if let Some(n) = k.and_then(|k| self.frames_by_kind.get_mut(k)) {
                    *n += 1;
                }
            }
            Err(DecodeError::Oversize) => self.oversize += 1,
            Err(DecodeError::Framing(_) | DecodeError::TooShort(_)) => self.framing_errors += 1,
            Err(DecodeError::Crc { .. }) => self.crc_errors += 1,
            Err(DecodeError::BadMagic(_) | DecodeError::Payload(_)) => self.malformed += 1,
            Err(DecodeError::UnknownVersion(_)) => self.unknown_versions += 1,
            Err(DecodeError::UnknownKind(_)) => self.unknown_kinds += 1,
            Err(DecodeError::Truncated) => self.truncated += 1,
        }
    }
}

/// Checks and splits a raw frame (after COBS): returns the kind byte, the header and the
/// payload bytes. The envelope checks of every version: length, CRC, magic, version.
fn open_envelope(raw: &[u8]) -> Result<(u8, Header, &[u8]), DecodeError> {
    if raw.len() < MIN_RAW_LEN {
        return Err(DecodeError::TooShort(raw.len()));
    }
    let (body, trailer) = raw.split_at(raw.len() - CRC_LEN);
    let received = u32::from_le_bytes([trailer[0], trailer[1], trailer[2], trailer[3]]);
    let computed = crc32(body);
    if received != computed {
        return Err(DecodeError::Crc { received, computed });
    }
    let (fixed, rest) = body.split_at(FIXED_HEADER_LEN);
    if fixed[0] != MAGIC {
        return Err(DecodeError::BadMagic(fixed[0]));
    }
    if fixed[1] != PROTOCOL_VERSION {
        return Err(DecodeError::UnknownVersion(fixed[1]));
    }
    let (sample_index, payload) =
        postcard::take_from_bytes::<u64>(rest).map_err(|_| DecodeError::Payload(None))?;
    let header =
        Header { array_id: fixed[3], seq: u16::from_le_bytes([fixed[4], fixed[5]]), sample_index };
    Ok((fixed[2], header, payload))
}

/// Decodes a payload of a known kind. Trailing bytes are fields appended by a later firmware
/// (compatibility rule 3) and are ignored.
fn decode_body(kind: Kind, payload: &[u8]) -> Result<Body, DecodeError> {
    let err = |_| DecodeError::Payload(Some(kind));
    Ok(match kind {
        Kind::Hello => Body::Hello(crate::Hello::from_payload(payload).map_err(err)?),
        Kind::Doa => Body::Doa(postcard::take_from_bytes(payload).map_err(err)?.0),
        Kind::Peaks => Body::Peaks(crate::Peaks::from_payload(payload).map_err(err)?),
        Kind::Health => Body::Health(crate::Health::from_payload(payload).map_err(err)?),
        Kind::Mfcc => Body::Mfcc(crate::Mfcc::from_payload(payload).map_err(err)?),
        Kind::Beacon => Body::Beacon(postcard::take_from_bytes(payload).map_err(err)?.0),
        Kind::Snippet => Body::Snippet(postcard::take_from_bytes(payload).map_err(err)?.0),
    })
}

/// Decodes one raw frame (COBS already removed, no delimiters). Stateless: no statistics, no
/// sequence tracking; the [`Deframer`] adds those.
pub fn decode(raw: &[u8]) -> Result<Frame, DecodeError> {
    let (kind, header, payload) = open_envelope(raw)?;
    let kind = Kind::from_byte(kind).ok_or(DecodeError::UnknownKind(kind))?;
    Ok(Frame { header, body: decode_body(kind, payload)? })
}

/// Turns a byte stream into frames. Holds one buffer of `N` bytes ([`DEFAULT_CAPACITY`] by
/// default) and never allocates or panics, whatever it is fed. After any damage it resumes at
/// the next `0x00`; what it could not decode it counts in [`LinkStats`].
///
/// Feed it bytes as they arrive, in any chunking: [`Deframer::push`] byte by byte, or
/// [`Deframer::feed`] for an iterator over a slice. Call [`Deframer::finish`] at the end of a
/// finite stream to count a frame cut off by the end.
#[derive(Debug, Clone)]
pub struct Deframer<const N: usize = DEFAULT_CAPACITY> {
    buf: [u8; N],
    len: usize,
    overflowed: bool,
    stats: LinkStats,
    /// Last sequence number seen per array id.
    last_seq: [Option<u16>; 256],
}

impl<const N: usize> Default for Deframer<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Deframer<N> {
    /// An empty deframer with zeroed statistics.
    pub const fn new() -> Self {
        Deframer {
            buf: [0; N],
            len: 0,
            overflowed: false,
            stats: LinkStats {
                bytes: 0,
                frames: 0,
                frames_by_kind: [0; Kind::ALL.len()],
                crc_errors: 0,
                framing_errors: 0,
                oversize: 0,
                unknown_versions: 0,
                unknown_kinds: 0,
                malformed: 0,
                truncated: 0,
                seq_gaps: 0,
                frames_missed: 0,
                seq_resets: 0,
            },
            last_seq: [None; 256],
        }
    }

    /// The statistics so far.
    pub fn stats(&self) -> &LinkStats {
        &self.stats
    }

    /// Takes one byte; returns the outcome of a chunk when `byte` is a delimiter that ends a
    /// non-empty one.
    pub fn push(&mut self, byte: u8) -> Option<Result<Frame, DecodeError>> {
        self.stats.bytes += 1;
        if byte != 0 {
            if self.len < N {
                self.buf[self.len] = byte;
                self.len += 1;
            } else {
                self.overflowed = true;
            }
            return None;
        }
        let result = if self.overflowed {
            Err(DecodeError::Oversize)
        } else if self.len == 0 {
            return None;
        } else {
            self.decode_chunk()
        };
        self.len = 0;
        self.overflowed = false;
        self.stats.count(&result);
        Some(result)
    }

    /// An iterator over the outcomes of the chunks that `bytes` completes.
    pub fn feed<'d, 'b>(&'d mut self, bytes: &'b [u8]) -> Feed<'d, 'b, N> {
        Feed { deframer: self, bytes }
    }

    /// Ends the stream: a partial chunk left in the buffer is counted as truncated (and
    /// returned as such). The deframer is then empty and can be fed again.
    pub fn finish(&mut self) -> Option<DecodeError> {
        if self.len == 0 && !self.overflowed {
            return None;
        }
        self.len = 0;
        self.overflowed = false;
        let result = Err(DecodeError::Truncated);
        self.stats.count(&result);
        result.err()
    }

    fn decode_chunk(&mut self) -> Result<Frame, DecodeError> {
        let chunk = &mut self.buf[..self.len];
        let raw_len = cobs::decode_in_place(chunk).map_err(DecodeError::Framing)?;
        let (kind, header, payload) = open_envelope(&chunk[..raw_len])?;
        // Every frame with a valid envelope counts in the sequence, known kind or not.
        track_seq(&mut self.last_seq, &mut self.stats, header);
        let kind = Kind::from_byte(kind).ok_or(DecodeError::UnknownKind(kind))?;
        Ok(Frame { header, body: decode_body(kind, payload)? })
    }
}

/// Updates the last sequence number of the frame's array and counts jumps.
fn track_seq(last_seq: &mut [Option<u16>; 256], stats: &mut LinkStats, header: Header) {
    let last = &mut last_seq[usize::from(header.array_id)];
    if let Some(prev) = *last {
        let step = header.seq.wrapping_sub(prev);
        if step == 0 || step >= 0x8000 {
            stats.seq_resets += 1;
        } else if step > 1 {
            stats.seq_gaps += 1;
            stats.frames_missed += u64::from(step - 1);
        }
    }
    *last = Some(header.seq);
}

/// Iterator returned by [`Deframer::feed`]: one item per chunk completed by the fed bytes.
#[derive(Debug)]
pub struct Feed<'d, 'b, const N: usize> {
    deframer: &'d mut Deframer<N>,
    bytes: &'b [u8],
}

impl<const N: usize> Iterator for Feed<'_, '_, N> {
    type Item = Result<Frame, DecodeError>;

    fn next(&mut self) -> Option<Self::Item> {
        while let Some((&byte, rest)) = self.bytes.split_first() {
            self.bytes = rest;
            if let Some(result) = self.deframer.push(byte) {
                return Some(result);
            }
        }
        None
    }
}
