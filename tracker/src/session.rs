//! The one path from link bytes to fixes: [`crate::link::FrameSource`] → [`Intake`] →
//! [`Tracker`]. `aim track` (a serial port), `aim replay` (a recording or stdin) and
//! `host-sim fly` (the `frames-<id>.aimraw` it wrote) all run [`Session::track_reader`], so
//! the accuracy `fly` reports is what a user gets from the same bytes.
//!
//! Latency: a fix for instant `t` is emitted once a frame of the tracked array whose audio ends
//! at least [`crate::intake::IntakeConfig::reorder_s`] (0.3 s) after `t` has arrived, i.e.
//! 0.3–0.47 s of audio after `t` with the firmware's 0.171 s `Doa` frames, plus the link.
//! Every fix carries that moment in [`Fix::available`].

use std::io::Read;

use aim_wire::{Frame, LinkStats};
use anyhow::Context as _;
use serde_json::{json, Value};

use crate::intake::{Intake, IntakeConfig, IntakeError, IntakeStats, Released};
use crate::link::{json as link_json, FrameSource};
use crate::status::Status;
use crate::tracker::{Fix, Tracker};

/// Counts of the tracker's output.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FixStats {
    /// Fixes emitted.
    pub fixes: u64,
    /// Mean of `available − t`, s (0 without fixes).
    pub mean_latency_s: f64,
    /// Largest `available − t`, s (0 without fixes).
    pub max_latency_s: f64,
}

/// An intake feeding a tracker.
pub struct Session {
    intake: Intake,
    tracker: Tracker,
    fixes: u64,
    latency_sum_s: f64,
    latency_max_s: f64,
    /// Stamps of the first and the newest input of the tracked array, s.
    inputs_span: Option<(f64, f64)>,
    /// What the frames say of the arrays and the link (shared with `aim track`'s status line).
    status: std::sync::Arc<std::sync::Mutex<Status>>,
    /// The origin of the status clock.
    started: std::time::Instant,
    /// The drone classifier on the tracked array's `Mfcc` frames, if any.
    identifier: Option<Identifier>,
    /// Everything the intake has handed the tracker, oldest first, while the classifier may
    /// still change the profile (at most [`RETRACK_HISTORY`] items; `None` once it overflowed
    /// or without a classifier that chooses profiles).
    history: Option<Vec<Released>>,
}

/// Most intake items a session keeps to re-track the flight from its start when the
/// classifier changes the profile. One array hands on at most ≈ 39 items per second (an
/// `Audio` and an `Until` per frame, 14.7 frames/s, plus 9.8 inputs/s on the 10 m square), so
/// this covers at least 14 min of one array (with N arrays about 1/N of that); a choice made
/// later changes the profile in place ([`Tracker::set_profile`]).
pub const RETRACK_HISTORY: usize = 32_768;

/// The live drone classifier of a session and the automatic profile choice.
pub struct Identifier {
    live: crate::id::chip::Live,
    /// Profiles by class name: the tracker takes a class's profile once that class leads the
    /// verdicts so far (module docs of [`Identifier::push`]). Empty: the profile never
    /// changes (`--profile` given).
    profiles: Vec<(String, crate::profile::Profile)>,
    /// The class whose profile is in force, if one was chosen.
    chosen: Option<String>,
    /// Sum over the verdicts so far of each class's probability (model class order).
    evidence: Vec<f64>,
    /// Per class (model order), the sum over the tracked array's rotor `Peaks` frames of how
    /// well their groups fit the class's profile's hover BPF ([`bpf_fit`]; 1 for a class
    /// without a profile, `none` included: it never takes a profile, but its share counts).
    bpf_fit: Vec<f64>,
    /// Rotor `Peaks` frames counted in `bpf_fit`.
    bpf_frames: u32,
    /// Verdicts so far.
    verdicts: u32,
    /// `Mfcc` frames of the tracked array classified (each makes a verdict once the window is
    /// full; frames without the second comb are not counted).
    frames: u64,
    /// Sample index of the newest one: an older one means the array restarted its clock.
    last_index: u64,
    /// stderr has said that the tracked array's `Mfcc` frames carry no second comb (firmware
    /// older than the model's features; such frames are not classified).
    noted_no_second_comb: bool,
    /// The newest `Mfcc` frame had no second comb: no verdict until one that has comes (a
    /// board put back on older firmware does not keep the newer firmware's last verdict).
    lacks_second_comb: bool,
}

