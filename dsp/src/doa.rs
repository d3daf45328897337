//! Direction of arrival: a robust weighted least-squares fit over all microphone pairs (far
//! field, planar).
//!
//! For a plane wave from unit direction u, the pair delay is c·τ_ij = (p_i − p_j)·u
//! (τ_ij = t_j − t_i). The horizontal part (u_x, u_y) is the weighted least-squares solution
//! over all pairs; |u_xy| is clamped to 1 and u_z = +sqrt(1 − |u_xy|²): the source is on the
//! array's open side. Azimuth α = atan2(u_y, u_x), zenith φ = asin(|u_xy|).
//!
//! In a room a pair's correlation peak can jump to a reflection (its delay then misfits the
//! plane wave by samples, against tenths of a sample for the direct path), and one such pair
//! drags the plain least-squares azimuth by ten degrees on a four-microphone array. So when
//! some pair misfits the plain fit by more than [`HUBER_PATH_M`], the fit is iterated:
//! [`HUBER_STEPS`] reweighted steps with Huber weights (a convex loss: they converge to the
//! bulk of the pairs from any start), then [`TUKEY_STEPS`] with Tukey's biweight, which gives
//! pairs misfitting by more than [`REJECT_PATH_M`] no weight at all. A frame whose pairs all
//! fit within [`HUBER_PATH_M`] gets the plain fit unchanged.

use crate::gcc_phat::DelayEstimate;
use crate::MAX_PAIRS;

/// Huber threshold on a pair's misfit, metres of path difference (c·τ): 0.71 cm, one sample
/// at 48 kHz (21 µs). Pairs within it keep their full weight; misfits beyond it are weighted
/// down as 1/|misfit|. A clean frame's pairs misfit by 0.1–0.2 samples.
pub const HUBER_PATH_M: f32 = 0.0071;
/// Tukey biweight cut-off, metres of path difference: 1.79 cm, 2.5 samples at 48 kHz (52 µs).
/// A pair whose delay misfits the robust fit by more gets no weight: a reflection-locked pair
/// misfits by about 3 samples.
pub const REJECT_PATH_M: f32 = 0.0179;
/// Huber reweighting steps.
pub const HUBER_STEPS: usize = 3;
/// Tukey reweighting steps after the Huber steps.
pub const TUKEY_STEPS: usize = 2;

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
    /// RMS misfit of all pair delays to this direction, weighted by pair quality, samples.
    pub residual_samples: f32,
    /// Pairs with non-zero quality.
    pub pairs_used: u8,
    /// Share of the pairs' quality weight the robust fit kept, 0–1: 1 when every pair fits
    /// one plane wave, lower when pairs were weighted down or rejected as reflections
    /// (a reverberation- or obstruction-dominated frame).
    pub kept_weight: f32,
}

/// Weighted normal equations of the scaled horizontal direction v = u · fs / c (samples of
/// delay per metre of baseline).
#[derive(Clone, Copy, Default)]
struct Normal {
    axx: f32,
    axy: f32,
    ayy: f32,
    bx: f32,
    by: f32,
}

impl Normal {
    /// Adds a pair of baseline `[dx, dy]` (metres) and delay `tau` (samples) with weight `w`.
    fn add(&mut self, w: f32, [dx, dy]: [f32; 2], tau: f32) {
        let (wx, wy) = (w * dx, w * dy);
        self.axx += wx * dx;
        self.axy += wx * dy;
        self.ayy += wy * dy;
        self.bx += wx * tau;
        self.by += wy * tau;
    }

    /// v, or `None` when the weighted baselines do not span the plane.
    fn solve(&self) -> Option<[f32; 2]> {
        let det = self.axx * self.ayy - self.axy * self.axy;
        let scale = self.axx + self.ayy;
        if det.is_nan() || det <= 1e-6 * scale * scale {
            return None;
        }
        let inv = 1.0 / det;
        Some([
            (self.ayy * self.bx - self.axy * self.by) * inv,
            (self.axx * self.by - self.axy * self.bx) * inv,
        ])
    }
}

