//! Propagation from a source to one microphone: every path (direct, image sources, a diffracted
//! path around a blocking box) as a time-varying fractional delay with spreading, reflection,
//! obstacle and air-absorption losses.
//!
//! For output sample n at true time t the path delay solves the retarded-time equation
//! `c τ = |S(t − τ) − M|` (three fixed-point iterations; the map contracts by |v|/c), so a
//! moving source is heard where it was when it emitted, and Doppler follows. Delay and gain are
//! solved at block boundaries and interpolated linearly inside a block (the delay's curvature
//! over a 128-sample block is below 10⁻³ sample at drone speeds). The source signal is read with
//! 4-tap (cubic) Lagrange interpolation. Air absorption is the zero-phase 3-tap smoother
//! `1 + b (z⁻¹ − 2 + z)`, whose attenuation `≈ 8.686 b ω²` dB follows the quadratic law of
//! `Air::absorption_quadratic_coefficient` for the path length; it costs no group delay.
use nalgebra::Vector3;

use crate::obstacle::{self, Obstacle};
use crate::room::{Image, Room};
use crate::sound::SourceSignal;

/// Where a source is at a given time.
pub trait Trajectory: Sync {
    /// Position at true time `t_s`, ENU m.
    fn position(&self, t_s: f64) -> Vector3<f64>;
    /// Whether the source never moves (its paths are then solved once).
    fn is_static(&self) -> bool {
        false
    }
}

/// A source that stays put.
#[derive(Clone, Copy, Debug)]
pub struct Fixed(pub Vector3<f64>);

impl Trajectory for Fixed {
    fn position(&self, _t_s: f64) -> Vector3<f64> {
        self.0
    }
    fn is_static(&self) -> bool {
        true
    }
}

/// One kind of path from a source to a microphone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PathKind {
    /// Straight, or reflected by the walls when the image is not the direct one.
    Image(Image),
    /// Around the first box blocking the direct path (absent when the direct path is clear).
    Diffracted,
}

/// The acoustic world a path runs through.
#[derive(Clone, Debug)]
pub struct Medium<'a> {
    /// Speed of sound, m/s.
    pub c_mps: f64,
    /// Quadratic air absorption coefficient, dB/(m·Hz²) (0 turns absorption off).
    pub absorption_per_m_hz2: f64,
    /// The room, if any (free field otherwise).
    pub room: Option<&'a Room>,
    /// Boxes that block paths.
    pub obstacles: &'a [Obstacle],
    /// Reference frequency of the diffraction loss, Hz.
    pub diffraction_ref_hz: f64,
}

/// Length and pressure gain (reflections, obstacles; spreading not included) of a path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathState {
    /// Path length, m.
    pub length_m: f64,
    /// Pressure gain apart from 1/r spreading.
    pub gain: f64,
}

