//! Consistent Overhead Byte Stuffing (Cheshire & Baker, 1999).
//!
//! COBS rewrites a byte string so that it contains no `0x00`, which then delimits frames on the
//! link. The encoding costs one byte per started run of 254 bytes: an encoded string of `n` bytes
//! is at most [`max_encoded_len`]`(n)` long. This is the minimal variant (no trailing code byte
//! after a final run of exactly 254 non-zero bytes), byte for byte the same as the `cobs` crate.
//!
//! Hand-written rather than the `cobs` crate (0.5, no_std): the crate's streaming encoder made
//! the firmware 88 bytes smaller but the encode path 0.2 % more instructions on the Cortex-M4F
//! model (BENCHMARKS.md, "Wire: CRC-32 and COBS crates"); the crate stays the tests' oracle.

/// Why a byte string is not valid COBS.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CobsError {
    /// A code byte of zero: impossible in an encoded string (zeros are frame delimiters).
    ZeroCode,
    /// A code byte announces more bytes than are left.
    Truncated,
}

/// Upper bound of the COBS encoding of `n` bytes (without the `0x00` delimiter).
pub const fn max_encoded_len(n: usize) -> usize {
    n + n / 254 + 1
}

/// Encodes `src` into `dst`; returns the encoded length, or `None` if `dst` is too small.
/// The output contains no `0x00` and no delimiter.
pub fn encode(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    if dst.len() < max_encoded_len(src.len()) {
        return None;
    }
    let mut code_at = 0;
    let mut out = 1;
    let mut code: u8 = 1;
    for (i, &b) in src.iter().enumerate() {
        if b == 0 {
            dst[code_at] = code;
            code_at = out;
            out += 1;
            code = 1;
        } else {
            dst[out] = b;
            out += 1;
            code += 1;
            if code == 0xFF && i + 1 < src.len() {
                dst[code_at] = code;
                code_at = out;
                out += 1;
                code = 1;
            }
        }
    }
    dst[code_at] = code;
    Some(out)
}

/// Decodes the COBS string in `buf` in place; returns the decoded length (a prefix of `buf`).
///
/// Never panics: every index is checked against the length first. The write position never
/// overtakes the read position, so decoding in place is safe.
pub fn decode_in_place(buf: &mut [u8]) -> Result<usize, CobsError> {
    let len = buf.len();
    let mut read = 0;
    let mut write = 0;
    while read < len {
        let code = buf[read];
        if code == 0 {
            return Err(CobsError::ZeroCode);
        }
        read += 1;
        let run = usize::from(code - 1);
        if run > len - read {
            return Err(CobsError::Truncated);
        }
        buf.copy_within(read..read + run, write);
        write += run;
        read += run;
        if code != 0xFF && read < len {
            buf[write] = 0;
            write += 1;
        }
    }
    Ok(write)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roundtrip(src: &[u8]) -> Vec<u8> {
        let mut enc = vec![0u8; max_encoded_len(src.len())];
        let n = encode(src, &mut enc).unwrap();
        enc.truncate(n);
        assert!(!enc.contains(&0), "encoding of {src:?} contains a zero");
        let mut dec = enc.clone();
        let m = decode_in_place(&mut dec).unwrap();
        assert_eq!(&dec[..m], src);
        enc
    }

    #[test]
    fn wikipedia_examples() {
        // The examples table of the COBS article (encoded form without the delimiter).
        assert_eq!(roundtrip(&[0x00]), [0x01, 0x01]);
        assert_eq!(roundtrip(&[0x00, 0x00]), [0x01, 0x01, 0x01]);
        assert_eq!(roundtrip(&[0x00, 0x11, 0x00]), [0x01, 0x02, 0x11, 0x01]);
        assert_eq!(roundtrip(&[0x11, 0x22, 0x00, 0x33]), [0x03, 0x11, 0x22, 0x02, 0x33]);
        assert_eq!(roundtrip(&[0x11, 0x22, 0x33, 0x44]), [0x05, 0x11, 0x22, 0x33, 0x44]);
        assert_eq!(roundtrip(&[0x11, 0x00, 0x00, 0x00]), [0x02, 0x11, 0x01, 0x01, 0x01]);
        let run: Vec<u8> = (1..=254).collect();
        let mut expected = vec![0xFF];
        expected.extend(1..=254u8);
        assert_eq!(roundtrip(&run), expected);
        let run: Vec<u8> = (0..=254).collect();
        let mut expected = vec![0x01, 0xFF];
        expected.extend(1..=254u8);
        assert_eq!(roundtrip(&run), expected);
        let run: Vec<u8> = (1..=255).collect();
        let mut expected = vec![0xFF];
        expected.extend(1..=254u8);
        expected.extend([0x02, 0xFF]);
        assert_eq!(roundtrip(&run), expected);
    }

    #[test]
    fn agrees_with_the_cobs_crate() {
        // The reference implementation as the oracle, on a fixed pseudo-random corpus.
        let mut state = 0x1234_5678_9ABC_DEF0u64;
        // From 1: for the empty string the crate writes nothing, where COBS (and this module) write
        // the single code byte 0x01.
        for len in 1..600usize {
            let src: Vec<u8> = (0..len)
                .map(|_| {
                    state =
                        state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    let r = (state >> 56) as u8;
                    // Even lengths: a third of the bytes zero (short runs); odd lengths: few (long runs).
                    if r.is_multiple_of(3) && len.is_multiple_of(2) {
                        0
                    } else {
                        r
                    }
                })
                .collect();
            let ours = roundtrip(&src);
            assert_eq!(ours, cobs::encode_vec(&src), "len {len}");
        }
    }

    #[test]
    fn rejects_invalid_strings() {
        assert_eq!(decode_in_place(&mut [0x03, 0x11]), Err(CobsError::Truncated));
        assert_eq!(decode_in_place(&mut [0x02, 0x11, 0x00]), Err(CobsError::ZeroCode));
        assert_eq!(decode_in_place(&mut []), Ok(0));
    }

    #[test]
    fn encode_refuses_a_short_buffer() {
        assert_eq!(encode(&[1, 2, 3], &mut [0u8; 3]), None);
        assert_eq!(encode(&[1, 2, 3], &mut [0u8; 4]), Some(4));
    }
}
