//! One clock for several arrays from a beacon loudspeaker (issue 14, ALGORITHMS.md §9).
//!
//! Every array p counts samples on its own crystal; its map to the common time is
//! t = a_p + b_p·n (n = the board's sample index, f64). The reference array keeps a fixed map
//! (at first the lowest id heard: a = 0, b = 1/fs; see [`ClockModel::reference`]). Beacon
//! emission k happens at an unknown common time e_k (the speaker has a clock of its own, so the
//! e_k are free unknowns and the speaker's drift needs no model); each arrival satisfies
//!
//! a_p + b_p·n_pk = e_k + |B − A_p| / c.
//!
//! Over the last [`ClockConfig::window`] emissions the model solves {a_p, b_p} of every other
//! array and {e_k} by weighted linear least squares (weight = arrival quality), rejects the worst
//! arrival beyond a robust residual gate and solves again until none is left, then reports per
//! array the map, the residual rms (µs), and a [`SyncStatus`].
//!
//! Grouping. Boards start at arbitrary times, so an arrival's sample index says nothing about
//! which emission it heard. The caller gives each arrival a coarse common time (the host's link
//! time of that sample, [`LinkAlignment`]); an arrival joins the emission whose coarse time lies
//! within [`ClockConfig::coarse_gate_s`], opens a new one when it lies a whole number of periods
//! (± the gate) from the others, and is refused ([`ArrivalSkipped::Ambiguous`]) otherwise. The
//! beacon alone cannot resolve a whole-period slip of one board (it would be absorbed in a_p);
//! only the coarse alignment does, so its error must stay below the gate (< period / 4).
//!
//! Precision (the oracle of the tests). With all arrays hearing K equally spaced emissions with
//! the same timing jitter σ_t, the Fisher information of the lines, after the free e_k are
//! eliminated, is (I − 11ᵀ/P)⊗S/σ_t² (S = Σ_k [1 s_k; s_k s_k²]); its inverse gives for any two
//! arrays the variance of their relative clock offset at time s from the window's centre
//! 2σ_t²·(1/K + s²/Σ_k s_k²), whatever the number of arrays. At the newest emission that is
//! var = 2σ_t²·(4K − 2)/(K(K + 1)) — [`offset_variance_bound`].

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};

/// One beacon arrival as a board reports it (BEACON frame: header sample index + fraction).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeaconArrival {
    /// Array id, as in the frames and the site file.
    pub array_id: u8,
    /// Arrival of the sequence's first sample, in the board's own samples (sample index +
    /// fraction).
    pub arrival_samples: f64,
    /// Detection quality, 0..1 (used as the relative weight of the arrival).
    pub quality: f32,
}

/// Tunables of the clock model.
#[derive(Clone, Debug, PartialEq)]
pub struct ClockConfig {
    /// Nominal sample rate of the boards, Hz.
    pub sample_rate_hz: f64,
    /// Nominal beacon period, s.
    pub period_s: f64,
    /// Emissions kept in the sliding window.
    pub window: usize,
    /// Inlier arrivals in the window an array needs to be [`SyncStatus::Synced`] (≥ 2).
    pub min_emissions: usize,
    /// Largest difference between the coarse times of arrivals of one emission, s (< period/4).
    pub coarse_gate_s: f64,
    /// Arrivals of lower quality are not used.
    pub min_quality: f32,
    /// Residual gate in robust standard deviations (1.4826·MAD of the weighted residuals).
    pub outlier_sigmas: f64,
    /// The gate is never tighter than this, s.
    pub min_gate_s: f64,
    /// A synced array not heard for this long (coarse time, against the newest emission) is
    /// [`SyncStatus::Stale`], s.
    pub stale_after_s: f64,
    /// A solved rate error beyond this (ppm against the reference) is refused: the array stays
    /// unsynced.
    pub max_drift_ppm: f64,
}

impl Default for ClockConfig {
    fn default() -> Self {
        Self {
            sample_rate_hz: 48_000.0,
            period_s: 1.0,
            window: 30,
            min_emissions: 3,
            coarse_gate_s: 0.2,
            min_quality: 0.05,
            outlier_sigmas: 5.0,
            min_gate_s: 20e-6,
            stale_after_s: 5.0,
            max_drift_ppm: 1000.0,
        }
    }
}

/// Why an arrival was not used.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum ArrivalSkipped {
    /// The array is not in the model.
    #[error("array {0} is not in the clock model")]
    UnknownArray(u8),
    /// Arrival or coarse time not finite, or quality below [`ClockConfig::min_quality`].
    #[error("arrival not finite or of too low quality")]
    Unusable,
    /// The coarse time fits no emission and no whole number of periods from them: `offset_s`
    /// is its distance to the nearest emission.
    #[error(
        "arrival {offset_s} s from the nearest emission: which emission it heard is ambiguous"
    )]
    Ambiguous {
        /// Coarse distance to the nearest emission, s.
        offset_s: f64,
    },
    /// The array already has an arrival in that emission.
    #[error("array {0} already heard that emission")]
    Duplicate(u8),
    /// Older than the window.
    #[error("arrival older than the window")]
    TooOld,
}

/// Whether an array's map can be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SyncStatus {
    /// No map (too few arrivals since start or since its last reboot).
    Unsynced,
    /// Map solved from at least [`ClockConfig::min_emissions`] inlier arrivals in the window.
    Synced,
    /// Map kept from an earlier solve, but the array has not heard the beacon for
    /// [`ClockConfig::stale_after_s`] (its drift is extrapolated).
    Stale,
}

