//! aim-dsp outputs to frames (feature `dsp`).
//!
//! The firmware and the simulator both turn [`aim_dsp::Output`]s into frames through these
//! functions, so a simulated array sends the very bytes a real one would.
//!
//! ```
//! use aim_wire::{from_dsp, Encoder, MAX_ENCODED_LEN};
//! let out = aim_dsp::Output::Doa(aim_dsp::Doa { azimuth_rad: 0.5, quality: 0.9, ..Default::default() });
//! let mut encoder = Encoder::new(1);
//! let mut buf = [0u8; MAX_ENCODED_LEN];
//! let n = from_dsp::encode_output(&mut encoder, &out, &from_dsp::FirmwareCounters::default(), &mut buf)
//!     .unwrap();
//! assert!(n > 0);
//! ```

use crate::frame::{
    Beacon, Body, Detection, Doa, Health, Hello, Mfcc, MicLevels, Peak, Peaks, Snippet, MAX_MICS,
    MAX_PEAKS, MFCC_COEFFS, MFCC_HARMONIC, MFCC_MEL_BANDS, SNIPPET_SAMPLES,
};

// The frame's layout follows the DSP's feature counts.
const _: () = assert!(MFCC_MEL_BANDS == aim_dsp::idframe::MEL_BANDS);
const _: () = assert!(MFCC_COEFFS == aim_dsp::idframe::MFCC_COUNT);
const _: () = assert!(MFCC_HARMONIC == aim_dsp::features::HARMONIC_FEATURES);
const _: () = assert!(SNIPPET_SAMPLES == aim_dsp::snippet::SNIPPET_LEN);
use crate::{fixed, EncodeError, Encoder};

/// What the firmware knows and the DSP does not; goes into [`Health`] frames. All zero in
/// simulation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FirmwareCounters {
    /// CPU cycles spent on the last block.
    pub cycles_per_block: u32,
    /// Audio DMA overruns since start-up.
    pub dma_overruns: u32,
    /// Frames dropped since start-up because the uplink queue was full.
    pub dropped_frames: u32,
    /// Frames waiting in the uplink queue.
    pub queue_depth: u8,
    /// Capture chunks discarded because the DSP queue was full.
    pub dsp_overloads: u32,
    /// SAI FIFO overruns (the SAI's overrun flag).
    pub sai_overruns: u32,
    /// Gaps in the sample clock handed to the DSP.
    pub gaps: u32,
    /// Audio frames lost in those gaps.
    pub frames_lost: u32,
    /// DSP outputs dropped because their span crossed a gap.
    pub outputs_dropped: u32,
    /// DSP outputs beyond what the firmware buffers per chunk.
    pub outputs_overflowed: u32,
    /// Uplink UART transmit errors.
    pub uart_errors: u32,
    /// Frames that could not be encoded.
    pub frames_unencodable: u32,
    /// Capture chunks handed to the DSP.
    pub chunks_captured: u32,
}

/// The `Hello` of an array running `config`.
pub fn hello(config: &aim_dsp::Config, firmware_version: [u8; 3]) -> Hello {
    Hello::new(
        firmware_version,
        config.sample_rate_hz,
        u16::try_from(config.block_len).unwrap_or(u16::MAX),
        config.geometry.positions(),
    )
}

/// A DoA estimate at 0.01° resolution.
pub fn doa(d: &aim_dsp::Doa) -> Doa {
    Doa {
        span_samples: d.span_samples,
        pairs_used: d.pairs_used,
        ..Doa::new(d.azimuth_rad, d.zenith_rad, d.residual, d.quality)
    }
}

/// Amplitude as a fraction of full scale to dBFS; zero or less (silence) gives `-inf`, which
/// quantises to the field's minimum.
fn dbfs(fraction: f32) -> f32 {
    if fraction > 0.0 {
        20.0 * libm::log10f(fraction)
    } else {
        f32::NEG_INFINITY
    }
}

/// BPF peak groups at 0.01 Hz and 0.1 dB resolution (at most `count`, at most [`MAX_PEAKS`])
/// with their qualities, and the rotor-signature decision.
pub fn peaks(p: &aim_dsp::Peaks) -> Peaks {
    let mut list = heapless::Vec::new();
    let mut quality = heapless::Vec::new();
    for q in p.peaks.iter().take(usize::from(p.count).min(MAX_PEAKS)) {
        // Cannot fail: at most MAX_PEAKS are taken.
        let _ = list.push(Peak::new(q.hz, dbfs(q.amplitude), q.harmonicity));
        let _ = quality.push(fixed::to_u8(q.quality, 255.0));
    }
    Peaks {
        span_samples: p.span_samples,
        bpf_chz: fixed::to_u32(p.bpf_hz, 100.0),
        peaks: list,
        detection: if p.rotor { Detection::Rotor } else { Detection::NoRotor },
        quality,
    }
}

