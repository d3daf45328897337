//! [`Merged`]: several arrays' recordings read as the one link a host with a port per array
//! receives.
//!
//! Each recording keeps its own order (its board's link order); between recordings, the frame
//! whose audio ends first comes first (ties: the lower array id): a board sends a `Doa`,
//! `Peaks` or `Mfcc` frame when its span ends, so on one host the arrays' frames interleave by
//! the end of their spans. The end is read on each array's nominal clock (sample index over
//! the rate its `Hello` announced, or the rate given before one): the boards' clocks are taken
//! to have started together, as the simulator's do within tens of milliseconds. A recording's
//! key follows its frames' ends while they run on; a break (ahead: a silence, back: a reboot's
//! count from 0) is followed once a second frame agrees with it, and after a reboot the keys
//! go on from where they were; a single absurd index keeps its recording's place (the intake
//! judges that frame). Frames go out re-encoded, so a reader of [`Merged`] decodes exactly the frames
//! the recordings held; what a recording could not decode (damage) is counted in
//! [`Merged::input_stats`], and at the end of the merge each recording's counts go to stderr
//! as one JSON line (`{"kind":"recording",...}`), with a warning for a recording that gave no
//! frame at all.

use std::io::{self, Read};

use aim_wire::{Body, Frame, LinkStats};

use super::frame_bytes::FrameBytes;
use super::FrameSource;

/// Largest step ahead of a recording's ordering key from one frame to the next that is
/// followed at once, s (the intake's plausibility window ahead); a longer one, or any step
/// back, needs a second frame that agrees with it within this.
pub const MAX_KEY_STEP_S: f64 = 2.0;

/// Several recordings as one byte stream (module docs).
pub struct Merged<R> {
    inputs: Vec<Input<R>>,
    /// The frame being read out.
    out: FrameBytes,
    /// The end of the merge has been reported.
    reported: bool,
}

struct Input<R> {
    name: String,
    source: FrameSource<R>,
    /// The next frame and its ordering key, s.
    head: Option<(Frame, f64)>,
    done: bool,
    /// Sample rate the array's `Hello` announced (or the one given), Hz.
    rate_hz: f64,
    /// The key of the recording's last frame, s.
    key_s: f64,
    /// Added to a frame's end to make its key (moves when a board's count went back), s.
    offset_s: f64,
    /// The end (with `offset_s`) of a frame that broke the recording's continuity, until the
    /// next frame confirms the break or not, s.
    candidate_s: Option<f64>,
}

/// Pause put between a recording's last key and its first after a reboot, s: the intake's
/// (`IntakeConfig::epoch_gap_s`), so the merge and the intake place a rebooted board alike.
const REBOOT_PAUSE_S: f64 = 5.0;

impl<R> Input<R> {
    /// The ordering key of a frame ending at `end_s` on the array's clock (module docs): the
    /// end itself while the recording runs on (within [`MAX_KEY_STEP_S`]); a break (a jump
    /// ahead: a silence; back: a reboot) counts once a second frame agrees with it, and a
    /// frame alone keeps the last key. After a confirmed jump back the keys go on from the
    /// last one (the host's time ran on while the board restarted its count).
    fn key(&mut self, end_s: f64) -> f64 {
        let e = end_s + self.offset_s;
        if e >= self.key_s && e <= self.key_s + MAX_KEY_STEP_S {
            self.candidate_s = None;
            self.key_s = e;
            return e;
        }
        match self.candidate_s.take() {
            Some(c) if (e - c).abs() <= MAX_KEY_STEP_S => {
                if c < self.key_s {
                    // A reboot: the new count goes on after a pause, as the intake places it.
                    self.offset_s += self.key_s - c + REBOOT_PAUSE_S;
                }
                self.key_s = end_s + self.offset_s;
            }
            _ => self.candidate_s = Some(e),
        }
        self.key_s
    }
}

impl Merged<Box<dyn Read + Send>> {
    /// The merge of the recordings at `paths` (files: stdin cannot be merged), their sample
    /// indices read at the `site` file's rate until a `Hello` says otherwise.
    pub fn open(paths: &[String], site: &crate::site::Site) -> anyhow::Result<Self> {
        if paths.iter().any(|p| p == "-") {
            anyhow::bail!("stdin (`-`) cannot be merged with other recordings");
        }
        // The same recording twice would feed every frame twice.
        let canonical = |p: &String| std::fs::canonicalize(p).unwrap_or_else(|_| p.into());
        for (i, p) in paths.iter().enumerate() {
            if let Some(q) = paths[..i].iter().find(|q| canonical(q) == canonical(p)) {
                anyhow::bail!("{p} and {q} are the same recording; give each array's once");
            }
        }
        let readers = paths
            .iter()
            .map(|p| Ok((p.clone(), super::open_input(p)?)))
            .collect::<anyhow::Result<_>>()?;
        let rate = site.sample_rate_hz.unwrap_or(crate::intake::DEFAULT_SAMPLE_RATE_HZ);
        Ok(Self::new(readers, rate))
    }
}

