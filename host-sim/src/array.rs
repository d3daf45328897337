//! Microphone arrays: geometry presets, placement, imperfections and sample clock.
//!
//! Array frame: x right, y forward, z up (the array normal); microphones lie in the plane
//! z = 0. The array is placed at `position_m` (ENU) with its x axis at `yaw_rad` from ENU +x
//! towards +y, facing up, or, mounted under a ceiling or a shelf (`facing_down`), turned over
//! about its x axis first (roll 180°: array y and z point against the unturned ones). Azimuth is measured from the array's +x towards +y, the zenith from
//! +z; the direction vector u points from the array towards the source.
use nalgebra::Vector3;

/// Microphone positions of a named preset, array frame, metres. The presets match `aim-dsp`'s
/// `Geometry` constructors: `respeaker-6mic` (circle r = 0.0463 m, mic 0 on +x,
/// counter-clockwise), `respeaker-4mic` (square of side 0.065 m, centred, mic 0 at +x+y,
/// counter-clockwise), `circle-8mic` (circle r = 0.05 m, mic 0 on +x, counter-clockwise).
pub fn preset_positions(name: &str) -> Option<Vec<[f64; 2]>> {
    let circle = |n: usize, r: f64, start_deg: f64| {
        (0..n)
            .map(|i| {
                let a = (start_deg + 360.0 * i as f64 / n as f64).to_radians();
                [r * a.cos(), r * a.sin()]
            })
            .collect()
    };
    match name {
        "respeaker-6mic" => Some(circle(6, 0.0463, 0.0)),
        "respeaker-4mic" => Some(circle(4, 0.065 / std::f64::consts::SQRT_2, 45.0)),
        "circle-8mic" => Some(circle(8, 0.05, 0.0)),
        _ => None,
    }
}

/// Names of the geometry presets.
pub const GEOMETRY_PRESETS: &[&str] = &["respeaker-6mic", "respeaker-4mic", "circle-8mic"];

/// Sample clock of an array relative to true time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clock {
    /// True time at which the array takes its sample 0, s.
    pub offset_s: f64,
    /// Clock rate error, parts per million (positive: the array samples fast).
    pub drift_ppm: f64,
}

impl Clock {
    /// True time of the array's sample `n` at nominal rate `sample_rate_hz`, s.
    pub fn time_of_sample(&self, n: u64, sample_rate_hz: f64) -> f64 {
        self.offset_s + n as f64 / (sample_rate_hz * (1.0 + self.drift_ppm * 1e-6))
    }
}

/// One array as the scenario places it.
#[derive(Clone, Debug, PartialEq)]
pub struct ArrayConfig {
    /// Array id (as in the frame header).
    pub id: u8,
    /// Geometry preset name, or `custom`.
    pub geometry: String,
    /// Microphone positions, array frame, m.
    pub positions: Vec<[f64; 2]>,
    /// Array centre, ENU m.
    pub position_m: Vector3<f64>,
    /// Rotation of the array's x axis from ENU +x towards +y, rad.
    pub yaw_rad: f64,
    /// The array faces down (turned over about its x axis, roll 180°) instead of up.
    pub facing_down: bool,
    /// Sample clock.
    pub clock: Clock,
    /// Self-noise of each microphone as an equivalent sound pressure level, dB re 20 µPa
    /// (white, full band).
    pub self_noise_db: f64,
    /// Standard deviation of the microphones' gain error, dB.
    pub gain_mismatch_db: f64,
    /// Standard deviation of the microphones' delay (phase) error, µs.
    pub phase_mismatch_us: f64,
    /// Microphones (indices) that give no signal at all: every sample 0.
    pub dead_mics: Vec<usize>,
    /// Microphones (indices) stuck at a constant output of [`STUCK_PA`].
    pub stuck_mics: Vec<usize>,
    /// The board's link is down (a cable pulled) over `[from, to)`, s of the array's own
    /// clock: what it sends meanwhile is lost, the board runs on.
    pub link_down_s: Option<[f64; 2]>,
}

/// The constant a stuck microphone outputs, Pa (a quarter of the default digital full scale).
pub const STUCK_PA: f32 = 5.0;

impl ArrayConfig {
    /// World position of microphone `i`, ENU m.
    pub fn mic_position(&self, i: usize) -> Vector3<f64> {
        let [x, y] = self.positions[i];
        // Roll 180° about the array x axis, then yaw: R = Rz(yaw)·Rx(π) on (x, y, 0).
        let y = if self.facing_down { -y } else { y };
        let (s, c) = self.yaw_rad.sin_cos();
        self.position_m + Vector3::new(c * x - s * y, s * x + c * y, 0.0)
    }