/// One array's map from its sample index to the common time, t = t_mid + (n − n_mid)·b.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClockMap {
    /// Common time of sample `n_mid`, s.
    pub t_mid_s: f64,
    /// Sample index the map is centred on (keeps a and b well conditioned), samples.
    pub n_mid: f64,
    /// b_p: common seconds per sample of this board, s.
    pub seconds_per_sample: f64,
}

impl ClockMap {
    /// Common time of sample `n`, s.
    pub fn time(&self, n: f64) -> f64 {
        self.t_mid_s + (n - self.n_mid) * self.seconds_per_sample
    }

    /// a_p: common time of sample 0, s.
    pub fn a_s(&self) -> f64 {
        self.time(0.0)
    }

    /// Rate error against the reference clock at nominal rate `fs` (Hz), ppm.
    pub fn drift_ppm(&self, fs: f64) -> f64 {
        (self.seconds_per_sample * fs - 1.0) * 1e6
    }
}

/// What the model says of one array.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArrayClock {
    /// Array id.
    pub array_id: u8,
    /// Status of the map.
    pub status: SyncStatus,
    /// The map, if any (also when stale).
    pub map: Option<ClockMap>,
    /// Rms of the array's inlier residuals in the last solve, µs (`None` before one).
    pub residual_rms_us: Option<f64>,
    /// Inlier arrivals in the window.
    pub inliers: usize,
    /// Arrivals in the window rejected by the residual gate.
    pub rejected: usize,
    /// Epoch of the board's sample count (incremented each time it restarts).
    pub epoch: u32,
}

/// Per array: geometry, epoch, map.
#[derive(Clone, Debug)]
struct ArrayState {
    /// |B − A_p| / c, s.
    delay_s: f64,
    epoch: u32,
    last_n: Option<f64>,
    map: Option<ClockMap>,
    residual_rms_s: Option<f64>,
    inliers: usize,
    rejected: usize,
    /// Coarse time of the newest emission the array was heard in (current epoch), s.
    last_heard_s: Option<f64>,
}

#[derive(Clone, Copy, Debug)]
struct Member {
    array: u8,
    n: f64,
    weight: f64,
    outlier: bool,
}

#[derive(Clone, Debug)]
struct Emission {
    /// Mean coarse emission time of the members, s.
    coarse_s: f64,
    coarse_count: usize,
    members: Vec<Member>,
}

/// The clock model of one site with one beacon.
#[derive(Clone, Debug)]
pub struct ClockModel {
    config: ClockConfig,
    arrays: BTreeMap<u8, ArrayState>,
    /// Emissions in the window, by coarse time.
    emissions: Vec<Emission>,
    /// The reference array and its fixed map.
    reference: Option<(u8, ClockMap)>,
}

/// Variance of the relative clock offset of two arrays at the newest of `k` equally spaced
/// emissions heard by both with timing jitter `sigma_s` (s) each: 2σ²(4K − 2)/(K(K + 1)), s².
pub fn offset_variance_bound(sigma_s: f64, k: usize) -> f64 {
    let k = k as f64;
    2.0 * sigma_s * sigma_s * (4.0 * k - 2.0) / (k * (k + 1.0))
}

impl ClockModel {
    /// A model for a beacon at `beacon_position` (world m), arrays `(id, position)` (world m),
    /// speed of sound `speed_of_sound_mps` (m/s). The coarse gate is kept below a quarter of
    /// the period.
    pub fn new(
        mut config: ClockConfig,
        beacon_position: [f64; 3],
        speed_of_sound_mps: f64,
        arrays: &[(u8, [f64; 3])],
    ) -> Self {
        let arrays = arrays
            .iter()
            .map(|&(id, a)| {
                let d = ((0..3).map(|i| (a[i] - beacon_position[i]).powi(2)).sum::<f64>()).sqrt();
                let state = ArrayState {
                    delay_s: d / speed_of_sound_mps,
                    epoch: 0,
                    last_n: None,
                    map: None,
                    residual_rms_s: None,
                    inliers: 0,
                    rejected: 0,
                    last_heard_s: None,
                };
                (id, state)
            })
            .collect();
        config.coarse_gate_s = config.coarse_gate_s.min(config.period_s / 4.0);
        Self { config, arrays, emissions: Vec::new(), reference: None }
    }

    /// The model of a site's first beacon: its position and period, the site's arrays (ids
    /// above 255 cannot send frames and are left out; each heard at its microphone 0 when the
    /// site lists the microphones, else at its centre), speed of sound and sample rate (the
    /// defaults where the site gives none). `None` without a beacon.
    pub fn from_site(
        site: &crate::site::Site,
        sync: &crate::site::SiteSync,
        config: ClockConfig,
    ) -> Option<Self> {
        let beacon = sync.beacons.first()?;
        let config = ClockConfig {
            period_s: beacon.period_s,
            sample_rate_hz: site.sample_rate_hz.map_or(config.sample_rate_hz, f64::from),
            ..config
        };
        let c = sync.speed_of_sound_mps.unwrap_or(crate::doppler::DEFAULT_SPEED_OF_SOUND_MPS);
        // A BEACON frame times the arrival at microphone 0 (aim-dsp `beacon`): where the site
        // gives the microphones, that is where the array hears the beacon.
        let heard_at = |a: &crate::site::ArrayPose| match a.mic_positions_m.first() {
            Some(&[x, y]) => {
                let m = a.to_world([x, y, 0.0]);
                [a.position[0] + m[0], a.position[1] + m[1], a.position[2] + m[2]]
            }
            None => a.position,
        };
        let arrays: Vec<(u8, [f64; 3])> = site
            .arrays
            .iter()
            .filter_map(|a| u8::try_from(a.id).ok().map(|id| (id, heard_at(a))))
            .collect();
        Some(Self::new(config, beacon.position, c, &arrays))
    }

