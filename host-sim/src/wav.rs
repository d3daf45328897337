//! The simulator's WAV files: 32-bit float, pascals, one channel per microphone, interleaved.
//! [`WavSink`] writes a simulation's arrays as their blocks arrive (hound appends the samples
//! and patches the header's lengths when finished), into `array-<id>.wav.part` files renamed to
//! `array-<id>.wav` only when complete: a recording with a sample that is not finite is never
//! written, and a run that fails or is interrupted leaves no WAV behind.
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Context as _;

use crate::{ArrayRecording, AudioSink};

type Writer = hound::WavWriter<std::io::BufWriter<std::fs::File>>;

/// The WAV format of a recording of `channels` microphones at `sample_rate_hz`.
fn spec(channels: usize, sample_rate_hz: u32) -> hound::WavSpec {
    hound::WavSpec {
        channels: channels as u16,
        sample_rate: sample_rate_hz,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    }
}

/// Writes one whole recording to `path`.
pub fn write_wav(path: &Path, a: &ArrayRecording) -> anyhow::Result<()> {
    let mut w = hound::WavWriter::create(path, spec(a.channels.len(), a.sample_rate_hz))?;
    let channels: Vec<&[f32]> = a.channels.iter().map(Vec::as_slice).collect();
    append(&mut w, &channels)?;
    w.finalize()?;
    Ok(())
}

/// Appends a block, interleaved.
fn append<W: std::io::Write + std::io::Seek>(
    w: &mut hound::WavWriter<W>,
    channels: &[&[f32]],
) -> anyhow::Result<()> {
    let len = channels.first().map_or(0, |c| c.len());
    for k in 0..len {
        for ch in channels {
            w.write_sample(ch[k])?;
        }
    }
    Ok(())
}

/// One array's file being written.
struct Open {
    id: u8,
    part: PathBuf,
    done: PathBuf,
    writer: Option<Writer>,
    /// Samples per channel written so far.
    written: usize,
}

/// Streams every array of a simulation to `dir/array-<id>.wav`.
pub struct WavSink<'a> {
    files: Vec<Open>,
    /// Once set (Ctrl-C, SIGTERM), the next block fails with `Interrupted`.
    stop: Option<&'a AtomicBool>,
}

impl<'a> WavSink<'a> {
    /// Creates the `.part` files for arrays `(id, microphones)` at `sample_rate_hz` in `dir`.
    pub fn create(dir: &Path, arrays: &[(u8, usize)], sample_rate_hz: u32) -> anyhow::Result<Self> {
        let mut sink = Self { files: Vec::new(), stop: None };
        for &(id, mics) in arrays {
            let done = dir.join(format!("array-{id}.wav"));
            let part = dir.join(format!("array-{id}.wav.part"));
            let writer = hound::WavWriter::create(&part, spec(mics, sample_rate_hz))
                .with_context(|| format!("creating {}", part.display()));
            let writer = match writer {
                Ok(w) => w,
                Err(e) => {
                    sink.abandon();
                    return Err(e);
                }
            };
            sink.files.push(Open { id, part, done, writer: Some(writer), written: 0 });
        }
        Ok(sink)
    }

    /// The same sink, stopping at the next block once `stop` is set: the run then fails with
    /// [`aim_tracker::exit::Interrupted`] and the unfinished files are removed.
    pub fn until(mut self, stop: Option<&'a AtomicBool>) -> Self {
        self.stop = stop;
        self
    }

    /// Completes every file (header patched) and gives it its final name.
    pub fn finish(mut self) -> anyhow::Result<()> {
        for f in &mut self.files {
            if let Some(w) = f.writer.take() {
                w.finalize().with_context(|| format!("writing {}", f.part.display()))?;
            }
            std::fs::rename(&f.part, &f.done).with_context(|| {
                format!("renaming {} to {}", f.part.display(), f.done.display())
            })?;
        }
        self.files.clear();
        Ok(())
    }

    /// Removes the unfinished files.
    fn abandon(&mut self) {
        for f in self.files.drain(..) {
            drop(f.writer);
            let _ = std::fs::remove_file(&f.part);
        }
    }
}

impl Drop for WavSink<'_> {
    /// A sink dropped before [`WavSink::finish`] (an error) leaves no file behind.
    fn drop(&mut self) {
        self.abandon();
    }
}

impl AudioSink for WavSink<'_> {
    fn block(&mut self, array: usize, channels: &[&[f32]]) -> anyhow::Result<()> {
        if self.stop.is_some_and(|s| s.load(Ordering::SeqCst)) {
            return Err(anyhow::Error::new(aim_tracker::exit::Interrupted))
                .context("the unfinished recordings (array-<id>.wav.part) are removed");
        }
        let f = &mut self.files[array];
        for (m, ch) in channels.iter().enumerate() {
            if let Some(k) = ch.iter().position(|x| !x.is_finite()) {
                anyhow::bail!(
                    "the simulation produced a sample that is not a number (array {}, \
                     microphone {m}, sample {}); nothing written. Some value of the scenario is \
                     out of the simulator's range",
                    f.id,
                    f.written + k
                );
            }
        }
        let w = f.writer.as_mut().expect("open until finished");
        append(w, channels).with_context(|| format!("writing {}", f.part.display()))?;
        f.written += channels.first().map_or(0, |c| c.len());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Blocks appended as they come read back as one recording with the header's lengths
    /// patched; a non-finite sample stops the sink and leaves no file behind.
    #[test]
    fn blocks_append_and_a_nan_leaves_nothing() {
        let dir = std::env::temp_dir().join(format!("aim-wav-sink-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut sink = WavSink::create(&dir, &[(3, 2)], 48_000).unwrap();
        sink.block(0, &[&[1.0, 2.0], &[-1.0, -2.0]]).unwrap();
        sink.block(0, &[&[3.0], &[-3.0]]).unwrap();
        sink.finish().unwrap();
        let mut r = hound::WavReader::open(dir.join("array-3.wav")).unwrap();
        assert_eq!((r.spec().channels, r.duration()), (2, 3));
        let x: Vec<f32> = r.samples::<f32>().map(Result::unwrap).collect();
        assert_eq!(x, [1.0, -1.0, 2.0, -2.0, 3.0, -3.0]);

        let mut sink = WavSink::create(&dir, &[(4, 1)], 48_000).unwrap();
        sink.block(0, &[&[0.5, 0.25]]).unwrap();
        let e = sink.block(0, &[&[0.0, f32::NAN]]).unwrap_err().to_string();
        assert!(e.contains("array 4, microphone 0, sample 3"), "{e}");
        drop(sink);
        assert!(!dir.join("array-4.wav").exists() && !dir.join("array-4.wav.part").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
