//! The format itself: pinned discriminants, worst-case sizes, golden bytes, compatibility rules.

mod common;

use aim_wire::{
    decode, reserved, stm32h7_revision_name, Body, ClockSource, DecodeError, Deframer, Frame, Kind,
    LinkStats, ResetCause, MAX_ENCODED_LEN, MAX_RAW_LEN, PROTOCOL_VERSION,
};
use common::{raw, reframe, sample_frames, strip_crc, wire, worst_case};
use proptest::prelude::*;
use std::f32::consts::PI;

#[test]
fn discriminants_are_pinned() {
    // These bytes are on the wire of every recording ever made: never change them.
    assert_eq!(Kind::Hello as u8, 0);
    assert_eq!(Kind::Doa as u8, 1);
    assert_eq!(Kind::Peaks as u8, 2);
    assert_eq!(Kind::Health as u8, 3);
    assert_eq!(Kind::Mfcc as u8, 4);
    assert_eq!(reserved::MFCC, Kind::Mfcc as u8);
    assert_eq!(Kind::Beacon as u8, 5);
    assert_eq!(reserved::BEACON, Kind::Beacon as u8);
    assert_eq!(reserved::SNIPPET, 6);
    assert_eq!(Kind::Snippet as u8, reserved::SNIPPET);
    assert_eq!(aim_wire::MAGIC, 0xA1);
    assert_eq!(PROTOCOL_VERSION, 1);
    for kind in Kind::ALL {
        assert_eq!(Kind::from_byte(kind.byte()), Some(kind));
    }
    for byte in [7, 255] {
        assert_eq!(Kind::from_byte(byte), None);
    }
    // The kind byte sits at offset 2 of every raw frame.
    for frame in sample_frames() {
        assert_eq!(raw(&frame)[2], frame.body.kind() as u8);
    }
}

#[test]
fn max_encoded_size_per_kind() {
    // Declared worst cases (computed by hand in `Kind::max_payload_len`) against real encodings
    // of frames with every varint at its widest.
    let expected = [
        (Kind::Hello, 156, 159),
        (Kind::Doa, 36, 39),
        (Kind::Peaks, 73, 76),
        (Kind::Health, 144, 147),
        (Kind::Mfcc, 191, 194),
        (Kind::Beacon, 27, 30),
        (Kind::Snippet, 280, 284),
    ];
    for (kind, raw_len, wire_len) in expected {
        let frame = worst_case(kind);
        assert_eq!(raw(&frame).len(), raw_len, "{kind:?} raw");
        assert_eq!(wire(&frame).len(), wire_len, "{kind:?} on the wire");
        assert_eq!(kind.max_raw_len(), raw_len, "{kind:?} declared raw");
        assert_eq!(kind.max_encoded_len(), wire_len, "{kind:?} declared wire");
    }
    assert_eq!(MAX_RAW_LEN, 280);
    assert_eq!(MAX_ENCODED_LEN, 284);
}

const GOLDEN_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden");

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" ")
}

fn unhex(text: &str) -> Vec<u8> {
    text.split_whitespace()
        .map(|h| u8::from_str_radix(h, 16).expect("golden file holds hex bytes"))
        .collect()
}

/// The frames decoded from `tests/golden/<name>-sample-base.hex`: the snapshot of a sample
/// frame's bytes as older firmware sent them, before fields were appended (rule 3).
fn older_firmware_snapshot(name: &str) -> Vec<Result<Frame, DecodeError>> {
    let path = format!("{GOLDEN_DIR}/{name}-sample-base.hex");
    let golden = std::fs::read_to_string(&path).unwrap();
    let mut deframer: Deframer = Deframer::new();
    deframer.feed(&unhex(&golden)).collect()
}

