//! Drone dynamics from the sound of the rotors (paper eqs. 1, 3, 4 with ALGORITHMS.md §5's
//! corrections: 1/n² everywhere, tilt from T cos γ = m g, yaw angle as the second integral).
//!
//! Thrust is T = (k_v/n²)·Σ BPF_i². A hover segment calibrates k_v (T = m g), and with it the
//! hover value of Σ BPF_i²; accelerations then follow from the *ratio* ρ = Σ/Σ_hover alone:
//! vertical a = g(ρ − 1), horizontal a = g·sqrt(ρ² − 1) (minus drag). Those are visible only
//! while the drone changes speed, so the speed estimate integrates acceleration phases and holds
//! the velocity between them.

use crate::motion::MotionClass;
use crate::observation::BpfPeak;
use crate::profile::{Profile, G};

/// Σ BPF_i² over all rotors, Hz², from the distinct BPF groups heard: the rotors are shared
/// equally among the groups (one group: all N alike; two: N/2 each, the pitch/roll/yaw pairs).
pub fn sum_bpf_squared(groups: &[BpfPeak], rotors: usize) -> Option<f64> {
    if groups.is_empty() {
        return None;
    }
    let per_group = rotors as f64 / groups.len() as f64;
    Some(groups.iter().map(|g| per_group * g.hz * g.hz).sum())
}

/// Total thrust T = (k_v/n²)·Σ BPF², N.
pub fn thrust_n(k_v: f64, blades: u32, sum_bpf_sq: f64) -> f64 {
    k_v / (blades as f64).powi(2) * sum_bpf_sq
}

/// k_v from a hover: k_v = m g n² / Σ BPF², N/Hz².
pub fn k_v_from_hover(mass_kg: f64, blades: u32, sum_bpf_sq: f64) -> f64 {
    mass_kg * G * (blades as f64).powi(2) / sum_bpf_sq
}

/// Vertical acceleration (eq. 4 corrected): a = (T − m g − λ_v v|v|)/m, m/s² (up positive),
/// for vertical speed `v_v` (m/s, up positive).
pub fn vertical_acceleration(thrust_n: f64, mass_kg: f64, lambda_v: f64, v_v: f64) -> f64 {
    (thrust_n - mass_kg * G - lambda_v * v_v * v_v.abs()) / mass_kg
}

/// Horizontal acceleration along the tilt (eq. 3 corrected): T cos γ = m g gives the tilt,
/// a = (T sin γ − λ_h v²)/m = (sqrt(T² − (m g)²) − λ_h v²)/m, m/s². With T ≤ m g there is no
/// tilt and only drag acts.
pub fn horizontal_acceleration(thrust_n: f64, mass_kg: f64, lambda_h: f64, v_h: f64) -> f64 {
    let w = mass_kg * G;
    let lateral = if thrust_n > w { (thrust_n * thrust_n - w * w).sqrt() } else { 0.0 };
    (lateral - lambda_h * v_h * v_h.abs()) / mass_kg
}

/// Yaw angular acceleration (eq. 1): I_z β = (k_h/n²)(Σ BPF_odd² − Σ BPF_even²), rad/s².
pub fn yaw_acceleration(k_h: f64, blades: u32, i_z: f64, sum_odd_sq: f64, sum_even_sq: f64) -> f64 {
    k_h / (blades as f64).powi(2) * (sum_odd_sq - sum_even_sq) / i_z
}

/// Horizontal speed from the cruise thrust excess, m/s.
///
/// In cruise the rotors downstream of the others lose a fraction `wake_loss_per_mps`·dᵢ·v of
/// their thrust (dᵢ: how far downstream, per unit speed) and the controller makes it up by
/// spinning them faster, so Σ BPF² rises by ρ − 1 ≈ (w v / N)·Σ dᵢ while the thrust stays
/// m g. Inverting: v = (ρ − 1) / k with k = w Σ dᵢ / N
/// ([`Profile::wake_excess_per_mps`]). `excess` is ρ − 1; `None` without a coefficient.
pub fn speed_from_wake(excess: f64, k: f64) -> Option<f64> {
    (k > 0.0 && excess.is_finite()).then(|| (excess / k).max(0.0))
}

/// Self-calibration of the hover thrust: the running mean and spread of Σ BPF² over hover.
#[derive(Clone, Debug)]
pub struct HoverCalibration {
    mass_kg: f64,
    blades: u32,
    time_constant_s: f64,
    /// Σ BPF² at hover, Hz².
    sum_sq: f64,
    /// Relative standard deviation of Σ BPF² at hover (block to block).
    rel_sigma: f64,
    /// Seconds of hover seen.
    seen_s: f64,
}