impl<R: Read> Merged<R> {
    /// The merge of `readers` (a name for messages and one recording each); `rate_hz` reads
    /// a recording's sample indices until its `Hello` says otherwise (the site file's rate).
    pub fn new(readers: Vec<(String, R)>, rate_hz: u32) -> Self {
        let inputs = readers
            .into_iter()
            .map(|(name, r)| Input {
                name,
                source: FrameSource::new(r),
                head: None,
                done: false,
                rate_hz: f64::from(rate_hz.max(1)),
                key_s: 0.0,
                offset_s: 0.0,
                candidate_s: None,
            })
            .collect();
        Self { inputs, out: FrameBytes::default(), reported: false }
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
                    Some(Ok(f)) => {
                        if let Body::Hello(h) = &f.body {
                            if h.sample_rate_hz > 0 {
                                input.rate_hz = f64::from(h.sample_rate_hz);
                            }
                        }
                        // A frame that describes no span of audio (Hello, Health, Beacon) is
                        // stamped at an instant behind the audio sent before it: it goes with
                        // the recording's current key and says nothing of its continuity (two
                        // in a row would otherwise read as a reboot).
                        let key =
                            if matches!(f.body, Body::Hello(_) | Body::Health(_) | Body::Beacon(_))
                            {
                                input.key_s
                            } else {
                                input.key(end_s(&f, input.rate_hz))
                            };
                        input.head = Some((f, key));
                    }
                    Some(Err(e)) => {
                        return Err(io::Error::new(e.kind(), format!("{}: {e}", input.name)))
                    }
                    None => input.done = true,
                }
            }
        }
        let first = self
            .inputs
            .iter()
            .enumerate()
            .filter_map(|(i, input)| {
                input.head.as_ref().map(|(f, key)| (i, *key, f.header.array_id))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.2.cmp(&b.2)))
            .map(|(i, _, _)| i);
        let Some(i) = first else {
            self.report();
            return Ok(None);
        };
        Ok(self.inputs[i].head.take().map(|(f, _)| f))
    }

    /// Each recording's counts on stderr, once, at the end of the merge.
    fn report(&mut self) {
        if std::mem::replace(&mut self.reported, true) {
            return;
        }
        for input in &self.inputs {
            let s = input.source.stats();
            eprintln!("{}", super::json::named_stats(s, "recording", "file", &input.name));
            if s.frames == 0 {
                eprintln!("warning: {}: no frame decoded (is it an AIM recording?)", input.name);
            }
        }
    }
}

/// When the audio of `frame` ends, s on its array's nominal clock.
fn end_s(frame: &Frame, rate_hz: f64) -> f64 {
    crate::intake::frame_end(frame) as f64 / rate_hz
}

