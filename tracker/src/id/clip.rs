//! One feature vector per clip, from the per-frame features of `aim_dsp::features`.
//!
//! Frames of 1024 samples (64 ms at 16 kHz) hop by 512. Per clip, in this order
//! ([`names`]):
//! - MFCC c1..c12: mean and standard deviation over the frames (24; c0, the level, is dropped:
//!   a recording's gain is unknown);
//! - log-mel bands minus the frame's mean band level, mean over the frames (32: the spectral
//!   shape, level-free);
//! - BPF harmonic features of each frame: median comb fundamental (octaves re 250 Hz), its
//!   standard deviation over the frames (the manoeuvre), mean salience, mean half- and
//!   third-way levels, mean harmonic envelope (10);
//! - the same nine harmonic features of the clip's mean power spectrum (lines stand out of the
//!   noise there far better than in one frame; 9);
//! - the frames' comb fundamental, half-, third-way levels and envelope again, averaged with
//!   weights `max(0, salience − 3 dB)²` (frames where the comb stands clear of the noise count,
//!   the others hardly; 8), the 90th percentile of the salience (1), the spectral flux (mean
//!   absolute frame-to-frame change of the level-free log-mel, dB; speech and music change,
//!   rotors hum; 1) and the share of frames whose fundamental is within 1/12 octave of the
//!   previous frame's (a rotor's comb glides, a voice or a tune jumps; 1).
use aim_dsp::features::{Extractor, BINS, FRAME_LEN, HARMONIC_FEATURES, MEL_BANDS, MFCC_COUNT};

/// Hop between frames, samples.
pub const HOP: usize = FRAME_LEN / 2;
/// Length of a clip's feature vector.
pub const FEATURES: usize =
    2 * (MFCC_COUNT - 1) + MEL_BANDS + (HARMONIC_FEATURES + 1) + HARMONIC_FEATURES + 11;

/// Names of the features, in vector order.
pub fn names() -> Vec<String> {
    let mut v = spectral_names("", MFCC_COUNT, MEL_BANDS);
    let h = HARMONIC_NAMES;
    v.push("frame_log2_f0_median".into());
    v.push("frame_log2_f0_sd".into());
    for n in &h[1..] {
        v.push(format!("frame_{n}_mean"));
    }
    for n in &h {
        v.push(format!("clip_{n}"));
    }
    for n in h.iter().filter(|n| **n != "salience_db") {
        v.push(format!("weighted_{n}"));
    }
    v.push("salience_p90_db".into());
    v.push("log_mel_flux_db".into());
    v.push("f0_continuity".into());
    v
}

/// Names of the harmonic features of a frame (`aim_dsp::features` / `idframe` order).
pub(crate) const HARMONIC_NAMES: [&str; 9] = [
    "log2_f0",
    "salience_db",
    "half_db",
    "third_db",
    "env2_db",
    "env3_db",
    "env4_db",
    "env5_db",
    "env6_db",
];

/// The names both feature sets start with, `prefix`ed: MFCC c1.. means, then their standard
/// deviations (`mfcc` coefficients with c0), then the level-free mel bands.
pub(crate) fn spectral_names(prefix: &str, mfcc: usize, mel: usize) -> Vec<String> {
    let mut v: Vec<String> = (1..mfcc).map(|c| format!("{prefix}mfcc{c}_mean")).collect();
    v.extend((1..mfcc).map(|c| format!("{prefix}mfcc{c}_sd")));
    v.extend((0..mel).map(|b| format!("{prefix}mel{b}_rel_db")));
    v
}

/// Mean and population standard deviation of `x` (0, 0 when empty).
pub(crate) fn mean_sd(x: impl Iterator<Item = f32> + Clone) -> (f32, f32) {
    let n = x.clone().count().max(1) as f32;
    let m = x.clone().sum::<f32>() / n;
    let var = x.map(|v| (v - m) * (v - m)).sum::<f32>() / n;
    (m, var.sqrt())
}

/// Of per-frame comb features `h` (in [`aim_dsp::features::HarmonicFeatures::to_array`]
/// order: fundamental, salience, ...): the median fundamental, its standard deviation and the
/// mean of each of the other eight.
pub(super) fn comb_stats(v: &mut Vec<f32>, h: &[[f32; HARMONIC_FEATURES]]) {
    let mut f0: Vec<f32> = h.iter().map(|a| a[0]).collect();
    f0.sort_by(f32::total_cmp);
    v.push(f0.get(f0.len() / 2).copied().unwrap_or(0.0));
    v.push(mean_sd(h.iter().map(|a| a[0])).1);
    for i in 1..HARMONIC_FEATURES {
        v.push(mean_sd(h.iter().map(move |a| a[i])).0);
    }
}

/// Of per-frame comb features `h` (as [`comb_stats`]): each but the salience averaged with
/// weights `max(0, salience − 3 dB)²`.
pub(super) fn comb_weighted(v: &mut Vec<f32>, h: &[[f32; HARMONIC_FEATURES]]) {
    let w: Vec<f32> = h.iter().map(|a| (a[1] - 3.0).max(0.0).powi(2) + 1e-6).collect();
    let wsum: f32 = w.iter().sum();
    for i in (0..HARMONIC_FEATURES).filter(|&i| i != 1) {
        v.push(h.iter().zip(&w).map(|(a, w)| a[i] * w).sum::<f32>() / wsum);
    }
}

