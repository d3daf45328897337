//! Frames and link statistics as JSON objects (what `aim frames` prints, one per line).
//!
//! Physical values are computed in f64 from the frames' integer fields, so they print exactly
//! at the wire resolution (`45.0`, not `44.99999237060547`).

use aim_wire::{Body, Frame, Kind, LinkStats};
use serde_json::{json, Map, Value};

/// Rounds `x` to `decimals` places (for values whose resolution is not a power of ten).
fn round(x: f64, decimals: i32) -> f64 {
    let scale = 10f64.powi(decimals);
    (x * scale).round() / scale
}

/// A board event ([`crate::link::boards`]): `{"kind":"reboot",...}` or
/// `{"kind":"duplicate_id",...}`.
pub fn board_event(event: &crate::link::boards::BoardEvent) -> Value {
    use crate::link::boards::BoardEvent;
    match event {
        BoardEvent::Reboot { array_id, cause, boot_count, message } => json!({
            "kind": "reboot",
            "array": array_id,
            "reset_cause": cause.map_or("unknown", |c| c.name()),
            "boot_count": boot_count,
            "panic_message": message,
        }),
        BoardEvent::DuplicateId { array_id, before, now } => json!({
            "kind": "duplicate_id",
            "array": array_id,
            "unique_id_before": before,
            "unique_id_now": now,
        }),
    }
}

/// One frame: `kind`, `array`, `seq`, `sample_index`, `t` (seconds on the array's clock, when
/// the sample rate is known from a `Hello`), and the payload in physical units.
pub fn frame(frame: &Frame, sample_rate_hz: Option<u32>) -> Value {
    let h = frame.header;
    let mut obj = Map::new();
    obj.insert("kind".into(), json!(frame.body.kind().name()));
    obj.insert("array".into(), json!(h.array_id));
    obj.insert("seq".into(), json!(h.seq));
    obj.insert("sample_index".into(), json!(h.sample_index));
    if let Some(rate) = sample_rate_hz.filter(|&r| r > 0) {
        obj.insert("t".into(), json!(round(h.sample_index as f64 / f64::from(rate), 6)));
    }
    let payload = match &frame.body {
        Body::Hello(p) => json!({
            "firmware_version": format!(
                "{}.{}.{}",
                p.firmware_version[0], p.firmware_version[1], p.firmware_version[2]
            ),
            "sample_rate_hz": p.sample_rate_hz,
            "block_len": p.block_len,
            "mic_positions_m": p
                .mic_positions_decimm
                .iter()
                .map(|m| [f64::from(m[0]) / 1e4, f64::from(m[1]) / 1e4])
                .collect::<Vec<_>>(),
            "reset_cause": p.reset_cause().map_or("unknown", |c| c.name()),
            "boot_count": p.boot_count,
            "unique_id": crate::link::boards::unique_id_hex(&p.unique_id),
            "panic_message": p.panic_message.as_str(),
            "chip_revision": format!("{:#06x}", p.chip_revision),
            "chip_revision_name": aim_wire::stm32h7_revision_name(p.chip_revision),
            "clock_source": p.clock_source().map_or("unknown", |c| c.name()),
            "sysclk_hz": p.sysclk_hz,
        }),
        Body::Doa(p) => json!({
            "azimuth_deg": f64::from(p.azimuth_cdeg) / 100.0,
            "zenith_deg": f64::from(p.zenith_cdeg) / 100.0,
            "residual_samples": f64::from(p.residual_csamples) / 100.0,
            "quality": round(f64::from(p.quality) / 255.0, 4),
            "span_samples": p.span_samples,
            "pairs_used": p.pairs_used,
        }),
        Body::Peaks(p) => json!({
            "bpf_hz": f64::from(p.bpf_chz) / 100.0,
            "rotor": p.is_rotor(),
            "span_samples": p.span_samples,
            "peaks": p.peaks.iter().enumerate().map(|(i, q)| json!({
                "hz": f64::from(q.freq_chz) / 100.0,
                "amp_db": f64::from(q.amplitude_ddb) / 10.0,
                "harmonicity": round(f64::from(q.harmonicity) / 255.0, 4),
                "quality": p.quality_of(i).map(|v| round(f64::from(v), 4)),
            })).collect::<Vec<_>>(),
        }),
        Body::Health(p) => {
            let mic_levels: (Vec<f64>, Vec<f64>) = (0..usize::from(p.mic_levels.count))
                .filter_map(|i| p.mic_levels.level_dbfs(i))
                .map(|(rms, dc)| (f64::from(rms), f64::from(dc)))
                .unzip();
            json!({
            "blocks": p.blocks,
            "clipped_samples": p.clipped_samples,
            "peak_dbfs": f64::from(p.peak_ddbfs) / 10.0,
            "block_exponent": p.block_exponent,
            "cycles_per_block": p.cycles_per_block,
            "dma_overruns": p.dma_overruns,
            "dropped_frames": p.dropped_frames,
            "queue_depth": p.queue_depth,
            "dsp_overloads": p.dsp_overloads,
            "sai_overruns": p.sai_overruns,
            "gaps": p.gaps,
            "frames_lost": p.frames_lost,
            "outputs_dropped": p.outputs_dropped,
            "outputs_overflowed": p.outputs_overflowed,
            "uart_errors": p.uart_errors,
            "frames_unencodable": p.frames_unencodable,
            "chunks_captured": p.chunks_captured,
            // Per microphone in slot order, dBFS (empty when the board sends none).
            "mic_rms_dbfs": mic_levels.0,
            "mic_dc_dbfs": mic_levels.1,
            })
        }
        Body::Mfcc(p) => {
            let mut v = json!({
                "span_samples": p.span_samples,
                "log_mel_db": (0..aim_wire::MFCC_MEL_BANDS)
                    .map(|b| round(f64::from(p.log_mel_cdb[b]) / 100.0, 2))
                    .collect::<Vec<_>>(),
                "mfcc_db": (0..aim_wire::MFCC_COEFFS)
                    .map(|c| round(f64::from(p.mfcc_ddb[c]) / 10.0, 1))
                    .collect::<Vec<_>>(),
            });
            // The first comb's fields flat (`comb_f0_hz`, ...), as before the second existed.
            if let Value::Object(first) = comb_json(&p.harmonic_values()) {
                for (k, x) in first {
                    v[format!("comb_{k}")] = x;
                }
            }
            // The strongest comb of another source: null when there is none (salience 0, as
            // `host-sim analyze` says) or the firmware sends none.
            v["second_comb"] = match p.second_harmonic_values() {
                Some(c) if c[1] > 0.0 => comb_json(&c),
                _ => Value::Null,
            };
            v
        }
        Body::Beacon(p) => json!({
            "arrival_samples": p.arrival_samples(h.sample_index),
            "fraction": p.fraction_samples(),
            "quality": round(f64::from(p.quality_f32()), 4),
            "level_db": f64::from(p.level_cdb) / 100.0,
        }),
        Body::Snippet(p) => {
            // A summary: the mantissas are audio for `interarray`, not for reading.
            let n = p.samples.len();
            let power = (0..n).map(|j| p.value(j).powi(2)).sum::<f64>() / n.max(1) as f64;
            let peak = p.samples.iter().map(|m| m.unsigned_abs()).max().unwrap_or(0);
            json!({
                "decimation": p.decimation,
                "exponent": p.exponent,
                "samples": n,
                "span_samples": n * usize::from(p.decimation),
                "rms_dbfs": round(10.0 * power.max(1e-30).log10(), 2),
                "peak_mantissa": peak,
            })
        }
        // A kind added to aim-wire but not yet here: header only.
        #[allow(unreachable_patterns)]
        _ => json!({}),
    };
    if let Value::Object(fields) = payload {
        obj.extend(fields);
    }
    Value::Object(obj)
}

