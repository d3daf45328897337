//! [`Merged`]: several arrays' recordings read as the one link a host with a port per array
//! receives.
//!
//! Each recording keeps its own order (its board's link order); between recordings, the frame
//! whose audio ends first comes first: a board sends a `Doa`, `Peaks` or `Mfcc` frame when its
//! span ends, so on one host the arrays' frames interleave by the end of their spans. The end
//! is read on each array's nominal clock (sample index over the rate its `Hello` announced, or
//! [`crate::intake::DEFAULT_SAMPLE_RATE_HZ`] before one): the boards' clocks are taken to have
//! started together, as the simulator's do within tens of milliseconds. Frames go out
//! re-encoded, so a reader of [`Merged`] decodes exactly the frames the recordings held; what
//! a recording could not decode (damage) is counted in [`Merged::input_stats`].

use std::io::{self, Read};

use aim_wire::{Body, Frame, LinkStats};

use super::FrameSource;

/// Several recordings as one byte stream (module docs).
pub struct Merged<R> {
    inputs: Vec<Input<R>>,
    /// Encoded bytes of the frame being read out, and how far.
    out: Vec<u8>,
    pos: usize,
}

struct Input<R> {
    source: FrameSource<R>,
    head: Option<Frame>,
    done: bool,
    /// Sample rate the array's `Hello` announced, Hz.
    rate_hz: f64,
}

impl<R: Read> Merged<R> {
    /// The merge of `readers` (one recording each).
    pub fn new(readers: Vec<R>) -> Self {
        let inputs = readers
            .into_iter()
            .map(|r| Input {
                source: FrameSource::new(r),
                head: None,
                done: false,
                rate_hz: f64::from(crate::intake::DEFAULT_SAMPLE_RATE_HZ),
            })
            .collect();
        Self { inputs, out: Vec::new(), pos: 0 }
    }

    /// Each recording's link statistics so far (damaged frames are counted there; the merged
    /// stream holds only frames that decoded).
    pub fn input_stats(&self) -> Vec<LinkStats> {
        self.inputs.iter().map(|i| *i.source.stats()).collect()
    }

    /// The next frame of the merge, `None` at the end of every recording.
    fn next_frame(&mut self) -> io::Result<Option<Frame>> {
        for input in &mut self.inputs {
            if input.head.is_none() && !input.done {
                match input.source.next() {
                    Some(Ok(f)) => input.head = Some(f),
                    Some(Err(e)) => return Err(e),
                    None => input.done = true,
                }
            }
        }
        let first = self
            .inputs
            .iter()
            .enumerate()
            .filter_map(|(i, input)| input.head.as_ref().map(|f| (i, end_s(f, input.rate_hz))))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i);
        let Some(i) = first else { return Ok(None) };
        let frame = self.inputs[i].head.take();
        if let Some(Body::Hello(h)) = frame.as_ref().map(|f| &f.body) {
            if h.sample_rate_hz > 0 {
                self.inputs[i].rate_hz = f64::from(h.sample_rate_hz);
            }
        }
        Ok(frame)
    }
}

/// When the audio of `frame` ends, s on its array's nominal clock.
fn end_s(frame: &Frame, rate_hz: f64) -> f64 {
    let span = match &frame.body {
        Body::Doa(d) => u64::from(d.span_samples),
        Body::Peaks(p) => u64::from(p.span_samples),
        Body::Mfcc(m) => u64::from(m.span_samples),
        _ => 0,
    };
    frame.header.sample_index.saturating_add(span) as f64 / rate_hz
}

impl<R: Read> Read for Merged<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        while self.pos == self.out.len() {
            let Some(frame) = self.next_frame()? else { return Ok(0) };
            self.out.resize(aim_wire::MAX_ENCODED_LEN, 0);
            // A frame that decoded encodes again (its fields are within the format's limits).
            let n = aim_wire::encode(&frame, &mut self.out)
                .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e.to_string()))?;
            self.out.truncate(n);
            self.pos = 0;
        }
        let n = buf.len().min(self.out.len() - self.pos);
        buf[..n].copy_from_slice(&self.out[self.pos..self.pos + n]);
        self.pos += n;
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aim_wire::{Doa, Header};

    fn doa(array_id: u8, seq: u16, sample_index: u64) -> Frame {
        let body = Body::Doa(Doa { span_samples: 8192, ..Doa::new(0.0, 0.8, 0.1, 0.9) });
        Frame { header: Header { array_id, seq, sample_index }, body }
    }

    fn bytes(frames: &[Frame]) -> Vec<u8> {
        let mut v = Vec::new();
        for f in frames {
            let mut buf = [0u8; aim_wire::MAX_ENCODED_LEN];
            let n = aim_wire::encode(f, &mut buf).unwrap();
            v.extend_from_slice(&buf[..n]);
        }
        v
    }

    /// Two arrays' recordings interleave by the end of each frame's span; each keeps its
    /// own order, and damage in one costs only its damaged frame.
    #[test]
    fn recordings_interleave_by_span_end_and_damage_stays_in_its_recording() {
        let a: Vec<Frame> = (0..4).map(|k| doa(1, k, 8192 * u64::from(k))).collect();
        let b: Vec<Frame> = (0..4).map(|k| doa(2, k, 4096 + 8192 * u64::from(k))).collect();
        let mut bytes_b = bytes(&b);
        // Damage the second frame of b (a byte in its middle).
        let second = bytes(&b[..1]).len() + 8;
        bytes_b[second] ^= 0x55;
        let bytes_a = bytes(&a);
        let merged = Merged::new(vec![&bytes_a[..], &bytes_b[..]]);
        let mut source = FrameSource::new(merged);
        let got: Vec<(u8, u16)> = source
            .by_ref()
            .map(|f| f.unwrap())
            .map(|f| (f.header.array_id, f.header.seq))
            .collect();
        assert_eq!(got, [(1, 0), (2, 0), (1, 1), (1, 2), (2, 2), (1, 3), (2, 3)]);
        assert_eq!(source.stats().crc_errors, 0);
        let inputs = source.get_mut().input_stats();
        assert_eq!(inputs[0].frames, 4);
        assert_eq!(inputs[1].frames, 3);
        assert_eq!(inputs[1].crc_errors + inputs[1].framing_errors + inputs[1].malformed, 1);
    }
}