/// Fewest verdicts (one per `Mfcc` frame, 0.256 s) before the profile follows a class: 10 s.
/// Waiting costs little (the flight is re-tracked from its start) and a choice on a few
/// seconds of sound flips between look-alike types (tuning seeds: BENCHMARKS.md
/// "Issue 16, session 10").
pub const PROFILE_SWITCH_VERDICTS: u32 = 40;
/// Least share of the evidence (`Identifier::push`) of the class whose profile is taken.
pub const PROFILE_SWITCH_PROBABILITY: f64 = 0.5;
/// Spread of a drone's BPF about its profile's hover BPF in [`bpf_fit`], natural-log units
/// (0.1: ±10 %, airframe spread and ordinary manoeuvres).
pub const BPF_FIT_SPREAD: f64 = 0.1;
/// Added to every class's mean BPF fit, so that a BPF the detector misses or misreads does
/// not veto a type the sound names clearly.
pub const BPF_FIT_FLOOR: f64 = 0.05;

/// How well rotor groups at `groups_hz` fit a drone hovering at `hover_bpf_hz`: the best
/// group's `exp(−½ (ln(f / f_hover) / BPF_FIT_SPREAD)²)`, in [0, 1].
pub fn bpf_fit(groups_hz: &[f64], hover_bpf_hz: f64) -> f64 {
    groups_hz
        .iter()
        .filter(|f| **f > 0.0)
        .map(|f| (-0.5 * ((f / hover_bpf_hz).ln() / BPF_FIT_SPREAD).powi(2)).exp())
        .fold(0.0, f64::max)
}

/// How far a class's share of the evidence must lead the chosen class's to replace it.
pub const PROFILE_SWITCH_MARGIN: f64 = 0.2;

impl Identifier {
    /// A classifier with `model` (trained with `--features chip`) and the profiles it may
    /// choose from, by class name (empty: keep the tracker's).
    pub fn new(
        model: crate::id::model::Model,
        profiles: Vec<(String, crate::profile::Profile)>,
    ) -> anyhow::Result<Self> {
        let classes = model.classes.len();
        Ok(Self {
            live: crate::id::chip::Live::new(model)?,
            profiles,
            chosen: None,
            evidence: vec![0.0; classes],
            bpf_fit: vec![0.0; classes],
            bpf_frames: 0,
            verdicts: 0,
            frames: 0,
            last_index: 0,
            noted_no_second_comb: false,
            lacks_second_comb: false,
        })
    }

    /// The class whose profile the tracker uses, if the classifier chose one.
    pub fn chosen(&self) -> Option<&str> {
        self.chosen.as_deref()
    }

    /// The `drone` field for the latest verdict; none before the tracked array's first `Mfcc`
    /// frame (a board that sends none, older firmware: fixes as before) and while its newest
    /// `Mfcc` frame carries no second comb (firmware older than the model's features).
    fn field(&self) -> Option<crate::tracker::DroneField> {
        use crate::tracker::DroneField;
        if self.frames == 0 || self.lacks_second_comb {
            return None;
        }
        Some(match self.live.verdict() {
            None => DroneField::Pending,
            Some(v) if v.class == crate::id::NONE_CLASS => {
                DroneField::NoDrone { probability: v.probability }
            }
            Some(v) => DroneField::Drone { class: v.class.clone(), probability: v.probability },
        })
    }

