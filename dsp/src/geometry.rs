//! Microphone array geometry: up to [`MAX_MICS`] planar positions in the array frame.
//!
//! Array frame: x right, y forward, z up (the array normal, towards the open side).

use crate::{ConfigError, MAX_MICS, MIN_MICS};

/// Radius of the ReSpeaker 6-mic circular array, metres.
pub const RESPEAKER_6MIC_RADIUS_M: f32 = 0.0463;
/// Side of the ReSpeaker 4-mic square array, metres.
pub const RESPEAKER_4MIC_SIDE_M: f32 = 0.065;
/// Radius of the generic 8-mic circular array preset, metres (a 10 cm diameter ring).
pub const CIRCLE_8MIC_RADIUS_M: f32 = 0.05;

/// Planar microphone positions, metres, in the array frame (x right, y forward).
///
/// ```
/// let g = aim_dsp::Geometry::respeaker_6mic();
/// assert_eq!(g.len(), 6);
/// assert!((g.positions()[0][0] - 0.0463).abs() < 1e-6);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geometry {
    positions: [[f32; 2]; MAX_MICS],
    len: usize,
}

impl Geometry {
    /// An empty geometry (no microphones); only useful as a placeholder in `const` contexts.
    pub const fn empty() -> Self {
        Self { positions: [[0.0; 2]; MAX_MICS], len: 0 }
    }

    /// ReSpeaker 6-mic circular array: radius 0.0463 m, mic 0 on +x, counter-clockwise.
    pub fn respeaker_6mic() -> Self {
        Self::circle(6, RESPEAKER_6MIC_RADIUS_M, 0.0)
    }

    /// ReSpeaker 4-mic square array: 0.065 m side, centred, mic 0 at (+x, +y), counter-clockwise.
    pub fn respeaker_4mic() -> Self {
        let r = RESPEAKER_4MIC_SIDE_M * core::f32::consts::FRAC_1_SQRT_2;
        Self::circle(4, r, core::f32::consts::FRAC_PI_4)
    }

    /// Generic 8-mic circle of radius [`CIRCLE_8MIC_RADIUS_M`], mic 0 on +x, counter-clockwise.
    pub fn circle_8mic() -> Self {
        Self::circle(8, CIRCLE_8MIC_RADIUS_M, 0.0)
    }

    fn circle(n: usize, radius_m: f32, first_angle_rad: f32) -> Self {
        let mut g = Self::empty();
        for i in 0..n {
            let a = first_angle_rad + 2.0 * core::f32::consts::PI * i as f32 / n as f32;
            g.positions[i] = [radius_m * libm::cosf(a), radius_m * libm::sinf(a)];
        }
        g.len = n;
        g
    }

    /// Any planar array of 4 to 8 microphones, positions in metres.
    ///
    /// Refuses non-finite coordinates, microphones closer than 1 mm, and collinear arrays.
    /// (The aperture limit depends on the sample rate and is checked by [`crate::Config`].)
    pub fn from_positions(p: &[[f32; 2]]) -> Result<Self, ConfigError> {
        if p.len() < MIN_MICS || p.len() > MAX_MICS {
            return Err(ConfigError::MicCount(p.len()));
        }
        if let Some(i) = p.iter().position(|q| !(q[0].is_finite() && q[1].is_finite())) {
            return Err(ConfigError::NonFinitePosition(i));
        }
        for i in 0..p.len() {
            for j in i + 1..p.len() {
                if distance(p[i], p[j]) < 1e-3 {
                    return Err(ConfigError::CoincidentMics(i, j));
                }
            }
        }
        // Scatter matrix about the centroid: a planar array needs two non-vanishing axes.
        let n = p.len() as f32;
        let cx = p.iter().map(|q| q[0]).sum::<f32>() / n;
        let cy = p.iter().map(|q| q[1]).sum::<f32>() / n;
        let (mut sxx, mut syy, mut sxy) = (0.0f32, 0.0f32, 0.0f32);
        for q in p {
            let (dx, dy) = (q[0] - cx, q[1] - cy);
            sxx += dx * dx;
            syy += dy * dy;
            sxy += dx * dy;
        }
        let trace = sxx + syy;
        let det = sxx * syy - sxy * sxy;
        // det / trace^2 is the product of the normalised eigenvalues; a 20:1 axis ratio gives ~0.05.
        if det <= 2.5e-3 * trace * trace {
            return Err(ConfigError::CollinearMics);
        }
        let mut g = Self::empty();
        g.positions[..p.len()].copy_from_slice(p);
        g.len = p.len();
        Ok(g)
    }

    /// Number of microphones.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True for the placeholder [`Geometry::empty`].
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Microphone positions, metres, `[x, y]` in the array frame; mic i is TDM slot i.
    pub fn positions(&self) -> &[[f32; 2]] {
        &self.positions[..self.len]
    }

    /// Largest distance between two microphones, metres.
    pub fn aperture_m(&self) -> f32 {
        let p = self.positions();
        let mut d = 0.0f32;
        for i in 0..p.len() {
            for j in i + 1..p.len() {
                d = d.max(distance(p[i], p[j]));
            }
        }
        d
    }
}

/// Euclidean distance of two planar points, metres.
pub(crate) fn distance(a: [f32; 2], b: [f32; 2]) -> f32 {
    libm::hypotf(a[0] - b[0], a[1] - b[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_have_documented_shape() {
        let g = Geometry::respeaker_6mic();
        let p = g.positions();
        // neighbours of a hexagon are one radius apart
        assert!((distance(p[0], p[1]) - RESPEAKER_6MIC_RADIUS_M).abs() < 1e-6);
        assert!((g.aperture_m() - 2.0 * RESPEAKER_6MIC_RADIUS_M).abs() < 1e-6);
        assert!(p[1][1] > 0.0, "counter-clockwise: mic 1 has +y");
        let g = Geometry::respeaker_4mic();
        let p = g.positions();
        assert!((distance(p[0], p[1]) - RESPEAKER_4MIC_SIDE_M).abs() < 1e-6);
        assert!((p[0][0] - RESPEAKER_4MIC_SIDE_M / 2.0).abs() < 1e-6);
        assert_eq!(Geometry::circle_8mic().len(), 8);
    }

    #[test]
    fn bad_positions_are_refused() {
        let sq = [[0.0, 0.0], [0.1, 0.0], [0.1, 0.1], [0.0, 0.1]];
        assert!(Geometry::from_positions(&sq).is_ok());
        assert_eq!(Geometry::from_positions(&sq[..3]), Err(ConfigError::MicCount(3)));
        let mut nan = sq;
        nan[2][1] = f32::NAN;
        assert_eq!(Geometry::from_positions(&nan), Err(ConfigError::NonFinitePosition(2)));
        let mut same = sq;
        same[3] = same[1];
        assert_eq!(Geometry::from_positions(&same), Err(ConfigError::CoincidentMics(1, 3)));
        let line = [[0.0, 0.0], [0.03, 0.0], [0.06, 0.0], [0.09, 0.0001]];
        assert_eq!(Geometry::from_positions(&line), Err(ConfigError::CollinearMics));
    }
}