#[test]
fn golden_bytes_of_every_kind() {
    // `AIM_WIRE_BLESS=1 cargo test -p aim-wire --test format` rewrites the snapshots.
    let bless = std::env::var_os("AIM_WIRE_BLESS").is_some();
    let frames: Vec<Frame> =
        sample_frames().into_iter().chain(Kind::ALL.iter().map(|&k| worst_case(k))).collect();
    let mut seen = Vec::new();
    for frame in frames {
        let kind = frame.body.kind();
        let variant = if frame.header.seq == u16::MAX { "max" } else { "sample" };
        let path = format!("{GOLDEN_DIR}/{}-{variant}.hex", kind.name());
        let bytes = wire(&frame);
        if bless {
            std::fs::write(&path, hex(&bytes) + "\n").unwrap();
        }
        let golden = std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("{path}: {e} (AIM_WIRE_BLESS=1 writes it)"));
        assert_eq!(hex(&bytes), golden.trim(), "{path} differs from the encoder");
        // And the snapshot decodes to the frame: old bytes stay readable.
        let mut deframer: Deframer = Deframer::new();
        let decoded: Vec<_> = deframer.feed(&unhex(&golden)).collect();
        assert_eq!(decoded, [Ok(frame)], "{path}");
        seen.push(kind);
    }
    for kind in Kind::ALL {
        assert!(seen.contains(&kind), "no golden snapshot of {kind:?}");
    }
}

#[test]
fn hello_and_health_of_older_firmware_decode_with_the_appended_fields_at_their_defaults() {
    // Rule 3, the other way: `*-base.hex` are the snapshots of the frames before the start-up
    // fields (Hello) and the loss counters (Health) were appended, bytes as older firmware
    // sends them.
    let frames = sample_frames();
    for (name, index) in [("hello", 0), ("health", 3)] {
        let decoded = older_firmware_snapshot(name);
        let mut expected = frames[index].clone();
        match &mut expected.body {
            Body::Hello(h) => {
                let positions = h.mic_positions_decimm.clone();
                *h = aim_wire::Hello {
                    firmware_version: h.firmware_version,
                    sample_rate_hz: h.sample_rate_hz,
                    block_len: h.block_len,
                    mic_positions_decimm: positions,
                    ..Default::default()
                };
                assert_eq!(h.reset_cause(), Some(ResetCause::Unknown));
            }
            Body::Health(h) => {
                *h = aim_wire::Health {
                    blocks: h.blocks,
                    clipped_samples: h.clipped_samples,
                    peak_ddbfs: h.peak_ddbfs,
                    block_exponent: h.block_exponent,
                    cycles_per_block: h.cycles_per_block,
                    dma_overruns: h.dma_overruns,
                    dropped_frames: h.dropped_frames,
                    queue_depth: h.queue_depth,
                    ..Default::default()
                };
            }
            _ => unreachable!(),
        }
        assert_eq!(decoded, [Ok(expected)], "{name}-sample-base.hex");
    }
    // A payload cut inside the appended fields is malformed, not silently defaulted.
    let body = strip_crc(&raw(&frames[0])).to_vec();
    let (out, _) = deframe_all(&reframe(&body[..body.len() - 10]));
    assert_eq!(out, [Err(DecodeError::Payload(Some(Kind::Hello)))]);
}

#[test]
fn the_chip_and_clock_report_is_appended_only_when_set_and_decodes_back() {
    // A Hello without the report (simulation, firmware before it) keeps its bytes: the golden
    // `hello-sample.hex` above is such a frame. With the report, three fields follow the panic
    // message: chip revision 0x2003 (LEB128 83 40), clock source 1, sysclk 480 000 000
    // (LEB128 80 f0 f0 e4 01).
    let frames = sample_frames();
    let plain = strip_crc(&raw(&frames[0])).to_vec();
    let mut with_report = frames[0].clone();
    let Body::Hello(h) = &mut with_report.body else { unreachable!() };
    h.chip_revision = 0x2003;
    h.clock_source = ClockSource::HseBypass.code();
    h.sysclk_hz = 480_000_000;
    assert_eq!(h.clock_source(), Some(ClockSource::HseBypass));
    let body = strip_crc(&raw(&with_report)).to_vec();
    assert_eq!(&body[..plain.len()], &plain[..]);
    assert_eq!(&body[plain.len()..], &[0x83, 0x40, 0x01, 0x80, 0xf0, 0xf0, 0xe4, 0x01]);
    let (out, _) = deframe_all(&reframe(&body));
    assert_eq!(out, [Ok(with_report)]);
    // Cut inside the report: malformed, not silently defaulted.
    let (out, _) = deframe_all(&reframe(&body[..body.len() - 2]));
    assert_eq!(out, [Err(DecodeError::Payload(Some(Kind::Hello)))]);
    // Codes and names are pinned; the revision letters are ES0392's.
    let sources: Vec<_> = [0u8, 1, 2, 3]
        .iter()
        .map(|&c| ClockSource::from_code(c).map(|s| (s.code(), s.name())))
        .collect();
    assert_eq!(sources, [Some((0, "unknown")), Some((1, "hse-bypass")), Some((2, "hsi")), None]);
    assert_eq!(stm32h7_revision_name(0x2003), Some("V"));
    assert_eq!(stm32h7_revision_name(0x1003), Some("Y"));
    assert_eq!(stm32h7_revision_name(0x0000), None);
}

