//! Helpers shared by the integration tests: sample frames, a seeded RNG, raw frame surgery.
#![allow(dead_code)]

use aim_wire::{
    cobs, crc32, encode, Body, Detection, Doa, Frame, Header, Health, Hello, Kind, Peak, Peaks,
    CRC_LEN, MAX_ENCODED_LEN, MAX_MICS, MAX_PANIC_MESSAGE, MAX_PEAKS, UNIQUE_ID_LEN,
};

/// SplitMix64: a tiny, seedable, well-mixed generator (the tests need no more).
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }
    pub fn u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `0..n` (n > 0); the modulo bias is irrelevant here.
    pub fn below(&mut self, n: usize) -> usize {
        (self.u64() % n as u64) as usize
    }
    pub fn byte(&mut self) -> u8 {
        self.u64() as u8
    }
    /// Random bytes of which about one in `zero_every` is a delimiter.
    pub fn garbage(&mut self, len: usize, zero_every: usize) -> Vec<u8> {
        (0..len).map(|_| if self.below(zero_every) == 0 { 0 } else { self.byte() }).collect()
    }
}

/// One representative frame per kind, as a ReSpeaker 6-mic array at 48 kHz would send them.
pub fn sample_frames() -> Vec<Frame> {
    let r = 0.0463f32;
    let positions: Vec<[f32; 2]> = (0..6)
        .map(|i| {
            let a = i as f32 * std::f32::consts::PI / 3.0;
            [r * a.cos(), r * a.sin()]
        })
        .collect();
    let header = |seq: u16, sample_index: u64| Header { array_id: 3, seq, sample_index };
    let mut peaks = heapless::Vec::new();
    for p in [
        Peak::new(187.42, -23.5, 0.91),
        Peak::new(374.9, -29.1, 0.8),
        Peak::new(562.3, -35.0, 0.62),
    ] {
        peaks.push(p).unwrap();
    }
    vec![
        Frame {
            header: header(0, 0),
            body: Body::Hello({
                let mut hello = Hello::new([0, 1, 0], 48_000, 1024, &positions);
                sample_hello_start(&mut hello);
                hello
            }),
        },
        Frame {
            header: header(1, 3_072_000),
            body: Body::Doa(Doa {
                span_samples: 4096,
                pairs_used: 15,
                ..Doa::new(std::f32::consts::FRAC_PI_4, std::f32::consts::FRAC_PI_3, 0.12, 0.87)
            }),
        },
        Frame {
            header: header(2, 3_072_000),
            body: Body::Peaks(Peaks {
                span_samples: 24_576,
                bpf_chz: 18_742,
                quality: peaks.iter().map(|_| 200).collect(),
                peaks,
                detection: Detection::Rotor,
            }),
        },
        Frame {
            header: header(3, 3_073_024),
            body: Body::Health(Health {
                blocks: 3001,
                clipped_samples: 17,
                peak_ddbfs: -123,
                block_exponent: 3,
                cycles_per_block: 1_850_000,
                dma_overruns: 0,
                dropped_frames: 2,
                queue_depth: 1,
                dsp_overloads: 1,
                sai_overruns: 0,
                gaps: 2,
                frames_lost: 2_304,
                outputs_dropped: 3,
                outputs_overflowed: 0,
                uart_errors: 0,
                frames_unencodable: 0,
                chunks_captured: 562_688,
                // Without the per-microphone levels: the bytes of a board that sends none.
                mic_levels: aim_wire::MicLevels::default(),
            }),
        },
        Frame { header: header(4, 3_072_000), body: Body::Mfcc(sample_mfcc()) },
        // A 60 dB beacon at 10 m, heard 1.2 s after start: arrival 57 912.6021 samples.
        Frame {
            header: header(5, 57_912),
            body: Body::Beacon(aim_wire::Beacon::new(0.6021, 0.93, -71.25)),
        },
        Frame { header: header(5, 3_073_536), body: Body::Snippet(sample_snippet()) },
    ]
}