    /// One `Peaks` frame of the tracked array: with a rotor signature, how well its groups
    /// fit each class's hover BPF goes into the choice.
    fn push_peaks(&mut self, peaks: &aim_wire::Peaks) {
        if peaks.detection != aim_wire::Detection::Rotor || peaks.peaks.is_empty() {
            return;
        }
        let groups: Vec<f64> = peaks.peaks.iter().map(|p| f64::from(p.freq_chz) / 100.0).collect();
        for (fit, class) in self.bpf_fit.iter_mut().zip(self.live.classes()) {
            *fit += match self.profiles.iter().find(|(c, _)| c == class) {
                Some((_, p)) => bpf_fit(&groups, p.hover_bpf_hz()),
                None => 1.0,
            };
        }
        self.bpf_frames += 1;
    }

    /// Each class's share of the evidence so far: its mean probability over the verdicts
    /// times the mean fit of the rotor groups to its hover BPF, normalised over the classes.
    fn shares(&self) -> Vec<f64> {
        let n = f64::from(self.verdicts.max(1));
        let m = f64::from(self.bpf_frames);
        let w: Vec<f64> = self
            .evidence
            .iter()
            .zip(&self.bpf_fit)
            .map(|(e, f)| e / n * if m > 0.0 { BPF_FIT_FLOOR + f / m } else { 1.0 })
            .collect();
        let total: f64 = w.iter().sum();
        w.iter().map(|x| if total > 0.0 { x / total } else { 0.0 }).collect()
    }

    /// One `Mfcc` frame of the tracked array; returns a profile to switch to, if any.
    ///
    /// A drone does not change type in flight, so the choice weighs every verdict so far,
    /// not the latest. Each class's evidence is its mean probability over the verdicts times
    /// how well the tracked array's rotor groups fit its profile's hover BPF ([`bpf_fit`],
    /// averaged over the rotor `Peaks` frames, plus [`BPF_FIT_FLOOR`]), as a share of all
    /// classes'. The class with the largest share takes the profile once there are
    /// [`PROFILE_SWITCH_VERDICTS`] verdicts and its share is at least
    /// [`PROFILE_SWITCH_PROBABILITY`]; the class in force (at first the start profile's) is
    /// replaced only by one leading it by [`PROFILE_SWITCH_MARGIN`]. A type confused with a
    /// look-alike in a third of the windows thus keeps its profile.
    fn push(
        &mut self,
        sample_index: u64,
        frame: &aim_wire::Mfcc,
    ) -> Option<crate::profile::Profile> {
        if frame.second_harmonic.is_none() {
            // Older firmware: the model's second-comb features would read as "none found",
            // which it never saw on a drone. No verdict rather than a wrong one.
            if !self.noted_no_second_comb {
                eprintln!(
                    "note: the tracked array's Mfcc frames carry no second comb (firmware older \
                     than the drone classifier's features): no drone verdict until it is updated"
                );
            }
            self.noted_no_second_comb = true;
            self.lacks_second_comb = true;
            // The window must not mix the two firmwares' frames.
            self.live.clear();
            return None;
        }
        self.lacks_second_comb = false;
        if sample_index < self.last_index {
            // The array rebooted: its new frames do not continue the old window (the drone,
            // and so the evidence, stays).
            self.live.clear();
        }
        self.last_index = sample_index;
        self.frames += 1;
        self.live.push(frame);
        let v = self.live.verdict()?;
        for (e, p) in self.evidence.iter_mut().zip(&v.window_probabilities) {
            *e += f64::from(*p);
        }
        self.verdicts += 1;
        if self.verdicts < PROFILE_SWITCH_VERDICTS {
            return None;
        }
        let shares = self.shares();
        let classes = self.live.classes();
        let lead = (0..shares.len()).max_by(|&a, &b| shares[a].total_cmp(&shares[b]))?;
        let lead_mean = shares[lead];
        let class = &classes[lead];
        if lead_mean < PROFILE_SWITCH_PROBABILITY || self.chosen.as_ref() == Some(class) {
            return None;
        }
        if let Some(chosen) = &self.chosen {
            let c = classes.iter().position(|x| x == chosen)?;
            if lead_mean < shares[c] + PROFILE_SWITCH_MARGIN {
                return None;
            }
        }
        let (class, profile) = self.profiles.iter().find(|(c, _)| c == class)?;
        self.chosen = Some(class.clone());
        Some(profile.clone())
    }
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session").field("intake", &self.intake.stats()).finish()
    }
}