#[test]
fn reset_causes_are_pinned_and_the_panic_message_is_cut_at_a_character() {
    let codes: Vec<(u8, &str)> = ResetCause::ALL.iter().map(|c| (c.code(), c.name())).collect();
    assert_eq!(
        codes,
        [
            (0, "unknown"),
            (1, "power-on"),
            (2, "pin"),
            (3, "brown-out"),
            (4, "software"),
            (5, "watchdog"),
            (6, "window-watchdog"),
            (7, "low-power"),
            (8, "panic"),
            (9, "fault"),
        ]
    );
    assert_eq!(ResetCause::from_code(10), None);
    let mut hello = aim_wire::Hello::default();
    // 47 ASCII bytes and a 2-byte character: the character does not fit and is left out.
    let message = format!("{}é", "x".repeat(47));
    hello.set_panic_message(&message);
    assert_eq!(hello.panic_message.as_str(), &message[..47]);
    hello.set_panic_message("short");
    assert_eq!(hello.panic_message.as_str(), "short");
}

#[test]
fn derived_array_ids_are_in_range_and_follow_the_crc() {
    // Oracle: the published CRC-32/ISO-HDLC of these 12 bytes, computed independently with
    // Python's zlib.crc32(b"123456789abc") = 0xBDB0C0E4 (3182477540): 3182477540 mod 255 = 20.
    let uid = *b"123456789abc";
    assert_eq!(aim_wire::crc32(&uid), 0xBDB0_C0E4);
    assert_eq!(aim_wire::derived_array_id(&uid), 21);
    // Every id in 1..=255 is reachable and 0 never comes out, over many unique IDs.
    let mut seen = [false; 256];
    let mut rng = common::Rng::new(1);
    for _ in 0..20_000 {
        let uid: [u8; 12] = core::array::from_fn(|_| rng.byte());
        seen[usize::from(aim_wire::derived_array_id(&uid))] = true;
    }
    assert!(!seen[0]);
    assert!(seen[1..].iter().all(|&s| s));
}

#[test]
fn golden_doa_bytes_by_hand() {
    // One frame spelled out byte by byte, so the format description in the crate docs is
    // checked against something a person wrote, not only against the encoder's past output.
    let frame = &sample_frames()[1];
    let mut expected = vec![
        0xA1, 0x01, 0x01, 0x03, // magic, version, kind Doa, array 3
        0x01, 0x00, // seq 1, little-endian
        0x80, 0xC0, 0xBB, 0x01, // sample index 3 072 000 as LEB128
        0x80, 0x20, // span 4096 samples
        0xA8, 0x46, // azimuth 45.00° = 4500 cdeg, zig-zag 9000
        0xF0, 0x2E, // zenith 60.00° = 6000 cdeg
        0x0C, // residual 0.12 samples = 12
        0xDE, // quality 0.87 * 255 = 221.85 -> 222
        0x0F, // 15 pairs used
    ];
    let crc = aim_wire::crc32(&expected);
    expected.extend_from_slice(&crc.to_le_bytes());
    assert_eq!(raw(frame), expected);
}

fn deframe_all(stream: &[u8]) -> (Vec<Result<Frame, DecodeError>>, LinkStats) {
    let mut deframer: Deframer = Deframer::new();
    let out = deframer.feed(stream).collect();
    deframer.finish();
    (out, *deframer.stats())
}