impl Medium<'_> {
    /// The paths to simulate for a source: image sources of the room (or the direct path alone
    /// in free field) and, when there are obstacles, the diffracted path.
    pub fn path_kinds(&self) -> Vec<PathKind> {
        let mut v: Vec<PathKind> = match self.room {
            Some(r) => r.images().into_iter().map(PathKind::Image).collect(),
            None => vec![PathKind::Image(Image::DIRECT)],
        };
        if !self.obstacles.is_empty() {
            v.push(PathKind::Diffracted);
        }
        v
    }

    /// The path of `kind` from a source at `s` to a microphone at `m` (None: no such path now).
    pub fn path(&self, kind: &PathKind, s: &Vector3<f64>, m: &Vector3<f64>) -> Option<PathState> {
        match kind {
            PathKind::Image(image) => {
                let si = image.apply(s);
                let length_m = (si - m).norm();
                let loss_db = if self.obstacles.is_empty() {
                    0.0
                } else if image.order == 0 {
                    obstacle::blocking(self.obstacles, s, m).loss_db
                } else {
                    let room = self.room.expect("images come from a room");
                    room.folded_pieces(&si, m)
                        .iter()
                        .map(|(a, b)| obstacle::blocking(self.obstacles, a, b).loss_db)
                        .sum()
                };
                Some(PathState {
                    length_m,
                    gain: image.reflection_gain * 10f64.powf(-loss_db / 20.0),
                })
            }
            PathKind::Diffracted => {
                obstacle::diffraction(self.obstacles, s, m, self.diffraction_ref_hz, self.c_mps)
                    .map(|d| PathState { length_m: d.length_m, gain: d.gain })
            }
        }
    }

    /// Delay (s) and path state of `kind` for reception at `m` at true time `t_s`: the
    /// retarded-time solution `c τ = L(S(t − τ), M)`. Image paths iterate on the length alone
    /// (three steps; the map contracts by |v|/c ≈ 10⁻²) and evaluate obstacles once; the
    /// diffracted path starts from the straight-line delay and takes two detour evaluations.
    pub fn retarded(
        &self,
        kind: &PathKind,
        source: &dyn Trajectory,
        t_s: f64,
        m: &Vector3<f64>,
    ) -> Option<(f64, PathState)> {
        let s_now = source.position(t_s);
        if source.is_static() {
            let st = self.path(kind, &s_now, m)?;
            return Some((st.length_m / self.c_mps, st));
        }
        let st = match kind {
            PathKind::Image(image) => {
                let mut s = s_now;
                for _ in 0..3 {
                    let tau = (image.apply(&s) - m).norm() / self.c_mps;
                    s = source.position(t_s - tau);
                }
                self.path(kind, &s, m)?
            }
            PathKind::Diffracted => {
                let mut tau = (s_now - m).norm() / self.c_mps;
                let mut st = None;
                for _ in 0..2 {
                    let p = self.path(kind, &source.position(t_s - tau), m)?;
                    tau = p.length_m / self.c_mps;
                    st = Some(p);
                }
                st?
            }
        };
        Some((st.length_m / self.c_mps, st))
    }

    /// Air-absorption smoother coefficient `b` for a path of `length_m` at `sample_rate_hz`
    /// (clamped to 0.25, where the smoother's response reaches zero at Nyquist).
    pub fn absorption_b(&self, length_m: f64, sample_rate_hz: f64) -> f64 {
        let b = self.absorption_per_m_hz2 * length_m * sample_rate_hz * sample_rate_hz
            / (8.686 * 4.0 * std::f64::consts::PI * std::f64::consts::PI);
        b.clamp(0.0, 0.25)
    }
}

/// The receiving side: a microphone's position and its sample clock.
#[derive(Clone, Copy, Debug)]
pub struct Receiver {
    /// Microphone position, ENU m.
    pub position: Vector3<f64>,
    /// True time of output sample 0, s.
    pub t0_s: f64,
    /// Output sample interval in true time, s (1 / (fs · (1 + drift))).
    pub dt_s: f64,
    /// Extra delay of this microphone (phase mismatch), s.
    pub extra_delay_s: f64,
}

/// A source signal with its second difference, ready for rendering.
#[derive(Debug)]
pub struct PreparedSource<'a> {
    signal: &'a SourceSignal,
    second_difference: Vec<f32>,
}

impl<'a> PreparedSource<'a> {
    /// Precomputes the second difference used by the air-absorption smoother.
    pub fn new(signal: &'a SourceSignal) -> Self {
        let s = &signal.samples;
        let mut d2 = vec![0.0f32; s.len()];
        for k in 1..s.len().saturating_sub(1) {
            d2[k] = s[k - 1] - 2.0 * s[k] + s[k + 1];
        }
        Self { signal, second_difference: d2 }
    }

    /// The whole signal as a window.
    pub fn view(&self) -> SourceView<'_> {
        SourceView {
            t0_s: self.signal.t0_s,
            sample_rate_hz: self.signal.sample_rate_hz,
            start: 0,
            total: self.signal.samples.len(),
            samples: &self.signal.samples,
            second_difference: &self.second_difference,
        }
    }
}