/// A `Snippet` payload: a 328 Hz fundamental with its second harmonic at 8 kHz, peak mantissa
/// 120, exponent −12 (about −31 dBFS).
pub fn sample_snippet() -> aim_wire::Snippet {
    let samples = (0..aim_wire::SNIPPET_SAMPLES)
        .map(|j| {
            let w = 2.0 * std::f64::consts::PI * 328.0 * j as f64 / 8000.0;
            (80.0 * w.sin() + 40.0 * (2.0 * w + 0.5).sin()).round() as i8
        })
        .collect();
    aim_wire::Snippet { decimation: 6, exponent: -12, samples }
}

/// An `Mfcc` payload as a hovering drone at 4 m gives (levels of a real run, rounded): a
/// falling log-mel spectrum, its cepstrum, a 328 Hz comb with 2-blade shaft lines, and a
/// weaker 117 Hz comb beside it (a desk fan).
pub fn sample_mfcc() -> aim_wire::Mfcc {
    let mut m = aim_wire::Mfcc { span_samples: 24_576, ..Default::default() };
    for (b, v) in m.log_mel_cdb.iter_mut().enumerate() {
        *v = -5_200 - 150 * b as i16;
    }
    m.mfcc_ddb = [-3_560, 245, -31, 12, -8, 40, -3, 5, 0, -17, 2, 9, -1];
    m.harmonic = [392, 2_112, 845, 96, -412, -905, -1_288, -1_702, -2_203];
    m.second_harmonic = Some([-1_095, 1_204, 130, 88, -655, -1_020, -1_540, -1_811, -2_630]);
    m
}

/// The sample `Hello` as a board reports its start: after a panic, second boot since power-on.
pub fn sample_hello_start(hello: &mut Hello) {
    hello.reset_cause = aim_wire::ResetCause::Panic.code();
    hello.boot_count = 2;
    hello.unique_id = [0x33, 0x00, 0x4A, 0x00, 0x0E, 0x51, 0x31, 0x30, 0x36, 0x38, 0x35, 0x39];
    hello.set_panic_message("src/processing.rs:171 index out of bounds");
}

