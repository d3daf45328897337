//! [`FrameSource`]: bytes from any reader in, frames and link statistics out.

use std::io::{self, ErrorKind, Read};

use aim_wire::{DecodeError, Deframer, Frame, LinkStats};
use anyhow::Context as _;

/// Bytes asked of the reader per `read` call.
const READ_CHUNK: usize = 4096;

/// Decodes the frames of a byte stream read from `R`: a serial port, a recorded file, stdin.
///
/// As an iterator it yields every decoded frame, in stream order, and ends at the end of the
/// stream; damaged, unknown and oversize frames are skipped and counted in [`Self::stats`]
/// ([`Self::next_outcome`] shows them too). `Err` items are I/O errors of the reader, after
/// which the source is finished. Read timeouts (a quiet serial port) and interrupted reads
/// are retried, so on a live port the iterator waits for the next frame.
pub struct FrameSource<R> {
    reader: R,
    deframer: Box<Deframer>,
    buf: Box<[u8; READ_CHUNK]>,
    pos: usize,
    len: usize,
    done: bool,
}

impl<R: Read> FrameSource<R> {
    /// A source reading from `reader`, with zeroed statistics.
    pub fn new(reader: R) -> Self {
        FrameSource {
            reader,
            deframer: Box::new(Deframer::new()),
            buf: Box::new([0; READ_CHUNK]),
            pos: 0,
            len: 0,
            done: false,
        }
    }

    /// Statistics of everything read so far (final once the iterator has ended).
    pub fn stats(&self) -> &LinkStats {
        self.deframer.stats()
    }

    /// The reader, e.g. to change a serial port's settings.
    pub fn get_mut(&mut self) -> &mut R {
        &mut self.reader
    }

    /// The outcome of the next chunk between delimiters, a frame or why it was dropped;
    /// `Ok(None)` at the end of the stream (after which a cut-off last frame is counted as
    /// truncated). Blocks until a chunk completes.
    pub fn next_outcome(&mut self) -> io::Result<Option<Result<Frame, DecodeError>>> {
        loop {
            while self.pos < self.len {
                let byte = self.buf[self.pos];
                self.pos += 1;
                if let Some(outcome) = self.deframer.push(byte) {
                    return Ok(Some(outcome));
                }
            }
            if self.done {
                return Ok(None);
            }
            match self.reader.read(&mut self.buf[..]) {
                Ok(0) => {
                    self.done = true;
                    return Ok(self.deframer.finish().map(Err));
                }
                Ok(n) => {
                    self.pos = 0;
                    self.len = n;
                }
                Err(e) if is_retryable(&e) => {}
                Err(e) => {
                    self.done = true;
                    self.deframer.finish();
                    return Err(e);
                }
            }
        }
    }
}

/// Errors after which reading again makes sense: an interrupted call, a quiet serial port.
pub(crate) fn is_retryable(e: &io::Error) -> bool {
    matches!(e.kind(), ErrorKind::Interrupted | ErrorKind::TimedOut | ErrorKind::WouldBlock)
}

impl<R: Read> Iterator for FrameSource<R> {
    type Item = io::Result<Frame>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            match self.next_outcome() {
                Ok(Some(Ok(frame))) => return Some(Ok(frame)),
                Ok(Some(Err(_))) => continue,
                Ok(None) => return None,
                Err(e) => return Some(Err(e)),
            }
        }
    }
}

/// Opens a recording for reading, or stdin for `-`.
pub fn open_input(path: &str) -> anyhow::Result<Box<dyn Read + Send>> {
    if path == "-" {
        return Ok(Box::new(io::stdin()));
    }
    let file = std::fs::File::open(path).with_context(|| format!("opening recording {path}"))?;
    Ok(Box::new(io::BufReader::new(file)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use aim_wire::{Body, Doa, Header, MAX_ENCODED_LEN};

    fn frame(seq: u16) -> Frame {
        Frame {
            header: Header { array_id: 1, seq, sample_index: u64::from(seq) * 1024 },
            body: Body::Doa(Doa::new(0.1 * f32::from(seq), 0.5, 0.2, 0.9)),
        }
    }

    fn stream(frames: &[Frame]) -> Vec<u8> {
        let mut out = Vec::new();
        for f in frames {
            let mut buf = [0u8; MAX_ENCODED_LEN];
            let n = aim_wire::encode(f, &mut buf).unwrap();
            out.extend_from_slice(&buf[..n]);
        }
        out
    }

    /// A reader that returns at most 3 bytes per call and fails with a timeout now and then,
    /// like a slow serial port.
    struct Trickle {
        data: Vec<u8>,
        pos: usize,
        calls: usize,
    }

    impl Read for Trickle {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            self.calls += 1;
            if self.calls.is_multiple_of(4) {
                return Err(io::Error::new(ErrorKind::TimedOut, "quiet"));
            }
            let n = buf.len().min(3).min(self.data.len() - self.pos);
            buf[..n].copy_from_slice(&self.data[self.pos..self.pos + n]);
            self.pos += n;
            Ok(n)
        }
    }

    #[test]
    fn frames_survive_short_reads_and_timeouts() {
        let sent: Vec<Frame> = (0..20).map(frame).collect();
        let source = FrameSource::new(Trickle { data: stream(&sent), pos: 0, calls: 0 });
        let got: Vec<Frame> = source.map(|r| r.unwrap()).collect();
        assert_eq!(got, sent);
    }

    #[test]
    fn damage_costs_one_frame_and_is_counted() {
        let sent: Vec<Frame> = (0..5).map(frame).collect();
        let mut bytes = stream(&sent);
        let one = bytes.len() / 5;
        bytes[2 * one + one / 2] ^= 0x40; // inside frame 2
        bytes.truncate(bytes.len() - 4); // frame 4 cut off by the end
        let mut source = FrameSource::new(&bytes[..]);
        let got: Vec<u16> = source.by_ref().map(|r| r.unwrap().header.seq).collect();
        assert_eq!(got, [0, 1, 3]);
        let stats = source.stats();
        assert_eq!(stats.crc_errors + stats.framing_errors, 1);
        assert_eq!(stats.truncated, 1);
        assert_eq!((stats.seq_gaps, stats.frames_missed), (1, 1));
    }

    #[test]
    fn an_io_error_ends_the_source() {
        struct Broken;
        impl Read for Broken {
            fn read(&mut self, _: &mut [u8]) -> io::Result<usize> {
                Err(io::Error::new(ErrorKind::BrokenPipe, "unplugged"))
            }
        }
        let mut source = FrameSource::new(Broken);
        assert_eq!(source.next().unwrap().unwrap_err().kind(), ErrorKind::BrokenPipe);
        assert!(source.next().is_none());
    }
}