/// A window of a source signal and its second difference (`s[k−1] − 2 s[k] + s[k+1]`, zero
/// at both ends of the signal): samples `start .. start + samples.len()` of a signal of
/// `total` samples whose sample k is at `t0_s + k / sample_rate_hz`. Outside `0 .. total`
/// the signal is zero; inside it but outside the window it is unknown.
#[derive(Clone, Copy, Debug)]
pub struct SourceView<'a> {
    /// Time of the signal's sample 0, s.
    pub t0_s: f64,
    /// Samples per second.
    pub sample_rate_hz: f64,
    /// Index of `samples[0]` in the signal.
    pub start: usize,
    /// Length of the whole signal, samples.
    pub total: usize,
    /// The window's samples, Pa at 1 m.
    pub samples: &'a [f32],
    /// Their second differences.
    pub second_difference: &'a [f32],
}

/// A render needed source samples the window did not hold (the window was cut too short).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OutsideWindow {
    /// First signal index needed, possibly negative.
    pub needed_from: isize,
    /// Last signal index needed.
    pub needed_to: isize,
}

/// Samples per block over which delay and gain are interpolated linearly.
pub const DEFAULT_BLOCK: usize = 128;

/// Adds the sound of `source` (moving along `trajectory`) over `paths` into `out` (pascals at
/// the microphone), one output sample per `receiver.dt_s`.
pub fn render(
    medium: &Medium,
    source: &PreparedSource,
    trajectory: &dyn Trajectory,
    paths: &[PathKind],
    receiver: &Receiver,
    block: usize,
    out: &mut [f32],
) {
    render_window(medium, &source.view(), trajectory, paths, receiver, block, out)
        .expect("the whole signal is in its window");
}