/// The link statistics of one of several inputs, named: `{"kind":KIND,KEY:NAME,...}` (the
/// fields of [`stats`]).
pub fn named_stats(s: &LinkStats, kind: &str, key: &str, name: &str) -> Value {
    let mut line = stats(s);
    line["kind"] = kind.into();
    line[key] = name.into();
    line
}

/// The link statistics, `{"kind":"stats",...}`.
pub fn stats(s: &LinkStats) -> Value {
    let by_kind: Map<String, Value> =
        Kind::ALL.iter().zip(s.frames_by_kind).map(|(k, n)| (k.name().into(), json!(n))).collect();
    json!({
        "kind": "stats",
        "bytes": s.bytes,
        "frames": s.frames,
        "frames_by_kind": by_kind,
        "errors": s.errors(),
        "crc_errors": s.crc_errors,
        "framing_errors": s.framing_errors,
        "oversize": s.oversize,
        "unknown_versions": s.unknown_versions,
        "unknown_kinds": s.unknown_kinds,
        "malformed": s.malformed,
        "truncated": s.truncated,
        "seq_gaps": s.seq_gaps,
        "frames_missed": s.frames_missed,
        "seq_resets": s.seq_resets,
    })
}

/// A comb's features (`aim_wire::Mfcc::harmonic_values`: `log2(f0 / 250 Hz)`, then dB) as
/// JSON: fundamental (Hz), salience, half- and third-way levels (dB) and harmonics 2..=6
/// relative to the first (dB), rounded to 0.01.
fn comb_json(c: &[f32; aim_wire::MFCC_HARMONIC]) -> Value {
    let db = |v: f32| round(f64::from(v), 2);
    json!({
        "f0_hz": round(f64::from(aim_dsp::features::F0_REF_HZ) * f64::from(c[0]).exp2(), 2),
        "salience_db": db(c[1]),
        "half_db": db(c[2]),
        "third_db": db(c[3]),
        "envelope_db": c[4..].iter().map(|&v| db(v)).collect::<Vec<_>>(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use aim_wire::{Doa, Header, Peak, Peaks};

    #[test]
    fn doa_in_physical_units() {
        let f = Frame {
            header: Header { array_id: 2, seq: 9, sample_index: 96_000 },
            body: Body::Doa(Doa {
                azimuth_cdeg: -4512,
                zenith_cdeg: 3000,
                residual_csamples: 7,
                quality: 51,
                span_samples: 8192,
                pairs_used: 28,
            }),
        };
        let v = frame(&f, Some(48_000));
        assert_eq!(
            v,
            json!({"kind":"doa","array":2,"seq":9,"sample_index":96000,"t":2.0,
                   "azimuth_deg":-45.12,"zenith_deg":30.0,"residual_samples":0.07,
                   "quality":0.2,"span_samples":8192,"pairs_used":28})
        );
        assert!(frame(&f, None).get("t").is_none());
    }

    #[test]
    fn peaks_in_physical_units() {
        let f = Frame {
            header: Header::default(),
            body: Body::Peaks(Peaks {
                span_samples: 1,
                bpf_chz: 18_750,
                peaks: [Peak { freq_chz: 18_750, amplitude_ddb: -203, harmonicity: 255 }]
                    .into_iter()
                    .collect(),
                detection: aim_wire::Detection::Rotor,
                quality: [51].into_iter().collect(),
            }),
        };
        let v = frame(&f, None);
        assert_eq!(v["bpf_hz"], json!(187.5));
        assert_eq!(v["rotor"], json!(true));
        assert_eq!(
            v["peaks"],
            json!([{"hz":187.5,"amp_db":-20.3,"harmonicity":1.0,"quality":0.2}])
        );
    }

    #[test]
    fn mfcc_in_physical_units() {
        let mut m = aim_wire::Mfcc { span_samples: 24_576, ..Default::default() };
        m.log_mel_cdb[3] = -6_346;
        m.mfcc_ddb[0] = -3_913;
        m.harmonic = [392, 1_713, 845, 96, -412, 0, 0, 0, -3_333];
        let f = Frame { header: Header::default(), body: Body::Mfcc(m) };
        let v = frame(&f, None);
        assert_eq!(v["kind"], json!("mfcc"));
        assert_eq!((&v["log_mel_db"][3], &v["mfcc_db"][0]), (&json!(-63.46), &json!(-391.3)));
        // 250 Hz · 2^0.392 = 328.05 Hz.
        assert_eq!(v["comb_f0_hz"], json!(328.05));
        assert_eq!((&v["comb_salience_db"], &v["comb_third_db"]), (&json!(17.13), &json!(0.96)));
        assert_eq!(v["comb_envelope_db"], json!([-4.12, 0.0, 0.0, 0.0, -33.33]));
        assert_eq!(v["second_comb"], Value::Null, "no second comb");
        // 250 Hz · 2^−1.095 = 117.03 Hz.
        m.second_harmonic = Some([-1_095, 1_204, 130, 88, -655, -1_020, -1_540, -1_811, -2_630]);
        let v = frame(&Frame { header: Header::default(), body: Body::Mfcc(m) }, None);
        assert_eq!(
            v["second_comb"],
            json!({"f0_hz": 117.03, "salience_db": 12.04, "half_db": 1.3, "third_db": 0.88,
                   "envelope_db": [-6.55, -10.2, -15.4, -18.11, -26.3]})
        );
    }

    #[test]
    fn hello_reports_the_chip_revision_and_the_clock() {
        let mut hello = aim_wire::Hello::new([0, 1, 0], 48_000, 1024, &[]);
        let f = Frame { header: Header::default(), body: Body::Hello(hello.clone()) };
        let v = frame(&f, None);
        assert_eq!(
            (&v["chip_revision"], &v["chip_revision_name"], &v["clock_source"], &v["sysclk_hz"]),
            (&json!("0x0000"), &Value::Null, &json!("unknown"), &json!(0))
        );
        (hello.chip_revision, hello.clock_source, hello.sysclk_hz) = (0x1003, 2, 400_000_000);
        let f = Frame { header: Header::default(), body: Body::Hello(hello) };
        let v = frame(&f, None);
        assert_eq!(
            (&v["chip_revision"], &v["chip_revision_name"], &v["clock_source"], &v["sysclk_hz"]),
            (&json!("0x1003"), &json!("Y"), &json!("hsi"), &json!(400_000_000))
        );
    }
}
