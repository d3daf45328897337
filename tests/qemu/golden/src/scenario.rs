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

#[cfg(test)]
mod tests {
    use super::*;
    use aim_dsp::{doa, Output, Pipeline};

    /// The instruction budget counts the robust direction fit only if the cost run takes it:
    /// the golden input's whole-sample microphone delays misfit the plane wave by more than
    /// the Huber threshold, so (nearly) every `Doa` of every cost scenario runs the reweighted
    /// steps.
    #[test]
    fn every_cost_doa_runs_the_robust_fit() {
        for scenario in &COST {
            let config = scenario.config();
            let mut pipeline = Pipeline::new(&config).unwrap();
            let k = config.sample_rate_hz as f32 / config.speed_of_sound_m_s;
            let mut signal = scenario.signal();
            let mut words = vec![0i32; 256 * config.tdm_slots];
            let (mut doas, mut robust) = (0, 0);
            while signal.sample_index() < scenario.measured_samples() as u64 {
                signal.fill(&mut words);
                let mut got = false;
                pipeline.push(&words, &mut |o| got |= matches!(o, Output::Doa(_)));
                if got {
                    doas += 1;
                    let f = doa::fit(pipeline.pairs(), pipeline.pair_delays(), k).unwrap();
                    // Only the reweighted path keeps less than all of the weight (Tukey
                    // weights are below 1 for any non-zero misfit).
                    if f.kept_weight < 1.0 {
                        robust += 1;
                    }
                }
            }
            assert!(doas > 10, "{}: {doas} DoA frames", scenario.name);
            eprintln!("{}: {robust} of {doas} DoA frames take the robust path", scenario.name);
            assert!(robust * 10 >= doas * 9, "{}: {robust} of {doas} robust", scenario.name);
        }
    }
}