#[test]
fn unknown_kind_is_skipped_and_counted() {
    // A newer firmware sends a frame of a kind this version does not know (7) between two
    // known frames.
    let frames = sample_frames();
    let mut snippet = strip_crc(&raw(&frames[1])).to_vec();
    snippet[2] = 7;
    snippet[4] = 2; // its own sequence number, between the two neighbours
    snippet.extend_from_slice(&[0xAB; 40]);
    let mut before = frames[0].clone();
    before.header.seq = 1;
    let mut after = frames[3].clone();
    after.header.seq = 3;
    let stream = [wire(&before), reframe(&snippet), wire(&after)].concat();
    let (out, stats) = deframe_all(&stream);
    assert_eq!(out, [Ok(before), Err(DecodeError::UnknownKind(7)), Ok(after)]);
    assert_eq!(stats.unknown_kinds, 1);
    assert_eq!(stats.crc_errors, 0);
    // Its sequence number counted: no gap reported.
    assert_eq!(stats.seq_gaps, 0);
    assert_eq!(stats.frames, 2);
}

#[test]
fn unknown_version_is_skipped_and_counted() {
    let frames = sample_frames();
    let mut v2 = strip_crc(&raw(&frames[1])).to_vec();
    v2[1] = PROTOCOL_VERSION + 1;
    let stream = [reframe(&v2), wire(&frames[2])].concat();
    let (out, stats) = deframe_all(&stream);
    assert_eq!(
        out,
        [Err(DecodeError::UnknownVersion(PROTOCOL_VERSION + 1)), Ok(frames[2].clone())]
    );
    assert_eq!((stats.unknown_versions, stats.crc_errors), (1, 0));
}

#[test]
fn appended_payload_fields_are_ignored() {
    // Rule 3: a later firmware appends fields; this version reads the prefix it knows. (A
    // Hello's later fields follow the chip and clock report, and a Health's the microphone
    // levels, which are then always sent.)
    for mut frame in sample_frames() {
        if let Body::Hello(h) = &mut frame.body {
            (h.chip_revision, h.clock_source, h.sysclk_hz) = (0x2003, 1, 480_000_000);
        }
        if let Body::Health(h) = &mut frame.body {
            h.mic_levels.count = 2;
            h.mic_levels.rms_ddbfs[..2].copy_from_slice(&[-412, -2000]);
            h.mic_levels.dc_ddbfs[..2].copy_from_slice(&[-655, -2000]);
        }
        let mut longer = strip_crc(&raw(&frame)).to_vec();
        longer.extend_from_slice(&[0x05, 0x7F, 0x00, 0x01]);
        let (out, _) = deframe_all(&reframe(&longer));
        assert_eq!(out, [Ok(frame)]);
    }
}

#[test]
fn truncated_payload_is_malformed_not_a_crash() {
    let frame = &sample_frames()[2];
    let body = strip_crc(&raw(frame)).to_vec();
    let cut = &body[..body.len() - 3];
    let (out, stats) = deframe_all(&reframe(cut));
    assert_eq!(out, [Err(DecodeError::Payload(Some(Kind::Peaks)))]);
    assert_eq!(stats.malformed, 1);
}

#[test]
fn bad_magic_with_valid_crc_is_malformed() {
    let mut body = strip_crc(&raw(&sample_frames()[1])).to_vec();
    body[0] = 0x7E;
    let (out, stats) = deframe_all(&reframe(&body));
    assert_eq!(out, [Err(DecodeError::BadMagic(0x7E))]);
    assert_eq!(stats.malformed, 1);
}

#[test]
fn too_many_peaks_do_not_decode() {
    // A count above MAX_PEAKS must fail cleanly, not overflow the fixed-capacity list.
    let frame = &sample_frames()[2];
    let body = strip_crc(&raw(frame)).to_vec();
    let header_len = 6 + 4; // fixed header + 4-byte sample index of this frame
    let mut payload = body[header_len..].to_vec();
    let count_at = 6; // after span 24 576 and BPF 18 742, 3-byte varints both
    assert_eq!(payload[count_at], 3);
    payload[count_at] = 5;
    payload.extend_from_within(count_at + 1..);
    let forged = [&body[..header_len], &payload[..]].concat();
    let (out, _) = deframe_all(&reframe(&forged));
    assert_eq!(out, [Err(DecodeError::Payload(Some(Kind::Peaks)))]);
}

#[test]
fn sequence_gaps_and_resets_are_counted() {
    let frames = sample_frames();
    let mut stream = Vec::new();
    for (i, seq) in [10u16, 11, 14, 15, 0, 1, 65535, 0].into_iter().enumerate() {
        let mut f = frames[i % frames.len()].clone();
        f.header.seq = seq;
        stream.extend(wire(&f));
    }
    let (_, stats) = deframe_all(&stream);
    // 11 -> 14 misses two; 15 -> 0 is a restart; 1 -> 65535 goes backwards; 65535 -> 0 wraps.
    assert_eq!(stats.seq_gaps, 1);
    assert_eq!(stats.frames_missed, 2);
    assert_eq!(stats.seq_resets, 2);
    assert_eq!(stats.frames, 8);
}