/// [`render`] from a window of the source signal: the same bits as from the whole signal as
/// long as every sample read lies in the window or outside the signal; otherwise the first
/// read the window could not serve is reported (what `out` holds then is not to be used).
pub fn render_window(
    medium: &Medium,
    source: &SourceView,
    trajectory: &dyn Trajectory,
    paths: &[PathKind],
    receiver: &Receiver,
    block: usize,
    out: &mut [f32],
) -> Result<(), OutsideWindow> {
    let fs_src = source.sample_rate_hz;
    let (src, d2, start, total) =
        (source.samples, source.second_difference, source.start, source.total);
    let end = start + src.len();
    let n_out = out.len();
    let blocks = n_out.div_ceil(block);
    // (source index, gain, absorption b) at a block boundary; None where the path is absent.
    let at = |n: usize, kind: &PathKind| -> Option<(f64, f64, f64)> {
        let t = receiver.t0_s + n as f64 * receiver.dt_s;
        let (tau, st) = medium.retarded(kind, trajectory, t, &receiver.position)?;
        let q = (t - tau - receiver.extra_delay_s - source.t0_s) * fs_src;
        let r = st.length_m.max(0.05);
        Some((q, st.gain / r, medium.absorption_b(st.length_m, fs_src)))
    };
    for kind in paths {
        let mut left = at(0, kind);
        for bi in 0..blocks {
            let n0 = bi * block;
            let n1 = ((bi + 1) * block).min(n_out);
            let right = at(n1, kind);
            let (l, r) = match (left, right) {
                (None, None) => {
                    left = right;
                    continue;
                }
                // A path appearing or vanishing fades in or out over the block.
                (Some(l), None) => (l, (l.0 + (n1 - n0) as f64 * receiver.dt_s * fs_src, 0.0, l.2)),
                (None, Some(r)) => ((r.0 - (n1 - n0) as f64 * receiver.dt_s * fs_src, 0.0, r.2), r),
                (Some(l), Some(r)) => (l, r),
            };
            let len = (n1 - n0) as f64;
            let dq = (r.0 - l.0) / len;
            let dg = (r.1 - l.1) / len;
            let db = (r.2 - l.2) / len;
            let seg = &mut out[n0..n1];
            let first = l.0.floor() as isize - 1;
            let last = r.0.ceil() as isize + 2;
            // What this segment reads (q is linear in j): the part inside the signal must lie
            // in the window.
            let q_end = l.0 + dq * (len - 1.0);
            let read_lo = l.0.min(q_end).floor() as isize - 1;
            let read_hi = l.0.max(q_end).floor() as isize + 2;
            let (lo, hi) = (read_lo.max(0), read_hi.min(total as isize - 1));
            if lo <= hi && (lo < start as isize || hi >= end as isize) {
                return Err(OutsideWindow { needed_from: read_lo, needed_to: read_hi });
            }
            if first >= 0 && (last as usize) < total && read_lo >= 0 && (read_hi as usize) < total {
                let from = read_lo as usize - start;
                let (src, d2) = (&src[from..], &d2[from..]);
                let base = read_lo as usize + 1;
                for (j, y) in seg.iter_mut().enumerate() {
                    let jf = j as f64;
                    let q = l.0 + dq * jf;
                    // q ≥ 1 here, so truncation is the floor (and much cheaper than `floor`,
                    // a library call on baseline x86-64).
                    let i = q as usize - base;
                    let f = (q - (q as usize) as f64) as f32;
                    let g = (l.1 + dg * jf) as f32;
                    let b = (l.2 + db * jf) as f32;
                    let c = lagrange4(f);
                    let (w, v) = (&src[i..i + 4], &d2[i..i + 4]);
                    let s = c[0] * w[0] + c[1] * w[1] + c[2] * w[2] + c[3] * w[3];
                    let a = c[0] * v[0] + c[1] * v[1] + c[2] * v[2] + c[3] * v[3];
                    *y += g * (s + b * a);
                }
            } else {
                // Near the ends of the source signal: read zeros outside it.
                let get = |v: &[f32], k: isize| {
                    if k >= 0 && (k as usize) < total {
                        v[k as usize - start]
                    } else {
                        0.0
                    }
                };
                for (j, y) in seg.iter_mut().enumerate() {
                    let jf = j as f64;
                    let q = l.0 + dq * jf;
                    let i = q.floor();
                    let f = (q - i) as f32;
                    let i = i as isize;
                    let g = (l.1 + dg * jf) as f32;
                    let b = (l.2 + db * jf) as f32;
                    let c = lagrange4(f);
                    let mut acc = 0.0;
                    for (k, ck) in c.iter().enumerate() {
                        let idx = i - 1 + k as isize;
                        acc += ck * (get(src, idx) + b * get(d2, idx));
                    }
                    *y += g * acc;
                }
            }
            left = right;
        }
    }
    Ok(())
}

/// Cubic Lagrange weights for taps at −1, 0, 1, 2 and fractional position `f` ∈ [0, 1).
#[inline(always)]
pub fn lagrange4(f: f32) -> [f32; 4] {
    let fm1 = f - 1.0;
    let fm2 = f - 2.0;
    let fp1 = f + 1.0;
    [
        -f * fm1 * fm2 * (1.0 / 6.0),
        fp1 * fm1 * fm2 * 0.5,
        -fp1 * f * fm2 * 0.5,
        fp1 * f * fm1 * (1.0 / 6.0),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lagrange_weights_interpolate_cubics_exactly() {
        for f in [0.0f32, 0.25, 0.5, 0.9] {
            let c = lagrange4(f);
            for p in 0..4 {
                let val = |x: f32| x.powi(p);
                let got: f32 = (0..4).map(|k| c[k] * val(k as f32 - 1.0)).sum();
                assert!((got - val(f)).abs() < 1e-5, "f {f} p {p}");
            }
        }
    }
}
