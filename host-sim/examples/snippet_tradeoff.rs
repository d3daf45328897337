//! Snippet format trade-off for inter-array delays (issue 14; BENCHMARKS.md "Snippets for
//! inter-array delays"). Simulates a multi-array scenario, makes each array's snippet stream in
//! several candidate formats (the chip's own pipeline for the chosen one; host emulations for
//! the others), and measures the delay error of `aim_tracker::interarray` against the true
//! inter-array delay of the drone's sound. Truth is used here for the evaluation only: the
//! arrays' TRUE clocks stand in for the clock model, and the prior window is centred on the
//! true delay (plus a stated offset).
//!
//! `cargo run -p host-sim --example snippet_tradeoff -- host-sim/scenarios/zigzag10-los.toml SEED...`

use aim_tracker::interarray::{DelayConfig, Prior, SnippetStore};
use host_sim::scenario::Scenario;

/// One candidate stream format.
#[derive(Clone, Copy)]
struct Candidate {
    name: &'static str,
    rate_hz: u32,
    /// Low-pass cut-off of the emulated decimator, Hz.
    cutoff_hz: f64,
    format: Format,
    mono: bool,
    /// The chip's pipeline instead of the emulation.
    chip: bool,
}

#[derive(Clone, Copy, PartialEq)]
enum Format {
    F64,
    I16,
    I8,
    MuLaw,
}

impl Format {
    fn bytes(self) -> f64 {
        match self {
            Format::F64 => 4.0,
            Format::I16 => 2.0,
            _ => 1.0,
        }
    }
}

/// Bytes per second on the wire: 256 samples per frame, 24 bytes of framing each (header with
/// a 4-byte index, decimation, exponent, length, CRC, COBS, delimiters: the measured 284-byte
/// frame of 256 i8 samples minus 256 — rounded up).
fn bytes_per_s(c: &Candidate) -> f64 {
    let fs = f64::from(c.rate_hz);
    fs * c.format.bytes() + fs / 256.0 * 28.0
}

fn quantize(x: &[f64], f: Format) -> Vec<f64> {
    match f {
        Format::F64 => x.to_vec(),
        Format::I16 | Format::I8 => {
            let bits = if f == Format::I16 { 15 } else { 7 };
            let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            if peak == 0.0 {
                return vec![0.0; x.len()];
            }
            let e = peak.log2().floor() + 1.0 - f64::from(bits);
            let step = e.exp2();
            let top = f64::from((1 << bits) - 1);
            x.iter().map(|v| (v / step).round().clamp(-top, top) * step).collect()
        }
        Format::MuLaw => {
            // G.711-like μ = 255 on a fixed full scale (no block exponent), 8 bits.
            let mu = 255.0f64;
            x.iter()
                .map(|&v| {
                    let y = v.signum() * (1.0 + mu * v.abs().min(1.0)).ln() / (1.0 + mu).ln();
                    let q = (y * 127.0).round() / 127.0;
                    q.signum() * ((1.0 + mu).powf(q.abs()) - 1.0) / mu
                })
                .collect()
        }
    }
}

/// Windowed-sinc low-pass (Blackman) at `cutoff` Hz for 48 kHz, `taps` long.
fn lowpass(cutoff: f64, taps: usize) -> Vec<f64> {
    let fc = cutoff / 48_000.0;
    let mid = (taps - 1) as f64 / 2.0;
    let mut h: Vec<f64> = (0..taps)
        .map(|n| {
            let x = n as f64 - mid;
            let s = if x == 0.0 {
                2.0 * fc
            } else {
                (2.0 * std::f64::consts::PI * fc * x).sin() / (std::f64::consts::PI * x)
            };
            let a = 2.0 * std::f64::consts::PI * n as f64 / (taps - 1) as f64;
            s * (0.42 - 0.5 * a.cos() + 0.08 * (2.0 * a).cos())
        })
        .collect();
    let sum: f64 = h.iter().sum();
    h.iter_mut().for_each(|v| *v /= sum);
    h
}