impl Session {
    /// A session of `tracker` fed by an intake with `config` over the tracker's site.
    pub fn new(mut tracker: Tracker, site: crate::site::Site, config: IntakeConfig) -> Self {
        tracker.gate_on_audio();
        let status = Status::new(site.arrays.iter().map(|a| (a.id, a.mic_positions_m.len())));
        Self {
            status: std::sync::Arc::new(std::sync::Mutex::new(status)),
            started: std::time::Instant::now(),
            intake: Intake::new(site, config),
            tracker,
            fixes: 0,
            latency_sum_s: 0.0,
            latency_max_s: 0.0,
            inputs_span: None,
            identifier: None,
            history: None,
        }
    }

    /// The session with a live drone classifier on the tracked array's `Mfcc` frames: every
    /// fix then carries a `drone` field, and the tracker takes the profile of a recognised
    /// class when the identifier has one for it.
    pub fn with_identifier(mut self, mut identifier: Identifier) -> Self {
        if !identifier.profiles.is_empty() {
            self.history = Some(Vec::new());
        }
        // The class whose profile the tracker starts with counts as chosen: leaving it takes
        // the same margin as leaving any other choice.
        let start = self.tracker.profile();
        identifier.chosen =
            identifier.profiles.iter().find(|(_, p)| p == start).map(|(c, _)| c.clone());
        self.identifier = Some(identifier);
        self
    }

    /// The classifier, if the session has one.
    pub fn identifier(&self) -> Option<&Identifier> {
        self.identifier.as_ref()
    }

    /// The tracker (for its calibration and diagnostics).
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// The intake's counts.
    pub fn intake_stats(&self) -> &IntakeStats {
        self.intake.stats()
    }

    /// Stamps of the first and the newest input of the tracked array released so far, s.
    pub fn inputs_span(&self) -> Option<(f64, f64)> {
        self.inputs_span
    }

    /// The fixes' counts.
    pub fn fix_stats(&self) -> FixStats {
        let n = self.fixes;
        FixStats {
            fixes: n,
            mean_latency_s: if n > 0 { self.latency_sum_s / n as f64 } else { 0.0 },
            max_latency_s: self.latency_max_s,
        }
    }

    /// The arrays' and the link's status, shared (`aim track` prints it from another thread).
    pub fn status(&self) -> std::sync::Arc<std::sync::Mutex<Status>> {
        self.status.clone()
    }

    /// When the session started: the origin of [`Self::clock_s`].
    pub fn started(&self) -> std::time::Instant {
        self.started
    }

