//! [`Tap`]: a reader between a link and the intake that shows the live map every frame and,
//! for a replay, releases the bytes at the link's pace (or a multiple of it).
//!
//! The bytes pass unchanged and in order: the intake decodes exactly what it would without the
//! tap. With a pace, each read returns the bytes up to the end of the next frame only once
//! that frame is due: when the audio it describes has been sampled (its sample index plus
//! span, at the rate of the array's `Hello`), divided by the pace, after the first frame.

use std::io::{self, Read};
use std::time::{Duration, Instant};

use aim_wire::{Body, Deframer, Frame};

use super::LiveMap;

/// How fast a replay goes: [`Pace::Free`] as fast as it can, [`Pace::Times`] `n` times the
/// link's own pace (1: real time).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pace {
    /// As fast as the reader gives bytes.
    Free,
    /// `n` times the link's pace (1: real time).
    Times(f64),
}

impl std::str::FromStr for Pace {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let refuse =
            || format!("--pace must be `real`, `free` or a speed-up from 0.01 to 1000, not {s:?}");
        match s {
            "real" => Ok(Pace::Times(1.0)),
            "free" => Ok(Pace::Free),
            _ => {
                let n: f64 = s.parse().map_err(|_| refuse())?;
                if n.is_finite() && (0.01..=1000.0).contains(&n) {
                    Ok(Pace::Times(n))
                } else {
                    Err(refuse())
                }
            }
        }
    }
}

/// Bytes read from `R`, passed on unchanged; every decoded frame also goes to the map.
pub struct Tap<R> {
    inner: R,
    map: Option<LiveMap>,
    pace: Pace,
    deframer: Box<Deframer>,
    buf: Vec<u8>,
    pos: usize,
    len: usize,
    /// Sample rate per array id, from its `Hello`.
    rates: [Option<u32>; 256],
    /// The first frame's end (s of its array's clock) and when it was released.
    origin: Option<(f64, Instant)>,
}

impl<R: Read> Tap<R> {
    /// A tap on `inner` showing `map` (if any) its frames, at `pace`.
    pub fn new(inner: R, map: Option<LiveMap>, pace: Pace) -> Self {
        Self {
            inner,
            map,
            pace,
            deframer: Box::new(Deframer::new()),
            buf: vec![0; 4096],
            pos: 0,
            len: 0,
            rates: [None; 256],
            origin: None,
        }
    }

    /// The reader underneath.
    pub fn get_mut(&mut self) -> &mut R {
        &mut self.inner
    }

    /// Shows the map `frame`; with a pace, waits until it is due.
    fn on_frame(&mut self, frame: &Frame) {
        let id = usize::from(frame.header.array_id);
        if let Body::Hello(h) = &frame.body {
            self.rates[id] = Some(h.sample_rate_hz).filter(|&r| r > 0);
        }
        if let (Pace::Times(n), Some(rate)) = (self.pace, self.rates[id]) {
            let span = match &frame.body {
                Body::Doa(d) => d.span_samples,
                Body::Peaks(p) => p.span_samples,
                _ => 0,
            };
            let end_s = (frame.header.sample_index + u64::from(span)) as f64 / f64::from(rate);
            let (first_s, started) = *self.origin.get_or_insert((end_s, Instant::now()));
            // A frame from before the first (another array, a reboot) is due at once.
            let due = Duration::try_from_secs_f64((end_s - first_s) / n).unwrap_or_default();
            if let Some(wait) = due.checked_sub(started.elapsed()) {
                std::thread::sleep(wait.min(MAX_WAIT));
            }
        }
        if let Some(map) = &self.map {
            map.frame(frame, self.rates[id]);
        }
    }
}

/// The longest a paced replay waits for one frame (a jump in the stream's sample index, e.g. a
/// reboot, does not stall the replay for longer).
pub const MAX_WAIT: Duration = Duration::from_secs(2);

impl<R: Read> Read for Tap<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        if self.pos == self.len {
            self.len = self.inner.read(&mut self.buf)?;
            self.pos = 0;
            if self.len == 0 {
                return Ok(0);
            }
        }
        // Up to and including the byte that completes the next frame, at most `out.len()`.
        let start = self.pos;
        let limit = self.len.min(start + out.len());
        let mut frame = None;
        while self.pos < limit && frame.is_none() {
            frame = self.deframer.push(self.buf[self.pos]);
            self.pos += 1;
        }
        if let Some(Ok(frame)) = frame {
            self.on_frame(&frame);
        }
        let n = self.pos - start;
        out[..n].copy_from_slice(&self.buf[start..self.pos]);
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_pass_unchanged_and_paces_parse() {
        let frames: Vec<Frame> = (0..5)
            .map(|seq| Frame {
                header: aim_wire::Header { array_id: 2, seq, sample_index: u64::from(seq) * 1024 },
                body: Body::Doa(aim_wire::Doa::new(0.1, 0.5, 0.2, 0.9)),
            })
            .collect();
        let mut bytes = vec![7u8, 7]; // noise first
        for f in &frames {
            let mut b = [0u8; aim_wire::MAX_ENCODED_LEN];
            let n = aim_wire::encode(f, &mut b).unwrap();
            bytes.extend_from_slice(&b[..n]);
        }
        let map = LiveMap::start("127.0.0.1:0", serde_json::json!({})).unwrap();
        let mut tap = Tap::new(&bytes[..], Some(map.clone()), Pace::Free);
        let mut got = Vec::new();
        tap.read_to_end(&mut got).unwrap();
        assert_eq!(got, bytes);
        // Every Doa frame reached the map (its backlog), in order.
        let hub = map.hub();
        let seqs: Vec<u64> = hub
            .backlog
            .iter()
            .map(|e| {
                let data = e.lines().nth(1).unwrap().strip_prefix("data: ").unwrap();
                serde_json::from_str::<serde_json::Value>(data).unwrap()["seq"].as_u64().unwrap()
            })
            .collect();
        assert_eq!(seqs, [0, 1, 2, 3, 4]);

        assert_eq!("real".parse::<Pace>(), Ok(Pace::Times(1.0)));
        assert_eq!("4".parse::<Pace>(), Ok(Pace::Times(4.0)));
        assert_eq!("free".parse::<Pace>(), Ok(Pace::Free));
        for bad in ["0", "-1", "nan", "1e9", "fast"] {
            assert!(bad.parse::<Pace>().unwrap_err().starts_with("--pace must be"), "{bad}");
        }
    }
}
