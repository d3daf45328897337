//! Motion classes (paper Table I, ALGORITHMS.md §4).
//!
//! |              | one BPF peak | two or more |
//! |--------------|--------------|-------------|
//! | DoA unstable | vertical     | horizontal  |
//! | DoA stable   | hover        | yaw         |

use std::collections::VecDeque;

use crate::observation::BpfPeak;
use crate::profile::Profile;

/// One of the four basic motions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MotionClass {
    /// Stationary, all rotors alike.
    Hover,
    /// Turning in place: odd and even rotors differ.
    Yaw,
    /// Moving horizontally: front and rear (or left and right) rotors differ.
    Horizontal,
    /// Climbing or descending: all rotors alike.
    Vertical,
}

impl MotionClass {
    /// The name used in JSON output.
    pub fn as_str(self) -> &'static str {
        match self {
            MotionClass::Hover => "hover",
            MotionClass::Yaw => "yaw",
            MotionClass::Horizontal => "horizontal",
            MotionClass::Vertical => "vertical",
        }
    }

    /// Table I.
    pub fn from_cues(multiple_peaks: bool, doa_moving: bool) -> Self {
        match (multiple_peaks, doa_moving) {
            (false, false) => MotionClass::Hover,
            (true, false) => MotionClass::Yaw,
            (true, true) => MotionClass::Horizontal,
            (false, true) => MotionClass::Vertical,
        }
    }

    /// The class of known kinematics (the oracle for tests and evaluation): vertical when
    /// |v_z| ≥ `v_min`, else horizontal when |v_xy| ≥ `v_min`, else yaw when
    /// |yaw rate| ≥ `yaw_rate_min`, else hover. Speeds in m/s, rate in rad/s.
    pub fn of_kinematics(velocity: [f64; 3], yaw_rate: f64, v_min: f64, yaw_rate_min: f64) -> Self {
        let vh = velocity[0].hypot(velocity[1]);
        if velocity[2].abs() >= v_min && velocity[2].abs() >= vh {
            MotionClass::Vertical
        } else if vh >= v_min {
            MotionClass::Horizontal
        } else if yaw_rate.abs() >= yaw_rate_min {
            MotionClass::Yaw
        } else {
            MotionClass::Hover
        }
    }
}

/// The distinct rotor-speed groups the peaks tell, each as a BPF (Hz).
///
/// A peak may be the BPF, one of its harmonics or a shaft-rate line (a harmonic of the rotor
/// speed that is not a multiple of the blade count): each peak is divided by its harmonic
/// number of the shaft rate `bpf_ref_hz / n` and multiplied by n, so all of them estimate a
/// BPF. Peaks weaker than `min_relative_amplitude` of the strongest, or landing outside the
/// profile's BPF range, are ignored; estimates closer than `min_separation_hz` merge
/// (amplitude-weighted). Returns the groups sorted by frequency.
pub fn bpf_groups(
    peaks: &[BpfPeak],
    profile: &Profile,
    bpf_ref_hz: f64,
    min_relative_amplitude: f64,
    min_separation_hz: f64,
) -> Vec<BpfPeak> {
    let mut inside: Vec<BpfPeak> = peaks
        .iter()
        .copied()
        .filter(|p| p.hz.is_finite() && p.amplitude.is_finite() && p.amplitude > 0.0)
        .filter_map(|p| {
            let n = f64::from(profile.blades);
            let shaft = bpf_ref_hz / n;
            let harmonic = (p.hz / shaft).round();
            (harmonic >= 1.0 && harmonic <= 4.0 * n)
                .then(|| BpfPeak { hz: p.hz * n / harmonic, amplitude: p.amplitude })
        })
        .filter(|p| p.hz >= profile.bpf_min_hz && p.hz <= profile.bpf_max_hz)
        .collect();
    let strongest = inside.iter().fold(0.0f64, |m, p| m.max(p.amplitude));
    inside.retain(|p| p.amplitude >= min_relative_amplitude * strongest);
    inside.sort_by(|a, b| a.hz.total_cmp(&b.hz));
    let mut groups: Vec<BpfPeak> = Vec::new();
    for p in inside {
        match groups.last_mut() {
            Some(g) if p.hz - g.hz < min_separation_hz => {
                let a = g.amplitude + p.amplitude;
                g.hz = (g.hz * g.amplitude + p.hz * p.amplitude) / a;
                g.amplitude = a;
            }
            _ => groups.push(p),
        }
    }
    groups
}