    /// Checks the array; names the problem.
    pub fn validate(&self) -> Result<(), String> {
        let n = self.positions.len();
        if !(4..=8).contains(&n) {
            return Err(format!("array {}: {n} microphones, the pipeline takes 4 to 8", self.id));
        }
        if self.positions.iter().flatten().any(|v| !v.is_finite())
            || !(self.position_m.iter().all(|v| v.is_finite()) && self.yaw_rad.is_finite())
        {
            return Err(format!("array {}: positions and yaw must be finite numbers", self.id));
        }
        let (drift, offset) = (self.clock.drift_ppm, self.clock.offset_s);
        if !(drift.is_finite() && drift.abs() < 1000.0) {
            return Err(format!(
                "array {}: clock_drift_ppm {drift:?} must be under 1000 ppm",
                self.id
            ));
        }
        if !(offset.is_finite() && offset.abs() < 10.0) {
            return Err(format!("array {}: clock_offset_s {offset:?} must be under 10 s", self.id));
        }
        let (gain, phase) = (self.gain_mismatch_db, self.phase_mismatch_us);
        if !(gain >= 0.0 && gain.is_finite() && phase >= 0.0 && phase.is_finite()) {
            return Err(format!(
                "array {}: gain_mismatch_db {gain:?} and phase_mismatch_us {phase:?} must be finite \
                 and not negative",
                self.id
            ));
        }
        if !self.self_noise_db.is_finite() {
            return Err(format!(
                "array {}: self_noise_db {:?} must be a finite level, dB SPL",
                self.id, self.self_noise_db
            ));
        }
        if let Some([a, b]) = self.link_down_s {
            if !(a.is_finite() && b.is_finite() && 0.0 <= a && a < b) {
                return Err(format!(
                    "array {}: link_down_s must be [from, to] with 0 <= from < to, s (got [{a}, {b}])",
                    self.id
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn respeaker_6mic_neighbours_are_4_6_cm_apart() {
        let p = preset_positions("respeaker-6mic").unwrap();
        let d = ((p[0][0] - p[1][0]).powi(2) + (p[0][1] - p[1][1]).powi(2)).sqrt();
        assert!((d - 0.0463).abs() < 1e-12);
        let q = preset_positions("respeaker-4mic").unwrap();
        let side = ((q[0][0] - q[1][0]).powi(2) + (q[0][1] - q[1][1]).powi(2)).sqrt();
        assert!((side - 0.065).abs() < 1e-12);
    }

    /// The simulator must place the microphones where the on-chip DSP assumes they are.
    #[test]
    fn presets_match_the_dsp_presets() {
        let dsp = [
            ("respeaker-6mic", aim_dsp::Geometry::respeaker_6mic()),
            ("respeaker-4mic", aim_dsp::Geometry::respeaker_4mic()),
            ("circle-8mic", aim_dsp::Geometry::circle_8mic()),
        ];
        for (name, geometry) in dsp {
            let sim = preset_positions(name).unwrap();
            assert_eq!(sim.len(), geometry.len(), "{name}");
            for (s, d) in sim.iter().zip(geometry.positions()) {
                for k in 0..2 {
                    assert!((s[k] - f64::from(d[k])).abs() < 1e-7, "{name}: {s:?} vs {d:?}");
                }
            }
        }
    }

    #[test]
    fn yaw_rotates_the_array_counter_clockwise() {
        let a = ArrayConfig {
            id: 1,
            geometry: "respeaker-6mic".into(),
            positions: preset_positions("respeaker-6mic").unwrap(),
            position_m: Vector3::new(1.0, 2.0, 0.5),
            yaw_rad: std::f64::consts::FRAC_PI_2,
            facing_down: false,
            clock: Clock { offset_s: 0.0, drift_ppm: 0.0 },
            self_noise_db: 30.0,
            gain_mismatch_db: 0.0,
            phase_mismatch_us: 0.0,
            dead_mics: Vec::new(),
            stuck_mics: Vec::new(),
            link_down_s: None,
        };
        // Mic 0 on the array's +x, which points along ENU +y.
        assert!((a.mic_position(0) - Vector3::new(1.0, 2.0463, 0.5)).norm() < 1e-12);
        // Mic 1 (60° counter-clockwise seen from the array's front) is on the ENU −x side
        // facing up and on the +x side facing down: seen from below, the circle runs the
        // other way.
        assert!(a.mic_position(1).x < 1.0);
        let down = ArrayConfig { facing_down: true, ..a };
        assert!((down.mic_position(0) - Vector3::new(1.0, 2.0463, 0.5)).norm() < 1e-12);
        assert!(down.mic_position(1).x > 1.0);
    }
}
