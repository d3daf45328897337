//! Diagnosis of the BPF bench (not part of the product, session 42): the detector's reported
//! groups re-estimated or re-ordered, scored as `bpf_replay` scores (first group within 2 Hz
//! of a rotor, octave errors), per airframe.
//! `cargo run --release -p host-sim --example bpf_refine -- DIR` on a `bpf_cache` directory.
//! Environment (unset: the default in brackets):
//! - `OFF=1`: the detector's own frequencies; else each group is re-estimated on the centre
//!   `N` [2048] decimated samples, lines searched within ±`TOL` [0.02] of h·f₀, weighted by
//!   `W` [1] (0 equal, 1 amplitude, 2 amplitude·h, 3 amplitude², 4 (amplitude·h)²), lines
//!   under `REL` [0] of the strongest left out, up to harmonic `H` [20]; `R0` ≥ 0: a power
//!   centroid over ±(`R0` + h·`R1`) bins instead of the ratio estimator;
//! - `HET=1`: time-resolved instead: each harmonic heterodyned to baseband, the phase advance
//!   between Hann blocks of `BLK` [256] samples (hop `BLK`/2), weighted by the window's power,
//!   harmonics from `HMIN` [1] (or only `HS`), combined by `HW` [1] (0 equal, 1 energy,
//!   2 energy·h²);
//! - `SEL` [0]: the first group swapped for the one in its cluster (±8 %) with the largest
//!   amplitude (1), harmonicity (2), quality (3) or the least spread of f_h/h (4);
//! - `DUMP=HZ` (with `DUMPJ=J,J,…`): each analysis's groups and the levels at multiples of HZ.
use std::collections::BTreeMap;

use aim_dsp::bpf::{Decimator, SpectralPath, ANALYSIS_LEN};
use aim_dsp::{Config, Geometry};
use host_sim::bpf_bench::{classify, Verdict};
use rustfft::{num_complex::Complex, FftPlanner};