/// Of per-frame comb features `h` (as [`comb_stats`]): the share of frames whose fundamental
/// is within 1/12 octave of the previous frame's (of the frame pairs; 0 for one frame).
pub(super) fn f0_continuity(h: &[[f32; HARMONIC_FEATURES]]) -> f32 {
    let pairs = h.len().saturating_sub(1).max(1) as f32;
    let steady = h.windows(2).filter(|p| (p[0][0] - p[1][0]).abs() < 1.0 / 12.0).count();
    steady as f32 / pairs
}

/// The feature vector of a 16 kHz clip (at least one frame long).
pub fn features(x: &[f32], ex: &Extractor) -> Vec<f32> {
    let mut frames = Vec::new();
    let mut mean_power = [0.0f32; BINS];
    let mut start = 0;
    while start + FRAME_LEN <= x.len() {
        let mut buf = [0.0f32; FRAME_LEN];
        buf.copy_from_slice(&x[start..start + FRAME_LEN]);
        let mut p = [0.0f32; BINS];
        ex.power_spectrum(&mut buf, &mut p);
        for (m, v) in mean_power.iter_mut().zip(&p) {
            *m += v;
        }
        frames.push(ex.features(&p));
        start += HOP;
    }
    let n = frames.len().max(1) as f32;
    mean_power.iter_mut().for_each(|v| *v /= n);
    let mut v = Vec::with_capacity(FEATURES);
    let stats: Vec<(f32, f32)> =
        (1..MFCC_COUNT).map(|c| mean_sd(frames.iter().map(move |f| f.mfcc[c]))).collect();
    v.extend(stats.iter().map(|s| s.0));
    v.extend(stats.iter().map(|s| s.1));
    for b in 0..MEL_BANDS {
        let rel = frames
            .iter()
            .map(move |f| f.log_mel_db[b] - f.log_mel_db.iter().sum::<f32>() / MEL_BANDS as f32);
        v.push(mean_sd(rel).0);
    }
    let h: Vec<[f32; HARMONIC_FEATURES]> = frames.iter().map(|f| f.harmonic.to_array()).collect();
    comb_stats(&mut v, &h);
    v.extend(ex.features(&mean_power).harmonic.to_array());
    comb_weighted(&mut v, &h);
    let mut sal: Vec<f32> = h.iter().map(|a| a[1]).collect();
    sal.sort_by(f32::total_cmp);
    v.push(sal.get(sal.len() * 9 / 10).copied().unwrap_or(0.0));
    let rel = |f: &aim_dsp::features::FrameFeatures| {
        let m = f.log_mel_db.iter().sum::<f32>() / MEL_BANDS as f32;
        f.log_mel_db.map(|l| l - m)
    };
    let pairs = frames.len().saturating_sub(1).max(1) as f32;
    let flux: f32 = frames
        .windows(2)
        .map(|p| {
            let (a, b) = (rel(&p[0]), rel(&p[1]));
            a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum::<f32>() / MEL_BANDS as f32
        })
        .sum::<f32>()
        / pairs;
    v.push(flux);
    v.push(f0_continuity(&h));
    debug_assert_eq!(v.len(), FEATURES);
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_match_the_vector_and_level_does_not_matter() {
        assert_eq!(names().len(), FEATURES);
        let ex = Extractor::new();
        // A 300 Hz comb with harmonics over a little noise.
        let mut lcg = 7u32;
        let x: Vec<f32> = (0..16_000)
            .map(|k| {
                lcg = lcg.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let t = k as f32 / 16_000.0;
                (1..6)
                    .map(|h| (2.0 * std::f32::consts::PI * 300.0 * h as f32 * t).sin() / h as f32)
                    .sum::<f32>()
                    + 0.05 * ((lcg >> 8) as f32 / (1u32 << 24) as f32 - 0.5)
            })
            .collect();
        let a = features(&x, &ex);
        assert_eq!(a.len(), FEATURES);
        assert!(a.iter().all(|v| v.is_finite()));
        // The clip's comb fundamental is 300 Hz within the 1/24-octave grid.
        let at = names().iter().position(|n| n == "clip_log2_f0").unwrap();
        let f0 = aim_dsp::features::F0_REF_HZ * 2f32.powf(a[at]);
        assert!((f0 / 300.0 - 1.0).abs() < 0.03, "{f0}");
        // 20 dB louder: the same features (level-free), to float rounding.
        let loud: Vec<f32> = x.iter().map(|v| 10.0 * v).collect();
        let b = features(&loud, &ex);
        for (i, (p, q)) in a.iter().zip(&b).enumerate() {
            assert!((p - q).abs() < 1e-2 * (1.0 + p.abs()), "{}: {p} vs {q}", names()[i]);
        }
    }
}