/// DSP health and firmware counters together.
pub fn health(h: &aim_dsp::Health, firmware: &FirmwareCounters) -> Health {
    Health {
        blocks: h.blocks,
        clipped_samples: h.clipped_samples,
        peak_ddbfs: fixed::to_i16(h.peak_dbfs, 10.0),
        block_exponent: h.block_exponent,
        cycles_per_block: firmware.cycles_per_block,
        dma_overruns: firmware.dma_overruns,
        dropped_frames: firmware.dropped_frames,
        queue_depth: firmware.queue_depth,
        dsp_overloads: firmware.dsp_overloads,
        sai_overruns: firmware.sai_overruns,
        gaps: firmware.gaps,
        frames_lost: firmware.frames_lost,
        outputs_dropped: firmware.outputs_dropped,
        outputs_overflowed: firmware.outputs_overflowed,
        uart_errors: firmware.uart_errors,
        frames_unencodable: firmware.frames_unencodable,
        chunks_captured: firmware.chunks_captured,
        mic_levels: mic_levels(h),
    }
}

/// The DSP's per-microphone levels at the wire's 0.1 dB.
fn mic_levels(h: &aim_dsp::Health) -> MicLevels {
    let mut levels = MicLevels { count: h.mics.min(MAX_MICS as u8), ..MicLevels::default() };
    for i in 0..usize::from(levels.count) {
        levels.rms_ddbfs[i] = fixed::to_i16(h.mic_rms_dbfs[i], 10.0);
        levels.dc_ddbfs[i] = fixed::to_i16(h.mic_dc_dbfs[i], 10.0);
    }
    levels
}

/// Identification features at the wire's resolution (log-mel and comb levels 0.01 dB, MFCC
/// 0.1 dB, fundamental 0.001 octave).
pub fn mfcc(f: &aim_dsp::IdFeatures) -> Mfcc {
    let mut m = Mfcc { span_samples: f.span_samples, ..Mfcc::default() };
    for (q, &v) in m.log_mel_cdb.iter_mut().zip(&f.log_mel_db) {
        *q = fixed::to_i16(v, 100.0);
    }
    for (q, &v) in m.mfcc_ddb.iter_mut().zip(&f.mfcc_db) {
        *q = fixed::to_i16(v, 10.0);
    }
    m.harmonic = comb(&f.harmonic);
    m.second_harmonic = Some(comb(&f.second));
    m
}

/// Comb features in their wire units (0.001 octave for the fundamental, then 0.01 dB).
fn comb(h: &aim_dsp::features::HarmonicFeatures) -> [i16; MFCC_HARMONIC] {
    let mut q = [0i16; MFCC_HARMONIC];
    for (i, (q, &v)) in q.iter_mut().zip(&h.to_array()).enumerate() {
        *q = fixed::to_i16(v, if i == 0 { 1000.0 } else { 100.0 });
    }
    q
}

/// The frame body and sample index of one pipeline output.
pub fn body(output: &aim_dsp::Output, firmware: &FirmwareCounters) -> (u64, Body) {
    match output {
        aim_dsp::Output::Doa(d) => (d.sample_index, Body::Doa(doa(d))),
        aim_dsp::Output::Peaks(p) => (p.sample_index, Body::Peaks(peaks(p))),
        aim_dsp::Output::Health(h) => (h.sample_index, Body::Health(health(h, firmware))),
        aim_dsp::Output::Mfcc(f) => (f.sample_index, Body::Mfcc(mfcc(f))),
        aim_dsp::Output::Beacon(b) => {
            (b.sample_index, Body::Beacon(Beacon::new(b.fraction, b.quality, b.level_db)))
        }
        aim_dsp::Output::Snippet(x) => (x.sample_index, Body::Snippet(snippet(x))),
    }
}

/// A snippet as it is: the chip's block exponent and mantissas.
pub fn snippet(x: &aim_dsp::Snippet) -> Snippet {
    Snippet {
        decimation: x.decimation,
        exponent: x.exponent,
        samples: heapless::Vec::from_slice(&x.samples).unwrap_or_default(),
    }
}

