//! Fusion of the multi-array fix with the AIM track: the complementary filter of eqs. 10–11
//! (ALGORITHMS.md §9), low-pass on the multi-array fix x_M (accurate, jittery), high-pass on the
//! AIM track x_A (smooth, drifting).
//!
//! Causal form, for `aim track`: x̂_k = G·(x̂_{k−1} + Δx_A,k) + (1 − G)·x_M,k with
//! G = τ/(τ + Δt). Its transfer functions are H_M(z) = (1 − G)/(1 − G z⁻¹) and
//! H_A(z) = G(1 − z⁻¹)/(1 − G z⁻¹), which add up to 1: a signal common to both passes
//! unchanged, a constant offset of x_A is removed (H_A(1) = 0), white noise of x_M keeps the
//! standard-deviation fraction √((1 − G)/(1 + G)) ≈ √(Δt / 2τ) ([`ComplementaryFilter::noise_factor`]).
//! A step without a multi-array fix just carries x̂ by Δx_A.
//!
//! Offline form, for replay (paper eq. 11): Ŝ(f) = Z_M(f)·G(f) + Z_A(f)·(1 − G(f)) over the
//! whole window, computed as x_A + IFFT(G·FFT(x_M − x_A)) with the difference mirrored to twice
//! its length (no jump at the window's ends) and G(f) = 1/(1 + (2πfτ)²), the zero-phase
//! counterpart of the causal first-order filter.

use rustfft::{num_complex::Complex, FftPlanner};

/// The causal complementary filter of one track (3-D).
#[derive(Clone, Debug)]
pub struct ComplementaryFilter {
    /// Time constant τ, s: periods longer than about 2πτ come from the multi-array fix.
    pub time_constant_s: f64,
    estimate: Option<[f64; 3]>,
    last_aim: Option<[f64; 3]>,
}

impl ComplementaryFilter {
    /// A filter with time constant `time_constant_s` (s, > 0).
    pub fn new(time_constant_s: f64) -> Self {
        Self { time_constant_s, estimate: None, last_aim: None }
    }

    /// G = τ/(τ + Δt) for a step of `dt_s` (s).
    pub fn gain(&self, dt_s: f64) -> f64 {
        self.time_constant_s / (self.time_constant_s + dt_s)
    }

    /// Fraction of the standard deviation of white noise on x_M that passes at gain `g`:
    /// √((1 − G)/(1 + G)).
    pub fn noise_factor(g: f64) -> f64 {
        ((1.0 - g) / (1.0 + g)).sqrt()
    }

    /// One step of `dt_s` (s): the AIM position `aim` and, if there is one, the multi-array fix
    /// `multi` (world m) → the fused position (world m). The first step starts at the fix (or,
    /// without one, at the AIM position).
    pub fn update(&mut self, dt_s: f64, aim: [f64; 3], multi: Option<[f64; 3]>) -> [f64; 3] {
        let g = self.gain(dt_s);
        let estimate = match (self.estimate, self.last_aim) {
            (Some(x), Some(last)) => std::array::from_fn(|i| {
                let carried = x[i] + aim[i] - last[i];
                match multi {
                    Some(m) => g * carried + (1.0 - g) * m[i],
                    None => carried,
                }
            }),
            _ => multi.unwrap_or(aim),
        };
        self.estimate = Some(estimate);
        self.last_aim = Some(aim);
        estimate
    }

    /// The current fused position, if any.
    pub fn estimate(&self) -> Option<[f64; 3]> {
        self.estimate
    }
}

