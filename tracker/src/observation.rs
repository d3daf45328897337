//! What the tracker consumes: bearings and BPF peaks of one array, in seconds and radians.
//!
//! These are plain types on purpose: the tracker core is tested on synthetic kinematics
//! without the wire format; `frames` turns decoded wire frames into them.

/// One direction-of-arrival estimate of one array, in the array frame
/// (x right, y forward, z up along the array normal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bearing {
    /// Time of the block the estimate describes, s (the array's clock, converted).
    pub t: f64,
    /// Array id (as in the site file).
    pub array_id: u16,
    /// Azimuth from +x towards +y, rad.
    pub azimuth_rad: f64,
    /// Zenith angle from the array normal (+z), rad.
    pub zenith_rad: f64,
    /// Weighted least-squares residual of the DoA fit, s (delay units, as the DSP reports it).
    pub residual: f64,
    /// Mean pair quality (peak-to-next-peak ratio of the correlations), ≥ 1 for a clean peak.
    pub quality: f64,
}

/// One blade-passing-frequency peak.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BpfPeak {
    /// Frequency, Hz.
    pub hz: f64,
    /// Amplitude (linear, arbitrary but consistent units).
    pub amplitude: f64,
}

/// The BPF peaks one array heard in one spectral block.
#[derive(Clone, Debug, PartialEq)]
pub struct Spectrum {
    /// Time of the block, s.
    pub t: f64,
    /// Array id.
    pub array_id: u16,
    /// Up to four fundamental peaks, strongest first or in any order.
    pub peaks: Vec<BpfPeak>,
}

/// One beacon arrival an array heard (a BEACON frame): what the clock model needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeaconHeard {
    /// Time of the arrival on the array's time base (the intake's, as every input's), s: the
    /// coarse time that tells which emission it was.
    pub t: f64,
    /// Array id.
    pub array_id: u16,
    /// The arrival in the board's own samples (header sample index + fraction).
    pub arrival_samples: f64,
    /// Detection quality, 0–1.
    pub quality: f64,
}

/// A piece of one array's sound stream (a SNIPPET frame): for inter-array delays.
#[derive(Clone, Debug, PartialEq)]
pub struct SnippetHeard {
    /// Time of the piece's middle on the array's time base (the intake's), s.
    pub t: f64,
    /// Array id.
    pub array_id: u16,
    /// The board's input-rate sample index of `values[0]`.
    pub sample_index: u64,
    /// Input samples per value.
    pub decimation: u32,
    /// The sound, fractions of microphone full scale.
    pub values: Vec<f64>,
}

/// One input of the tracker, in time order.
#[derive(Clone, Debug, PartialEq)]
pub enum Input {
    /// A direction of arrival.
    Bearing(Bearing),
    /// BPF peaks.
    Spectrum(Spectrum),
    /// A beacon arrival (several arrays: the clock model).
    Beacon(BeaconHeard),
    /// A piece of an array's sound (several arrays: inter-array delays).
    Snippet(SnippetHeard),
}

impl Input {
    /// Time of the input, s.
    pub fn t(&self) -> f64 {
        match self {
            Input::Bearing(b) => b.t,
            Input::Spectrum(s) => s.t,
            Input::Beacon(b) => b.t,
            Input::Snippet(x) => x.t,
        }
    }

    /// The array the input came from.
    pub fn array_id(&self) -> u16 {
        match self {
            Input::Bearing(b) => b.array_id,
            Input::Spectrum(s) => s.array_id,
            Input::Beacon(b) => b.array_id,
            Input::Snippet(x) => x.array_id,
        }
    }
}

/// Unit vector of a direction given by azimuth (from +x towards +y) and zenith (from +z), rad.
pub fn unit_vector(azimuth_rad: f64, zenith_rad: f64) -> [f64; 3] {
    let (sa, ca) = azimuth_rad.sin_cos();
    let (sz, cz) = zenith_rad.sin_cos();
    [sz * ca, sz * sa, cz]
}

/// Azimuth and zenith (rad) of a non-zero vector.
pub fn angles_of(v: [f64; 3]) -> (f64, f64) {
    let r = norm(v);
    let zen = (v[2] / r).clamp(-1.0, 1.0).acos();
    (v[1].atan2(v[0]), zen)
}

/// Euclidean norm.
pub fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Euclidean distance between two points (same units as they are given in).
pub fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm([a[0] - b[0], a[1] - b[1], a[2] - b[2]])
}

/// Wraps an angle to (−π, π].
pub fn wrap_pi(a: f64) -> f64 {
    let w = (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    if w <= -std::f64::consts::PI {
        w + std::f64::consts::TAU
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_round_trip() {
        for &(a, z) in &[(0.3, 1.2), (-2.9, 0.1), (3.0, 1.5), (1.0, 2.5)] {
            let (a2, z2) = angles_of(unit_vector(a, z));
            assert!((wrap_pi(a2 - a)).abs() < 1e-12 && (z2 - z).abs() < 1e-12);
        }
        assert!((wrap_pi(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
    }
}