/// A pair's weight in the fit: its quality, or 0 for a pair without a usable peak.
fn base_weight(d: &DelayEstimate) -> f32 {
    let w = d.quality();
    if w.is_nan() || w <= 0.0 {
        0.0
    } else {
        w
    }
}

/// Delay misfit of a pair to the scaled direction `v` (see [`Normal`]), samples.
fn misfit(p: &Pair, d: &DelayEstimate, v: [f32; 2]) -> f32 {
    d.delay_samples - (p.baseline_m[0] * v[0] + p.baseline_m[1] * v[1])
}

/// One weighted fit with weight `q · weight(misfit to v)` per pair (`q` = [`base_weight`]),
/// and the largest |misfit| to `v` of a weighted pair, samples.
fn reweighted(
    pairs: &[Pair],
    delays: &[DelayEstimate],
    q: &[f32],
    v: [f32; 2],
    weight: impl Fn(f32) -> f32,
) -> (Option<[f32; 2]>, f32) {
    let mut n = Normal::default();
    let mut largest = 0.0f32;
    for ((p, d), &q) in pairs.iter().zip(delays).zip(q) {
        if q > 0.0 {
            let e = misfit(p, d, v);
            largest = largest.max(libm::fabsf(e));
            let w = q * weight(e);
            if w > 0.0 {
                n.add(w, p.baseline_m, d.delay_samples);
            }
        }
    }
    (n.solve(), largest)
}

/// Huber weight of a misfit `e` with threshold `h` (same units): 1 within h, h / |e| beyond.
fn huber(e: f32, h: f32) -> f32 {
    let a = libm::fabsf(e);
    if a <= h {
        1.0
    } else {
        h / a
    }
}

/// Tukey biweight of a misfit `e` with cut-off `c` (same units): (1 − (e/c)²)² within c,
/// 0 beyond.
fn tukey(e: f32, c: f32) -> f32 {
    let r = e / c;
    let r2 = r * r;
    if r2 >= 1.0 {
        0.0
    } else {
        (1.0 - r2) * (1.0 - r2)
    }
}