    /// The tunables.
    pub fn config(&self) -> &ClockConfig {
        &self.config
    }

    /// The reference array (its map is fixed; the common time is its clock). It is the lowest
    /// id among the arrays first heard often enough; if it restarts or goes stale, the lowest
    /// synced array takes over with its current map, so the common time runs on.
    pub fn reference(&self) -> Option<u8> {
        self.reference.map(|(id, _)| id)
    }

    /// Adds one arrival with its coarse common time `coarse_s` (s; e.g.
    /// [`LinkAlignment::coarse_s`] of its sample index) and solves the model again.
    pub fn push(&mut self, arrival: BeaconArrival, coarse_s: f64) -> Result<(), ArrivalSkipped> {
        let id = arrival.array_id;
        let Some(state) = self.arrays.get_mut(&id) else {
            return Err(ArrivalSkipped::UnknownArray(id));
        };
        if !(arrival.arrival_samples.is_finite()
            && coarse_s.is_finite()
            && arrival.quality.is_finite()
            && arrival.quality >= self.config.min_quality)
        {
            return Err(ArrivalSkipped::Unusable);
        }
        // A sample count that goes back is a restarted board: a new epoch, a new map.
        if state.last_n.is_some_and(|last| arrival.arrival_samples < last) {
            state.epoch += 1;
            state.map = None;
            state.residual_rms_s = None;
            state.last_heard_s = None;
            for e in &mut self.emissions {
                e.members.retain(|m| m.array != id);
            }
            self.emissions.retain(|e| !e.members.is_empty());
            if self.reference.is_some_and(|(r, _)| r == id) {
                self.hand_over_reference();
            }
        }
        let state = self.arrays.get_mut(&id).expect("checked above");
        let emitted = coarse_s - state.delay_s;
        let k = self.emission_of(emitted)?;
        let member = Member {
            array: id,
            n: arrival.arrival_samples,
            weight: f64::from(arrival.quality.min(1.0)),
            outlier: false,
        };
        match k {
            Some(k) => {
                let e = &mut self.emissions[k];
                if e.members.iter().any(|m| m.array == id) {
                    return Err(ArrivalSkipped::Duplicate(id));
                }
                e.coarse_s += (emitted - e.coarse_s) / (e.coarse_count + 1) as f64;
                e.coarse_count += 1;
                e.members.push(member);
            }
            None => {
                if self.emissions.len() >= self.config.window
                    && emitted < self.emissions[0].coarse_s
                {
                    return Err(ArrivalSkipped::TooOld);
                }
                let at = self.emissions.partition_point(|e| e.coarse_s < emitted);
                let e = Emission { coarse_s: emitted, coarse_count: 1, members: vec![member] };
                self.emissions.insert(at, e);
                if self.emissions.len() > self.config.window {
                    self.emissions.remove(0);
                }
            }
        }
        let state = self.arrays.get_mut(&id).expect("checked above");
        state.last_n = Some(arrival.arrival_samples);
        self.solve();
        Ok(())
    }

    /// The emission an arrival of coarse emission time `emitted` (s) belongs to: `Some(index)`,
    /// `None` for a new one, or why it is ambiguous.
    fn emission_of(&self, emitted: f64) -> Result<Option<usize>, ArrivalSkipped> {
        let gate = self.config.coarse_gate_s;
        let near: Vec<usize> = (0..self.emissions.len())
            .filter(|&k| (self.emissions[k].coarse_s - emitted).abs() < gate)
            .collect();
        match near.as_slice() {
            [k] => Ok(Some(*k)),
            [] => {
                let Some(nearest) = self
                    .emissions
                    .iter()
                    .map(|e| emitted - e.coarse_s)
                    .min_by(|a, b| a.abs().total_cmp(&b.abs()))
                else {
                    return Ok(None);
                };
                let periods = nearest / self.config.period_s;
                if (periods - periods.round()).abs() * self.config.period_s < gate {
                    Ok(None)
                } else {
                    Err(ArrivalSkipped::Ambiguous { offset_s: nearest })
                }
            }
            _ => Err(ArrivalSkipped::Ambiguous { offset_s: 0.0 }),
        }
    }

    /// Common time, s, of sample `n` of array `array_id`, if the array has a map (synced or
    /// stale; check [`ClockModel::status`] for which).
    pub fn common_time(&self, array_id: u8, n: f64) -> Option<f64> {
        self.map(array_id).map(|m| m.time(n))
    }

    /// The array's current map (the reference's fixed one for the reference).
    pub fn map(&self, array_id: u8) -> Option<ClockMap> {
        match self.reference {
            Some((r, map)) if r == array_id => Some(map),
            _ => self.arrays.get(&array_id)?.map,
        }
    }

    /// The array's status.
    pub fn status(&self, array_id: u8) -> Option<ArrayClock> {
        let s = self.arrays.get(&array_id)?;
        let newest = self.emissions.last().map(|e| e.coarse_s);
        let map = self.map(array_id);
        let heard_lately = match (s.last_heard_s, newest) {
            (Some(h), Some(n)) => n - h <= self.config.stale_after_s,
            _ => false,
        };
        let status = match map {
            None => SyncStatus::Unsynced,
            Some(_) if heard_lately && s.inliers >= self.config.min_emissions => SyncStatus::Synced,
            Some(_) if heard_lately && self.reference() == Some(array_id) => SyncStatus::Synced,
            Some(_) => SyncStatus::Stale,
        };
        Some(ArrayClock {
            array_id,
            status,
            map,
            residual_rms_us: s.residual_rms_s.map(|r| r * 1e6),
            inliers: s.inliers,
            rejected: s.rejected,
            epoch: s.epoch,
        })
    }