impl HoverCalibration {
    /// Starts from the profile's k_v and a conservative spread.
    pub fn new(profile: &Profile) -> Self {
        let sum_sq = profile.mass_kg * G * (profile.blades as f64).powi(2) / profile.k_v;
        Self {
            mass_kg: profile.mass_kg,
            blades: profile.blades,
            time_constant_s: 3.0,
            sum_sq,
            rel_sigma: 0.004,
            seen_s: 0.0,
        }
    }

    /// Adds a hover block of length `dt` (s) with Σ BPF² = `sum_sq`.
    pub fn add_hover(&mut self, sum_sq: f64, dt: f64) {
        if !(sum_sq.is_finite() && sum_sq > 0.0 && dt > 0.0) {
            return;
        }
        let rel = sum_sq / self.sum_sq - 1.0;
        // Once calibrated, a sample far outside the hover spread is not a hover (the drone has
        // begun to accelerate before the classifier noticed): it must not move the calibration.
        if self.is_calibrated() && rel.abs() > 4.0 * self.rel_sigma {
            return;
        }
        self.seen_s += dt;
        // A fast start (the profile constant may be wrong), then an exponential average.
        let alpha = (dt / self.seen_s.min(self.time_constant_s)).min(1.0);
        self.sum_sq += alpha * (sum_sq - self.sum_sq);
        // The spread around the *updated* mean (the first sample sets the mean and no spread).
        let dev = sum_sq / self.sum_sq - 1.0;
        if self.seen_s > dt {
            let var = self.rel_sigma * self.rel_sigma;
            self.rel_sigma = (var + alpha * (dev * dev - var)).sqrt().max(2e-4);
        }
    }

    /// Calibrated k_v, N/Hz².
    pub fn k_v(&self) -> f64 {
        k_v_from_hover(self.mass_kg, self.blades, self.sum_sq)
    }

    /// Σ BPF² at hover, Hz².
    pub fn hover_sum_sq(&self) -> f64 {
        self.sum_sq
    }

    /// Relative spread of Σ BPF² at hover.
    pub fn rel_sigma(&self) -> f64 {
        self.rel_sigma
    }

    /// True once a second of hover has been used: the profile's k_v is no longer trusted.
    pub fn is_calibrated(&self) -> bool {
        self.seen_s >= 1.0
    }

    /// Thrust excess ρ − 1 = Σ/Σ_hover − 1 of a block, and whether it is significant
    /// (beyond `sigmas` hover spreads, and only once calibrated).
    pub fn excess(&self, sum_sq: f64, sigmas: f64) -> (f64, bool) {
        let e = sum_sq / self.sum_sq - 1.0;
        (e, self.is_calibrated() && e.abs() > sigmas * self.rel_sigma)
    }

    /// Seconds of hover used so far.
    pub fn hover_seconds(&self) -> f64 {
        self.seen_s
    }
}

/// Speeds from the dynamics: horizontal speed magnitude and vertical velocity, each with a
/// standard deviation, m/s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AcousticSpeed {
    /// Horizontal speed, m/s.
    pub horizontal: f64,
    /// Its standard deviation, m/s.
    pub horizontal_sigma: f64,
    /// Vertical velocity, m/s, up positive.
    pub vertical: f64,
    /// Its standard deviation, m/s.
    pub vertical_sigma: f64,
    /// Horizontal acceleration magnitude now, m/s² (0 outside acceleration phases).
    pub horizontal_accel: f64,
    /// True while a horizontal acceleration phase is under way.
    pub accelerating: bool,
}

/// Integrates acceleration phases and holds the velocity between them (ALGORITHMS.md §5).
#[derive(Clone, Debug)]
pub struct SpeedIntegrator {
    lambda_h: f64,
    lambda_v: f64,
    mass_kg: f64,
    /// Excess thrust must exceed this many hover spreads to count as acceleration.
    threshold_sigmas: f64,
    speed: AcousticSpeed,
    /// Sign of the current horizontal phase: +1 speeding up, −1 braking.
    phase_sign: f64,
    /// Horizontal speed when the phase began.
    phase_start_speed: f64,
    /// Speed at the end of the last phase that sped up (the cruise speed), m/s.
    cruise: f64,
    hover_s: f64,
}

impl SpeedIntegrator {
    /// A drone at rest.
    pub fn new(profile: &Profile) -> Self {
        Self {
            lambda_h: profile.lambda_h,
            lambda_v: profile.lambda_v,
            mass_kg: profile.mass_kg,
            threshold_sigmas: 3.0,
            speed: AcousticSpeed {
                horizontal: 0.0,
                horizontal_sigma: 0.1,
                vertical: 0.0,
                vertical_sigma: 0.1,
                horizontal_accel: 0.0,
                accelerating: false,
            },
            phase_sign: 1.0,
            phase_start_speed: 0.0,
            cruise: 0.0,
            hover_s: 0.0,
        }
    }

