//! How well the tracker's beacon clock model synchronised the arrays, against the truth.
//!
//! The model maps each board's sample index n to a common time (`ClockMap::time`). Two samples
//! taken at the same true instant τ must map to the same common time; the sync error of array p
//! at τ is `map_p(n_p(τ)) − map_r(n_r(τ))`, r the lowest-id array with a map, where
//! `n(τ) = (τ − offset)·fs·(1 + drift)` inverts the array's true clock ([`Clock`]). That is the
//! error of an inter-array delay measured through the model (1 µs ≈ 0.34 mm of range difference).

use aim_tracker::multi::clock::{ArrayClock, SyncStatus};

use crate::array::Clock;
use crate::truth::Truth;

/// The sync error of one clock snapshot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SyncError {
    /// Time of the snapshot (the beacon arrival that produced it), s.
    pub t_s: f64,
    /// Largest |error| over the synced arrays, µs.
    pub max_us: f64,
    /// Root mean square of the errors, µs.
    pub rms_us: f64,
    /// Arrays synced (the reference included).
    pub synced: usize,
    /// Arrays in the truth.
    pub arrays: usize,
}

/// The board's sample index at true time `tau_s` of an array with clock `clock` at nominal
/// rate `fs` (Hz).
fn sample_at(clock: &Clock, tau_s: f64, fs: f64) -> f64 {
    (tau_s - clock.offset_s) * fs * (1.0 + clock.drift_ppm * 1e-6)
}

/// The error of snapshot `clocks` at true time `tau_s` (its synced arrays against the lowest
/// synced id), or None with fewer than two synced arrays.
pub fn snapshot_error(
    clocks: &[ArrayClock],
    truth: &Truth,
    fs: f64,
    t_s: f64,
    tau_s: f64,
) -> Option<SyncError> {
    let times: Vec<f64> = clocks
        .iter()
        .filter(|c| c.status == SyncStatus::Synced)
        .filter_map(|c| {
            let i = truth.array_ids.iter().position(|&id| id == c.array_id)?;
            let clock = truth.clocks.get(i)?;
            Some(c.map?.time(sample_at(clock, tau_s, fs)))
        })
        .collect();
    let (&first, rest) = times.split_first()?;
    if rest.is_empty() {
        return None;
    }
    let errors: Vec<f64> = rest.iter().map(|t| (t - first) * 1e6).collect();
    Some(SyncError {
        t_s,
        max_us: errors.iter().fold(0.0f64, |m, e| m.max(e.abs())),
        rms_us: (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt(),
        synced: times.len(),
        arrays: truth.array_ids.len(),
    })
}

/// The error `after_s` seconds after the first beacon arrival the model used: the last
/// snapshot of `history` (the tracker's `clock_history`) at or before that, evaluated at its
/// own time. None if there is no such snapshot or fewer than two arrays were synced then.
pub fn error_after(
    history: &[(f64, Vec<ArrayClock>)],
    truth: &Truth,
    fs: f64,
    after_s: f64,
) -> Option<SyncError> {
    let start = history.first()?.0;
    let (t, clocks) = history.iter().rev().find(|(t, _)| *t <= start + after_s)?;
    snapshot_error(clocks, truth, fs, *t, *t)
}

#[cfg(test)]
mod tests {
    use aim_tracker::multi::clock::ClockMap;

    use super::*;

    /// Maps built from the true clocks have no error; a map 3 µs late shows 3 µs.
    #[test]
    fn true_maps_have_no_error_and_an_offset_map_shows_its_offset() {
        let fs = 48_000.0;
        let clocks = [
            Clock { offset_s: 0.0, drift_ppm: 0.0 },
            Clock { offset_s: 0.0137, drift_ppm: 80.0 },
            Clock { offset_s: -2.5, drift_ppm: -95.0 },
        ];
        let truth = Truth {
            blades: 2,
            array_ids: vec![1, 2, 3],
            clocks: clocks.to_vec(),
            airframe: None,
            rows: Vec::new(),
        };
        // The true map of a clock: common time = true time of sample n.
        let map = |c: &Clock, late_s: f64| ClockMap {
            t_mid_s: c.offset_s + late_s,
            n_mid: 0.0,
            seconds_per_sample: 1.0 / (fs * (1.0 + c.drift_ppm * 1e-6)),
        };
        let snapshot = |late3: f64| -> Vec<ArrayClock> {
            (0..3)
                .map(|i| ArrayClock {
                    array_id: i as u8 + 1,
                    status: SyncStatus::Synced,
                    map: Some(map(&clocks[i], if i == 2 { late3 } else { 0.0 })),
                    residual_rms_us: Some(1.0),
                    inliers: 10,
                    rejected: 0,
                    epoch: 0,
                })
                .collect()
        };
        let e = snapshot_error(&snapshot(0.0), &truth, fs, 10.0, 10.0).unwrap();
        assert!(e.max_us < 1e-3, "{e:?}");
        let e = snapshot_error(&snapshot(3e-6), &truth, fs, 10.0, 10.0).unwrap();
        assert!((e.max_us - 3.0).abs() < 1e-3, "{e:?}");
        assert_eq!((e.synced, e.arrays), (3, 3));
    }
}