    /// Every array's status, by id.
    pub fn statuses(&self) -> Vec<ArrayClock> {
        self.arrays.keys().filter_map(|&id| self.status(id)).collect()
    }

    /// Gives the reference role to the lowest other array with a map (keeping that map, so the
    /// common time runs on), or to nobody (the next solve picks one afresh).
    fn hand_over_reference(&mut self) {
        let old = self.reference();
        self.reference = self
            .arrays
            .iter()
            .filter(|(id, _)| Some(**id) != old)
            .find_map(|(&id, s)| s.map.map(|m| (id, m)));
    }

    /// Solves the window again (called by [`ClockModel::push`]).
    pub fn solve(&mut self) {
        // Each array's newest emission.
        for s in self.arrays.values_mut() {
            s.last_heard_s = None;
        }
        for e in &self.emissions {
            for m in &e.members {
                if let Some(s) = self.arrays.get_mut(&m.array) {
                    s.last_heard_s = Some(e.coarse_s);
                }
            }
        }
        let newest = self.emissions.last().map_or(f64::NEG_INFINITY, |e| e.coarse_s);
        if let Some((r, _)) = self.reference {
            let heard = self.arrays[&r].last_heard_s;
            if heard.is_none_or(|h| newest - h > self.config.stale_after_s) {
                self.hand_over_reference();
            }
        }
        if self.reference.is_none() {
            // The lowest id heard often enough starts the common time on its own clock.
            let counts = self.counts(|_| true);
            let Some(id) = counts
                .iter()
                .find(|(_, c)| **c >= self.config.min_emissions.max(2))
                .map(|(&id, _)| id)
            else {
                return;
            };
            let map = ClockMap {
                t_mid_s: 0.0,
                n_mid: 0.0,
                seconds_per_sample: 1.0 / self.config.sample_rate_hz,
            };
            self.reference = Some((id, map));
        }
        for e in &mut self.emissions {
            for m in &mut e.members {
                m.outlier = false;
            }
        }
        // Solve, reject the worst arrival beyond the gate, solve again; at most a quarter of
        // the window's arrivals (beyond that the window is not trusted: no new maps).
        let total: usize = self.emissions.iter().map(|e| e.members.len()).sum();
        let mut solution = None;
        for _ in 0..=total / 4 {
            let Some(s) = self.solve_once() else { break };
            match self.worst_outlier(&s) {
                Some((k, j)) => {
                    self.emissions[k].members[j].outlier = true;
                    solution = None;
                }
                None => {
                    solution = Some(s);
                    break;
                }
            }
        }
        let counts = self.counts(|m| !m.outlier);
        let rejected = self.counts(|m| m.outlier);
        for (id, s) in &mut self.arrays {
            s.inliers = counts.get(id).copied().unwrap_or(0);
            s.rejected = rejected.get(id).copied().unwrap_or(0);
        }
        let Some(solution) = solution else { return };
        let mut sums: BTreeMap<u8, (f64, usize)> = BTreeMap::new();
        for &(k, j, r) in &solution.residuals {
            let m = &self.emissions[k].members[j];
            let e = sums.entry(m.array).or_default();
            e.0 += r * r;
            e.1 += 1;
        }
        let fs = self.config.sample_rate_hz;
        for (id, s) in &mut self.arrays {
            if let Some(map) = solution.maps.get(id) {
                let synced = s.inliers >= self.config.min_emissions
                    && map.drift_ppm(fs).abs() <= self.config.max_drift_ppm;
                if synced {
                    s.map = Some(*map);
                }
            }
            s.residual_rms_s = sums.get(id).map(|&(ss, n)| (ss / n as f64).sqrt());
        }
    }

    /// Per array: how many members of the window pass `keep`.
    fn counts(&self, keep: impl Fn(&Member) -> bool) -> BTreeMap<u8, usize> {
        let mut counts = BTreeMap::new();
        for m in self.emissions.iter().flat_map(|e| &e.members).filter(|m| keep(m)) {
            *counts.entry(m.array).or_insert(0) += 1;
        }
        counts
    }

