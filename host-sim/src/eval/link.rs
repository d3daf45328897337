//! A simulated array's recording through the real path: TDM words → `aim_dsp::Pipeline` →
//! `aim_wire::from_dsp` (the firmware's encoder) → bytes → `aim_wire::Deframer` → frames.

use aim_dsp::{Config, Geometry, Pipeline};
use aim_wire::{from_dsp, Body, Deframer, Encoder, Frame, MAX_ENCODED_LEN};
use anyhow::Context as _;

use crate::ArrayRecording;

/// TDM slots per frame, as on the reference board.
pub const TDM_SLOTS: usize = 8;
/// Frames handed to the pipeline per call (a DMA half-buffer's worth).
const CHUNK_FRAMES: usize = 256;
/// Firmware version written into the simulated arrays' `Hello`.
pub const SIM_FIRMWARE_VERSION: [u8; 3] = [0, 1, 0];

/// The byte stream the array would send over its link: a `Hello`, then one frame per
/// pipeline output, in order. `full_scale_pa` maps to digital full scale.
pub fn link_bytes(rec: &ArrayRecording, full_scale_pa: f64) -> anyhow::Result<Vec<u8>> {
    let positions: Vec<[f32; 2]> =
        rec.positions.iter().map(|p| [p[0] as f32, p[1] as f32]).collect();
    let geometry = Geometry::from_positions(&positions)
        .map_err(|e| anyhow::anyhow!("{e:?}"))
        .with_context(|| format!("array {}: geometry", rec.id))?;
    let config = Config::new(geometry, rec.sample_rate_hz);
    let mut pipeline = Pipeline::new(&config)
        .map_err(|e| anyhow::anyhow!("{e:?}"))
        .with_context(|| format!("array {}: pipeline", rec.id))?;
    let mut encoder = Encoder::new(rec.id);
    let mut bytes = Vec::new();
    let mut buf = [0u8; MAX_ENCODED_LEN];
    let n = encoder
        .encode(0, Body::Hello(from_dsp::hello(&config, SIM_FIRMWARE_VERSION)), &mut buf)
        .map_err(|e| anyhow::anyhow!("{e:?}"))
        .context("encoding Hello")?;
    bytes.extend_from_slice(&buf[..n]);
    let words = rec.tdm_words(full_scale_pa, TDM_SLOTS);
    let firmware = from_dsp::FirmwareCounters::default();
    let mut error = None;
    for chunk in words.chunks(CHUNK_FRAMES * TDM_SLOTS) {
        pipeline.push(chunk, &mut |out| match from_dsp::encode_output(
            &mut encoder,
            &out,
            &firmware,
            &mut buf,
        ) {
            Ok(n) => bytes.extend_from_slice(&buf[..n]),
            Err(e) => error = Some(format!("{e:?}")),
        });
    }
    if let Some(e) = error {
        anyhow::bail!("array {}: encoding a frame: {e}", rec.id);
    }
    Ok(bytes)
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
