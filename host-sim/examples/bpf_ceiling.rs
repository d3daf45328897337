//! Diagnosis of the BPF bench (not part of the product): the best any estimator that reads one
//! 0.512 s window can do on the bench's airframes, against the bench's truth (each rotor's BPF
//! averaged over the window, Hann-power weighted).
//!
//! Per frame, each rotor's own sound at 1 m (no room, no background, no other rotor) is
//! windowed like the chip's analysis (Hann, 0.512 s, frames 0.256 s apart, the first two left
//! out as the bench does) and the peak of its magnitude spectrum is found on a 0.1 Hz grid
//! within ±15 Hz of its truth: "own" counts the rotor-frames whose peak lies within 2 Hz of
//! that rotor's truth. "sum" takes the strongest peak of all rotors together (still no room,
//! no noise) between the lowest and highest rotor BPF ± 10 Hz and counts the frames where it
//! lies within 2 Hz of some rotor's truth, the bench's criterion. Rotor speeds that sweep
//! within a window (a small airframe's attitude control in manoeuvres) put the peak away from
//! the window's mean speed; no detector working on that window can do better than "sum".
//!
//! `cargo run --release -p host-sim --example bpf_ceiling -- tune|eval|SEED,SEED,… [DURATION]`
use host_sim::bpf_bench::{airframes, flight, rotor_sounds, true_bpf, FS};

/// Frequency (Hz) of the largest Hann-windowed DFT magnitude of `x` on a 0.1 Hz grid in
/// `lo..=hi`.
fn peak(x: &[f64], lo: f64, hi: f64) -> f64 {
    let fs = f64::from(FS);
    let n = x.len();
    let w: Vec<f64> = (0..n)
        .map(|i| x[i] * (std::f64::consts::PI * (i as f64 + 0.5) / n as f64).sin().powi(2))
        .collect();
    let (mut best, mut at) = (0.0, lo);
    let steps = ((hi - lo) / 0.1).round() as usize;
    for s in 0..=steps {
        let f = lo + 0.1 * s as f64;
        let d = std::f64::consts::TAU * f / fs;
        let (mut re, mut im) = (0.0, 0.0);
        for (i, v) in w.iter().enumerate() {
            let a = d * i as f64;
            re += v * a.cos();
            im += v * a.sin();
        }
        let p = re * re + im * im;
        if p > best {
            (best, at) = (p, f);
        }
    }
    at
}

fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    anyhow::ensure!(!a.is_empty(), "usage: tune|eval|SEED,SEED,… [DURATION]");
    let seeds: Vec<u64> = match a[0].as_str() {
        "tune" => host_sim::bpf_bench::TUNING_SEEDS.to_vec(),
        "eval" => host_sim::bpf_bench::EVALUATION_SEEDS.to_vec(),
        list => list.split(',').map(str::parse).collect::<Result<_, _>>()?,
    };
    let dur: f64 = a.get(1).map_or(Ok(8.0), |d| d.parse())?;
    let window = 8192; // 0.512 s at 16 kHz
    let hop = 4096;
    println!("airframe             own rotor within 2 Hz   strongest line within 2 Hz of a rotor");
    let (mut all_sum, mut all_n) = (0usize, 0usize);
    for p in airframes() {
        let (mut own, mut sum_ok, mut n, mut nr) = (0usize, 0usize, 0usize, 0usize);
        for &seed in &seeds {
            let log = flight(&p, dur, seed)?;
            let rotors = rotor_sounds(&p, &log, dur, seed);
            let mut sum = vec![0.0; rotors[0].len()];
            for r in &rotors {
                host_sim::tonal::add(&mut sum, r, 1.0);
            }
            let frames = (sum.len() - window) / hop + 1;
            for j in host_sim::bpf_bench::SETTLING_FRAMES..frames {
                let t_mid = j as f64 * 0.256 + 0.256;
                let span = j * hop..j * hop + window;
                let truth: Vec<f64> = (0..p.rotor_count())
                    .map(|r| true_bpf(&log, r, f64::from(p.blades), t_mid))
                    .collect();
                for (r, x) in rotors.iter().enumerate() {
                    let f = peak(&x[span.clone()], truth[r] - 15.0, truth[r] + 15.0);
                    nr += 1;
                    own += usize::from((f - truth[r]).abs() <= 2.0);
                }
                let lo = truth.iter().copied().fold(f64::MAX, f64::min) - 10.0;
                let hi = truth.iter().copied().fold(0.0, f64::max) + 10.0;
                let f = peak(&sum[span], lo, hi);
                n += 1;
                sum_ok += usize::from(truth.iter().any(|&b| (f - b).abs() <= 2.0));
            }
        }
        all_sum += sum_ok;
        all_n += n;
        println!(
            "{:20} {:6.1}% of {:5}          {:6.1}% of {:5}",
            p.name,
            100.0 * own as f64 / nr as f64,
            nr,
            100.0 * sum_ok as f64 / n as f64,
            n
        );
    }
    println!(
        "all airframes                                {:6.1}% of {all_n}",
        100.0 * all_sum as f64 / all_n as f64
    );
    Ok(())
}