/// The frame of `kind` whose every varint is at its widest: its encoding is the longest.
pub fn worst_case(kind: Kind) -> Frame {
    let header = Header { array_id: u8::MAX, seq: u16::MAX, sample_index: u64::MAX };
    let body = match kind {
        Kind::Hello => Body::Hello(Hello {
            firmware_version: [u8::MAX; 3],
            sample_rate_hz: u32::MAX,
            block_len: u16::MAX,
            mic_positions_decimm: heapless::Vec::from_slice(&[[i16::MIN; 2]; MAX_MICS]).unwrap(),
            reset_cause: u8::MAX,
            boot_count: u32::MAX,
            unique_id: [u8::MAX; UNIQUE_ID_LEN],
            // 0x7F is the longest character whose byte COBS and postcard leave alone.
            panic_message: core::iter::repeat_n('\u{7f}', MAX_PANIC_MESSAGE).collect(),
            chip_revision: u16::MAX,
            clock_source: u8::MAX,
            sysclk_hz: u32::MAX,
        }),
        Kind::Doa => Body::Doa(Doa {
            span_samples: u32::MAX,
            pairs_used: u8::MAX,
            azimuth_cdeg: i16::MIN,
            zenith_cdeg: u16::MAX,
            residual_csamples: u16::MAX,
            quality: u8::MAX,
        }),
        Kind::Peaks => Body::Peaks(Peaks {
            span_samples: u32::MAX,
            bpf_chz: u32::MAX,
            peaks: heapless::Vec::from_slice(
                &[Peak { freq_chz: u32::MAX, amplitude_ddb: i16::MIN, harmonicity: u8::MAX };
                    MAX_PEAKS],
            )
            .unwrap(),
            detection: Detection::Rotor,
            quality: heapless::Vec::from_slice(&[u8::MAX; MAX_PEAKS]).unwrap(),
        }),
        Kind::Health => Body::Health(Health {
            blocks: u32::MAX,
            clipped_samples: u32::MAX,
            peak_ddbfs: i16::MIN,
            block_exponent: i8::MIN,
            cycles_per_block: u32::MAX,
            dma_overruns: u32::MAX,
            dropped_frames: u32::MAX,
            queue_depth: u8::MAX,
            dsp_overloads: u32::MAX,
            sai_overruns: u32::MAX,
            gaps: u32::MAX,
            frames_lost: u32::MAX,
            outputs_dropped: u32::MAX,
            outputs_overflowed: u32::MAX,
            uart_errors: u32::MAX,
            frames_unencodable: u32::MAX,
            chunks_captured: u32::MAX,
            mic_levels: aim_wire::MicLevels {
                count: aim_wire::MAX_MICS as u8,
                rms_ddbfs: [i16::MIN; aim_wire::MAX_MICS],
                dc_ddbfs: [i16::MIN; aim_wire::MAX_MICS],
            },
        }),
        Kind::Mfcc => Body::Mfcc(aim_wire::Mfcc {
            span_samples: u32::MAX,
            log_mel_cdb: [i16::MIN; aim_wire::MFCC_MEL_BANDS],
            mfcc_ddb: [i16::MIN; aim_wire::MFCC_COEFFS],
            harmonic: [i16::MIN; aim_wire::MFCC_HARMONIC],
            second_harmonic: Some([i16::MIN; aim_wire::MFCC_HARMONIC]),
        }),
        Kind::Beacon => Body::Beacon(aim_wire::Beacon {
            fraction: u16::MAX,
            quality: u8::MAX,
            level_cdb: i16::MIN,
        }),
        // 0x7F: no byte for COBS to remove.
        Kind::Snippet => Body::Snippet(aim_wire::Snippet {
            decimation: u8::MAX,
            exponent: i8::MIN,
            samples: heapless::Vec::from_slice(&[i8::MAX; aim_wire::SNIPPET_SAMPLES]).unwrap(),
        }),
        _ => unreachable!("a kind without a worst case: add it here"),
    };
    Frame { header, body }
}