    /// Seconds since the session started: the clock of [`Self::status`]'s frame times.
    pub fn clock_s(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// The status, locked (a panic elsewhere while it was held does not hide it).
    fn status_lock(&self) -> std::sync::MutexGuard<'_, Status> {
        self.status.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// One frame, in link order; returns the fixes it made available.
    pub fn push(&mut self, frame: &Frame) -> Result<Vec<Fix>, IntakeError> {
        let now = self.clock_s();
        self.status_lock().observe(frame, now);
        if let (Some(id), aim_wire::Body::Peaks(p)) = (&mut self.identifier, &frame.body) {
            if u16::from(frame.header.array_id) == self.tracker.array_id() {
                id.push_peaks(p);
            }
        }
        if let (Some(id), aim_wire::Body::Mfcc(m)) = (&mut self.identifier, &frame.body) {
            if u16::from(frame.header.array_id) == self.tracker.array_id() {
                let index = frame.header.sample_index;
                let switch = id.push(index, m).filter(|p| p != self.tracker.profile());
                if let Some(profile) = switch {
                    eprintln!(
                        "note: drone classified as {}; tracking with its profile ({})",
                        id.chosen().unwrap_or("?"),
                        profile.name
                    );
                    self.retrack(profile);
                }
            }
        }
        let (tracked, takeovers) = (self.tracker.array_id(), self.tracker.takeovers());
        let tracker = &mut self.tracker;
        let span = &mut self.inputs_span;
        let mut fixes = Vec::new();
        let history = &mut self.history;
        let before = *self.intake.stats();
        self.intake.push(frame, &mut |r| {
            keep(history, &r);
            feed(tracker, span, r, &mut fixes)
        })?;
        note_time_base(
            frame.header.array_id,
            &before,
            &self.intake,
            self.tracker.clock().is_some(),
        );
        if self.tracker.takeovers() != takeovers {
            eprintln!(
                "note: array {} took over the track from array {tracked}",
                self.tracker.array_id()
            );
        }
        Ok(self.stamp(fixes))
    }

    /// The tracker takes `profile`: a new tracker with it replays everything the intake has
    /// handed on since the start (its fixes were sent already and are dropped), so the flight
    /// so far — the first hover's calibration above all — counts as if the profile had been
    /// given from the start. Beyond [`RETRACK_HISTORY`] items the tracker changes profile
    /// where it is ([`Tracker::set_profile`]).
    fn retrack(&mut self, profile: crate::profile::Profile) {
        let Some(history) = &self.history else {
            self.tracker.set_profile(profile);
            return;
        };
        let mut tracker = self.tracker.fresh(profile);
        let (mut span, mut dropped) = (None, Vec::new());
        for r in history {
            feed(&mut tracker, &mut span, r.clone(), &mut dropped);
        }
        self.tracker = tracker;
    }

    /// The end of the stream: everything still held, then the last instants.
    pub fn finish(&mut self) -> Vec<Fix> {
        let tracker = &mut self.tracker;
        let span = &mut self.inputs_span;
        let mut fixes = Vec::new();
        let history = &mut self.history;
        self.intake.finish(&mut |r| {
            keep(history, &r);
            feed(tracker, span, r, &mut fixes)
        });
        fixes.extend(self.tracker.flush());
        self.stamp(fixes)
    }

    /// Every frame of `source` to the end (or an I/O error), each fix to `out` as soon as it
    /// is available; then the last fixes. An I/O error of the reader ends the stream like its
    /// end (the last fixes still go out) and is returned after them.
    pub fn track_reader<R: Read>(
        &mut self,
        source: &mut FrameSource<R>,
        out: &mut dyn FnMut(&Fix) -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        let mut failure = None;
        while let Some(frame) = source.next() {
            match frame {
                Ok(frame) => {
                    let fixes = self.push(&frame)?;
                    let warnings = {
                        let mut status = self.status_lock();
                        status.set_link(source.stats());
                        status.take_warnings()
                    };
                    for w in warnings {
                        eprintln!("warning: {w}");
                    }
                    for fix in fixes {
                        out(&fix)?;
                    }
                }
                Err(e) => {
                    failure = Some(e);
                    break;
                }
            }
        }
        self.status_lock().set_link(source.stats());
        for fix in self.finish() {
            out(&fix)?;
        }
        match failure {
            Some(e) => Err(e).context("reading the link"),
            None => Ok(()),
        }
    }

    /// The statistics line of `aim track`/`aim replay`: the link's, the intake's and the
    /// fixes' counts and the arrays' status ([`Status::to_json`]: frames, sequence gaps,
    /// restarts, the boards' `Health` counters, the microphone flag, unknown arrays) as one JSON
    /// object, `{"kind":"stats",...}`.
    pub fn stats_json(&self, link: &LinkStats) -> Value {
        let i = self.intake.stats();
        let f = self.fix_stats();
        let status = self.status_lock().to_json(None);
        json!({
            "kind": "stats",
            "link": link_json::stats(link),
            "intake": {
                "frames": i.frames,
                "inputs": i.inputs,
                "unknown_array": i.unknown_array,
                "hellos": i.hellos,
                "new_epochs": i.new_epochs,
                "reboots_announced": i.reboots_announced,
                "reboots_withdrawn": i.reboots_withdrawn,
                "gaps": i.gaps,
                "out_of_window": i.out_of_window,
                "bad_span": i.bad_span,
                "late": i.late,
                "aligned_to_link": i.aligned_to_link,
            },
            "takeovers": self.tracker.takeovers(),
            "clocks": clocks_json(self.tracker.clock()),
            "arrays": status["arrays"],
            "unknown_arrays": status["unknown_arrays"],
            "fixes": f.fixes,
            "mean_latency_s": (f.mean_latency_s * 1e3).round() / 1e3,
            "max_latency_s": (f.max_latency_s * 1e3).round() / 1e3,
        })
    }

    fn stamp(&mut self, mut fixes: Vec<Fix>) -> Vec<Fix> {
        let now = self.intake.now();
        let drone = self.identifier.as_ref().and_then(Identifier::field);
        for f in &mut fixes {
            f.drone.clone_from(&drone);
            f.available = now.max(f.t);
            let latency = f.available - f.t;
            self.fixes += 1;
            self.latency_sum_s += latency;
            self.latency_max_s = self.latency_max_s.max(latency);
        }
        fixes
    }
}

/// Says on stderr when a frame moved an array's time base (a board placed on the link's time,
/// a reboot, a silence the stream jumped over, a reboot announced and then withdrawn): the
/// fixes' times jump there. `beacon`: the site has a beacon ([`placed_on_link_time`]).
fn note_time_base(array: u8, before: &IntakeStats, intake: &Intake, beacon: bool) {
    let (after, config) = (intake.stats(), intake.config());
    if after.aligned_to_link > before.aligned_to_link {
        let shift = intake.shift_s(array.into()).unwrap_or(f64::NAN);
        eprintln!("note: {}", placed_on_link_time(array, shift, beacon));
    }
    if after.new_epochs > before.new_epochs {
        eprintln!(
            "note: array {array} restarted (its sample count went back); its time base starts \
             again {} s after its last audio",
            config.epoch_gap_s
        );
    }
    if after.gaps > before.gaps {
        eprintln!(
            "note: array {array}'s frames skipped ahead (frames lost on the link, or a silence); \
             no fix is made across the gap"
        );
    }
    if after.reboots_withdrawn > before.reboots_withdrawn {
        eprintln!(
            "note: array {array}: a Hello announced a reboot but the frames go on with the old \
             sample count; the old time base is kept"
        );
    }
}

/// What the operator is told when array `array`'s first frames were `shift_s` from the other
/// arrays' newest audio by its clock and the site file, and were placed on the link's time
/// instead ([`crate::intake::IntakeStats::aligned_to_link`]); `beacon`: the site has a beacon,
/// whose clock model times the inter-array range differences (not the bearings) once synced.
fn placed_on_link_time(array: u8, shift_s: f64, beacon: bool) -> String {
    let (by, side) = (shift_s.abs(), if shift_s < 0.0 { "after" } else { "before" });
    let beacon = if beacon {
        " (the beacon's clock model times the range differences of the arrays' snippets once \
         synced, not the bearings)"
    } else {
        ""
    };
    format!(
        "array {array}'s clock put its first frames {by:.1} s {side} the other arrays' newest \
         audio (started at another time than the site file's clock_offset_s says); it is placed \
         on the link's time instead, good to the link's latency (a few tenths of a second), and \
         its bearings fused with the other arrays' are timed only that well{beacon}; set its \
         clock_offset_s for better"
    )
}

/// Keeps `r` in the re-tracking history, which is dropped once it would exceed
/// [`RETRACK_HISTORY`] items.
fn keep(history: &mut Option<Vec<Released>>, r: &Released) {
    // Snippets are not kept: 31 a second per array, each 256 samples; a fresh tracker takes
    // the old one's recent snippets instead (`Tracker::fresh`).
    if matches!(r, Released::Input(crate::observation::Input::Snippet(_))) {
        return;
    }
    if let Some(h) = history {
        if h.len() < RETRACK_HISTORY {
            h.push(r.clone());
        } else {
            *history = None;
        }
    }
}

/// One released item to the tracker.
fn feed(
    tracker: &mut Tracker,
    span: &mut Option<(f64, f64)>,
    released: Released,
    fixes: &mut Vec<Fix>,
) {
    match released {
        Released::Audio { array_id, from_s, to_s } => tracker.add_audio(array_id, from_s, to_s),
        Released::Input(input) => {
            let (id, t) = (input.array_id(), input.t());
            let observation = matches!(
                input,
                crate::observation::Input::Bearing(_) | crate::observation::Input::Spectrum(_)
            );
            if observation && id == tracker.array_id() {
                *span = Some(span.map_or((t, t), |(a, _)| (a, t)));
            }
            fixes.extend(tracker.push(input));
        }
        Released::Until { array_id, t } if array_id == tracker.array_id() => {
            fixes.extend(tracker.advance(t));
        }
        Released::Until { .. } => {}
    }
}

/// The clock model's view of every array for the statistics line (`null` without a beacon):
/// status, the map as the common time of the board's sample 0 (s) and its rate error against
/// the reference (ppm), the inlier residual rms (µs) and the arrivals used and rejected.
fn clocks_json(clock: Option<&crate::multi::clock::ClockModel>) -> Value {
    let Some(clock) = clock else { return Value::Null };
    let fs = clock.config().sample_rate_hz;
    let arrays: serde_json::Map<String, Value> = clock
        .statuses()
        .into_iter()
        .map(|a| {
            let status = match a.status {
                crate::multi::clock::SyncStatus::Unsynced => "unsynced",
                crate::multi::clock::SyncStatus::Synced => "synced",
                crate::multi::clock::SyncStatus::Stale => "stale",
            };
            let value = json!({
                "status": status,
                "zero_s": a.map.map(|m| (m.time(0.0) * 1e9).round() / 1e9),
                "drift_ppm": a.map.map(|m| (m.drift_ppm(fs) * 1e3).round() / 1e3),
                "residual_us": a.residual_rms_us.map(|r| (r * 1e2).round() / 1e2),
                "inliers": a.inliers,
                "rejected": a.rejected,
                "epoch": a.epoch,
            });
            (a.array_id.to_string(), value)
        })
        .collect();
    json!({ "reference": clock.reference(), "arrays": arrays })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fit is the Gaussian in log frequency of the best group (oracle: e^−½ one spread
    /// off, e^−2 two spreads off), 0 without groups, blind to non-positive frequencies.
    #[test]
    fn bpf_fit_is_a_log_gaussian_of_the_best_group() {
        let hover = 300.0;
        assert!((bpf_fit(&[hover], hover) - 1.0).abs() < 1e-12);
        let one = hover * BPF_FIT_SPREAD.exp();
        assert!((bpf_fit(&[one], hover) - (-0.5f64).exp()).abs() < 1e-12);
        let two_below = hover / (2.0 * BPF_FIT_SPREAD).exp();
        assert!((bpf_fit(&[two_below, one], hover) - (-0.5f64).exp()).abs() < 1e-12);
        assert!((bpf_fit(&[two_below], hover) - (-2.0f64).exp()).abs() < 1e-12);
        assert_eq!(bpf_fit(&[], hover), 0.0);
        assert_eq!(bpf_fit(&[0.0, -5.0], hover), 0.0);
    }

    /// The note names the array, how far and on which side its clock put it (a board whose
    /// clock reads ahead was moved back: a negative shift), and what times the fused bearings.
    #[test]
    fn the_link_time_note_says_how_far_and_what_follows() {
        let ahead = placed_on_link_time(2, -100.04, false);
        assert!(ahead.starts_with("array 2's clock put its first frames 100.0 s after"), "{ahead}");
        assert!(ahead.contains("timed only that well; set its clock_offset_s"), "{ahead}");
        assert!(!ahead.contains("beacon"), "{ahead}");
        let behind = placed_on_link_time(3, 7.5, true);
        assert!(behind.contains("7.5 s before") && behind.contains("not the bearings"), "{behind}");
    }
}