/// Offline form over a window sampled every `dt_s` (s): `multi` and `aim` (world m, same
/// length) → the fused track, with G(f) = 1/(1 + (2πfτ)²) for `time_constant_s` τ (s).
pub fn fuse_offline(
    multi: &[[f64; 3]],
    aim: &[[f64; 3]],
    dt_s: f64,
    time_constant_s: f64,
) -> Vec<[f64; 3]> {
    let n = multi.len().min(aim.len());
    if n == 0 {
        return Vec::new();
    }
    let len = 2 * n;
    let mut planner = FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(len);
    let inverse = planner.plan_fft_inverse(len);
    let mut out: Vec<[f64; 3]> = aim[..n].to_vec();
    for axis in 0..3 {
        // The difference x_M − x_A, mirrored: d_0 … d_{n−1} d_{n−1} … d_0.
        let mut buf: Vec<Complex<f64>> = (0..len)
            .map(|i| {
                let k = if i < n { i } else { len - 1 - i };
                Complex::new(multi[k][axis] - aim[k][axis], 0.0)
            })
            .collect();
        forward.process(&mut buf);
        for (i, v) in buf.iter_mut().enumerate() {
            let bin = if i <= len / 2 { i } else { len - i };
            let f = bin as f64 / (len as f64 * dt_s);
            *v *= 1.0 / (1.0 + (std::f64::consts::TAU * f * time_constant_s).powi(2));
        }
        inverse.process(&mut buf);
        for (o, v) in out.iter_mut().zip(&buf) {
            o[axis] += v.re / len as f64;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::Rng;

    /// A wandering true track, m.
    fn truth(t: f64) -> [f64; 3] {
        [3.0 + 2.0 * (0.3 * t).sin(), 4.0 + 1.5 * (0.17 * t).cos(), 1.5 + 0.2 * t.sin()]
    }

    /// The AIM track off by a constant 0.8 m, the multi-array fix exact: the offset decays as
    /// G^k and is gone; the fused track is the truth.
    #[test]
    fn a_constant_offset_of_the_aim_track_is_removed() {
        let (dt, tau) = (0.1, 2.0);
        let mut f = ComplementaryFilter::new(tau);
        let g = f.gain(dt);
        let offset = [0.8, -0.5, 0.3];
        let aim_at = |t: f64| std::array::from_fn(|i| truth(t)[i] + offset[i]);
        // Started on the AIM track (no fix at first), then fixes every step.
        f.update(dt, aim_at(0.0), None);
        for k in 1..=300 {
            let t = k as f64 * dt;
            let x = f.update(dt, aim_at(t), Some(truth(t)));
            for i in 0..3 {
                // Exactly: x − s = G^k · offset.
                let want = g.powi(k) * offset[i];
                assert!((x[i] - truth(t)[i] - want).abs() < 1e-9, "{k} {i}");
            }
        }
        // Offline: the offset (DC) is removed exactly, at the ends too.
        let multi: Vec<[f64; 3]> = (0..512).map(|k| truth(k as f64 * dt)).collect();
        let aim: Vec<[f64; 3]> = (0..512).map(|k| aim_at(k as f64 * dt)).collect();
        let fused = fuse_offline(&multi, &aim, dt, tau);
        for (x, s) in fused.iter().zip(&multi) {
            for i in 0..3 {
                assert!((x[i] - s[i]).abs() < 1e-9, "{x:?} {s:?}");
            }
        }
    }

    /// White noise of the multi-array fix (σ = 0.3 m) with an exact AIM track: the fused
    /// error's standard deviation is σ·√((1 − G)/(1 + G)) (0.047 m at Δt = 0.1 s, τ = 2 s),
    /// within 5 % over 100 000 steps; the offline form keeps Σ G(f)² / N of the variance.
    #[test]
    fn noise_of_the_multi_array_fix_is_attenuated_by_the_stated_factor() {
        let (dt, tau, sigma) = (0.1, 2.0, 0.3);
        let mut f = ComplementaryFilter::new(tau);
        let factor = ComplementaryFilter::noise_factor(f.gain(dt));
        assert!((factor - (1.0 / 41.0f64).sqrt()).abs() < 1e-12, "{factor}");
        let mut rng = Rng::new(10);
        let n = 100_000;
        let (mut sum, mut sum_sq, mut count) = (0.0, 0.0, 0);
        let mut multi = Vec::new();
        let mut aim = Vec::new();
        for k in 0..n {
            let t = k as f64 * dt;
            let s = truth(t);
            let m = [s[0] + sigma * rng.normal(), s[1], s[2]];
            let x = f.update(dt, s, Some(m));
            if k > 200 {
                let e = x[0] - s[0];
                sum += e;
                sum_sq += e * e;
                count += 1;
            }
            multi.push(m);
            aim.push(s);
        }
        let sd = (sum_sq / count as f64 - (sum / count as f64).powi(2)).sqrt();
        assert!((sd / (sigma * factor) - 1.0).abs() < 0.05, "{sd} vs {}", sigma * factor);
        let fused = fuse_offline(&multi, &aim, dt, tau);
        let len = 2.0 * multi.len() as f64;
        // Variance kept by the zero-phase filter: mean of G(f)² over the bins.
        let kept: f64 = (0..2 * multi.len())
            .map(|i| {
                let bin = i.min(2 * multi.len() - i) as f64;
                let f = bin / (len * dt);
                (1.0 + (std::f64::consts::TAU * f * tau).powi(2)).powi(-2)
            })
            .sum::<f64>()
            / len;
        let middle = &fused[20_000..80_000];
        let exact = &aim[20_000..80_000];
        let e: Vec<f64> = middle.iter().zip(exact).map(|(x, s)| x[0] - s[0]).collect();
        let sd = (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt();
        assert!((sd / (sigma * kept.sqrt()) - 1.0).abs() < 0.05, "{sd} vs {}", sigma * kept.sqrt());
        // The zero-phase filter passes less noise than the causal one.
        assert!(kept.sqrt() < factor);
        // And the other axes, noiseless, pass unchanged.
        assert!(middle.iter().zip(exact).all(|(x, s)| (x[1] - s[1]).abs() < 1e-9));
    }

    /// Without a multi-array fix the filter follows the AIM track's steps.
    #[test]
    fn steps_without_a_fix_follow_the_aim_track() {
        let mut f = ComplementaryFilter::new(1.0);
        assert_eq!(f.update(0.1, [1.0, 1.0, 1.0], Some([2.0, 2.0, 2.0])), [2.0, 2.0, 2.0]);
        assert_eq!(f.update(0.1, [1.5, 1.0, 0.0], None), [2.5, 2.0, 1.0]);
        assert_eq!(f.estimate(), Some([2.5, 2.0, 1.0]));
    }
}
