//! [`FrameBytes`]: the wire bytes of one frame at a time, read out by the `Read`
//! implementations that hand frames from elsewhere to a [`super::FrameSource`]
//! ([`super::Merged`], [`super::Ports`], the Zenoh bus's `FrameFeed`).

use std::io;

use aim_wire::Frame;

/// One frame's wire bytes and how far they have been read.
#[derive(Debug, Default)]
pub(crate) struct FrameBytes {
    bytes: Vec<u8>,
    pos: usize,
}

impl FrameBytes {
    /// The wire bytes of `frame` (`0x00`, COBS, `0x00`). A frame that decoded always encodes
    /// again; the error is for a frame built with fields beyond the format's limits.
    pub(crate) fn encode(frame: &Frame) -> io::Result<Vec<u8>> {
        let mut bytes = vec![0u8; aim_wire::MAX_ENCODED_LEN];
        let n = aim_wire::encode(frame, &mut bytes)
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e.to_string()))?;
        bytes.truncate(n);
        Ok(bytes)
    }

    /// Whether every byte has been read out.
    pub(crate) fn is_drained(&self) -> bool {
        self.pos == self.bytes.len()
    }

    /// The next frame's bytes (the previous ones should be drained).
    pub(crate) fn set(&mut self, bytes: Vec<u8>) {
        self.bytes = bytes;
        self.pos = 0;
    }

    /// Copies as many unread bytes as fit into `buf`; returns how many.
    pub(crate) fn read_into(&mut self, buf: &mut [u8]) -> usize {
        let n = buf.len().min(self.bytes.len() - self.pos);
        buf[..n].copy_from_slice(&self.bytes[self.pos..self.pos + n]);
        self.pos += n;
        n
    }
}