/// (candidate index, window s, band Hz, prior half width s, prior offset s)
type Run = (usize, f64, (f64, f64), f64, f64);

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let path = std::path::Path::new(&args[1]);
    let seeds: Vec<u64> = args[2..].iter().map(|s| s.parse().unwrap()).collect();
    let chip = |rate| Candidate {
        name: "",
        rate_hz: rate,
        cutoff_hz: 3500.0,
        format: Format::I8,
        mono: false,
        chip: true,
    };
    let emu = |name, rate, cutoff, format, mono| Candidate {
        name,
        rate_hz: rate,
        cutoff_hz: cutoff,
        format,
        mono,
        chip: false,
    };
    let mut candidates = vec![
        Candidate { name: "chip 8k i8 mean", ..chip(8000) },
        emu("8k f64 mean", 8000, 3500.0, Format::F64, false),
        emu("8k i16 mean", 8000, 3500.0, Format::I16, false),
        emu("8k i8 mean", 8000, 3500.0, Format::I8, false),
        emu("8k mu-law mean", 8000, 3500.0, Format::MuLaw, false),
        emu("8k i8 mic0", 8000, 3500.0, Format::I8, true),
        emu("6k i8 mean", 6000, 2700.0, Format::I8, false),
        emu("12k i8 mean", 12_000, 5000.0, Format::I8, false),
        emu("24k i8 mean", 24_000, 10_000.0, Format::I8, false),
    ];
    let mut runs: Vec<Run> =
        (0..candidates.len()).map(|i| (i, 0.5, (150.0, 3000.0), 1.0e-3, 0.0)).collect();
    for w in [0.25, 1.0] {
        runs.push((0, w, (150.0, 3000.0), 1.0e-3, 0.0));
    }
    runs.push((0, 0.5, (150.0, 1500.0), 1.0e-3, 0.0));
    runs.push((0, 0.5, (150.0, 3500.0), 1.0e-3, 0.0));
    runs.push((7, 0.5, (150.0, 5000.0), 1.0e-3, 0.0));
    runs.push((8, 0.5, (150.0, 10_000.0), 1.0e-3, 0.0));
    for (half, off) in
        [(0.5e-3, 0.0), (1.5e-3, 0.0), (1.5e-3, 1.0e-3), (2.0e-3, 0.0), (3.0e-3, 0.0)]
    {
        runs.push((0, 0.5, (150.0, 3000.0), half, off));
    }
    let mut errors: Vec<Vec<f64>> = vec![Vec::new(); runs.len()];
    let mut missing = vec![0usize; runs.len()];
    for &seed in &seeds {
        let scenario = Scenario::load_with(path, seed, &toml::Table::new())?;
        let sim = host_sim::simulate(&scenario, &indicatif::ProgressBar::hidden())?;
        let c = sim.site.speed_of_sound_mps;
        let rows = &sim.truth.rows;
        let pos = |t: f64| -> [f64; 3] {
            let k = rows.partition_point(|r| r.t_s <= t).clamp(1, rows.len() - 1);
            let (a, b) = (&rows[k - 1], &rows[k]);
            let u = ((t - a.t_s) / (b.t_s - a.t_s)).clamp(0.0, 1.0);
            core::array::from_fn(|i| a.position[i] + u * (b.position[i] - a.position[i]))
        };
        let dist = |s: [f64; 3], a: [f64; 3]| {
            ((s[0] - a[0]).powi(2) + (s[1] - a[1]).powi(2) + (s[2] - a[2]).powi(2)).sqrt()
        };
        let true_delay = |p: usize, q: usize, t: f64| {
            let (ap, aq) = (sim.arrays[p].position_m, sim.arrays[q].position_m);
            let mut te = t - dist(pos(t), aq) / c;
            for _ in 0..4 {
                te = t - dist(pos(te), aq) / c;
            }
            (dist(pos(te), ap) - dist(pos(te), aq)) / c
        };
        let clocks: Vec<_> = sim
            .arrays
            .iter()
            .map(|a| {
                let k = a.clock;
                move |n: f64| k.offset_s + n / (48_000.0 * (1.0 + k.drift_ppm * 1e-6))
            })
            .collect();
        // Streams per candidate.
        let mut stores: Vec<SnippetStore> = Vec::new();
        for cand in &mut candidates {
            let mut store = SnippetStore::new(1_000_000);
            for a in &sim.arrays {
                if cand.chip {
                    let g = aim_dsp::Geometry::from_positions(
                        &a.positions.iter().map(|p| [p[0] as f32, p[1] as f32]).collect::<Vec<_>>(),
                    )
                    .unwrap();
                    let config = aim_dsp::Config::new(g, 48_000);
                    let mut pipe = aim_dsp::Pipeline::new(&config).unwrap();
                    let words = a.tdm_words(host_sim::DEFAULT_FULL_SCALE_PA, config.tdm_slots);
                    for chunk in words.chunks(256 * config.tdm_slots) {
                        pipe.push(chunk, &mut |o| {
                            if let aim_dsp::Output::Snippet(x) = o {
                                let w = aim_wire::from_dsp::snippet(&x);
                                store.push(a.id, x.sample_index, &w);
                            }
                        });
                    }
                } else {
                    let n = a.channels[0].len();
                    let m = if cand.mono { 1 } else { a.channels.len() };
                    let fs_pa = host_sim::DEFAULT_FULL_SCALE_PA;
                    let x: Vec<f64> = (0..n)
                        .map(|k| {
                            a.channels[..m].iter().map(|ch| f64::from(ch[k])).sum::<f64>()
                                / (m as f64 * fs_pa)
                        })
                        .collect();
                    let d = (48_000 / cand.rate_hz) as usize;
                    let h = lowpass(cand.cutoff_hz, 16 * d + 1);
                    let half = h.len() / 2;
                    // Output j centred on input j·d (zero phase: the same on every array).
                    let y: Vec<f64> = (0..n / d)
                        .map(|j| {
                            let c0 = j * d;
                            h.iter()
                                .enumerate()
                                .map(|(i, &t)| {
                                    let k = (c0 + i).checked_sub(half);
                                    k.and_then(|k| x.get(k)).map_or(0.0, |v| v * t)
                                })
                                .sum()
                        })
                        .collect();
                    for (f, chunk) in y.chunks_exact(256).enumerate() {
                        store.push_samples(
                            a.id,
                            (f * 256 * d) as u64,
                            d as u32,
                            quantize(chunk, cand.format),
                        );
                    }
                }
            }
            stores.push(store);
        }
        let pairs = [(0usize, 1usize), (0, 2), (1, 2), (1, 3), (2, 3), (2, 4), (3, 4)];
        let end = sim.truth.rows.last().map_or(0.0, |r| r.t_s) - 1.0;
        let mut t = 1.5;
        while t < end {
            for &(p, q) in &pairs {
                let truth = true_delay(p, q, t);
                for (r, &(ci, w, band, half, off)) in runs.iter().enumerate() {
                    let config = DelayConfig { window_s: w, frame_len: 512, band_hz: band };
                    let mut config = config;
                    let ratio = f64::from(candidates[ci].rate_hz) / 8000.0;
                    config.frame_len = ((512.0 * ratio) as usize).next_power_of_two();
                    let prior = Prior { centre_s: truth + off, half_width_s: half };
                    let (ip, iq) = (sim.arrays[p].id, sim.arrays[q].id);
                    match stores[ci].delay(ip, iq, &clocks[p], &clocks[q], t, prior, &config) {
                        Some(d) => errors[r].push(d.delay_s - true_delay(p, q, d.time_s)),
                        None => missing[r] += 1,
                    }
                }
            }
            t += 0.5;
        }
        eprintln!("seed {seed} done");
    }
    println!("| candidate | window s | band Hz | prior ± ms (offset) | B/s | % link | median |e| µs | rms µs | p90 µs | > 0.1 ms | n |");
    println!("|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|");
    for (r, &(ci, w, band, half, off)) in runs.iter().enumerate() {
        let c = &candidates[ci];
        let mut e: Vec<f64> = errors[r].iter().map(|v| v.abs() * 1e6).collect();
        e.sort_by(f64::total_cmp);
        let n = e.len();
        let med = e.get(n / 2).copied().unwrap_or(f64::NAN);
        let p90 = e.get(n * 9 / 10).copied().unwrap_or(f64::NAN);
        let rms = (e.iter().map(|v| v * v).sum::<f64>() / n.max(1) as f64).sqrt();
        let gross = e.iter().filter(|&&v| v > 100.0).count() as f64 / n.max(1) as f64;
        let b = bytes_per_s(c);
        println!(
            "| {} | {w} | {:.0}–{:.0} | {:.1} ({:+.1}) | {b:.0} | {:.1} | {med:.1} | {rms:.1} | {p90:.1} | {:.1} % | {n} (+{} none) |",
            c.name,
            band.0,
            band.1,
            half * 1e3,
            off * 1e3,
            100.0 * b * 10.0 / 921_600.0,
            100.0 * gross,
            missing[r]
        );
    }
    Ok(())
}
