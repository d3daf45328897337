//! Recording a link: the raw bytes of a port, unchanged, to a file.
//!
//! The file holds exactly the bytes the port delivered, so replaying it through a
//! [`super::FrameSource`] gives the frame sequence a live decoder would have seen, damage
//! included. Recordings have no header of their own: any tool that reads a raw capture of the
//! port (`cat /dev/ttyACM0 > file` after `stty raw`) reads them too.

use std::io::{self, Read, Write};
use std::time::Instant;

use aim_wire::{Deframer, LinkStats};

use super::source::is_retryable;

/// When a recording stops (besides an I/O error of the port or the file).
#[derive(Debug, Clone, Copy, Default)]
pub struct Until {
    /// Stop at this time.
    pub deadline: Option<Instant>,
    /// Stop once this many frames have been decoded (the rest of the read that completed the
    /// last one is still written).
    pub frames: Option<u64>,
}

/// Copies bytes from `port` to `out` until `until` says stop or `port` ends (a serial
/// [`super::serial::Link`] ends on Ctrl-C); decodes along the way only to count (the file gets
/// the bytes as read, damage and all). `progress` sees the statistics after every read.
/// Returns the final statistics, also when an I/O error of the port or the file ended the
/// recording (everything read before it is in `out`), with that error.
pub fn record(
    port: &mut dyn Read,
    out: &mut dyn Write,
    until: Until,
    progress: &mut dyn FnMut(&LinkStats),
) -> (LinkStats, io::Result<()>) {
    let mut deframer: Box<Deframer> = Box::default();
    let mut buf = vec![0u8; 4096];
    let result = loop {
        if until.deadline.is_some_and(|d| Instant::now() >= d) {
            break Ok(());
        }
        if until.frames.is_some_and(|n| deframer.stats().frames >= n) {
            break Ok(());
        }
        let n = match port.read(&mut buf) {
            Ok(0) => break Ok(()),
            Ok(n) => n,
            Err(e) if is_retryable(&e) => continue,
            Err(e) => break Err(e),
        };
        // With a frame limit, the bytes up to the delimiter (0x00) that ends the last frame
        // asked for, no more: the file then holds exactly that many frames.
        let end = match until.frames {
            Some(limit) => {
                let mut pos = 0;
                while pos < n && deframer.stats().frames < limit {
                    let stop = buf[pos..n].iter().position(|&b| b == 0).map_or(n, |i| pos + i + 1);
                    for _ in deframer.feed(&buf[pos..stop]) {}
                    pos = stop;
                }
                pos
            }
            None => {
                for _ in deframer.feed(&buf[..n]) {}
                n
            }
        };
        // Flushed per read: a recording killed by Ctrl-C keeps everything read so far.
        if let Err(e) = out.write_all(&buf[..end]).and_then(|()| out.flush()) {
            break Err(e);
        }
        progress(deframer.stats());
    };
    (*deframer.stats(), result)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_every_byte_and_stops_after_the_frames_asked_for() {
        let frame = aim_wire::Frame {
            header: aim_wire::Header { array_id: 4, seq: 0, sample_index: 0 },
            body: aim_wire::Body::Health(aim_wire::Health::default()),
        };
        let mut wire = [0u8; aim_wire::MAX_ENCODED_LEN];
        let n = aim_wire::encode(&frame, &mut wire).unwrap();
        let mut input: Vec<u8> = vec![0x13, 0x37]; // line noise before the first frame
        for _ in 0..3 {
            input.extend_from_slice(&wire[..n]);
        }
        let wanted = input.clone();
        // Frames beyond the limit, in the same read: not written.
        input.extend_from_slice(&wire[..n]);
        input.extend_from_slice(&wire[..n / 2]);
        let mut out = Vec::new();
        let mut reads = 0;
        let stats = record(
            &mut &input[..],
            &mut out,
            Until { frames: Some(3), ..Until::default() },
            &mut |_| reads += 1,
        );
        stats.1.unwrap();
        let stats = stats.0;
        assert_eq!(out, wanted);
        assert_eq!(stats.frames, 3);
        assert_eq!(stats.framing_errors + stats.crc_errors, 1, "the noise");
        assert!(reads >= 1);
    }

    #[test]
    fn a_quiet_port_stops_at_the_deadline() {
        // A port that only ever times out, like an unplugged board's: the deadline still ends
        // the recording (the test would hang otherwise), with nothing written.
        struct Quiet;
        impl Read for Quiet {
            fn read(&mut self, _: &mut [u8]) -> io::Result<usize> {
                std::thread::sleep(std::time::Duration::from_millis(5));
                Err(io::Error::new(io::ErrorKind::TimedOut, "no data"))
            }
        }
        let mut out = Vec::new();
        let deadline = Some(Instant::now() + std::time::Duration::from_millis(30));
        let (stats, result) =
            record(&mut Quiet, &mut out, Until { deadline, frames: None }, &mut |_| {});
        result.unwrap();
        assert!(out.is_empty());
        assert_eq!(stats.bytes, 0);
    }
}