fn envf(k: &str, d: f64) -> f64 {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

/// The Hann-window ratio estimator's offset of the peak at bin `k`, bins (−0.5…0.5).
fn grandke(mags: &[f64], k: usize) -> f64 {
    let (m0, ml, mr) = (mags[k], mags[k - 1], mags[k + 1]);
    let (a, sign) = if mr > ml { (mr / m0, 1.0) } else { (ml / m0, -1.0) };
    (sign * (2.0 * a - 1.0) / (a + 1.0)).clamp(-0.5, 0.5)
}

/// Magnitudes of the Hann-windowed `n` samples of `win` from `off`.
fn hann_mags(win: &[f32], off: usize, n: usize, fft: &dyn rustfft::Fft<f64>) -> Vec<f64> {
    let mut buf: Vec<Complex<f64>> = (0..n)
        .map(|i| {
            let w = 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos();
            Complex::new(f64::from(win[off + i]) * w, 0.0)
        })
        .collect();
    fft.process(&mut buf);
    buf[..n / 2].iter().map(|c| c.norm()).collect()
}

/// Refines f0 on the centre `n` samples of `win` (decimated, 8 kHz).
fn refine(win: &[f32], f0: f64, n: usize, fft: &dyn rustfft::Fft<f64>) -> Option<f64> {
    let off = (win.len() - n) / 2;
    let mags = hann_mags(win, off, n, fft);
    let bin = 8000.0 / n as f64;
    let tol = envf("TOL", 0.02);
    let wmode = envf("W", 1.0) as i32;
    let hmax = envf("H", 20.0) as usize;
    let (mut num, mut den) = (0.0, 0.0);
    let mut best = 0.0f64;
    let mut lines = Vec::new();
    for h in 1..=hmax {
        let fh = h as f64 * f0;
        if fh > 3800.0 {
            break;
        }
        let lo = (((fh * (1.0 - tol)) / bin).floor() as usize).max(2);
        let hi = (((fh * (1.0 + tol)) / bin).ceil() as usize).min(n / 2 - 2);
        let k = (lo..=hi).max_by(|&a, &b| mags[a].total_cmp(&mags[b]))?;
        if mags[k] <= mags[k - 1] || mags[k] < mags[k + 1] {
            continue;
        }
        let m0 = mags[k];
        let mut f = (k as f64 + grandke(&mags, k)) * bin;
        let r0 = envf("R0", -1.0);
        if r0 >= 0.0 {
            let r = (r0 + h as f64 * envf("R1", 0.0)).round() as usize;
            let (a, b) = (k.saturating_sub(r).max(1), (k + r).min(n / 2 - 1));
            let (mut s1, mut s0) = (0.0, 0.0);
            for (i, m) in mags.iter().enumerate().take(b + 1).skip(a) {
                let p = m * m;
                s1 += p * i as f64;
                s0 += p;
            }
            f = s1 / s0 * bin;
        }
        best = best.max(m0);
        lines.push((h as f64, f, m0));
    }
    let rel = envf("REL", 0.0);
    for &(h, f, a) in &lines {
        if a < rel * best {
            continue;
        }
        let w = match wmode {
            0 => 1.0,
            1 => a,
            2 => a * h,
            3 => a * a,
            _ => a * a * h * h,
        };
        num += w * f / h;
        den += w;
    }
    (den > 0.0).then(|| num / den)
}

/// Time-resolved: heterodyne harmonic h of f0 to baseband, short Hann blocks, the phase
/// advance between blocks gives the instantaneous frequency; sin^4-weighted mean over the window.
fn hetero(win: &[f32], f0: f64) -> Option<f64> {
    let n = win.len();
    let blk = envf("BLK", 256.0) as usize;
    let hop = blk / 2;
    let hsel = envf("HS", 0.0) as usize;
    let (mut num, mut den) = (0.0, 0.0);
    for h in 1..=20usize {
        let fh = h as f64 * f0;
        if fh > 3800.0 {
            break;
        }
        if hsel > 0 && h != hsel {
            continue;
        }
        if (h as f64) < envf("HMIN", 1.0) {
            continue;
        }
        let w0 = std::f64::consts::TAU * fh / 8000.0;
        let mut prev: Option<Complex<f64>> = None;
        let mut start = 0;
        let (mut hn, mut hd) = (0.0, 0.0);
        while start + blk <= n {
            let mut z = Complex::new(0.0, 0.0);
            for i in 0..blk {
                let t = start + i;
                let w = 0.5 - 0.5 * (std::f64::consts::TAU * (i as f64 + 0.5) / blk as f64).cos();
                let ph = -w0 * t as f64;
                z += Complex::new(ph.cos(), ph.sin()) * (win[t] as f64 * w);
            }
            if let Some(p) = prev {
                let d = (z * p.conj()).arg(); // phase advance over `hop` samples
                let df = d / (std::f64::consts::TAU * hop as f64 / 8000.0);
                let tc = (start as f64) / n as f64; // centre of the pair, fraction of window
                let ww = (std::f64::consts::PI * tc).sin().powi(4);
                let e = (z.norm() * p.norm()) * ww;
                hn += e * (fh + df) / h as f64;
                hd += e;
            }
            prev = Some(z);
            start += hop;
        }
        if hd > 0.0 {
            let wh = match envf("HW", 1.0) as i32 {
                0 => 1.0,
                1 => hd,
                _ => hd * (h * h) as f64,
            };
            num += wh * hn / hd;
            den += wh;
        }
    }
    (den > 0.0).then(|| num / den)
}

/// Weighted dispersion (Hz) of f_h/h over the comb's lines on the long window.
fn dispersion(win: &[f32], f0: f64) -> f64 {
    let n = win.len();
    thread_local! { static F: std::sync::Arc<dyn rustfft::Fft<f64>> = FftPlanner::new().plan_fft_forward(4096); }
    let mags = F.with(|f| hann_mags(win, 0, n, f.as_ref()));
    let bin = 8000.0 / n as f64;
    let mut v = Vec::new();
    for h in 1..=20usize {
        let fh = h as f64 * f0;
        if fh > 3800.0 {
            break;
        }
        let r = 1 + (fh / bin * 0.003) as usize;
        let c = (fh / bin).round() as usize;
        let k = (c - r..=c + r).max_by(|&a, &b| mags[a].total_cmp(&mags[b])).unwrap();
        if mags[k] < mags[k - 1] || mags[k] < mags[k + 1] {
            continue;
        }
        v.push(((k as f64 + grandke(&mags, k)) * bin / h as f64, mags[k]));
    }
    let sw: f64 = v.iter().map(|x| x.1).sum();
    let mean = v.iter().map(|x| x.0 * x.1).sum::<f64>() / sw;
    (v.iter().map(|x| x.1 * (x.0 - mean).powi(2)).sum::<f64>() / sw).sqrt()
}

fn dump(win: &[f32], base: f64) {
    let n = win.len();
    let fft = FftPlanner::new().plan_fft_forward(n);
    let mags = hann_mags(win, 0, n, fft.as_ref());
    let bin = 8000.0 / n as f64;
    let mut line = String::new();
    for m in 1..=28 {
        let fc = m as f64 * base;
        if fc > 3800.0 {
            break;
        }
        let lo = (fc * 0.995 / bin) as usize;
        let hi = (fc * 1.005 / bin) as usize + 1;
        let k = (lo..=hi).max_by(|&a, &b| mags[a].total_cmp(&mags[b])).unwrap();
        line += &format!(" {m}:{:.0}", 20.0 * mags[k].log10());
    }
    println!("  shaft {base:.1}:{line}");
}

fn frames(x: &[f32], config: &Config, n: usize, fft: &dyn rustfft::Fft<f64>) -> Vec<Vec<f64>> {
    let mut path = SpectralPath::empty();
    path.configure(16_000, 1);
    let mut dec = Decimator::empty();
    dec.configure(16_000);
    let mut hist: Vec<f32> = Vec::new();
    let tw = aim_dsp::gcc_phat::Twiddles::new();
    let mut scratch = [0.0f32; ANALYSIS_LEN];
    let mut out = Vec::new();
    let on = std::env::var_os("OFF").is_none();
    for &v in x {
        if let Some(y) = dec.push(v * 0.05) {
            hist.push(y);
        }
        if path.push(v * 0.05) {
            let p = path.analyze(config, &mut scratch, &tw);
            let win = &hist[hist.len() - ANALYSIS_LEN..];
            if let Ok(d) = std::env::var("DUMP") {
                let j = out.len();
                let base: f64 = d.parse().unwrap();
                if std::env::var("DUMPJ")
                    .map_or(true, |v| v.split(',').any(|x| x.parse::<usize>().ok() == Some(j)))
                {
                    println!(
                        "frame {j}: {:?}",
                        p.peaks[..p.count as usize]
                            .iter()
                            .map(|q| (q.hz, q.quality))
                            .collect::<Vec<_>>()
                    );
                    dump(win, base);
                }
            }
            let mut pk: Vec<aim_dsp::Peak> = p.peaks[..p.count as usize].to_vec();
            let sel = envf("SEL", 0.0) as i32;
            if sel > 0 && pk.len() > 1 {
                let f1 = pk[0].hz;
                let key = |q: &aim_dsp::Peak| -> f64 {
                    match sel {
                        1 => q.amplitude as f64,
                        2 => q.harmonicity as f64,
                        3 => q.quality as f64,
                        _ => -dispersion(win, q.hz as f64),
                    }
                };
                let mut bi = 0;
                for i in 1..pk.len() {
                    if (pk[i].hz - f1).abs() <= 0.08 * f1 && key(&pk[i]) > key(&pk[bi]) {
                        bi = i;
                    }
                }
                pk.swap(0, bi);
            }
            out.push(
                pk.iter()
                    .map(|q| {
                        let f = q.hz as f64;
                        if std::env::var_os("HET").is_some() {
                            hetero(win, f).unwrap_or(f)
                        } else if on {
                            refine(win, f, n, fft).unwrap_or(f)
                        } else {
                            f
                        }
                    })
                    .collect(),
            );
        }
    }
    out
}

fn main() -> anyhow::Result<()> {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).expect("DIR"));
    let n = envf("N", 2048.0) as usize;
    let fft = FftPlanner::new().plan_fft_forward(n);
    let config = Config::new(Geometry::respeaker_6mic(), 16_000);
    let mut names: Vec<_> = std::fs::read_dir(&dir)?
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".f32") && n.starts_with("d_"))
        .collect();
    names.sort();
    let mut by: BTreeMap<String, [usize; 4]> = BTreeMap::new();
    for nm in names {
        let bytes = std::fs::read(dir.join(&nm))?;
        let x: Vec<f32> =
            bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        let fr = frames(&x, &config, n, fft.as_ref());
        let stem = nm.trim_end_matches(".f32");
        let parts: Vec<&str> = stem.split('_').collect();
        let e = by.entry(parts[1].to_string()).or_default();
        let truth = std::fs::read_to_string(dir.join(format!("{stem}.truth")))?;
        let truth: Vec<Vec<f64>> =
            truth.lines().map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
        for (j, g) in fr.iter().enumerate().skip(2) {
            e[0] += 1;
            let Some(&f) = g.first() else { continue };
            e[1] += 1;
            let tr = &truth[j.min(truth.len() - 1)];
            match classify(f, tr) {
                Verdict::Correct => e[2] += 1,
                Verdict::Octave => e[3] += 1,
                Verdict::Wrong => {}
            }
        }
    }
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
    let mut t = [0usize; 4];
    for (k, v) in &by {
        println!(
            "{k:24} {:5} with {:5.1}% within {:5.1}% octave {:5.2}%",
            v[0],
            pct(v[1], v[0]),
            pct(v[2], v[0]),
            pct(v[3], v[0])
        );
        for i in 0..4 {
            t[i] += v[i];
        }
    }
    println!(
        "ALL {:5} with {:5.1}% within {:5.2}% octave {:5.2}%",
        t[0],
        pct(t[1], t[0]),
        pct(t[2], t[0]),
        pct(t[3], t[0])
    );
    Ok(())
}