    /// One weighted least-squares solve over the inlier members of the arrays connected to the
    /// reference.
    fn solve_once(&self) -> Option<Solution> {
        let (reference, ref_map) = self.reference?;
        let fs = self.config.sample_rate_hz;
        // Arrays joined to the reference by at least two shared emissions, step by step.
        let mut included = vec![reference];
        loop {
            let mut added = false;
            for &id in self.arrays.keys() {
                if included.contains(&id) {
                    continue;
                }
                let shared = self
                    .emissions
                    .iter()
                    .filter(|e| {
                        e.members.iter().any(|m| m.array == id && !m.outlier)
                            && e.members.iter().any(|m| included.contains(&m.array) && !m.outlier)
                    })
                    .count();
                if shared >= 2 {
                    included.push(id);
                    added = true;
                }
            }
            if !added {
                break;
            }
        }
        let used = |m: &Member| !m.outlier && included.contains(&m.array);
        // Emissions with at least two used members, and their members.
        let rows: Vec<(usize, usize)> = (0..self.emissions.len())
            .filter(|&k| self.emissions[k].members.iter().filter(|m| used(m)).count() >= 2)
            .flat_map(|k| {
                let members = &self.emissions[k].members;
                (0..members.len()).filter(move |&j| used(&members[j])).map(move |j| (k, j))
            })
            .collect();
        let mut emission_col: BTreeMap<usize, usize> = BTreeMap::new();
        let free: Vec<u8> = included.iter().copied().filter(|&id| id != reference).collect();
        // The centre of each free array's samples, for conditioning.
        let mut centre: BTreeMap<u8, (f64, f64)> = BTreeMap::new();
        for &(k, j) in &rows {
            let m = &self.emissions[k].members[j];
            let c = centre.entry(m.array).or_default();
            c.0 += m.weight * m.n;
            c.1 += m.weight;
            let next = 2 * free.len() + emission_col.len();
            emission_col.entry(k).or_insert(next);
        }
        let unknowns = 2 * free.len() + emission_col.len();
        if unknowns == 0 || rows.len() <= unknowns {
            return None;
        }
        let n_mid = |id: u8| centre.get(&id).map_or(0.0, |&(s, w)| s / w);
        let mut a = DMatrix::<f64>::zeros(rows.len(), unknowns);
        let mut b = DVector::<f64>::zeros(rows.len());
        for (i, &(k, j)) in rows.iter().enumerate() {
            let m = &self.emissions[k].members[j];
            let w = m.weight.sqrt();
            let delay = self.arrays[&m.array].delay_s;
            // residual = T_p(n) − delay − e_k
            a[(i, emission_col[&k])] = -w;
            if m.array == reference {
                b[i] = w * (delay - ref_map.time(m.n));
            } else {
                let p = free.iter().position(|&f| f == m.array).expect("included");
                let u = (m.n - n_mid(m.array)) / fs;
                a[(i, 2 * p)] = w;
                a[(i, 2 * p + 1)] = w * u;
                b[i] = w * (delay - u);
            }
        }
        let x = a.clone().svd(true, true).solve(&b, 1e-12).ok()?;
        if !x.iter().all(|v| v.is_finite()) {
            return None;
        }
        let r = &a * &x - &b;
        let residuals = rows
            .iter()
            .enumerate()
            .map(|(i, &(k, j))| (k, j, r[i] / self.emissions[k].members[j].weight.sqrt()))
            .collect();
        let maps = free
            .iter()
            .enumerate()
            .map(|(p, &id)| {
                let map = ClockMap {
                    t_mid_s: x[2 * p],
                    n_mid: n_mid(id),
                    seconds_per_sample: (1.0 + x[2 * p + 1]) / fs,
                };
                (id, map)
            })
            .collect();
        Some(Solution { maps, residuals })
    }

    /// The member with the largest residual beyond the gate, if any.
    fn worst_outlier(&self, s: &Solution) -> Option<(usize, usize)> {
        let weighted: Vec<f64> = s
            .residuals
            .iter()
            .map(|&(k, j, r)| (r * self.emissions[k].members[j].weight.sqrt()).abs())
            .collect();
        let sigma = 1.4826 * median(&weighted);
        s.residuals
            .iter()
            .map(|&(k, j, r)| {
                let w = self.emissions[k].members[j].weight;
                let gate =
                    (self.config.outlier_sigmas * sigma / w.sqrt()).max(self.config.min_gate_s);
                (k, j, r.abs() / gate)
            })
            .filter(|&(_, _, ratio)| ratio > 1.0)
            .max_by(|a, b| a.2.total_cmp(&b.2))
            .map(|(k, j, _)| (k, j))
    }
}

/// One solve's maps of the free arrays and residuals (emission, member, s).
struct Solution {
    maps: BTreeMap<u8, ClockMap>,
    residuals: Vec<(usize, usize, f64)>,
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// The coarse alignment of boards to the host's clock from their frames' link times: each
/// board's sample 0 is placed at the earliest (least delayed) link time seen, allowed to creep
/// later by [`LinkAlignment::max_rate`] s/s so that a board slower than the host stays aligned.
/// A sample count that goes back (a restarted board) starts the board afresh.
#[derive(Clone, Debug)]
pub struct LinkAlignment {
    sample_rate_hz: f64,
    /// How fast the estimate of a board's sample 0 may move later, s per s of link time
    /// (twice the largest crystal error).
    pub max_rate: f64,
    boards: BTreeMap<u8, Board>,
}

#[derive(Clone, Copy, Debug)]
struct Board {
    zero_s: f64,
    last_link_s: f64,
    last_n: f64,
}

impl LinkAlignment {
    /// Boards at nominal rate `sample_rate_hz` (Hz).
    pub fn new(sample_rate_hz: f64) -> Self {
        Self { sample_rate_hz, max_rate: 2e-4, boards: BTreeMap::new() }
    }

    /// A frame of `array_id` whose samples end at `sample_index` was read at `link_time_s`
    /// (host clock, s).
    pub fn observe(&mut self, array_id: u8, sample_index: f64, link_time_s: f64) {
        let zero = link_time_s - sample_index / self.sample_rate_hz;
        let fresh = Board { zero_s: zero, last_link_s: link_time_s, last_n: sample_index };
        let board = self.boards.entry(array_id).or_insert(fresh);
        if sample_index < board.last_n {
            *board = fresh;
            return;
        }
        let crept = board.zero_s + self.max_rate * (link_time_s - board.last_link_s).max(0.0);
        *board = Board { zero_s: crept.min(zero), last_link_s: link_time_s, last_n: sample_index };
    }