/// Encodes one pipeline output with the encoder's next sequence number into `out`; returns the
/// bytes written.
pub fn encode_output(
    encoder: &mut Encoder,
    output: &aim_dsp::Output,
    firmware: &FirmwareCounters,
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    let (sample_index, body) = body(output, firmware);
    encoder.encode(sample_index, body, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn doa_fields_map_with_their_units() {
        let d = aim_dsp::Doa {
            sample_index: 4096,
            span_samples: 4096,
            azimuth_rad: -1.0,
            zenith_rad: 0.5,
            residual: 0.37,
            quality: 0.66,
            pairs_used: 15,
        };
        let w = doa(&d);
        assert_eq!(w.azimuth_cdeg, -5730); // -57.2958°
        assert_eq!(w.zenith_cdeg, 2865); // 28.6479°
        assert_eq!(w.residual_csamples, 37);
        assert_eq!(w.quality, 168); // 0.66 * 255 = 168.3
        assert_eq!((w.span_samples, w.pairs_used), (4096, 15));
        assert_eq!(body(&aim_dsp::Output::Doa(d), &FirmwareCounters::default()).0, 4096);
    }

    #[test]
    fn peaks_amplitude_becomes_dbfs() {
        let mut p = aim_dsp::Peaks {
            rotor: true,
            sample_index: 0,
            span_samples: 24_576,
            bpf_hz: 187.5,
            count: 2,
            peaks: [aim_dsp::Peak::default(); 4],
        };
        p.peaks[0] = aim_dsp::Peak { hz: 187.5, amplitude: 0.1, harmonicity: 0.75, quality: 0.6 };
        p.peaks[1] = aim_dsp::Peak { hz: 250.0, amplitude: 0.0, harmonicity: 0.5, quality: 0.4 };
        p.peaks[2] = aim_dsp::Peak { hz: 999.0, amplitude: 0.5, harmonicity: 1.0, quality: 1.0 };
        let w = peaks(&p);
        assert_eq!(w.bpf_chz, 18_750);
        assert_eq!(w.peaks.len(), 2, "entries past count are not sent");
        assert_eq!(w.peaks[0].amplitude_ddb, -200); // 0.1 of full scale = -20 dBFS
        assert_eq!(w.peaks[0].harmonicity, 191); // 0.75 * 255 = 191.25
        assert_eq!(w.peaks[1].amplitude_ddb, i16::MIN, "silence");
        assert_eq!(w.span_samples, 24_576);
        assert_eq!((w.detection, w.quality.as_slice()), (Detection::Rotor, &[153u8, 102][..]));
        let none = peaks(&aim_dsp::Peaks { span_samples: 24_576, ..Default::default() });
        assert_eq!(none, Peaks::no_rotor(24_576), "no rotor signature: no BPF, no groups");
    }

    #[test]
    fn mfcc_fields_map_with_their_units() {
        let mut f =
            aim_dsp::IdFeatures { sample_index: 8192, span_samples: 24_576, ..Default::default() };
        f.log_mel_db[0] = -63.456;
        f.log_mel_db[23] = -400.0;
        f.mfcc_db[0] = -391.26;
        f.mfcc_db[12] = 1.04;
        f.harmonic.log2_f0 = 0.392; // 327.9 Hz
        f.harmonic.salience_db = 17.125;
        f.harmonic.envelope_db[4] = -33.333;
        let (index, body) = body(&aim_dsp::Output::Mfcc(f), &FirmwareCounters::default());
        let Body::Mfcc(m) = body else { panic!("{body:?}") };
        assert_eq!((index, m.span_samples), (8192, 24_576));
        assert_eq!(m.log_mel_cdb[0], -6346);
        assert_eq!(m.log_mel_cdb[23], i16::MIN, "saturates");
        assert_eq!((m.mfcc_ddb[0], m.mfcc_ddb[12]), (-3913, 10));
        assert_eq!(m.harmonic, [392, 1713, 0, 0, 0, 0, 0, 0, -3333]);
        assert!((m.harmonic_values()[0] - 0.392).abs() < 1e-6);
        assert!((m.mfcc_db(0) + 391.3).abs() < 1e-3);
    }

    #[test]
    fn beacon_fields_map_with_their_units() {
        let b = aim_dsp::beacon::Beacon {
            sample_index: 57_912,
            fraction: 0.602_1,
            quality: 0.93,
            level_db: -71.254,
        };
        let (index, body) = body(&aim_dsp::Output::Beacon(b), &FirmwareCounters::default());
        let Body::Beacon(w) = body else { panic!("{body:?}") };
        assert_eq!(index, 57_912);
        assert_eq!((w.fraction, w.quality, w.level_cdb), (39_459, 237, -7125));
        assert!((w.arrival_samples(index) - 57_912.602_1).abs() < 1.0 / 65_536.0);
        // A fraction that rounds up to a whole sample saturates below it.
        assert_eq!(Beacon::new(0.999_999, 1.0, 0.0).fraction, u16::MAX);
    }

    #[test]
    fn a_snippet_keeps_every_bit_and_its_value() {
        let mut x = aim_dsp::Snippet {
            sample_index: 1536,
            decimation: 6,
            exponent: -9,
            ..Default::default()
        };
        x.samples[0] = -127;
        x.samples[255] = 100;
        let (index, body) = body(&aim_dsp::Output::Snippet(x), &FirmwareCounters::default());
        let Body::Snippet(w) = body else { panic!("{body:?}") };
        assert_eq!((index, w.decimation, w.exponent, w.samples.len()), (1536, 6, -9, 256));
        assert_eq!((w.samples[0], w.samples[255]), (-127, 100));
        assert_eq!(w.value(255), f64::from(x.value(255)));
        assert_eq!(w.value(0), -127.0 / 512.0);
        assert_eq!(w.rate_hz(48_000), 8000.0);
    }

    #[test]
    fn hello_carries_the_geometry() {
        let config = aim_dsp::Config::new(aim_dsp::Geometry::respeaker_6mic(), 48_000);
        let h = hello(&config, [1, 2, 3]);
        assert_eq!(h.mic_positions_decimm.len(), 6);
        assert_eq!(h.mic_positions_decimm[0], [463, 0]); // 0.0463 m on +x
        assert_eq!((h.sample_rate_hz, h.block_len), (48_000, 1024));
    }
}
