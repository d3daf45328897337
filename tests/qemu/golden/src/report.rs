//! The parity report: every output of the checked computations, one line each, floats as bit
//! patterns (hex) followed by the output's `Debug` text, so that equal text means equal bits.
use core::fmt::{self, Write};

use aim_dsp::{Output, Pipeline};
use aim_wire::{from_dsp, Body, Encoder, MAX_ENCODED_LEN};

use crate::{scenario::PARITY, signal::Signal};

/// Sample rate of the reference `rfft_1024` input, Hz.
pub const SAMPLE_RATE_HZ: u32 = 48_000;

/// TDM frames per `push`: a DMA half-buffer of the firmware.
pub const CHUNK_FRAMES: usize = 256;

/// Most TDM slots per frame the golden configurations use.
pub const MAX_TDM_SLOTS: usize = 8;

/// Writes the whole parity report to `w`, using `pipeline` (about 112 KB: the caller decides
/// where it lives) for every scenario in turn.
pub fn write_parity(w: &mut impl Write, pipeline: &mut Pipeline) -> fmt::Result {
    write_rfft(w)?;
    for scenario in &PARITY {
        writeln!(w, "scenario {}", scenario.name)?;
        let config = scenario.config();
        if pipeline.configure(&config).is_err() {
            return writeln!(w, "error: scenario {} does not configure", scenario.name);
        }
        // The firmware's encode path: a `Hello`, then every output as a frame.
        let mut encoder = Encoder::new(ARRAY_ID);
        let hello = Body::Hello(from_dsp::hello(&config, FIRMWARE_VERSION));
        let mut frame = [0; MAX_ENCODED_LEN];
        let n = encoder.encode(0, hello, &mut frame);
        write_frame(w, n, &frame)?;
        let mut signal = scenario.signal();
        let mut words = [0i32; CHUNK_FRAMES * MAX_TDM_SLOTS];
        let words = &mut words[..CHUNK_FRAMES * config.tdm_slots];
        let mut result = Ok(());
        while signal.sample_index() < scenario.measured_samples() as u64 {
            signal.fill(words);
            pipeline.push(words, &mut |output| {
                if result.is_ok() {
                    result = write_output(w, &output).and_then(|()| {
                        let mut frame = [0; MAX_ENCODED_LEN];
                        let n =
                            from_dsp::encode_output(&mut encoder, &output, &COUNTERS, &mut frame);
                        write_frame(w, n, &frame)
                    });
                }
            });
            result?;
        }
    }
    writeln!(w, "end")
}

/// Array id in the frames' headers.
const ARRAY_ID: u8 = 3;

/// Firmware version in the `Hello` frames.
const FIRMWARE_VERSION: [u8; 3] = [0, 1, 0];

/// Firmware counters in the `Health` frames: non-zero, so that every field is exercised.
const COUNTERS: from_dsp::FirmwareCounters = from_dsp::FirmwareCounters {
    cycles_per_block: 1_234_567,
    dma_overruns: 2,
    dropped_frames: 300,
    queue_depth: 4,
};

/// One encoded frame, `frame <hex bytes>`, or the encoder's error.
fn write_frame<E: core::fmt::Debug>(
    w: &mut impl Write,
    written: Result<usize, E>,
    frame: &[u8],
) -> fmt::Result {
    match written {
        Ok(n) => {
            w.write_str("frame ")?;
            for byte in frame.get(..n).unwrap_or(frame) {
                write!(w, "{byte:02x}")?;
            }
            writeln!(w)
        }
        Err(e) => writeln!(w, "frame error {e:?}"),
    }
}

/// One output: kind, sample index, the float fields as hex bit patterns, then `Debug`.
pub fn write_output(w: &mut impl Write, output: &Output) -> fmt::Result {
    match output {
        Output::Doa(d) => write!(
            w,
            "doa {} {:08x} {:08x} {:08x} {:08x}",
            d.sample_index,
            d.azimuth_rad.to_bits(),
            d.zenith_rad.to_bits(),
            d.residual.to_bits(),
            d.quality.to_bits()
        )?,
        Output::Peaks(p) => {
            let rotor = if p.rotor { "rotor" } else { "no-rotor" };
            write!(w, "peaks {} {rotor} {:08x}", p.sample_index, p.bpf_hz.to_bits())?;
            for peak in &p.peaks[..usize::from(p.count).min(p.peaks.len())] {
                write!(
                    w,
                    " {:08x}/{:08x}/{:08x}/{:08x}",
                    peak.hz.to_bits(),
                    peak.amplitude.to_bits(),
                    peak.harmonicity.to_bits(),
                    peak.quality.to_bits()
                )?;
            }
        }
        Output::Health(h) => write!(w, "health {} {:08x}", h.sample_index, h.peak_dbfs.to_bits())?,
    }
    // Debug prints every field (also ones added later) with round-trip exact floats.
    writeln!(w, " | {output:?}")
}

/// microfft `rfft_1024` of the first 1024 samples of microphone 0 (as f32 of the 24-bit value):
/// `rfft <bin> <re> <im>`.
fn write_rfft(w: &mut impl Write) -> fmt::Result {
    let mut x = [0f32; 1024];
    reference_rfft_input(&mut x);
    let spectrum = microfft::real::rfft_1024(&mut x);
    for (k, c) in spectrum.iter().enumerate() {
        writeln!(w, "rfft {k} {:08x} {:08x}", c.re.to_bits(), c.im.to_bits())?;
    }
    Ok(())
}

/// The input of the reference `rfft_1024`: microphone 0 of the golden signal, 24-bit values as
/// f32 scaled to ±1.
pub fn reference_rfft_input(x: &mut [f32; 1024]) {
    let mut signal = Signal::new(&[0], 1, SAMPLE_RATE_HZ, 1);
    let mut words = [0i32; 1024];
    signal.fill(&mut words);
    for (x, w) in x.iter_mut().zip(words) {
        *x = (w >> 8) as f32 * (1.0 / 8_388_608.0);
    }
}
