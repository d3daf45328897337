//! Direction of arrival: weighted least squares over all microphone pairs (far field, planar).
//!
//! For a plane wave from unit direction u, the pair delay is c·τ_ij = (p_i − p_j)·u
//! (τ_ij = t_j − t_i). The horizontal part (u_x, u_y) is the weighted least-squares solution
//! over all pairs; |u_xy| is clamped to 1 and u_z = +sqrt(1 − |u_xy|²): the source is on the
//! array's open side. Azimuth α = atan2(u_y, u_x), zenith φ = asin(|u_xy|).

use crate::gcc_phat::DelayEstimate;

/// One microphone pair of the array.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pair {
    /// First microphone (i).
    pub i: u8,
    /// Second microphone (j), j > i.
    pub j: u8,
    /// Baseline p_i − p_j, metres.
    pub baseline_m: [f32; 2],
    /// Lag search range |τ| ≤ `max_lag` samples: |p_i − p_j| / c · fs + 1, rounded up.
    pub max_lag: u8,
}

/// A direction fit.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Direction {
    /// Azimuth, radians, from +x towards +y.
    pub azimuth_rad: f32,
    /// Zenith angle from +z, radians.
    pub zenith_rad: f32,
    /// Weighted RMS misfit of the pair delays, samples.
    pub residual_samples: f32,
    /// Pairs with non-zero weight.
    pub pairs_used: u8,
}

/// Fits a direction to pair delays. `samples_per_metre` = fs / c. Weights are
/// [`DelayEstimate::quality`]. Returns `None` when the weighted pairs do not span the plane.
///
/// ```
/// use aim_dsp::doa::{fit, Pair};
/// use aim_dsp::gcc_phat::DelayEstimate;
/// // Square array, source along +x at zenith 90°: mics with larger x hear it first.
/// let p = [[0.05f32, 0.0], [0.0, 0.05], [-0.05, 0.0], [0.0, -0.05]];
/// let k = 48_000.0 / 343.0;
/// let mut pairs = Vec::new();
/// let mut delays = Vec::new();
/// for i in 0..4 {
///     for j in i + 1..4 {
///         let b = [p[i][0] - p[j][0], p[i][1] - p[j][1]];
///         pairs.push(Pair { i: i as u8, j: j as u8, baseline_m: b, max_lag: 16 });
///         delays.push(DelayEstimate { delay_samples: k * b[0], coherence: 1.0, peak_margin: 1.0 });
///     }
/// }
/// let d = fit(&pairs, &delays, k).unwrap();
/// assert!(d.azimuth_rad.abs() < 1e-4);
/// assert!((d.zenith_rad - core::f32::consts::FRAC_PI_2).abs() < 1e-2);
/// ```
pub fn fit(pairs: &[Pair], delays: &[DelayEstimate], samples_per_metre: f32) -> Option<Direction> {
    let (mut axx, mut axy, mut ayy, mut bx, mut by, mut wsum) =
        (0.0f32, 0.0f32, 0.0f32, 0.0f32, 0.0f32, 0.0f32);
    let mut used = 0u8;
    for (p, d) in pairs.iter().zip(delays) {
        let w = d.quality();
        if w.is_nan() || w <= 0.0 {
            continue;
        }
        used += 1;
        let [dx, dy] = p.baseline_m;
        let path = d.delay_samples / samples_per_metre; // c·τ, metres
        axx += w * dx * dx;
        axy += w * dx * dy;
        ayy += w * dy * dy;
        bx += w * dx * path;
        by += w * dy * path;
        wsum += w;
    }
    let det = axx * ayy - axy * axy;
    let scale = axx + ayy;
    if used < 2 || det.is_nan() || det <= 1e-6 * scale * scale {
        return None;
    }
    let mut ux = (ayy * bx - axy * by) / det;
    let mut uy = (axx * by - axy * bx) / det;
    let mut norm = libm::sqrtf(ux * ux + uy * uy);
    if norm > 1.0 {
        ux /= norm;
        uy /= norm;
        norm = 1.0;
    }
    let mut sq = 0.0f32;
    for (p, d) in pairs.iter().zip(delays) {
        let w = d.quality();
        if w.is_nan() || w <= 0.0 {
            continue;
        }
        let model = (p.baseline_m[0] * ux + p.baseline_m[1] * uy) * samples_per_metre;
        let e = d.delay_samples - model;
        sq += w * e * e;
    }
    Some(Direction {
        azimuth_rad: libm::atan2f(uy, ux),
        zenith_rad: libm::asinf(norm),
        residual_samples: libm::sqrtf(sq / wsum),
        pairs_used: used,
    })
}
