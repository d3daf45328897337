//! The golden configurations: which arrays, rates and source directions the checks run.
use aim_dsp::{Config, Geometry};

use crate::signal::{plane_wave_delays, Signal, MAX_MICS};

/// One checked configuration: an array at a sample rate, hearing the golden tone from a fixed
/// direction.
#[derive(Debug, Clone, Copy)]
pub struct Scenario {
    /// Short name, used in reports and budget names (`4mic`, `6mic`, `8mic`, …).
    pub name: &'static str,
    /// Array preset.
    pub geometry: fn() -> Geometry,
    /// Sample rate, Hz.
    pub sample_rate_hz: u32,
    /// Unit vector towards the source, array-plane components (x, y), Q15.
    pub direction_q15: [i32; 2],
    /// Noise seed.
    pub seed: u32,
}

/// Source at azimuth 40°, zenith 60°: (sin 60° cos 40°, sin 60° sin 40°) in Q15.
const DIRECTION_Q15: [i32; 2] = [21_739, 18_241];

/// The three array sizes of the cost budgets, at 48 kHz.
pub const COST: [Scenario; 3] = [
    Scenario {
        name: "4mic",
        geometry: Geometry::respeaker_4mic,
        sample_rate_hz: 48_000,
        direction_q15: DIRECTION_Q15,
        seed: 4,
    },
    Scenario {
        name: "6mic",
        geometry: Geometry::respeaker_6mic,
        sample_rate_hz: 48_000,
        direction_q15: DIRECTION_Q15,
        seed: 6,
    },
    Scenario {
        name: "8mic",
        geometry: Geometry::circle_8mic,
        sample_rate_hz: 48_000,
        direction_q15: DIRECTION_Q15,
        seed: 8,
    },
];

/// The parity checks: the cost configurations plus the 16 kHz path.
pub const PARITY: [Scenario; 4] = [
    COST[0],
    COST[1],
    COST[2],
    Scenario {
        name: "6mic-16k",
        geometry: Geometry::respeaker_6mic,
        sample_rate_hz: 16_000,
        direction_q15: [-26_000, 9_000],
        seed: 16,
    },
];

impl Scenario {
    /// The pipeline configuration: the preset with the default tunables.
    pub fn config(&self) -> Config {
        Config::new((self.geometry)(), self.sample_rate_hz)
    }

    /// The golden input of this scenario: the tone with each microphone's plane-wave delay.
    pub fn signal(&self) -> Signal {
        let config = self.config();
        let positions = config.geometry.positions();
        let mut mm = [[0i32; 2]; MAX_MICS];
        for (m, p) in mm.iter_mut().zip(positions) {
            *m = [libm::roundf(p[0] * 1000.0) as i32, libm::roundf(p[1] * 1000.0) as i32];
        }
        let mics = positions.len();
        let mut delays = [0u32; MAX_MICS];
        plane_wave_delays(&mm[..mics], self.direction_q15, self.sample_rate_hz, &mut delays);
        Signal::new(&delays[..mics], config.tdm_slots, self.sample_rate_hz, self.seed)
    }

    /// Input samples per microphone of one measurement: a whole number of DoA periods
    /// (4 blocks) and BPF hops (2048 samples at 8 kHz), about 4 s.
    pub fn measured_samples(&self) -> usize {
        let hop = self.sample_rate_hz as usize / 8_000 * 2048; // BPF hop at the input rate
        16 * hop
    }
}
