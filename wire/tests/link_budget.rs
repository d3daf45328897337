//! Link utilisation of one 8-microphone array at 921 600 baud, from encoded frame sizes and the
//! DSP's real output rates (read from aim-dsp's defaults, not restated here).
//!
//! `cargo test -p aim-wire --test link_budget -- --nocapture` prints the table that
//! BENCHMARKS.md quotes.

mod common;

use aim_wire::Kind;
use common::{sample_frames, wire, worst_case};

/// Default uplink: USART3 at 921 600 baud, 8N1, so 10 bit times per byte.
const BAUD: f64 = 921_600.0;
const BITS_PER_BYTE: f64 = 10.0;
/// The firmware repeats its `Hello` every 5 s (an assumption of this budget: the period is the
/// firmware's choice, and anything slower only lowers the load).
const HELLO_PERIOD_S: f64 = 5.0;
/// Most the data may take, so that retransmit-free bursts, logs and later kinds still fit.
const BUDGET: f64 = 0.5;

/// Frames per second of each kind for a pipeline configuration.
fn rates(config: &aim_dsp::Config) -> [(Kind, f64); 7] {
    let block_s = config.block_len as f64 / f64::from(config.sample_rate_hz);
    let peaks_hop_s =
        aim_dsp::bpf::ANALYSIS_HOP as f64 / f64::from(aim_dsp::bpf::DECIMATED_RATE_HZ);
    [
        (Kind::Hello, 1.0 / HELLO_PERIOD_S),
        (Kind::Doa, 1.0 / (block_s * f64::from(config.average_blocks))),
        (Kind::Peaks, 1.0 / peaks_hop_s),
        (Kind::Health, 1.0 / (block_s * f64::from(config.health_interval_blocks))),
        (Kind::Mfcc, {
            let every = f64::from(config.mfcc_interval);
            if every > 0.0 {
                1.0 / (peaks_hop_s * every)
            } else {
                0.0
            }
        }),
        // One emission per second (the site's default period).
        (Kind::Beacon, if config.sample_rate_hz == 48_000 { 1.0 } else { 0.0 }),
        (Kind::Snippet, {
            let snippet_s =
                aim_dsp::snippet::SNIPPET_LEN as f64 / f64::from(aim_dsp::bpf::DECIMATED_RATE_HZ);
            if config.snippets {
                1.0 / snippet_s
            } else {
                0.0
            }
        }),
    ]
}

/// Fraction of the link taken when every frame has its worst-case size; prints the table, with
/// the load of typical frames (`common::sample_frames`, a 6-mic Hello) beside it.
fn load(config: &aim_dsp::Config, label: &str) -> f64 {
    let (mut worst_per_s, mut typical_per_s) = (0.0, 0.0);
    println!("{label}:");
    println!("  kind    rate/s  worst B  worst B/s  typical B  typical B/s");
    for (kind, rate) in rates(config) {
        let worst = wire(&worst_case(kind)).len();
        assert_eq!(worst, kind.max_encoded_len());
        let typical = sample_frames()
            .iter()
            .find(|f| f.body.kind() == kind)
            .map(|f| wire(f).len())
            .expect("a sample frame of every kind");
        let row = (rate * worst as f64, rate * typical as f64);
        println!(
            "  {:7} {rate:6.2} {worst:8} {:10.1} {typical:10} {:12.1}",
            kind.name(),
            row.0,
            row.1
        );
        worst_per_s += row.0;
        typical_per_s += row.1;
    }
    let utilisation = worst_per_s * BITS_PER_BYTE / BAUD;
    let typical = typical_per_s * BITS_PER_BYTE / BAUD;
    println!(
        "  worst case {worst_per_s:.1} B/s = {:.2} % of {BAUD} baud; typical {typical_per_s:.1} B/s = {:.2} %",
        100.0 * utilisation,
        100.0 * typical
    );
    utilisation
}

#[test]
fn eight_mics_at_default_rates_use_at_most_half_the_link() {
    let config = aim_dsp::Config::new(aim_dsp::Geometry::circle_8mic(), 48_000);
    assert_eq!(config.geometry.len(), 8);
    let utilisation = load(&config, "aim-dsp defaults, 48 kHz, 8 mics, worst-case sizes");
    assert!(utilisation <= BUDGET, "{:.1} % of the link", 100.0 * utilisation);
    // Physical sanity of the rates read from aim-dsp: a DoA per few blocks, ~1 Health/s.
    let [_, (_, doa), (_, peaks), (_, health), (_, mfcc), _, (_, snippets)] = rates(&config);
    assert_eq!(snippets, 31.25, "a contiguous 8 kHz stream of 256-sample snippets");
    assert!((1.0..=47.0).contains(&doa), "DoA rate {doa}");
    assert!(mfcc > 0.0 && mfcc <= peaks, "Mfcc rate {mfcc}: one per analysis at most");
    assert!((0.5..=24.0).contains(&peaks), "Peaks rate {peaks}");
    assert!((0.5..=2.0).contains(&health), "Health rate {health}");
}

#[test]
fn even_one_doa_per_block_fits() {
    // The densest configuration aim-dsp accepts at 48 kHz: no DoA averaging, Health per block.
    let mut config = aim_dsp::Config::new(aim_dsp::Geometry::circle_8mic(), 48_000);
    config.average_blocks = 1;
    config.health_interval_blocks = 1;
    config.validate().expect("aim-dsp accepts this configuration");
    let utilisation = load(&config, "one DoA and one Health per 1024-sample block");
    assert!(utilisation <= BUDGET, "{:.1} % of the link", 100.0 * utilisation);
}

#[test]
fn without_snippets_the_link_is_as_before() {
    // A single-array site (`Config::snippets` = false): today's load, for comparison.
    let mut config = aim_dsp::Config::new(aim_dsp::Geometry::circle_8mic(), 48_000);
    config.snippets = false;
    let utilisation = load(&config, "aim-dsp defaults without snippets");
    assert!(utilisation <= 0.02, "{:.1} % of the link", 100.0 * utilisation);
}