#[test]
fn oversize_chunk_is_counted_and_the_next_frame_survives() {
    let frame = sample_frames()[1].clone();
    let mut stream = vec![0x55; 3000];
    stream.extend(wire(&frame));
    let (out, stats) = deframe_all(&stream);
    assert_eq!(out, [Err(DecodeError::Oversize), Ok(frame)]);
    assert_eq!(stats.oversize, 1);
    // A small deframer counts the frame itself as oversize.
    let mut small: Deframer<16> = Deframer::new();
    let out: Vec<_> = small.feed(&wire(&sample_frames()[0])).collect();
    assert_eq!(out, [Err(DecodeError::Oversize)]);
}

#[test]
fn stream_cut_inside_a_frame_counts_as_truncated() {
    let w = wire(&sample_frames()[3]);
    let (out, stats) = deframe_all(&w[..w.len() / 2]);
    assert!(out.is_empty());
    assert_eq!(stats.truncated, 1);
}

#[test]
fn encoder_numbers_frames_and_refuses_small_buffers() {
    let mut encoder = aim_wire::Encoder::new(9);
    let body = sample_frames()[1].body.clone();
    let mut buf = [0u8; MAX_ENCODED_LEN];
    let mut small = [0u8; 8];
    assert!(matches!(
        encoder.encode(5, body.clone(), &mut small),
        Err(aim_wire::EncodeError::BufferTooSmall { available: 8, .. })
    ));
    let mut stream = Vec::new();
    for i in 0..3u64 {
        let n = encoder.encode(i * 1024, body.clone(), &mut buf).unwrap();
        stream.extend_from_slice(&buf[..n]);
    }
    let (out, stats) = deframe_all(&stream);
    let seqs: Vec<_> = out.iter().map(|r| r.as_ref().unwrap().header.seq).collect();
    assert_eq!(seqs, [0, 1, 2], "the failed encode consumed no sequence number");
    assert!(out.iter().all(|r| r.as_ref().unwrap().header.array_id == 9));
    assert_eq!(stats.seq_gaps, 0);
}

#[test]
fn quantisation_resolution() {
    // Each field is within half a unit of the physical value it was made from.
    let doa = aim_wire::Doa::new(-2.5, 0.3, 1.234, 0.5);
    assert!((doa.azimuth_rad() - -2.5).abs() <= 0.005f32.to_radians() + 1e-6);
    assert!((doa.zenith_rad() - 0.3).abs() <= 0.005f32.to_radians() + 1e-6);
    assert!((doa.residual_samples() - 1.234).abs() <= 0.005 + 1e-6);
    assert!((doa.quality() - 0.5).abs() <= 0.5 / 255.0 + 1e-6);
    // Azimuth beyond ±π wraps instead of saturating.
    let wrapped = aim_wire::Doa::new(3.5, 0.0, 0.0, 0.0);
    assert!((wrapped.azimuth_rad() - (3.5 - std::f32::consts::TAU)).abs() < 1e-3);
    let peak = aim_wire::Peak::new(187.426, -12.34, 0.25);
    assert_eq!((peak.freq_chz, peak.amplitude_ddb, peak.harmonicity), (18743, -123, 64));
}

fn arb_frame() -> impl Strategy<Value = Frame> {
    (any::<u64>(), any::<u8>(), any::<u16>()).prop_map(|(seed, array_id, seq)| {
        common::random_frame(&mut common::Rng::new(seed), array_id, seq)
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 4096, ..ProptestConfig::default() })]

    #[test]
    fn every_frame_roundtrips_within_its_size(frame in arb_frame()) {
        let bytes = wire(&frame);
        prop_assert!(bytes.len() <= frame.body.kind().max_encoded_len());
        prop_assert_eq!(bytes[0], 0);
        prop_assert_eq!(*bytes.last().unwrap(), 0);
        prop_assert!(!bytes[1..bytes.len() - 1].contains(&0));
        let inner = &raw(&frame);
        prop_assert_eq!(decode(inner), Ok(frame));
    }

    #[test]
    fn doa_quantisation_is_within_half_a_unit(
        az in -PI..PI, zen in 0.0f32..PI, res in 0.0f32..600.0, q in 0.0f32..1.0
    ) {
        let doa = aim_wire::Doa::new(az, zen, res, q);
        prop_assert!((doa.azimuth_deg() - az.to_degrees()).abs() <= 0.005 + 1e-3);
        prop_assert!((doa.zenith_deg() - zen.to_degrees()).abs() <= 0.005 + 1e-3);
        prop_assert!((doa.residual_samples() - res).abs() <= 0.005 + 1e-4 * res);
        prop_assert!((doa.quality() - q).abs() <= 0.5 / 255.0 + 1e-6);
    }
}