    /// The current estimate.
    pub fn speed(&self) -> AcousticSpeed {
        self.speed
    }

    /// Advances by `dt` seconds with the motion class and, if heard, Σ BPF² (Hz²).
    pub fn update(
        &mut self,
        dt: f64,
        class: MotionClass,
        sum_sq: Option<f64>,
        cal: &HoverCalibration,
    ) -> AcousticSpeed {
        let s = &mut self.speed;
        let rho = sum_sq.map(|x| x / cal.hover_sum_sq());
        let (excess, significant) =
            sum_sq.map_or((0.0, false), |x| cal.excess(x, self.threshold_sigmas));
        // Noise of one acceleration sample from the ratio's spread (a = g√(ρ²−1) is steep near 1).
        let sigma_a = G * (2.0 * cal.rel_sigma()).sqrt();
        s.horizontal_accel = 0.0;
        match class {
            MotionClass::Hover | MotionClass::Yaw => {
                // Stable DoA, no climb: the drone is still (a split with an excess would have
                // been classed horizontal).
                self.hover_s += dt;
                s.horizontal = 0.0;
                s.vertical = 0.0;
                s.horizontal_sigma = 0.05;
                s.vertical_sigma = 0.05;
                s.accelerating = false;
            }
            MotionClass::Vertical => {
                self.hover_s = 0.0;
                s.accelerating = false;
                let a = if significant {
                    G * excess - self.lambda_v * s.vertical * s.vertical.abs() / self.mass_kg
                } else {
                    -self.lambda_v * s.vertical * s.vertical.abs() / self.mass_kg
                };
                s.vertical += a * dt;
                s.vertical_sigma =
                    (s.vertical_sigma.powi(2) + (0.3 * a.abs() * dt).powi(2) + 0.01 * dt).sqrt();
                s.horizontal = 0.0;
                s.horizontal_sigma = 0.1;
            }
            _ => {
                // Horizontal (or a yaw-looking split with a thrust excess: a tilt starting).
                self.hover_s = 0.0;
                s.vertical = 0.0;
                s.vertical_sigma = 0.1;
                if significant && excess > 0.0 {
                    let r = rho.unwrap_or(1.0);
                    let drag = self.lambda_h * s.horizontal * s.horizontal / self.mass_kg;
                    let a = G * (r * r - 1.0).max(0.0).sqrt() - self.phase_sign * drag;
                    if !s.accelerating {
                        // A new phase: speeding up from (near) rest, braking from cruise.
                        s.accelerating = true;
                        self.phase_start_speed = s.horizontal;
                        self.phase_sign =
                            if s.horizontal < 0.5 * self.cruise.max(0.4) { 1.0 } else { -1.0 };
                    }
                    s.horizontal_accel = a;
                    s.horizontal = (s.horizontal + self.phase_sign * a * dt).max(0.0);
                    s.horizontal_sigma = (s.horizontal_sigma.powi(2)
                        + (sigma_a * dt).powi(2)
                        + (0.15 * a * dt).powi(2))
                    .sqrt();
                } else {
                    if s.accelerating
                        && self.phase_sign > 0.0
                        && s.horizontal > self.phase_start_speed
                    {
                        self.cruise = s.horizontal;
                    }
                    s.accelerating = false;
                    // Hold: in cruise the tilt that balances drag is too small to hear, so the
                    // speed is held rather than decayed by the drag law.
                    s.horizontal_sigma = (s.horizontal_sigma.powi(2) + 0.002 * dt).sqrt();
                }
            }
        }
        *s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hover_groups(bpf: f64) -> Vec<BpfPeak> {
        vec![BpfPeak { hz: bpf, amplitude: 1.0 }]
    }

    #[test]
    fn hover_calibration_recovers_k_v() {
        // The profile's k_v is 20 % off; the true drone hovers at BPF 2·f with
        // 4 k_v f² = m g.
        let mut p = Profile::dji_mini_2();
        let true_k_v = p.k_v;
        p.k_v *= 1.2;
        let f = (p.mass_kg * G / (4.0 * true_k_v)).sqrt();
        let mut cal = HoverCalibration::new(&p);
        let mut rng = crate::testutil::Rng::new(3);
        for _ in 0..200 {
            let bpf = 2.0 * f + 0.05 * rng.normal();
            cal.add_hover(sum_bpf_squared(&hover_groups(bpf), 4).unwrap(), 0.02);
        }
        assert!((cal.k_v() / true_k_v - 1.0).abs() < 1e-3, "{} vs {}", cal.k_v(), true_k_v);
        // Thrust at hover equals weight.
        let t = thrust_n(cal.k_v(), 2, cal.hover_sum_sq());
        assert!((t - p.mass_kg * G).abs() < 1e-9);
    }

    #[test]
    fn wake_speed_inverts_the_wake_model() {
        // A quad X at 1.5 m/s with 2 % loss per m/s: the two rear rotors (0.707 downstream
        // each) lose 2.12 % of thrust and spin up to make it back: Σ f² rises by their
        // 1/(1 − loss) − 1 ≈ 2.17 %, i.e. ρ − 1 = 2.17 % / 2. (The bundled profile has no
        // wake constant; the test drone is given one.)
        let p = Profile { wake_loss_per_mps: 0.02, ..Profile::dji_mini_2() };
        let loss = 0.02 * std::f64::consts::FRAC_1_SQRT_2 * 1.5;
        let excess = (2.0 / (1.0 - loss) + 2.0) / 4.0 - 1.0;
        let v = speed_from_wake(excess, p.wake_excess_per_mps()).unwrap();
        assert!((v - 1.5).abs() < 0.04, "{v}");
        assert!(speed_from_wake(0.01, 0.0).is_none());
    }

    #[test]
    fn vertical_acceleration_from_a_thrust_step() {
        let p = Profile::dji_mini_2();
        let hover_f = p.hover_bpf_hz() / 2.0;
        // Step every rotor up by 2 %: thrust × 1.0404, so a = 0.0404 g at zero speed.
        let f = hover_f * 1.02;
        let t = 4.0 * p.k_v * f * f;
        let sum = sum_bpf_squared(&hover_groups(2.0 * f), 4).unwrap();
        assert!((thrust_n(p.k_v, 2, sum) - t).abs() < 1e-12);
        let a = vertical_acceleration(t, p.mass_kg, p.lambda_v, 0.0);
        assert!((a - 0.0404 * G).abs() < 1e-9, "{a}");
        // With speed, drag opposes it: λ v² / m.
        let a1 = vertical_acceleration(t, p.mass_kg, p.lambda_v, 1.0);
        assert!((a - a1 - p.lambda_v / p.mass_kg).abs() < 1e-12);
        // Horizontal: a tilt of γ needs T = m g / cos γ and yields g tan γ.
        let gamma = 5.0f64.to_radians();
        let ah = horizontal_acceleration(p.mass_kg * G / gamma.cos(), p.mass_kg, p.lambda_h, 0.0);
        assert!((ah - G * gamma.tan()).abs() < 1e-9);
        // Yaw: equal pairs give no angular acceleration.
        assert_eq!(
            yaw_acceleration(2.72e-7, 2, 7.5e-4, 2.0 * 330.0f64.powi(2), 2.0 * 330.0f64.powi(2)),
            0.0
        );
    }

    #[test]
    fn speed_integrates_a_phase_and_holds_then_brakes() {
        let p = Profile::dji_mini_2();
        let mut cal = HoverCalibration::new(&p);
        let hover_sum = cal.hover_sum_sq();
        for _ in 0..100 {
            cal.add_hover(hover_sum, 0.02);
        }
        assert!(cal.is_calibrated() && cal.rel_sigma() < 1e-3);
        let mut s = SpeedIntegrator::new(&p);
        let dt = 0.02;
        // Accelerate at 1 m/s² for 1.5 s, cruise 3 s, brake at 1 m/s² for 1.5 s. The tilt
        // supplies m·a plus the drag λ v² (against the motion), so T sin γ = m a ± λ v² and the
        // thrust ratio is √(1 + (T sin γ / m g)²).
        let mut v_true: f64 = 0.0;
        let mut cruise = 0.0;
        for k in 0..450 {
            let t = k as f64 * dt;
            let a_true = if t < 1.5 {
                1.0
            } else if (4.5..6.0).contains(&t) {
                -1.0
            } else {
                0.0
            };
            let drag = p.lambda_h * v_true * v_true / p.mass_kg;
            let lateral = (a_true + drag).abs();
            let rho = if a_true == 0.0 { 1.0 } else { (1.0 + (lateral / G).powi(2)).sqrt() };
            v_true = (v_true + a_true * dt).max(0.0);
            let out = s.update(dt, MotionClass::Horizontal, Some(hover_sum * rho), &cal);
            if (3.0..3.02).contains(&t) {
                cruise = out.horizontal;
            }
        }
        assert!((cruise - 1.5).abs() < 0.05, "cruise {cruise}");
        assert!(s.speed().horizontal < 0.05, "after braking {}", s.speed().horizontal);
    }
}
