//! The paper's baseline (§V-A, §V-C): per-step coordinates S = h·w from the corrected
//! eq. (5)/(6), fused by a Kalman filter whose state is the position only.
//!
//! Height h (along the array normal) comes from the horizontal speed and the change of
//! w = (tan φ cos α, tan φ sin α, 1) between steps: h = v τ / |w_{t+1} − w_t|_xy; during
//! vertical motion h changes by v_v τ. In NLoS the DoA is dropped and the coordinate is dead
//! reckoned with the acoustic speed along the last heading.

use std::collections::VecDeque;

use super::{Estimate, Filter, Step};
use crate::linalg::Mat;
use crate::motion::MotionClass;

/// Tunables of the baseline.
#[derive(Clone, Debug, PartialEq)]
pub struct PaperConfig {
    /// Height assumed until the first horizontal motion measures it, m.
    pub initial_height_m: f64,
    /// Per-step height solutions kept for a median, steps.
    pub height_median_steps: usize,
    /// Random-walk density of the position, m²/s.
    pub q: f64,
    /// Standard deviation of a per-step coordinate in LoS / NLoS, m.
    pub sigma_los_m: f64,
    /// ... in NLoS.
    pub sigma_nlos_m: f64,
}

impl Default for PaperConfig {
    fn default() -> Self {
        Self {
            initial_height_m: 1.0,
            height_median_steps: 5,
            q: 1.0,
            sigma_los_m: 0.5,
            sigma_nlos_m: 1.0,
        }
    }
}

/// Position-only Kalman filter on per-step coordinates.
#[derive(Clone, Debug, Default)]
pub struct PaperFilter {
    config: PaperConfig,
    state: Option<([f64; 3], Mat)>,
    height: Option<f64>,
    recent_heights: VecDeque<f64>,
    previous_w: Option<[f64; 3]>,
    heading: [f64; 2],
    previous_estimate: Option<[f64; 3]>,
}

impl PaperFilter {
    /// A filter with explicit tunables.
    pub fn new(config: PaperConfig) -> Self {
        Self { config, ..Self::default() }
    }
}

fn median(v: &VecDeque<f64>) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().collect();
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}

impl Filter for PaperFilter {
    fn step(&mut self, step: &Step) -> Option<Estimate> {
        let c = self.config.clone();
        let normal_up = step.array.to_world([0.0, 0.0, 1.0])[2];
        let w = step.doa.map(|d| {
            let tz = d.zenith_rad.clamp(0.0, 88f64.to_radians()).tan();
            [tz * d.azimuth_rad.cos(), tz * d.azimuth_rad.sin(), 1.0]
        });
        let s = step.speed;
        // Height from eq. (5) corrected, or (6).
        if step.los {
            if let (Some(w1), Some(w0)) = (w, self.previous_w) {
                if step.motion == MotionClass::Horizontal && s.horizontal > 0.1 {
                    let dw = (w1[0] - w0[0]).hypot(w1[1] - w0[1]);
                    if dw > 1e-5 {
                        let h = (s.horizontal * step.dt
                            + 0.5 * s.horizontal_accel * step.dt * step.dt)
                            / dw;
                        self.recent_heights.push_back(h.clamp(0.2, 30.0));
                        while self.recent_heights.len() > c.height_median_steps {
                            self.recent_heights.pop_front();
                        }
                        self.height = Some(median(&self.recent_heights));
                    }
                }
            }
        }
        if step.motion == MotionClass::Vertical {
            let h = self.height.unwrap_or(c.initial_height_m);
            self.height = Some((h + normal_up.signum() * s.vertical * step.dt).max(0.2));
        }
        let h = self.height.unwrap_or(c.initial_height_m);
        // The first fix comes from the first DoA, LoS or not (the paper initialises A_0 from
        // the first points of the flight); afterwards NLoS DoA is dropped.
        let first = self.previous_estimate.is_none();
        let measured = match (step.los || first, w) {
            (true, Some(w)) => {
                let rel = step.array.to_world([h * w[0], h * w[1], h * w[2]]);
                let p = step.array.position;
                let sigma = if step.los { c.sigma_los_m } else { c.sigma_nlos_m };
                Some(([p[0] + rel[0], p[1] + rel[1], p[2] + rel[2]], sigma))
            }
            _ => self.previous_estimate.map(|prev| {
                let mut x = prev;
                if step.motion == MotionClass::Horizontal {
                    x[0] += self.heading[0] * s.horizontal * step.dt;
                    x[1] += self.heading[1] * s.horizontal * step.dt;
                }
                if step.motion == MotionClass::Vertical {
                    x[2] += s.vertical * step.dt;
                }
                (x, c.sigma_nlos_m)
            }),
        };
        if step.los {
            self.previous_w = w;
        }
        let (z, sigma) = measured?;
        let (x, p) = match self.state.take() {
            None => (z, Mat::identity(3).scaled(sigma * sigma)),
            Some((x, p)) => {
                let p = &p + &Mat::identity(3).scaled(c.q * step.dt);
                let r = Mat::identity(3).scaled(sigma * sigma);
                let k = &p * &(&p + &r).inverse()?;
                let y = Mat::column(&[z[0] - x[0], z[1] - x[1], z[2] - x[2]]);
                let dx = &k * &y;
                let i_k = &Mat::identity(3) - &k;
                let p = (&(&(&i_k * &p) * &i_k.t()) + &(&(&k * &r) * &k.t())).symmetrized();
                ([x[0] + dx[(0, 0)], x[1] + dx[(1, 0)], x[2] + dx[(2, 0)]], p)
            }
        };
        if let Some(prev) = self.previous_estimate {
            let (dx, dy) = (x[0] - prev[0], x[1] - prev[1]);
            let d = dx.hypot(dy);
            if step.los && step.motion == MotionClass::Horizontal && d > 1e-3 {
                self.heading = [dx / d, dy / d];
            }
        }
        let velocity = match self.previous_estimate {
            Some(prev) if step.dt > 0.0 => {
                [(x[0] - prev[0]) / step.dt, (x[1] - prev[1]) / step.dt, (x[2] - prev[2]) / step.dt]
            }
            _ => [0.0; 3],
        };
        self.previous_estimate = Some(x);
        self.state = Some((x, p.clone()));
        Some(Estimate { position: x, velocity, position_covariance: p })
    }
}
