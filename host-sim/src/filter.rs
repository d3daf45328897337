//! Small IIR filters for shaping noise (RBJ audio-EQ-cookbook biquads), and a Gaussian source.
use rand::{rngs::StdRng, Rng};

/// A biquad section, direct form I, f64 state.
#[derive(Clone, Debug)]
pub struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
    x: [f64; 2],
    y: [f64; 2],
}

impl Biquad {
    fn from_rbj(b0: f64, b1: f64, b2: f64, a0: f64, a1: f64, a2: f64) -> Self {
        Self { b: [b0 / a0, b1 / a0, b2 / a0], a: [a1 / a0, a2 / a0], x: [0.0; 2], y: [0.0; 2] }
    }

    fn omega(hz: f64, sample_rate_hz: f64) -> (f64, f64) {
        let w = std::f64::consts::TAU * hz / sample_rate_hz;
        (w.cos(), w.sin())
    }

    /// Second-order low-pass at `hz` with quality `q`.
    pub fn lowpass(hz: f64, q: f64, sample_rate_hz: f64) -> Self {
        let (c, s) = Self::omega(hz, sample_rate_hz);
        let alpha = s / (2.0 * q);
        Self::from_rbj(
            (1.0 - c) / 2.0,
            1.0 - c,
            (1.0 - c) / 2.0,
            1.0 + alpha,
            -2.0 * c,
            1.0 - alpha,
        )
    }

    /// Second-order high-pass at `hz` with quality `q`.
    pub fn highpass(hz: f64, q: f64, sample_rate_hz: f64) -> Self {
        let (c, s) = Self::omega(hz, sample_rate_hz);
        let alpha = s / (2.0 * q);
        Self::from_rbj(
            (1.0 + c) / 2.0,
            -(1.0 + c),
            (1.0 + c) / 2.0,
            1.0 + alpha,
            -2.0 * c,
            1.0 - alpha,
        )
    }

    /// Band-pass (0 dB peak) centred on `hz` with quality `q` = centre / bandwidth.
    pub fn bandpass(hz: f64, q: f64, sample_rate_hz: f64) -> Self {
        let (c, s) = Self::omega(hz, sample_rate_hz);
        let alpha = s / (2.0 * q);
        Self::from_rbj(alpha, 0.0, -alpha, 1.0 + alpha, -2.0 * c, 1.0 - alpha)
    }

    /// Filters one sample.
    #[inline]
    pub fn process(&mut self, x: f64) -> f64 {
        let y = self.b[0] * x + self.b[1] * self.x[0] + self.b[2] * self.x[1]
            - self.a[0] * self.y[0]
            - self.a[1] * self.y[1];
        self.x = [x, self.x[0]];
        self.y = [y, self.y[0]];
        y
    }
}

/// A cascade of biquads.
#[derive(Clone, Debug, Default)]
pub struct Cascade(pub Vec<Biquad>);

impl Cascade {
    /// Filters one sample.
    #[inline]
    pub fn process(&mut self, x: f64) -> f64 {
        self.0.iter_mut().fold(x, |x, s| s.process(x))
    }

    /// Power gain for white input, `Σ h[k]²`, from the impulse response (fresh state).
    pub fn white_noise_power_gain(&self) -> f64 {
        let mut probe = Cascade(
            self.0.iter().map(|b| Biquad { x: [0.0; 2], y: [0.0; 2], ..b.clone() }).collect(),
        );
        let mut sum = 0.0;
        let mut tail = 0.0;
        for k in 0..1usize << 20 {
            let h = probe.process(if k == 0 { 1.0 } else { 0.0 });
            sum += h * h;
            tail += h * h;
            // Stop once a whole 4096-sample stretch adds less than 1e-12 of the total.
            if k % 4096 == 4095 {
                if tail < 1e-12 * sum {
                    break;
                }
                tail = 0.0;
            }
        }
        sum
    }
}

/// Standard normal deviates by the Box–Muller transform, two per draw.
#[derive(Debug)]
pub struct Gaussian {
    rng: StdRng,
    spare: Option<f64>,
}

impl Gaussian {
    /// A generator driven by `rng`.
    pub fn new(rng: StdRng) -> Self {
        Self { rng, spare: None }
    }

    /// Next standard normal value.
    #[inline]
    pub fn sample(&mut self) -> f64 {
        if let Some(v) = self.spare.take() {
            return v;
        }
        let u1: f64 = self.rng.random::<f64>().max(1e-300);
        let u2: f64 = self.rng.random();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
        self.spare = Some(r * s);
        r * c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn bandpass_passes_the_centre_at_unit_gain() {
        let fs = 48_000.0;
        let mut f = Biquad::bandpass(600.0, 6.0, fs);
        let mut peak: f64 = 0.0;
        for k in 0..48_000 {
            let y = f.process((std::f64::consts::TAU * 600.0 * k as f64 / fs).sin());
            if k > 24_000 {
                peak = peak.max(y.abs());
            }
        }
        assert!((peak - 1.0).abs() < 1e-3, "{peak}");
    }

    #[test]
    fn gaussian_has_unit_variance() {
        let mut g = Gaussian::new(StdRng::seed_from_u64(7));
        let n = 200_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let x = g.sample();
            s += x;
            s2 += x * x;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.01 && (var - 1.0).abs() < 0.01, "{mean} {var}");
    }
}