/// Table I with a short majority vote, so one noisy block does not flip the class.
#[derive(Clone, Debug)]
pub struct MotionClassifier {
    window_s: f64,
    votes: VecDeque<(f64, MotionClass)>,
}

impl MotionClassifier {
    /// A classifier voting over `window_s` seconds.
    pub fn new(window_s: f64) -> Self {
        Self { window_s, votes: VecDeque::new() }
    }

    /// Adds the raw Table-I class at time `t` and returns the majority class of the window
    /// (ties go to the newest vote).
    pub fn update(&mut self, t: f64, raw: MotionClass) -> MotionClass {
        self.votes.push_back((t, raw));
        while self.votes.front().is_some_and(|(t0, _)| *t0 < t - self.window_s) {
            self.votes.pop_front();
        }
        let classes =
            [MotionClass::Hover, MotionClass::Yaw, MotionClass::Horizontal, MotionClass::Vertical];
        let count = |c: MotionClass| self.votes.iter().filter(|(_, v)| *v == c).count();
        let best = classes.iter().map(|&c| count(c)).max().unwrap_or(0);
        if count(raw) == best {
            raw
        } else {
            classes.into_iter().find(|&c| count(c) == best).unwrap_or(raw)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_one() {
        assert_eq!(MotionClass::from_cues(false, false), MotionClass::Hover);
        assert_eq!(MotionClass::from_cues(true, false), MotionClass::Yaw);
        assert_eq!(MotionClass::from_cues(true, true), MotionClass::Horizontal);
        assert_eq!(MotionClass::from_cues(false, true), MotionClass::Vertical);
    }

    #[test]
    fn groups_merge_close_peaks_and_drop_weak_or_out_of_range_ones() {
        let p = Profile::dji_mini_2();
        let peaks = [
            BpfPeak { hz: 328.0, amplitude: 1.0 },
            BpfPeak { hz: 328.4, amplitude: 1.0 },
            BpfPeak { hz: 336.0, amplitude: 0.8 },
            BpfPeak { hz: 656.0, amplitude: 2.0 },
            BpfPeak { hz: 300.0, amplitude: 0.05 },
        ];
        // The 656 Hz harmonic folds onto 328; 300 Hz is too weak.
        let g = bpf_groups(&peaks, &p, 328.0, 0.2, 1.0);
        assert_eq!(g.len(), 2, "{g:?}");
        assert!((g[0].hz - (328.0 + 2.0 * 656.0 / 2.0 + 328.4) / 4.0).abs() < 1e-9, "{g:?}");
        assert!((g[1].hz - 336.0).abs() < 1e-9);
        // Shaft-rate lines: 164.1 (×1) and 492.3 (×3) are the same rotor speed as 328.2.
        let shaft = [BpfPeak { hz: 164.1, amplitude: 1.0 }, BpfPeak { hz: 492.3, amplitude: 1.0 }];
        let g = bpf_groups(&shaft, &p, 328.0, 0.2, 1.0);
        assert_eq!(g.len(), 1, "{g:?}");
        assert!((g[0].hz - 328.2).abs() < 1e-9, "{g:?}");
    }

    #[test]
    fn majority_vote_suppresses_single_flips() {
        let mut c = MotionClassifier::new(0.5);
        let mut out = Vec::new();
        for k in 0..20 {
            let raw = if k == 10 { MotionClass::Vertical } else { MotionClass::Hover };
            out.push(c.update(k as f64 * 0.05, raw));
        }
        assert!(out.iter().all(|&m| m == MotionClass::Hover));
    }
}