/// A random frame of a random kind with random fields (any value the types allow).
pub fn random_frame(rng: &mut Rng, array_id: u8, seq: u16) -> Frame {
    let header = Header { array_id, seq, sample_index: rng.u64() >> rng.below(64) };
    let small = |rng: &mut Rng| (rng.u64() >> rng.below(64)) as u32;
    let body = match rng.below(6) {
        0 => Body::Hello(Hello {
            firmware_version: [rng.byte(), rng.byte(), rng.byte()],
            sample_rate_hz: small(rng),
            block_len: small(rng) as u16,
            mic_positions_decimm: (0..rng.below(MAX_MICS + 1))
                .map(|_| [rng.u64() as i16, rng.u64() as i16])
                .collect(),
            reset_cause: rng.byte(),
            boot_count: small(rng),
            unique_id: core::array::from_fn(|_| rng.byte()),
            panic_message: (0..rng.below(MAX_PANIC_MESSAGE / 4 + 1))
                .map(|_| char::from_u32(rng.u64() as u32 % 0x11_0000).unwrap_or('\u{fffd}'))
                .collect(),
            chip_revision: small(rng) as u16,
            clock_source: rng.byte(),
            sysclk_hz: small(rng),
        }),
        1 => Body::Doa(Doa {
            span_samples: small(rng),
            pairs_used: rng.byte(),
            azimuth_cdeg: rng.u64() as i16,
            zenith_cdeg: rng.u64() as u16,
            residual_csamples: small(rng) as u16,
            quality: rng.byte(),
        }),
        2 => Body::Peaks(Peaks {
            span_samples: small(rng),
            bpf_chz: small(rng),
            peaks: (0..rng.below(MAX_PEAKS + 1))
                .map(|_| Peak {
                    freq_chz: small(rng),
                    amplitude_ddb: rng.u64() as i16,
                    harmonicity: rng.byte(),
                })
                .collect(),
            detection: [Detection::Unstated, Detection::NoRotor, Detection::Rotor][rng.below(3)],
            quality: (0..rng.below(MAX_PEAKS + 1)).map(|_| rng.byte()).collect(),
        }),
        4 => Body::Beacon(aim_wire::Beacon {
            fraction: rng.u64() as u16,
            quality: rng.byte(),
            level_cdb: rng.u64() as i16,
        }),
        3 => Body::Mfcc(aim_wire::Mfcc {
            span_samples: small(rng),
            log_mel_cdb: core::array::from_fn(|_| rng.u64() as i16),
            mfcc_ddb: core::array::from_fn(|_| rng.u64() as i16),
            harmonic: core::array::from_fn(|_| rng.u64() as i16),
            second_harmonic: (rng.byte() & 1 == 1)
                .then(|| core::array::from_fn(|_| rng.u64() as i16)),
        }),
        _ => Body::Health(Health {
            blocks: small(rng),
            clipped_samples: small(rng),
            peak_ddbfs: rng.u64() as i16,
            block_exponent: rng.byte() as i8,
            cycles_per_block: small(rng),
            dma_overruns: small(rng),
            dropped_frames: small(rng),
            queue_depth: rng.byte(),
            dsp_overloads: small(rng),
            sai_overruns: small(rng),
            gaps: small(rng),
            frames_lost: small(rng),
            outputs_dropped: small(rng),
            outputs_overflowed: small(rng),
            uart_errors: small(rng),
            frames_unencodable: small(rng),
            chunks_captured: small(rng),
            mic_levels: {
                let count = rng.below(aim_wire::MAX_MICS + 1) as u8;
                let mut levels = aim_wire::MicLevels { count, ..aim_wire::MicLevels::default() };
                for i in 0..usize::from(count) {
                    levels.rms_ddbfs[i] = rng.u64() as i16;
                    levels.dc_ddbfs[i] = rng.u64() as i16;
                }
                levels
            },
        }),
    };
    Frame { header, body }
}

/// The wire bytes of `frame`.
pub fn wire(frame: &Frame) -> Vec<u8> {
    let mut out = [0u8; MAX_ENCODED_LEN];
    let n = encode(frame, &mut out).expect("MAX_ENCODED_LEN fits every frame");
    out[..n].to_vec()
}

/// The raw bytes (header, payload, CRC; no COBS) of `frame`.
pub fn raw(frame: &Frame) -> Vec<u8> {
    let w = wire(frame);
    let mut inner = w[1..w.len() - 1].to_vec();
    let n = cobs::decode_in_place(&mut inner).unwrap();
    inner.truncate(n);
    inner
}

/// Wire bytes of a hand-made raw frame: `body` (header and payload) gets a fresh CRC, COBS and
/// delimiters.
pub fn reframe(body: &[u8]) -> Vec<u8> {
    let mut raw = body.to_vec();
    raw.extend_from_slice(&crc32(body).to_le_bytes());
    let mut out = vec![0u8; cobs::max_encoded_len(raw.len()) + 2];
    let n = cobs::encode(&raw, &mut out[1..]).unwrap();
    out.truncate(n + 2);
    let last = out.len() - 1;
    out[last] = 0;
    out
}

/// `raw` without its CRC trailer.
pub fn strip_crc(raw: &[u8]) -> &[u8] {
    &raw[..raw.len() - CRC_LEN]
}

/// Number of non-empty chunks between delimiters (a trailing unterminated chunk included): the
/// number of outcomes a deframer must report for `stream`, counted without it.
pub fn chunk_count(stream: &[u8]) -> u64 {
    stream.split(|&b| b == 0).filter(|c| !c.is_empty()).count() as u64
}