    /// Coarse host time of sample `sample_index` of `array_id`, s (the link's smallest delay
    /// included).
    pub fn coarse_s(&self, array_id: u8, sample_index: f64) -> Option<f64> {
        let b = self.boards.get(&array_id)?;
        Some(b.zero_s + sample_index / self.sample_rate_hz)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::Rng;

    const FS: f64 = 48_000.0;
    const C: f64 = 343.2;
    const BEACON: [f64; 3] = [8.0, 0.2, 1.5];
    const ARRAYS: [[f64; 3]; 4] =
        [[0.0, 0.0, 0.5], [10.0, 0.0, 2.0], [10.0, 10.0, 0.5], [0.0, 10.0, 2.5]];

    /// A simulated board: true time of its sample n is `offset_s + n/fs·(1 + drift)`.
    #[derive(Clone, Copy)]
    struct Board {
        offset_s: f64,
        drift_ppm: f64,
    }

    impl Board {
        fn sample_at(&self, t: f64) -> f64 {
            (t - self.offset_s) * FS / (1.0 + self.drift_ppm * 1e-6)
        }
    }

    struct World {
        boards: Vec<Board>,
        speaker_drift_ppm: f64,
        first_emission_s: f64,
    }

    impl World {
        fn new(rng: &mut Rng) -> Self {
            let boards = (0..4)
                .map(|_| Board {
                    offset_s: -5.0 * rng.uniform(),
                    drift_ppm: 200.0 * rng.uniform() - 100.0,
                })
                .collect();
            Self { boards, speaker_drift_ppm: 80.0, first_emission_s: 0.3 }
        }

        fn emission(&self, k: usize) -> f64 {
            self.first_emission_s + k as f64 * (1.0 + self.speaker_drift_ppm * 1e-6)
        }

        /// True arrival at array p of emission k, with jitter `sigma_s`, and its coarse time
        /// (true + 0–30 ms of link delay).
        fn arrival(&self, p: usize, k: usize, sigma_s: f64, rng: &mut Rng) -> (BeaconArrival, f64) {
            let d = (0..3).map(|i| (ARRAYS[p][i] - BEACON[i]).powi(2)).sum::<f64>().sqrt();
            let t = self.emission(k) + d / C;
            let n = self.boards[p].sample_at(t + sigma_s * rng.normal());
            let arrival = BeaconArrival { array_id: p as u8, arrival_samples: n, quality: 0.8 };
            (arrival, t + 0.03 * rng.uniform())
        }

        /// Error of the model's common time of array p at true time t against the reference
        /// array 0's true clock, s.
        fn error(&self, model: &ClockModel, p: usize, t: f64) -> Option<f64> {
            let truth = self.boards[0].sample_at(t) / FS;
            Some(model.common_time(p as u8, self.boards[p].sample_at(t))? - truth)
        }
    }

    fn model() -> ClockModel {
        let arrays: Vec<(u8, [f64; 3])> = (0..4).map(|p| (p as u8, ARRAYS[p])).collect();
        ClockModel::new(ClockConfig::default(), BEACON, C, &arrays)
    }

    /// 10 s after start (10 emissions), ±100 ppm drifts, offsets of seconds, 10 µs of jitter:
    /// the rms error of the relative offsets at the newest emission matches the bound
    /// σ_t·√(2(4K − 2)/(K(K + 1))) = 8.3 µs (least squares is efficient here) within the
    /// Monte-Carlo spread, and is below the 20 µs.
    #[test]
    fn relative_offsets_reach_the_bound() {
        let sigma = 10e-6;
        let k = 10;
        let bound = offset_variance_bound(sigma, k).sqrt();
        assert!((bound - 8.31e-6).abs() < 0.01e-6, "{bound}");
        let mut rng = Rng::new(14);
        let (mut sum_sq, mut count) = (0.0, 0);
        for _ in 0..200 {
            let world = World::new(&mut rng);
            let mut m = model();
            for e in 0..k {
                for p in 0..4 {
                    let (a, coarse) = world.arrival(p, e, sigma, &mut rng);
                    m.push(a, coarse).unwrap();
                }
            }
            assert_eq!(m.reference(), Some(0));
            for p in 1..4 {
                let s = m.status(p as u8).unwrap();
                assert_eq!(s.status, SyncStatus::Synced);
                let err = world.error(&m, p, world.emission(k - 1)).unwrap();
                sum_sq += err * err;
                count += 1;
                let drift = s.map.unwrap().drift_ppm(FS);
                let truth = (1.0 + world.boards[p].drift_ppm * 1e-6)
                    / (1.0 + world.boards[0].drift_ppm * 1e-6);
                assert!((drift - (truth - 1.0) * 1e6).abs() < 8.0, "{drift}");
            }
        }
        let rms = (sum_sq / count as f64).sqrt();
        assert!(rms > 0.85 * bound && rms < 1.15 * bound, "rms {rms} bound {bound}");
        assert!(rms < 20e-6);
    }

    /// A wrong detection (2 ms late, a reflection) is rejected and leaves the model as good
    /// as without it.
    #[test]
    fn a_wrong_detection_is_rejected() {
        let mut rng = Rng::new(3);
        let world = World::new(&mut rng);
        let mut m = model();
        for e in 0..15 {
            for p in 0..4 {
                let (mut a, coarse) = world.arrival(p, e, 5e-6, &mut rng);
                if e == 7 && p == 2 {
                    a.arrival_samples += 0.002 * FS;
                }
                m.push(a, coarse).unwrap();
            }
        }
        let s = m.status(2).unwrap();
        assert_eq!((s.status, s.rejected, s.inliers), (SyncStatus::Synced, 1, 14));
        assert!(s.residual_rms_us.unwrap() < 15.0, "{s:?}");
        for p in 1..4 {
            let err = world.error(&m, p, world.emission(14)).unwrap();
            assert!(err.abs() < 20e-6, "array {p}: {err}");
            assert_eq!(m.status(p as u8).unwrap().rejected, usize::from(p == 2));
        }
    }

    /// Quality weights: two arrays, noiseless but for one arrival of array 1 late by 15 µs
    /// (inside the gate). With e_k free, each emission's weight in the relative clock line is
    /// w₀w₁/(w₀ + w₁); the change of the model's error at the newest emission equals that
    /// weighted regression's response to the shift (the oracle), and a low quality shrinks it.
    #[test]
    fn quality_weights_the_arrivals() {
        let run = |q: f32, shift: f64| {
            let mut rng = Rng::new(17);
            let world = World::new(&mut rng);
            let mut m = model();
            let (k, j) = (12, 4);
            let mut points = Vec::new();
            for e in 0..k {
                for p in 0..2 {
                    let (mut a, coarse) = world.arrival(p, e, 0.0, &mut rng);
                    if p == 1 {
                        if e == j {
                            a.arrival_samples += shift * FS;
                            a.quality = q;
                        }
                        let w = 0.8 * f64::from(a.quality) / (0.8 + f64::from(a.quality));
                        points.push((a.arrival_samples, w));
                    }
                    m.push(a, coarse).unwrap();
                }
            }
            assert_eq!(m.status(1).unwrap().rejected, 0);
            let t = world.emission(k - 1);
            let err = world.error(&m, 1, t).unwrap();
            // Weighted regression's response at sample n to a shift of point j.
            let n = world.boards[1].sample_at(t);
            let total: f64 = points.iter().map(|p| p.1).sum();
            let mean = points.iter().map(|p| p.0 * p.1).sum::<f64>() / total;
            let spread: f64 = points.iter().map(|p| p.1 * (p.0 - mean).powi(2)).sum();
            let (nj, wj) = points[j];
            (err, shift * wj * (1.0 / total + (n - mean) * (nj - mean) / spread))
        };
        let (base, _) = run(0.8, 0.0);
        // Noiseless data: no error but a residue of 0.13 µs (not explained yet, see the report).
        assert!(base.abs() < 0.2e-6, "{base}");
        let mut changes = Vec::new();
        for q in [0.8f32, 0.1] {
            let (err, response) = run(q, 15e-6);
            // A later arrival makes the array's clock read early: the error is −response.
            assert!((err - base + response).abs() < 5e-9, "q {q}: {err} − {base} vs {response}");
            changes.push((err - base).abs());
        }
        assert!(changes[1] < 0.5 * changes[0], "{changes:?}");
    }

    /// A board that starts 8 s late is unsynced until it has heard three emissions, then synced
    /// to within the bound for three emissions; one that never hears the beacon stays unsynced
    /// and does not disturb the others.
    #[test]
    fn a_late_board_syncs_and_a_deaf_one_stays_unsynced() {
        let mut rng = Rng::new(5);
        let mut world = World::new(&mut rng);
        world.boards[2].offset_s = 8.0;
        let mut m = model();
        for e in 0..14 {
            for p in 0..3 {
                if p == 2 && world.emission(e) < 8.0 {
                    continue;
                }
                let (a, coarse) = world.arrival(p, e, 10e-6, &mut rng);
                m.push(a, coarse).unwrap();
                let heard = (0..=e).filter(|&k| world.emission(k) > 8.0).count();
                if p == 2 {
                    let want = if heard >= 3 { SyncStatus::Synced } else { SyncStatus::Unsynced };
                    assert_eq!(m.status(2).unwrap().status, want, "emission {e}");
                }
            }
        }
        let err = world.error(&m, 2, world.emission(13)).unwrap();
        // Six emissions heard: 4σ of the bound for K = 6.
        assert!(err.abs() < 4.0 * offset_variance_bound(10e-6, 6).sqrt(), "{err}");
        let deaf = m.status(3).unwrap();
        assert_eq!((deaf.status, deaf.map, deaf.inliers), (SyncStatus::Unsynced, None, 0));
        assert_eq!(m.common_time(3, 1000.0), None);
    }

    /// A board that reboots (its count restarts at 0 with a new offset) starts a new epoch: its
    /// old arrivals are dropped, it is unsynced until it has heard three emissions, then synced
    /// again. When the reference reboots, the next array takes over and the common time runs on.
    #[test]
    fn a_rebooted_board_syncs_again() {
        for rebooted in [1usize, 0] {
            let mut rng = Rng::new(9);
            let mut world = World::new(&mut rng);
            let mut m = model();
            for e in 0..12 {
                for p in 0..3 {
                    let (a, coarse) = world.arrival(p, e, 10e-6, &mut rng);
                    m.push(a, coarse).unwrap();
                }
            }
            let before = m.common_time(2, world.boards[2].sample_at(world.emission(11)));
            world.boards[rebooted].offset_s = world.emission(12) - 0.5;
            for e in 12..20 {
                for p in 0..3 {
                    let (a, coarse) = world.arrival(p, e, 10e-6, &mut rng);
                    m.push(a, coarse).unwrap();
                    if p == rebooted {
                        let s = m.status(p as u8).unwrap();
                        assert_eq!(s.epoch, 1);
                        let want = if e >= 14 { SyncStatus::Synced } else { SyncStatus::Unsynced };
                        if rebooted == 1 {
                            assert_eq!(s.status, want, "emission {e}");
                        }
                    }
                }
            }
            // The common time did not jump: array 2 (never rebooted) maps the same sample to
            // the same time as before the reboot.
            let after = m.common_time(2, world.boards[2].sample_at(world.emission(11)));
            assert!((after.unwrap() - before.unwrap()).abs() < 50e-6, "{before:?} {after:?}");
            // Every array agrees again on the common time of the newest emission.
            let t = world.emission(19);
            let times: Vec<f64> = (0..3)
                .map(|p| m.common_time(p as u8, world.boards[p].sample_at(t)).unwrap())
                .collect();
            for p in 1..3 {
                assert!((times[p] - times[0]).abs() < 30e-6, "reboot of {rebooted}: {times:?}");
            }
            if rebooted == 0 {
                assert_eq!(m.reference(), Some(1));
                assert_eq!(m.status(0).unwrap().status, SyncStatus::Synced);
            }
        }
    }

    /// An arrival whose coarse time is half a period off every emission is refused, not put in
    /// a wrong group; one heard twice in one emission is refused; unknown arrays are refused.
    #[test]
    fn ambiguous_arrivals_are_refused() {
        let mut rng = Rng::new(11);
        let world = World::new(&mut rng);
        let mut m = model();
        for e in 0..4 {
            for p in 0..2 {
                let (a, coarse) = world.arrival(p, e, 10e-6, &mut rng);
                m.push(a, coarse).unwrap();
            }
        }
        let (a, coarse) = world.arrival(2, 4, 10e-6, &mut rng);
        assert!(matches!(m.push(a, coarse + 0.5), Err(ArrivalSkipped::Ambiguous { .. })));
        m.push(a, coarse).unwrap();
        let b = BeaconArrival { arrival_samples: a.arrival_samples + 1.0, ..a };
        assert_eq!(m.push(b, coarse + 0.05), Err(ArrivalSkipped::Duplicate(2)));
        let unknown = BeaconArrival { array_id: 9, ..a };
        assert_eq!(m.push(unknown, coarse), Err(ArrivalSkipped::UnknownArray(9)));
        let weak = BeaconArrival { quality: 0.0, ..a };
        assert_eq!(m.push(weak, coarse), Err(ArrivalSkipped::Unusable));
    }

    /// A board not heard for longer than `stale_after_s` keeps its map but is stale.
    #[test]
    fn a_silent_board_goes_stale() {
        let mut rng = Rng::new(13);
        let world = World::new(&mut rng);
        let mut m = model();
        for e in 0..14 {
            for p in 0..3 {
                if p == 2 && e >= 6 {
                    continue;
                }
                let (a, coarse) = world.arrival(p, e, 2e-6, &mut rng);
                m.push(a, coarse).unwrap();
            }
        }
        let s = m.status(2).unwrap();
        assert_eq!(s.status, SyncStatus::Stale);
        // Extrapolated 8 s on the solved drift: still close.
        let err = world.error(&m, 2, world.emission(13)).unwrap();
        assert!(err.abs() < 100e-6, "{err}");
    }

    /// The site's beacon, arrays, speed of sound and sample rate make the model.
    #[test]
    fn a_site_with_a_beacon_makes_the_model() {
        use crate::site::{Site, SiteSync};
        let text = "sample_rate_hz = 44100\nspeed_of_sound_mps = 340.0\n[[array]]\nid = 3\nposition = [0.0, 0.0, 0.0]\n[[array]]\nid = 4\nposition = [6.8, 0.0, 0.0]\nyaw_deg = 90.0\nroll_deg = 180.0\npositions = [[0.1, 0.0], [0.0, 0.1], [-0.1, 0.0], [0.0, -0.1]]\n[[beacon]]\nid = 1\nposition = [3.4, 0.0, 0.0]\nperiod_s = 2.0\nsequence = \"aim-beacon-v1\"\n";
        let path = std::path::Path::new("s.toml");
        let (site, sync) = (Site::parse(text, path).unwrap(), SiteSync::parse(text, path).unwrap());
        let m = ClockModel::from_site(&site, &sync, ClockConfig::default()).unwrap();
        assert_eq!((m.config().period_s, m.config().sample_rate_hz), (2.0, 44_100.0));
        let fast = ClockConfig { period_s: 0.4, ..ClockConfig::default() };
        assert_eq!(ClockModel::new(fast, [0.0; 3], 343.0, &[]).config().coarse_gate_s, 0.1);
        assert_eq!(m.arrays[&3].delay_s, 0.01);
        // Array 4 hears at its microphone 0: 0.1 m along its x, turned 90° (roll 180°
        // leaves x): (6.8, 0.1, 0).
        let mic0 = (3.4f64 * 3.4 + 0.1 * 0.1).sqrt() / 340.0;
        assert!((m.arrays[&4].delay_s - mic0).abs() < 1e-12, "{}", m.arrays[&4].delay_s);
        assert!(
            ClockModel::from_site(&site, &SiteSync::default(), ClockConfig::default()).is_none()
        );
    }

    /// The coarse alignment of a board 100 ppm slower than the host with 0–50 ms of link delay
    /// stays within the delay range over an hour.
    #[test]
    fn link_alignment_follows_a_drifting_board() {
        let mut rng = Rng::new(21);
        let mut align = LinkAlignment::new(FS);
        let board = Board { offset_s: 12.0, drift_ppm: 100.0 };
        let other = Board { offset_s: 3.0, drift_ppm: -100.0 };
        for i in 0..36_000 {
            let t = 12.5 + i as f64 * 0.1;
            for (id, b) in [(0u8, board), (1, other)] {
                align.observe(id, b.sample_at(t), t + 0.05 * rng.uniform());
                let err = align.coarse_s(id, b.sample_at(t)).unwrap() - t;
                assert!((-1e-3..0.051).contains(&err), "{i}: {err}");
            }
        }
        // A restart re-aligns at once.
        align.observe(0, 100.0, 5000.0);
        assert!((align.coarse_s(0, 100.0).unwrap() - 5000.0).abs() < 1e-9);
    }
}
