//! A simulated array's recording through the real path: TDM words → `aim_dsp::Pipeline` →
//! `aim_wire::from_dsp` (the firmware's encoder) → bytes → `aim_wire::Deframer` → frames.

use aim_dsp::{Config, Geometry, Pipeline};
use aim_wire::{from_dsp, Body, Deframer, Encoder, Frame, MAX_ENCODED_LEN};
use anyhow::Context as _;

use crate::ArrayRecording;

/// TDM slots per frame, as on the reference board.
pub const TDM_SLOTS: usize = 8;
/// Frames handed to the pipeline per call (a DMA half-buffer's worth).
pub const CHUNK_FRAMES: usize = 256;
/// Firmware version written into the simulated arrays' `Hello`.
pub const SIM_FIRMWARE_VERSION: [u8; 3] = [0, 1, 0];

/// A simulated board's encoder: its `Hello`, then each pipeline output as the firmware frames
/// it (`aim_wire::from_dsp`). A simulated board has no firmware faults: its counters stay zero.
pub struct BoardEncoder {
    encoder: Encoder,
    firmware: from_dsp::FirmwareCounters,
}

impl BoardEncoder {
    /// The encoder of array `id`, and the bytes of its `Hello` for `config` (geometry, rate)
    /// with [`SIM_FIRMWARE_VERSION`].
    pub fn new(id: u8, config: &Config) -> anyhow::Result<(Self, Vec<u8>)> {
        let mut encoder = Encoder::new(id);
        let mut buf = [0u8; MAX_ENCODED_LEN];
        let n = encoder
            .encode(0, Body::Hello(from_dsp::hello(config, SIM_FIRMWARE_VERSION)), &mut buf)
            .map_err(|e| anyhow::anyhow!("array {id}: encoding the Hello: {e:?}"))?;
        Ok((Self { encoder, firmware: from_dsp::FirmwareCounters::default() }, buf[..n].to_vec()))
    }

    /// Encodes `output` into `buf`; the frame's length, bytes.
    pub fn encode(
        &mut self,
        output: &aim_dsp::Output,
        buf: &mut [u8; MAX_ENCODED_LEN],
    ) -> Result<usize, aim_wire::EncodeError> {
        from_dsp::encode_output(&mut self.encoder, output, &self.firmware, buf)
    }
}

/// The byte stream the array would send over its link: a `Hello`, then one frame per
/// pipeline output, in order. `full_scale_pa` maps to digital full scale.
pub fn link_bytes(rec: &ArrayRecording, full_scale_pa: f64) -> anyhow::Result<Vec<u8>> {
    let mut link = LinkStream::new(rec, full_scale_pa)?;
    let channels: Vec<&[f32]> = rec.channels.iter().map(Vec::as_slice).collect();
    link.push(&channels)?;
    link.finish()
}

/// [`link_bytes`] fed block by block: the recording's TDM words go to the pipeline in the same
/// [`CHUNK_FRAMES`] pieces whatever the blocks, so the bytes are the same.
pub struct LinkStream {
    id: u8,
    full_scale_pa: f64,
    pipeline: Pipeline,
    encoder: BoardEncoder,
    /// TDM words not handed to the pipeline yet (less than one chunk).
    pending: Vec<i32>,
    /// Samples handed to the pipeline so far.
    samples: u64,
    /// The link is down over these samples of the array's clock (frames sent then are lost).
    down: Option<(u64, u64)>,
    bytes: Vec<u8>,
    error: Option<String>,
}

impl LinkStream {
    /// A board with `rec`'s id, geometry and rate (its channels are not read) that has sent
    /// its `Hello`.
    pub fn new(rec: &ArrayRecording, full_scale_pa: f64) -> anyhow::Result<Self> {
        let positions: Vec<[f32; 2]> =
            rec.positions.iter().map(|p| [p[0] as f32, p[1] as f32]).collect();
        let geometry = Geometry::from_positions(&positions)
            .map_err(|e| anyhow::anyhow!("{e:?}"))
            .with_context(|| format!("array {}: geometry", rec.id))?;
        let config = Config::new(geometry, rec.sample_rate_hz);
        let pipeline = Pipeline::new(&config)
            .map_err(|e| anyhow::anyhow!("{e:?}"))
            .with_context(|| format!("array {}: pipeline", rec.id))?;
        let (encoder, hello) = BoardEncoder::new(rec.id, &config)?;
        Ok(Self {
            id: rec.id,
            full_scale_pa,
            pipeline,
            encoder,
            pending: Vec::with_capacity(CHUNK_FRAMES * TDM_SLOTS),
            samples: 0,
            down: rec.link_down_s.map(|[a, b]| {
                let rate = f64::from(rec.sample_rate_hz);
                ((a * rate) as u64, (b * rate) as u64)
            }),
            bytes: hello,
            error: None,
        })
    }

