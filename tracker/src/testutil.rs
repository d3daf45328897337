//! Deterministic random numbers for tests (fixed seeds, no dependency).

/// xorshift64* generator.
pub struct Rng(u64);

impl Rng {
    /// A generator from a non-zero seed.
    pub fn new(seed: u64) -> Self {
        Self(seed.max(1).wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// A DoA frame of a drone at `pos` (site ENU, m) seen at `t` (s) by an array at the origin:
/// its true angles with 0.5° of Gaussian noise each, in line of sight, quality 0.5.
pub fn doa(t: f64, pos: [f64; 3], rng: &mut Rng) -> crate::doa::DoaState {
    let (az, zen) = crate::observation::angles_of(pos);
    let noise = 0.5f64.to_radians();
    crate::doa::DoaState {
        t,
        azimuth_rad: az + noise * rng.normal(),
        zenith_rad: zen + noise * rng.normal(),
        azimuth_rate: 0.0,
        zenith_rate: 0.0,
        angular_rate: 0.0,
        angular_rate_sigma: 0.0,
        erratic_rad: 0.0,
        fit_residual: 0.2,
        quality: 0.5,
        inlier_fraction: 1.0,
        inliers: 6,
        noise_rad: 0.01,
        time_spread_s: 0.5,
        los: true,
        moving: false,
    }
}

/// The exact DoA frame `array` hears from a drone at `drone` (world m) at `t` (s): its true
/// angles, fit residual 0.2, quality 3.0.
pub fn exact_bearing(
    array: &crate::site::ArrayPose,
    drone: [f64; 3],
    t: f64,
) -> crate::observation::Bearing {
    let rel = [0, 1, 2].map(|i| drone[i] - array.position[i]);
    let (azimuth_rad, zenith_rad) = crate::observation::angles_of(array.to_array(rel));
    crate::observation::Bearing {
        t,
        array_id: array.id,
        azimuth_rad,
        zenith_rad,
        residual: 0.2,
        quality: 3.0,
    }
}
