//! [`Ports`]: several boards' links read at once, as one stream of frames in arrival order
//! (`aim track --serial A --serial B ...`).
//!
//! A thread per link decodes its bytes ([`FrameSource`]) and hands each frame over as it is
//! decoded; the stream gives them out re-encoded in the order they arrived, so the intake sees
//! what a host with one port per board receives. Damage costs the damaged frame of its own
//! link only; when a link ends, its statistics go to stderr as one JSON line
//! (`{"kind":"port","port":..,...}`) and the stream goes on with the others; it ends when
//! every link has ended.

use std::io::{self, Read};
use std::sync::mpsc;

use super::frame_bytes::FrameBytes;
use super::FrameSource;

/// Frames waiting between the links' threads and the reader; a reader that stops reading
/// holds the threads back (the boards' own buffers then overflow, as with one slow port).
const QUEUE_FRAMES: usize = 4096;

/// Several links as one byte stream (module docs).
pub struct Ports {
    rx: mpsc::Receiver<Vec<u8>>,
    out: FrameBytes,
}

impl Ports {
    /// Starts reading every link (a name for messages, the reader).
    pub fn spawn(links: Vec<(String, Box<dyn Read + Send>)>) -> io::Result<Self> {
        let (tx, rx) = mpsc::sync_channel(QUEUE_FRAMES);
        for (name, reader) in links {
            let tx = tx.clone();
            std::thread::Builder::new().name(format!("port {name}")).spawn(move || {
                let mut source = FrameSource::new(reader);
                for frame in source.by_ref() {
                    let frame = match frame {
                        Ok(f) => f,
                        Err(e) => {
                            eprintln!("warning: {name}: {e}");
                            break;
                        }
                    };
                    let Ok(bytes) = FrameBytes::encode(&frame) else { continue };
                    if tx.send(bytes).is_err() {
                        return;
                    }
                }
                eprintln!("{}", super::json::named_stats(source.stats(), "port", "port", &name));
            })?;
        }
        Ok(Self { rx, out: FrameBytes::default() })
    }
}

impl Read for Ports {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.out.is_drained() {
            match self.rx.recv() {
                Ok(frame) => self.out.set(frame),
                // Every link has ended.
                Err(_) => return Ok(0),
            }
        }
        Ok(self.out.read_into(buf))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aim_wire::{Body, Doa, Frame, Header};

    fn bytes(array_id: u8, n: u16) -> Vec<u8> {
        let mut v = Vec::new();
        for seq in 0..n {
            let body = Body::Doa(Doa { span_samples: 8192, ..Doa::new(0.0, 0.8, 0.1, 0.9) });
            let f = Frame {
                header: Header { array_id, seq, sample_index: 8192 * u64::from(seq) },
                body,
            };
            let mut buf = [0u8; aim_wire::MAX_ENCODED_LEN];
            let k = aim_wire::encode(&f, &mut buf).unwrap();
            v.extend_from_slice(&buf[..k]);
        }
        v
    }

    /// Every frame of every link comes out once, each link's in its own order; damage in one
    /// link costs its damaged frame only; the stream ends when both links have.
    #[test]
    fn every_links_frames_come_out_once_in_their_order() {
        let a = bytes(1, 50);
        let mut b = bytes(2, 40);
        let third = bytes(2, 2).len() + 6;
        b[third] ^= 0x5a;
        let links: Vec<(String, Box<dyn Read + Send>)> = vec![
            ("a".into(), Box::new(std::io::Cursor::new(a))),
            ("b".into(), Box::new(std::io::Cursor::new(b))),
        ];
        let got: Vec<(u8, u16)> = FrameSource::new(Ports::spawn(links).unwrap())
            .map(|f| f.unwrap())
            .map(|f| (f.header.array_id, f.header.seq))
            .collect();
        let of = |id: u8| got.iter().filter(|f| f.0 == id).map(|f| f.1).collect::<Vec<_>>();
        assert_eq!(of(1), (0..50).collect::<Vec<_>>());
        assert_eq!(of(2), (0..40).filter(|&s| s != 2).collect::<Vec<_>>());
    }
}