    /// The next samples of every microphone (Pa, all the same length).
    pub fn push(&mut self, channels: &[&[f32]]) -> anyhow::Result<()> {
        let len = channels.first().map_or(0, |c| c.len());
        for k in 0..len {
            let frame = self.pending.len();
            self.pending.resize(frame + TDM_SLOTS, 0);
            for (i, ch) in channels.iter().enumerate().take(TDM_SLOTS) {
                self.pending[frame + i] = crate::tdm_word(ch[k], self.full_scale_pa);
            }
            if self.pending.len() == CHUNK_FRAMES * TDM_SLOTS {
                self.flush();
            }
        }
        match self.error.take() {
            Some(e) => anyhow::bail!("array {}: encoding a frame: {e}", self.id),
            None => Ok(()),
        }
    }

    /// Hands the pending words to the pipeline.
    fn flush(&mut self) {
        let mut buf = [0u8; MAX_ENCODED_LEN];
        // A frame goes out when the chunk that completes it has been handed over: with the
        // link down then, it is lost (the encoder's sequence number still counts it).
        self.samples += (self.pending.len() / TDM_SLOTS) as u64;
        let lost = self.down.is_some_and(|(a, b)| (a..b).contains(&self.samples));
        let (encoder, bytes, error) = (&mut self.encoder, &mut self.bytes, &mut self.error);
        self.pipeline.push(&self.pending, &mut |out| match encoder.encode(&out, &mut buf) {
            Ok(n) if !lost => bytes.extend_from_slice(&buf[..n]),
            Ok(_) => {}
            Err(e) => *error = Some(format!("{e:?}")),
        });
        self.pending.clear();
    }

    /// The last (partial) chunk through the pipeline; the bytes sent.
    pub fn finish(mut self) -> anyhow::Result<Vec<u8>> {
        if !self.pending.is_empty() {
            self.flush();
        }
        match self.error {
            Some(e) => anyhow::bail!("array {}: encoding a frame: {e}", self.id),
            None => Ok(self.bytes),
        }
    }
}

/// Every array of a simulation through its link as the audio is rendered.
struct LinkSink(Vec<LinkStream>);

impl crate::AudioSink for LinkSink {
    fn block(&mut self, array: usize, channels: &[&[f32]]) -> anyhow::Result<()> {
        self.0[array].push(channels)
    }
}

/// Simulates `scenario` straight into every array's link bytes (in scenario order; the
/// simulation's `channels` are empty): what [`link_bytes`] gives for each recording of
/// [`crate::simulate_with`], without holding the recordings.
pub fn simulate_links(
    scenario: &crate::scenario::Scenario,
    options: &crate::Options,
    progress: &indicatif::ProgressBar,
    full_scale_pa: f64,
) -> anyhow::Result<(crate::Simulation, Vec<Vec<u8>>)> {
    let mut links = Vec::new();
    for a in &scenario.arrays {
        let rec = ArrayRecording::empty_for(scenario, a);
        links.push(LinkStream::new(&rec, full_scale_pa)?);
    }
    let mut sink = LinkSink(links);
    let sim = crate::simulate_to(scenario, options, progress, &mut sink)?;
    let bytes = sink.0.into_iter().map(LinkStream::finish).collect::<anyhow::Result<_>>()?;
    Ok((sim, bytes))
}

/// Decodes a byte stream into frames, as the host's intake does; returns the frames and the
/// number of chunks that failed to decode.
pub fn decode_frames(bytes: &[u8]) -> (Vec<Frame>, u64) {
    let mut deframer: Box<Deframer> = Box::default();
    let mut frames = Vec::new();
    let mut errors = 0;
    for &b in bytes {
        match deframer.push(b) {
            Some(Ok(f)) => frames.push(f),
            Some(Err(_)) => errors += 1,
            None => {}
        }
    }
    if deframer.finish().is_some() {
        errors += 1;
    }
    (frames, errors)
}
