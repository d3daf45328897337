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
}

/// The live drone classifier of a session and the automatic profile choice.
#[derive(Debug)]
pub struct Identifier {
    live: crate::id::chip::Live,
    /// Profiles by class name: the tracker switches to a class's profile once it has been the
    /// verdict [`PROFILE_SWITCH_VERDICTS`] times in a row with at least
    /// [`PROFILE_SWITCH_PROBABILITY`]. Empty: the profile never changes (`--profile` given).
    profiles: Vec<(String, crate::profile::Profile)>,
    /// The class whose profile is in force, if one was chosen.
    chosen: Option<String>,
    /// The newest verdict's class and how many verdicts in a row it has had.
    streak: (String, u32),
    /// `Mfcc` frames of the tracked array seen (each makes a verdict once the window is full).
    frames: u64,
    /// Sample index of the newest one: an older one means the array restarted its clock.
    last_index: u64,
}

/// Verdicts in a row (one per `Mfcc` frame, 0.256 s) before the profile follows a class: 2 s.
pub const PROFILE_SWITCH_VERDICTS: u32 = 8;
/// Least probability of those verdicts.
pub const PROFILE_SWITCH_PROBABILITY: f32 = 0.7;

impl Identifier {
    /// A classifier with `model` (trained with `--features chip`) and the profiles it may
    /// choose from, by class name (empty: keep the tracker's).
    pub fn new(
        model: crate::id::model::Model,
        profiles: Vec<(String, crate::profile::Profile)>,
    ) -> anyhow::Result<Self> {
        Ok(Self {
            live: crate::id::chip::Live::new(model)?,
            profiles,
            chosen: None,
            streak: (String::new(), 0),
            frames: 0,
            last_index: 0,
        })
    }

    /// The class whose profile the tracker uses, if the classifier chose one.
    pub fn chosen(&self) -> Option<&str> {
        self.chosen.as_deref()
    }

    /// The `drone` field for the latest verdict; none before the tracked array's first `Mfcc`
    /// frame (a board that sends none, older firmware: fixes as before).
    fn field(&self) -> Option<crate::tracker::DroneField> {
        use crate::tracker::DroneField;
        if self.frames == 0 {
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

    /// One `Mfcc` frame of the tracked array; returns a profile to switch to, if any.
    fn push(
        &mut self,
        sample_index: u64,
        frame: &aim_wire::Mfcc,
    ) -> Option<crate::profile::Profile> {
        if sample_index < self.last_index {
            // The array rebooted: its new frames do not continue the old window.
            self.live.clear();
        }
        self.last_index = sample_index;
        self.frames += 1;
        self.live.push(frame);
        let v = self.live.verdict()?;
        if v.class == self.streak.0 && v.probability >= PROFILE_SWITCH_PROBABILITY {
            self.streak.1 += 1;
        } else {
            let n = u32::from(v.probability >= PROFILE_SWITCH_PROBABILITY);
            self.streak = (v.class.clone(), n);
        }
        if self.streak.1 < PROFILE_SWITCH_VERDICTS || self.chosen.as_deref() == Some(&self.streak.0)
        {
            return None;
        }
        let (class, profile) = self.profiles.iter().find(|(c, _)| *c == self.streak.0)?;
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
        }
    }

    /// The session with a live drone classifier on the tracked array's `Mfcc` frames: every
    /// fix then carries a `drone` field, and the tracker takes the profile of a recognised
    /// class when the identifier has one for it.
    pub fn with_identifier(mut self, identifier: Identifier) -> Self {
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
        if let (Some(id), aim_wire::Body::Mfcc(m)) = (&mut self.identifier, &frame.body) {
            if u16::from(frame.header.array_id) == self.tracker.array_id() {
                let index = frame.header.sample_index;
                let switch = id.push(index, m).filter(|p| p != self.tracker.profile());
                if let Some(profile) = switch {
                    eprintln!(
                        "note: drone classified as {} ; tracking with its profile ({})",
                        id.chosen().unwrap_or("?"),
                        profile.name
                    );
                    self.tracker.set_profile(profile);
                }
            }
        }
        let tracker = &mut self.tracker;
        let span = &mut self.inputs_span;
        let mut fixes = Vec::new();
        self.intake.push(frame, &mut |r| feed(tracker, span, r, &mut fixes))?;
        Ok(self.stamp(fixes))
    }

    /// The end of the stream: everything still held, then the last instants.
    pub fn finish(&mut self) -> Vec<Fix> {
        let tracker = &mut self.tracker;
        let span = &mut self.inputs_span;
        let mut fixes = Vec::new();
        self.intake.finish(&mut |r| feed(tracker, span, r, &mut fixes));
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
                "gaps": i.gaps,
                "out_of_window": i.out_of_window,
                "bad_span": i.bad_span,
                "late": i.late,
            },
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
            let (id, t) = match &input {
                crate::observation::Input::Bearing(b) => (b.array_id, b.t),
                crate::observation::Input::Spectrum(s) => (s.array_id, s.t),
            };
            if id == tracker.array_id() {
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