impl<R: Read> Read for Merged<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        while self.out.is_drained() {
            let Some(frame) = self.next_frame()? else { return Ok(0) };
            self.out.set(FrameBytes::encode(&frame)?);
        }
        Ok(self.out.read_into(buf))
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
        let merged =
            Merged::new(vec![("a".into(), &bytes_a[..]), ("b".into(), &bytes_b[..])], 48_000);
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

    fn order(inputs: Vec<(&str, Vec<u8>)>) -> Vec<(u8, u16)> {
        let readers = inputs.iter().map(|(n, b)| (n.to_string(), &b[..])).collect();
        FrameSource::new(Merged::new(readers, 48_000))
            .map(|f| f.unwrap())
            .map(|f| (f.header.array_id, f.header.seq))
            .collect()
    }

    /// Two frames without a span in a row, stamped behind the audio already sent (a Health
    /// at its interval's start after a Hello), are not a reboot: the recording keeps its
    /// place in the merge instead of jumping 5 s behind the other one.
    #[test]
    fn frames_without_a_span_do_not_read_as_a_reboot() {
        let health = |seq: u16, sample_index: u64| Frame {
            header: Header { array_id: 1, seq, sample_index },
            body: Body::Health(aim_wire::Health::default()),
        };
        let mut a: Vec<Frame> = (0..3).map(|k| doa(1, k, 8192 * u64::from(k))).collect();
        a.push(health(3, 0));
        a.push(health(4, 8192));
        a.extend((5..8).map(|k| doa(1, k, 8192 * u64::from(k - 2))));
        let b: Vec<Frame> = (0..6).map(|k| doa(2, k, 4096 + 8192 * u64::from(k))).collect();
        let got = order(vec![("a", bytes(&a)), ("b", bytes(&b))]);
        // Array 1's frame ending at 6·8192 goes before array 2's ending at 6·8192 + 4096.
        let one = got.iter().position(|&f| f == (1, 7)).unwrap();
        let two = got.iter().position(|&f| f == (2, 5)).unwrap();
        assert!(one < two, "{got:?}");
    }

    /// Frames ending together go out by array id, whatever the order of the recordings.
    #[test]
    fn ties_go_by_array_id_not_by_the_order_of_the_files() {
        let a: Vec<Frame> = (0..3).map(|k| doa(1, k, 8192 * u64::from(k))).collect();
        let b: Vec<Frame> = (0..3).map(|k| doa(2, k, 8192 * u64::from(k))).collect();
        let want = [(1, 0), (2, 0), (1, 1), (2, 1), (1, 2), (2, 2)];
        assert_eq!(order(vec![("a", bytes(&a)), ("b", bytes(&b))]), want);
        assert_eq!(order(vec![("b", bytes(&b)), ("a", bytes(&a))]), want);
    }

    /// A board that reboots (its index back to 0) or one absurd index keeps its recording's
    /// place in the merge instead of jumping ahead of or behind the other arrays.
    #[test]
    fn a_reboot_or_an_absurd_index_keeps_its_place() {
        let mut a: Vec<Frame> = (0..6).map(|k| doa(1, k, 8192 * u64::from(k))).collect();
        a[2].header.sample_index = u64::MAX / 4; // absurd
        a[4].header.sample_index = 0; // rebooted...
        a[5].header.sample_index = 8192; // ...and counting again
        let b: Vec<Frame> = (0..6).map(|k| doa(2, k, 4096 + 8192 * u64::from(k))).collect();
        let got = order(vec![("a", bytes(&a)), ("b", bytes(&b))]);
        let pos = |f: (u8, u16)| got.iter().position(|&g| g == f).unwrap();
        // The absurd frame keeps its place; after the reboot, array 1 goes on after a pause
        // (its last key, 0.68 s, + 5 s), after all of array 2's frames (the last ends 1.1 s).
        assert!(pos((1, 2)) < pos((2, 2)), "{got:?}");
        assert!(pos((1, 5)) > pos((2, 5)), "{got:?}");
        assert_eq!(got.len(), 12);
    }

    /// A board silent for a while (its link down) comes back later in the merge, not at once:
    /// after the first frame of the break, its frames wait for the other arrays' of the
    /// same time.
    #[test]
    fn a_silent_board_comes_back_in_its_time() {
        let mut a: Vec<Frame> = (0..4).map(|k| doa(1, k, 8192 * u64::from(k))).collect();
        a.extend((4..8).map(|k| doa(1, k, 30 * 48_000 + 8192 * u64::from(k))));
        let b: Vec<Frame> = (0..200).map(|k| doa(2, k, 8192 * u64::from(k))).collect();
        let got = order(vec![("a", bytes(&a)), ("b", bytes(&b))]);
        let pos = |f: (u8, u16)| got.iter().position(|&g| g == f).unwrap();
        // b's frame k ends at (k + 1)·8192 samples: 30 s is after its frame 175.
        assert!(pos((1, 6)) > pos((2, 175)), "{got:?}");
        assert!(pos((1, 3)) < pos((2, 4)), "{got:?}");
    }

    /// One stray index a few seconds ahead (within the intake's reach of a silence) does not
    /// move the rest of its recording: it is followed only when a second frame agrees. The
    /// pause after a reboot is the intake's.
    #[test]
    fn a_stray_index_a_few_seconds_ahead_moves_nothing() {
        let mut a: Vec<Frame> = (0..8).map(|k| doa(1, k, 8192 * u64::from(k))).collect();
        a[3].header.sample_index += 5 * 48_000;
        let b: Vec<Frame> = (0..8).map(|k| doa(2, k, 4096 + 8192 * u64::from(k))).collect();
        let got = order(vec![("a", bytes(&a)), ("b", bytes(&b))]);
        let pos = |f: (u8, u16)| got.iter().position(|&g| g == f).unwrap();
        for k in 4..8 {
            assert!(pos((1, k)) < pos((2, k)), "frame {k}: {got:?}");
        }
        let intake = crate::intake::IntakeConfig::default().epoch_gap_s;
        assert_eq!(REBOOT_PAUSE_S, intake);
    }
}