/// Fits a direction to pair delays. `samples_per_metre` = fs / c. Pair weights are
/// [`DelayEstimate::quality`], made robust against reflection-locked pairs as the module docs
/// describe. Returns `None` when the weighted pairs do not span the plane.
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
/// assert_eq!(d.kept_weight, 1.0);
/// ```
pub fn fit(pairs: &[Pair], delays: &[DelayEstimate], samples_per_metre: f32) -> Option<Direction> {
    let n = pairs.len().min(delays.len()).min(MAX_PAIRS);
    let (pairs, delays) = (&pairs[..n], &delays[..n]);
    let mut q = [0.0f32; MAX_PAIRS];
    let mut n_used = 0u8;
    let mut q_sum = 0.0f32;
    let mut plain = Normal::default();
    for ((p, d), q) in pairs.iter().zip(delays).zip(&mut q) {
        *q = base_weight(d);
        if *q > 0.0 {
            n_used += 1;
            q_sum += *q;
            plain.add(*q, p.baseline_m, d.delay_samples);
        }
    }
    let q = &q[..n];
    if n_used < 2 {
        return None;
    }
    let mut v = plain.solve()?;
    let (h, c) = (HUBER_PATH_M * samples_per_metre, REJECT_PATH_M * samples_per_metre);
    // The first Huber step also measures the plain fit's largest misfit: within h every Huber
    // weight is 1, the step would return the plain fit, and the frame keeps it.
    let (first, largest) = reweighted(pairs, delays, q, v, |e| huber(e, h));
    let robust = largest > h;
    if robust {
        v = first.unwrap_or(v);
        for _ in 1..HUBER_STEPS {
            match reweighted(pairs, delays, q, v, |e| huber(e, h)).0 {
                Some(next) => v = next,
                None => break,
            }
        }
        for _ in 0..TUKEY_STEPS {
            match reweighted(pairs, delays, q, v, |e| tukey(e, c)).0 {
                Some(next) => v = next,
                None => break,
            }
        }
    }
    let mut norm = libm::sqrtf(v[0] * v[0] + v[1] * v[1]);
    if norm > samples_per_metre {
        let s = samples_per_metre / norm;
        v = [v[0] * s, v[1] * s];
        norm = samples_per_metre;
    }
    let (mut sq, mut kept) = (0.0f32, 0.0f32);
    for ((p, d), &q) in pairs.iter().zip(delays).zip(q) {
        let e = misfit(p, d, v);
        sq += q * e * e;
        if robust {
            kept += q * tukey(e, c);
        }
    }
    let kept_weight = if robust { (kept / q_sum).clamp(0.0, 1.0) } else { 1.0 };
    Some(Direction {
        azimuth_rad: libm::atan2f(v[1], v[0]),
        zenith_rad: libm::asinf((norm / samples_per_metre).min(1.0)),
        residual_samples: libm::sqrtf(sq / q_sum),
        pairs_used: n_used,
        kept_weight,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Geometry;

    const K: f32 = 48_000.0 / 343.0;

    fn pairs_of(g: &Geometry) -> Vec<Pair> {
        let p = g.positions();
        let mut v = Vec::new();
        for i in 0..p.len() {
            for j in i + 1..p.len() {
                let b = [p[i][0] - p[j][0], p[i][1] - p[j][1]];
                v.push(Pair { i: i as u8, j: j as u8, baseline_m: b, max_lag: 16 });
            }
        }
        v
    }

    fn unit(az_deg: f64, zen_deg: f64) -> [f64; 2] {
        let (a, z) = (az_deg.to_radians(), zen_deg.to_radians());
        [z.sin() * a.cos(), z.sin() * a.sin()]
    }

    /// Plane-wave pair delays (f64 oracle) of direction (az, zen), plus a small deterministic
    /// spread of ±0.1 sample.
    fn delays(pairs: &[Pair], az_deg: f64, zen_deg: f64) -> Vec<DelayEstimate> {
        let u = unit(az_deg, zen_deg);
        pairs
            .iter()
            .enumerate()
            .map(|(n, p)| {
                let path = p.baseline_m[0] as f64 * u[0] + p.baseline_m[1] as f64 * u[1];
                let jitter = 0.1 * ((n as f64 * 2.399).sin());
                DelayEstimate {
                    delay_samples: (path * K as f64 + jitter) as f32,
                    coherence: 0.8,
                    peak_margin: 0.9,
                }
            })
            .collect()
    }

    /// The plain quality-weighted least squares, f64: the fit without outlier rejection.
    /// `skip`: pairs left out.
    fn plain_ls(pairs: &[Pair], d: &[DelayEstimate], skip: &[usize]) -> (f64, f64) {
        let (mut a, mut b, mut c, mut x, mut y) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (n, (p, d)) in pairs.iter().zip(d).enumerate() {
            if skip.contains(&n) {
                continue;
            }
            let w = d.quality() as f64;
            let (dx, dy) = (p.baseline_m[0] as f64, p.baseline_m[1] as f64);
            let path = d.delay_samples as f64 / K as f64;
            a += w * dx * dx;
            b += w * dx * dy;
            c += w * dy * dy;
            x += w * dx * path;
            y += w * dy * path;
        }
        let det = a * c - b * b;
        let (ux, uy) = ((c * x - b * y) / det, (a * y - b * x) / det);
        (uy.atan2(ux).to_degrees(), ux.hypot(uy).min(1.0).asin().to_degrees())
    }

    fn angle_error(a: f64, b: f64) -> f64 {
        (a - b + 540.0).rem_euclid(360.0) - 180.0
    }

    /// Moves pair `n`'s delay by 3 samples, as when its correlation peak locks onto a
    /// reflection (the fit residual of such frames in reverberant rooms: about 2.9 samples),
    /// towards the middle of its lag range, with a peak as good as the direct pairs'.
    fn lock_to_reflection(d: &mut [DelayEstimate], n: usize) {
        let x = &mut d[n].delay_samples;
        *x += if *x > 0.0 { -3.0 } else { 3.0 };
    }

    #[test]
    fn clean_frames_get_the_plain_least_squares_direction() {
        for g in [Geometry::respeaker_4mic(), Geometry::respeaker_6mic(), Geometry::circle_8mic()] {
            let pairs = pairs_of(&g);
            for (az, zen) in [(0.0, 30.0), (60.0, 45.0), (-135.0, 70.0), (100.0, 85.0)] {
                let d = delays(&pairs, az, zen);
                let f = fit(&pairs, &d, K).unwrap();
                let (paz, pzen) = plain_ls(&pairs, &d, &[]);
                assert!(angle_error(f.azimuth_rad.to_degrees() as f64, paz).abs() < 0.05);
                assert!((f.zenith_rad.to_degrees() as f64 - pzen).abs() < 0.05);
                assert!(angle_error(paz, az).abs() < 1.5 && (pzen - zen).abs() < 1.5);
                assert!(f.kept_weight > 0.9, "{f:?}");
                assert!(f.residual_samples < 0.12, "{f:?}");
            }
        }
    }

    #[test]
    fn reflection_locked_pairs_are_rejected_where_plain_least_squares_is_dragged() {
        // (array, pairs locked to the reflection): one of 6, two of 15, three of 28.
        let cases = [
            (Geometry::respeaker_4mic(), &[2usize][..]),
            (Geometry::respeaker_6mic(), &[0, 7][..]),
            (Geometry::circle_8mic(), &[1, 12, 20][..]),
        ];
        for (g, locked) in cases {
            let pairs = pairs_of(&g);
            for (az, zen) in [(20.0, 45.0), (60.0, 45.0), (100.0, 70.0), (-150.0, 80.0)] {
                let mut d = delays(&pairs, az, zen);
                for &n in locked {
                    lock_to_reflection(&mut d, n);
                }
                let (paz, pzen) = plain_ls(&pairs, &d, &[]);
                // The oracle: least squares over the pairs that kept the direct path.
                let (caz, czen) = plain_ls(&pairs, &d, locked);
                let f = fit(&pairs, &d, K).unwrap();
                let (raz, rzen) =
                    (f.azimuth_rad.to_degrees() as f64, f.zenith_rad.to_degrees() as f64);
                let plain = angle_error(paz, az).abs().max((pzen - zen).abs());
                let robust = angle_error(raz, caz).abs().max((rzen - czen).abs());
                assert!(plain > 1.5, "{} mics {az}/{zen}: plain error only {plain}", g.len());
                assert!(robust < 0.02, "{} mics {az}/{zen}: robust - clean {robust}", g.len());
                assert!(angle_error(caz, az).abs() < 0.5, "{} mics {az}/{zen}", g.len());
                // The frame says it is not one plane wave: weight was dropped, misfit is large.
                let share = locked.len() as f32 / pairs.len() as f32;
                assert!(f.kept_weight < 1.0 - 0.8 * share, "{f:?}");
                assert!(f.residual_samples > 0.3, "{f:?}");
            }
        }
    }

    #[test]
    fn unusable_pairs_give_no_direction() {
        let pairs = pairs_of(&Geometry::respeaker_4mic());
        let mut d = delays(&pairs, 10.0, 40.0);
        assert!(fit(&pairs, &d, K).is_some());
        for x in &mut d[1..] {
            x.coherence = 0.0;
        }
        assert_eq!(fit(&pairs, &d, K), None);
        d[3].coherence = f32::NAN;
        assert_eq!(fit(&pairs, &d, K), None);
    }
}