#[test]
fn bodies_report_their_kind() {
    for frame in sample_frames() {
        let kind = frame.body.kind();
        let matches = matches!(
            (&frame.body, kind),
            (Body::Hello(_), Kind::Hello)
                | (Body::Doa(_), Kind::Doa)
                | (Body::Peaks(_), Kind::Peaks)
                | (Body::Health(_), Kind::Health)
                | (Body::Mfcc(_), Kind::Mfcc)
                | (Body::Beacon(_), Kind::Beacon)
                | (Body::Snippet(_), Kind::Snippet)
        );
        assert!(matches, "{kind:?}");
    }
}

#[test]
fn mfcc_of_older_firmware_decode_with_no_second_comb() {
    // An Mfcc payload that ends after its comb features (written before the second comb was
    // appended) decodes with no second comb (rule 3), the rest as sent.
    let frame = &sample_frames()[4];
    let Body::Mfcc(m) = &frame.body else { panic!("sample frame 4 is an Mfcc") };
    let second = m.second_harmonic.expect("the sample has a second comb");
    let body = strip_crc(&raw(frame)).to_vec();
    // Each of the nine i16 at most 3 bytes (zigzag varint): cut them off exactly.
    let varint_len = |v: i16| match ((v << 1) ^ (v >> 15)) as u16 {
        0..=127 => 1,
        128..=16_383 => 2,
        _ => 3,
    };
    let appended: usize = 1 + second.iter().map(|&v| varint_len(v)).sum::<usize>(); // tag, values
    let old = &body[..body.len() - appended];
    let (out, stats) = deframe_all(&reframe(old));
    let Ok(Frame { body: Body::Mfcc(q), .. }) = &out[0] else { panic!("{out:?}") };
    let expected = aim_wire::Mfcc { second_harmonic: None, ..*m };
    assert_eq!((q, stats.malformed), (&expected, 0));
    // The snapshot of that frame's bytes as older firmware sent them decodes the same way.
    let decoded = older_firmware_snapshot("mfcc");
    assert!(
        matches!(&decoded[..], [Ok(Frame { body: Body::Mfcc(g), .. })] if g == q),
        "{decoded:?}"
    );
}

#[test]
fn peaks_of_older_firmware_decode_with_unstated_detection() {
    // A Peaks payload that ends after its group list (written before detection and quality
    // were appended) decodes with the appended fields at their defaults (rule 3).
    let frame = &sample_frames()[2];
    let Body::Peaks(p) = &frame.body else { panic!("sample frame 2 is a Peaks") };
    let body = strip_crc(&raw(frame)).to_vec();
    let appended = 1 + 1 + p.quality.len(); // detection, quality count, qualities
    let old = &body[..body.len() - appended];
    let (out, stats) = deframe_all(&reframe(old));
    let Ok(Frame { body: Body::Peaks(q), .. }) = &out[0] else { panic!("{out:?}") };
    assert_eq!((q.detection, q.quality.len()), (aim_wire::Detection::Unstated, 0));
    assert_eq!((q.bpf_chz, &q.peaks), (p.bpf_chz, &p.peaks));
    assert!(q.is_rotor() && p.is_rotor() && stats.malformed == 0);
    // The snapshot of that frame's bytes as older firmware sent them decodes the same way.
    let decoded = older_firmware_snapshot("peaks");
    assert!(
        matches!(&decoded[..], [Ok(Frame { body: Body::Peaks(g), .. })] if g == q),
        "{decoded:?}"
    );
    // And "no rotor signature" is no rotor, whatever else.
    assert!(!aim_wire::Peaks::no_rotor(24_576).is_rotor());
}
