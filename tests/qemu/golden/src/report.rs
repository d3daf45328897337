//! The parity report: every output of the checked computations, one line each, floats as bit
//! patterns (hex) followed by the output's `Debug` text, so that equal text means equal bits.
use core::fmt::{self, Write};

use aim_dsp::{Output, Pipeline};
use aim_wire::{from_dsp, Body, Encoder, MAX_ENCODED_LEN};

use aim_dsp::pdm::{PdmDecimator, BYTES_PER_OUTPUT};

use crate::{
    pdm::PdmSignal,
    scenario::{COST, PARITY},
    signal::Signal,
};

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
    write_doa_fits(w)?;
    write_pdm(w)?;
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

/// Chunks of [`CHUNK_FRAMES`] frames of the PDM parity check: 0.256 s at 48 kHz.
pub const PDM_PARITY_CHUNKS: usize = 48;

/// The PDM decimator (`aim_dsp::pdm`) on the golden PDM of the 8-microphone scenario, one line
/// per chunk: `pdm <chunk> <frames> <FNV-1a 64 of every word> <the chunk's first frame>`, words
/// in hex.
fn write_pdm(w: &mut impl Write) -> fmt::Result {
    let scenario = &COST[2];
    let mics = scenario.config().tdm_slots;
    let mut pdm = PdmSignal::new(scenario.signal(), mics);
    let mut decimator = PdmDecimator::new(mics, mics);
    let mut bytes = [0u8; CHUNK_FRAMES * BYTES_PER_OUTPUT * MAX_TDM_SLOTS];
    let bytes = &mut bytes[..CHUNK_FRAMES * pdm.frame_bytes()];
    let mut words = [0i32; CHUNK_FRAMES * MAX_TDM_SLOTS];
    let words = &mut words[..CHUNK_FRAMES * mics];
    for chunk in 0..PDM_PARITY_CHUNKS {
        pdm.fill(bytes);
        match decimator.push(bytes, words, mics) {
            Ok(frames) => {
                let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
                for byte in words.iter().flat_map(|word| word.to_le_bytes()) {
                    hash = (hash ^ u64::from(byte)).wrapping_mul(0x0000_0100_0000_01b3);
                }
                write!(w, "pdm {chunk} {frames} {hash:016x}")?;
                for word in &words[..mics] {
                    write!(w, " {word:08x}")?;
                }
                writeln!(w)?;
            }
            Err(e) => writeln!(w, "pdm {chunk} error {e:?}")?,
        }
    }
    Ok(())
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
    dsp_overloads: 5,
    sai_overruns: 6,
    gaps: 7,
    frames_lost: 70_000,
    outputs_dropped: 8,
    outputs_overflowed: 9,
    uart_errors: 10,
    frames_unencodable: 11,
    chunks_captured: 123_456,
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
        Output::Beacon(b) => write!(
            w,
            "beacon {} {:08x} {:08x} {:08x}",
            b.sample_index,
            b.fraction.to_bits(),
            b.quality.to_bits(),
            b.level_db.to_bits()
        )?,
        Output::Snippet(x) => {
            // Integers only: the mantissas in hex are every bit (the frame line repeats them).
            write!(w, "snippet {} {} {} ", x.sample_index, x.decimation, x.exponent)?;
            for m in x.samples {
                write!(w, "{:02x}", m as u8)?;
            }
            return writeln!(w);
        }
        Output::Mfcc(f) => {
            write!(w, "mfcc {}", f.sample_index)?;
            let harmonic = f.harmonic.to_array();
            for v in f.log_mel_db.iter().chain(&f.mfcc_db).chain(&harmonic) {
                write!(w, " {:08x}", v.to_bits())?;
            }
        }
    }
    // Debug prints every field (also ones added later) with round-trip exact floats.
    writeln!(w, " | {output:?}")
}

/// The robust direction fit on its own, with pairs locked onto reflections (the robust path
/// the golden tone rarely takes): per array and case, `fit <mics> <case>` and the fit's floats
/// as bit patterns, then `Debug`. Case 0 is clean; case k moves every (7·k)-th pair (from
/// pair k) by ±3 samples, as a reflection-locked correlation peak would.
pub fn write_doa_fits(w: &mut impl Write) -> fmt::Result {
    use aim_dsp::{doa, gcc_phat::DelayEstimate, Geometry, MAX_PAIRS};
    let k = SAMPLE_RATE_HZ as f32 / 343.0;
    let geometries =
        [Geometry::respeaker_4mic(), Geometry::respeaker_6mic(), Geometry::circle_8mic()];
    for g in geometries {
        let p = g.positions();
        let mut pairs = [doa::Pair::default(); MAX_PAIRS];
        let mut n = 0;
        for i in 0..p.len() {
            for j in i + 1..p.len() {
                let b = [p[i][0] - p[j][0], p[i][1] - p[j][1]];
                pairs[n] = doa::Pair { i: i as u8, j: j as u8, baseline_m: b, max_lag: 20 };
                n += 1;
            }
        }
        let pairs = &pairs[..n];
        for case in 0..4usize {
            // Direction (sin 70° cos 100°, sin 70° sin 100°), a different spread per case.
            let u = [-0.163_176_9f32, 0.925_416_6];
            let mut delays = [DelayEstimate::default(); MAX_PAIRS];
            for (m, (d, pair)) in delays.iter_mut().zip(pairs).enumerate() {
                let spread = 0.02 * ((m * 5 + case) % 9) as f32 - 0.08;
                let mut tau = (pair.baseline_m[0] * u[0] + pair.baseline_m[1] * u[1]) * k + spread;
                if case > 0 && m >= case && (m - case) % 7 == 0 {
                    tau += if tau > 0.0 { -3.0 } else { 3.0 };
                }
                let q = ((m * 3 + case) % 5) as f32;
                *d = DelayEstimate {
                    delay_samples: tau,
                    coherence: 0.6 + 0.08 * q,
                    peak_margin: 0.9,
                };
            }
            match doa::fit(pairs, &delays[..n], k) {
                Some(f) => writeln!(
                    w,
                    "fit {} {case} {:08x} {:08x} {:08x} {:08x} | {f:?}",
                    p.len(),
                    f.azimuth_rad.to_bits(),
                    f.zenith_rad.to_bits(),
                    f.residual_samples.to_bits(),
                    f.kept_weight.to_bits()
                )?,
                None => writeln!(w, "fit {} {case} none", p.len())?,
            }
        }
    }
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_report_holds_the_pdm_decimator_chunks() {
        let mut report = String::new();
        let mut pipeline = Box::new(Pipeline::empty());
        write_parity(&mut report, &mut pipeline).unwrap();
        let pdm: Vec<&str> = report.lines().filter(|l| l.starts_with("pdm ")).collect();
        assert_eq!(pdm.len(), PDM_PARITY_CHUNKS);
        for (chunk, line) in pdm.iter().enumerate() {
            let fields: Vec<&str> = line.split(' ').collect();
            assert_eq!(fields[1], chunk.to_string());
            assert_eq!(fields[2], CHUNK_FRAMES.to_string(), "{line}");
            assert_eq!(fields.len(), 4 + 8, "{line}");
        }
        // The words carry the golden tone: not all chunks hash alike.
        assert_ne!(pdm[10].split(' ').nth(3), pdm[11].split(' ').nth(3));
    }
}
