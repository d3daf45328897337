//! Decoded wire frames → tracker inputs in sample-time order, on one host time base.
//!
//! The one intake of `aim track`, `aim replay` and `host-sim fly` (through
//! [`crate::session::Session`]). Per array it keeps:
//!
//! - **a time base per boot** (an *epoch*): sample indices become host seconds through the site
//!   file's clock offset and drift ([`crate::site::ArrayPose::sample_time`]) for the first boot
//!   (an array whose clock puts its first frames more than [`IntakeConfig::align_to_link_s`]
//!   from the other arrays' newest audio, a board started at another time, is placed at that
//!   newest audio instead: counted in [`IntakeStats::aligned_to_link`]).
//!   A reboot starts a new epoch in one of two ways: a `Hello` whose boot count differs from the
//!   array's previous `Hello` and whose sample index went back (at once: everything the old
//!   boot left in the reorder stage is released first; should the frames after it go on with
//!   the old count, the `Hello` lied, the old time base is taken back and the frames follow
//!   it: [`IntakeStats::reboots_withdrawn`]), or, when that `Hello` was lost, the sample index
//!   jumping back (a restarted board counts from 0 again) once [`IntakeConfig::confirm_frames`]
//!   frames agree on the new count. The link carries no wall time, so the new epoch's first frame is placed
//!   [`IntakeConfig::epoch_gap_s`] after the previous epoch's last audio (the real pause is
//!   unknown; the tracker restarts across it).
//! - **a plausibility window**: a frame must end no earlier than
//!   [`IntakeConfig::window_behind_s`] before the newest audio and no later than
//!   [`IntakeConfig::window_ahead_s`] after it. A frame outside is held aside; if
//!   `confirm_frames` frames agree with each other there, the stream really moved (a silence in
//!   the same boot, or a reboot); otherwise they are counted as out of window and dropped — a
//!   single frame never moves the time base.
//! - **a bounded reorder stage**: the firmware sends each output when its span ends, but stamps
//!   it at the span's middle, so a `Peaks` frame (0.512 s span) arrives after `Doa` frames
//!   (0.171 s) that describe later instants. Inputs are held until a frame ending
//!   [`IntakeConfig::reorder_s`] after their stamp has arrived, then released in stamp order. This
//!   adds up to `reorder_s` (0.3 s) of latency; an input older than what was already released is
//!   counted as late and dropped.
//!
//! `Hello` frames are checked against the site file: a sample rate or microphone geometry that
//! contradicts it is an [`IntakeError`] naming both values. Every frame set aside is counted
//! in [`IntakeStats`].

use std::collections::HashMap;

use aim_wire::{Body, Frame, Hello};

use crate::observation::{BeaconHeard, Bearing, BpfPeak, Input, SnippetHeard, Spectrum};
use crate::site::{ArrayPose, Site};
use crate::status::{pair_count, RecentPairs};

/// Sample rate assumed before any `Hello` when the site file gives none, Hz.
pub const DEFAULT_SAMPLE_RATE_HZ: u32 = 48_000;

/// Sample rates a `Hello` may announce without the site file giving one, Hz.
pub const PLAUSIBLE_RATES_HZ: std::ops::RangeInclusive<u32> = 4_000..=384_000;

/// Tunables of the intake.
#[derive(Clone, Debug, PartialEq)]
pub struct IntakeConfig {
    /// Hold of the reorder stage, s: an input is released once a frame of its array ending at
    /// least this long after the input's stamp has arrived. The longest frame of the firmware
    /// (`Peaks`, 0.512 s stamped at its middle) lags the newest audio by 0.256 s.
    pub reorder_s: f64,
    /// A frame ending more than this before the newest audio of its epoch is out of window, s
    /// (`Peaks` end with the newest audio; the span is checked separately).
    pub window_behind_s: f64,
    /// A frame ending more than this after the newest audio of its epoch is out of window, s:
    /// it waits for `confirm_frames` frames that agree with it (frames lost on the link: the
    /// stream goes on after that short wait, on the same time base). A single frame whose
    /// sample index is wrong must not move the time base (inside the window it would: the
    /// frames after it would then be late).
    pub window_ahead_s: f64,
    /// An array's first time base is its own clock unless that puts its first frames more
    /// than this from the other arrays' newest audio, s (a board started at another time).
    pub align_to_link_s: f64,
    /// Frames that must agree with each other outside the window before the time base follows
    /// them (a silence or a reboot), and before the first time base is set.
    pub confirm_frames: usize,
    /// Longest span a `Doa` or `Peaks` frame may claim, s.
    pub max_span_s: f64,
    /// Host time between the last audio of one epoch and the first of the next, s.
    pub epoch_gap_s: f64,
}

impl Default for IntakeConfig {
    fn default() -> Self {
        Self {
            reorder_s: 0.3,
            window_behind_s: 1.0,
            window_ahead_s: 0.5,
            align_to_link_s: 2.0,
            confirm_frames: 3,
            max_span_s: 1.0,
            epoch_gap_s: 5.0,
        }
    }
}

/// Counts of what the intake did with the frames it was given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IntakeStats {
    /// Frames given to the intake.
    pub frames: u64,
    /// Inputs (bearings and BPF spectra) released in time order.
    pub inputs: u64,
    /// Frames from arrays not in the site file.
    pub unknown_array: u64,
    /// `Hello` frames that agreed with the site file.
    pub hellos: u64,
    /// Time bases started after an array's first (reboots: a `Hello` with a new boot count, or
    /// the sample index went back).
    pub new_epochs: u64,
    /// Of [`Self::new_epochs`], those a `Hello` with a new boot count announced.
    pub reboots_announced: u64,
    /// `Hello`s with a new boot count and a sample index gone back after which the frames went
    /// on with the old count: the old time base was taken back (not counted in
    /// [`Self::new_epochs`]).
    pub reboots_withdrawn: u64,
    /// Jumps ahead the time base followed within one boot (the sample index went on past frames
    /// lost on the link, or a silence).
    pub gaps: u64,
    /// Frames outside the expected window that no later frames confirmed: set aside.
    pub out_of_window: u64,
    /// Frames whose span is longer than [`IntakeConfig::max_span_s`]: set aside.
    pub bad_span: u64,
    /// Inputs older than what the reorder stage had already released: dropped.
    pub late: u64,
    /// Arrays whose first time base was placed at the link's newest audio because their own
    /// clock put it more than [`IntakeConfig::align_to_link_s`] away (a board started at
    /// another time than the others).
    pub aligned_to_link: u64,
}

/// A `Hello` that contradicts the site file (or an earlier `Hello` of the same array).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum IntakeError {
    /// Sample rates differ.
    #[error("array {array}: its Hello announces a sample rate of {hello_hz} Hz, {expected}")]
    SampleRate {
        /// Array id.
        array: u16,
        /// The Hello's rate, Hz.
        hello_hz: u32,
        /// What it contradicts, in words with the value.
        expected: String,
    },
    /// Microphone positions differ.
    #[error(
        "array {array}: its Hello gives microphone positions {hello:?} m, the site file {site:?} m"
    )]
    Geometry {
        /// Array id.
        array: u16,
        /// The Hello's positions, m.
        hello: Vec<[f64; 2]>,
        /// The site file's positions, m.
        site: Vec<[f64; 2]>,
    },
}

/// What the intake hands on, in order.
#[derive(Clone, Debug, PartialEq)]
pub enum Released {
    /// An array sent audio over `[from_s, to_s]` (host time): the span of an accepted frame.
    /// Comes when the frame is accepted, before its input is released.
    Audio {
        /// Array id.
        array_id: u16,
        /// Start, s.
        from_s: f64,
        /// End, s.
        to_s: f64,
    },
    /// An input, in stamp order per array.
    Input(Input),
    /// No input of `array_id` stamped before `t` will follow.
    Until {
        /// Array id.
        array_id: u16,
        /// Time, s.
        t: f64,
    },
}

/// One epoch's mapping and extent.
#[derive(Clone, Copy, Debug)]
struct Timeline {
    /// Added to the site file's mapping of the sample index, s.
    shift_s: f64,
    /// Newest end of audio accepted, sample index.
    newest_end: u64,
}

impl Timeline {
    /// Host time of the newest audio accepted, s (`fs`: the array's rate, Hz).
    fn newest_s(&self, pose: &ArrayPose, fs: f64) -> f64 {
        pose.sample_time(self.newest_end as f64, fs) + self.shift_s
    }

    /// The next epoch (a reboot), whose first frame starts at sample index `first`: placed
    /// `gap_s` after this epoch's newest audio.
    fn next_epoch(&self, pose: &ArrayPose, fs: f64, first: u64, gap_s: f64) -> Timeline {
        let shift_s = self.newest_s(pose, fs) + gap_s - pose.sample_time(first as f64, fs);
        Timeline { shift_s, newest_end: first }
    }
}

/// An array's time base, boot count and release mark before a `Hello` announced a reboot.
#[derive(Clone, Copy, Debug)]
struct BeforeReboot {
    timeline: Timeline,
    boot_count: Option<u32>,
    released_until: f64,
}

/// Everything the intake keeps of one array.
#[derive(Clone, Debug, Default)]
struct ArrayState {
    /// Sample rate from the site file or the first `Hello`, Hz.
    rate_hz: Option<u32>,
    timeline: Option<Timeline>,
    /// Frames outside the window that agree with each other, oldest first.
    pending: Vec<Frame>,
    /// Inputs held by the reorder stage (unsorted).
    held: Vec<Input>,
    /// Everything before this was released, s.
    released_until: f64,
    /// Boot count of the array's latest `Hello`.
    boot_count: Option<u32>,
    /// Microphones of the array by its latest `Hello` (before one: the site file's, if given).
    mics: Option<usize>,
    /// `pairs_used` of the array's newest `Doa` frames.
    recent_pairs: RecentPairs,
    /// What a `Hello` that announced a reboot changed, until the next frame tells whether the
    /// board really restarted.
    before_reboot: Option<BeforeReboot>,
}

/// The intake of the arrays of one site.
#[derive(Clone, Debug)]
pub struct Intake {
    site: Site,
    config: IntakeConfig,
    arrays: HashMap<u16, ArrayState>,
    /// Host time of the newest audio accepted from any array, s.
    now: f64,
    stats: IntakeStats,
}

impl Intake {
    /// An intake for `site`.
    pub fn new(site: Site, config: IntakeConfig) -> Self {
        Self {
            site,
            config,
            arrays: HashMap::new(),
            now: f64::NEG_INFINITY,
            stats: IntakeStats::default(),
        }
    }

    /// What it did so far.
    pub fn stats(&self) -> &IntakeStats {
        &self.stats
    }

    /// How far the array's current time base is moved from its clock as the site file maps it,
    /// s (non-zero once the array was placed on the link's time,
    /// [`IntakeStats::aligned_to_link`], and after a reboot); `None` before its first frame.
    pub fn shift_s(&self, array: u16) -> Option<f64> {
        self.arrays.get(&array)?.timeline.map(|t| t.shift_s)
    }

    /// Its tunables.
    pub fn config(&self) -> &IntakeConfig {
        &self.config
    }

    /// Host time of the newest audio accepted, s (−∞ before any): the moment everything
    /// released so far became available.
    pub fn now(&self) -> f64 {
        self.now
    }

    /// Takes one frame, in link order; `sink` gets what it releases.
    pub fn push(
        &mut self,
        frame: &Frame,
        sink: &mut impl FnMut(Released),
    ) -> Result<(), IntakeError> {
        self.stats.frames += 1;
        let id = u16::from(frame.header.array_id);
        let Some(pose) = self.site.array(id) else {
            self.stats.unknown_array += 1;
            return Ok(());
        };
        let state = self.arrays.entry(id).or_insert_with(|| ArrayState {
            rate_hz: self.site.sample_rate_hz,
            released_until: f64::NEG_INFINITY,
            ..ArrayState::default()
        });
        let span = match &frame.body {
            Body::Hello(h) => {
                check_hello(id, h, state, &self.site, pose.mic_positions_m.as_slice())?;
                self.stats.hellos += 1;
                let rebooted = state.boot_count.is_some_and(|b| b != h.boot_count);
                let previous_boot = state.boot_count;
                state.boot_count = Some(h.boot_count);
                state.mics = Some(h.mic_positions_decimm.len()).filter(|&n| n >= 2);
                // A new boot counts from zero again: its Hello's index lies behind the old
                // boot's newest audio.
                let went_back = |old: &Timeline| frame.header.sample_index < old.newest_end;
                if let (true, Some(old)) = (rebooted, state.timeline.filter(went_back)) {
                    let fs = f64::from(state.rate_hz.unwrap_or(DEFAULT_SAMPLE_RATE_HZ));
                    // The old boot's inputs all describe audio up to its last: release them.
                    self.stats.inputs += release(state, id, old.newest_s(pose, fs), sink);
                    let before = BeforeReboot {
                        timeline: old,
                        boot_count: previous_boot,
                        released_until: state.released_until,
                    };
                    self.stats.out_of_window += state.pending.len() as u64;
                    state.pending.clear();
                    self.stats.new_epochs += 1;
                    self.stats.reboots_announced += 1;
                    let first = frame.header.sample_index;
                    state.timeline = Some(old.next_epoch(pose, fs, first, self.config.epoch_gap_s));
                    state.before_reboot = Some(before);
                    // Nothing of the new boot to release yet: its first frame will (releasing
                    // up to the new time base now would tell the tracker no input before it
                    // follows, which a withdrawn reboot's frames would then contradict).
                    return Ok(());
                }
                0
            }
            Body::Doa(d) => d.span_samples,
            Body::Peaks(p) => p.span_samples,
            // A beacon arrival is an instant.
            Body::Beacon(_) => 0,
            Body::Snippet(x) => (x.samples.len() * usize::from(x.decimation)) as u32,
            // Health carries no observation and is stamped at the start of its second-long
            // interval: it takes no part in the time base.
            _ => return Ok(()),
        };
        let fs = f64::from(state.rate_hz.unwrap_or(DEFAULT_SAMPLE_RATE_HZ));
        if f64::from(span) / fs > self.config.max_span_s {
            self.stats.bad_span += 1;
            return Ok(());
        }
        let start = frame.header.sample_index;
        let end = start.saturating_add(u64::from(span));
        let c = &self.config;
        let in_window = |newest_end: u64| {
            let behind = (c.window_behind_s * fs) as u64;
            let ahead = (c.window_ahead_s * fs) as u64;
            end.saturating_add(behind) >= newest_end && end <= newest_end.saturating_add(ahead)
        };
        let mut accepted = Vec::new();
        // After a Hello announced a reboot, a frame that goes on with the old boot's count
        // and not the new one's: the Hello lied (a board does not reboot and keep counting).
        let hello = matches!(frame.body, Body::Hello(_));
        if let (Some(before), false) = (state.before_reboot, hello) {
            let new_fits = state.timeline.is_some_and(|tl| in_window(tl.newest_end));
            // Going on with the old count: ending at or after the old boot's newest audio (a
            // new boot's frames, counted from zero, end before it).
            let goes_on =
                end >= before.timeline.newest_end && in_window(before.timeline.newest_end);
            if !new_fits && goes_on {
                state.timeline = Some(before.timeline);
                state.boot_count = before.boot_count;
                state.released_until = before.released_until;
                self.stats.new_epochs -= 1;
                self.stats.reboots_announced -= 1;
                self.stats.reboots_withdrawn += 1;
            }
            state.before_reboot = None;
        }
        if state.timeline.is_some_and(|tl| in_window(tl.newest_end)) {
            self.stats.out_of_window += state.pending.len() as u64;
            state.pending.clear();
            accepted.push(frame.clone());
        } else {
            let chain_end = state.pending.iter().map(frame_end).max();
            if !chain_end.is_some_and(in_window) {
                self.stats.out_of_window += state.pending.len() as u64;
                state.pending.clear();
            }
            state.pending.push(frame.clone());
            if state.pending.len() >= c.confirm_frames.max(1) {
                let chain = std::mem::take(&mut state.pending);
                let first = chain.iter().map(|f| f.header.sample_index).min().unwrap_or(start);
                let chain_end = chain.iter().map(frame_end).max().unwrap_or(first);
                let earliest_end = chain.iter().map(frame_end).min().unwrap_or(first);
                state.timeline = Some(match state.timeline {
                    // An array's first time base is its own clock (with the site's offset and
                    // drift), unless the other arrays' newest audio, which arrived with it,
                    // is further away than the window: a board started at another time is
                    // placed where the link says it is (to within a frame or two).
                    None => {
                        let own = pose.sample_time(chain_end as f64, fs);
                        let shift_s =
                            if self.now.is_finite() && (own - self.now).abs() > c.align_to_link_s {
                                self.stats.aligned_to_link += 1;
                                self.now - own
                            } else {
                                0.0
                            };
                        Timeline { shift_s, newest_end: first }
                    }
                    // Ahead of the old audio (every frame of the chain ends after it): the
                    // same count went on after frames lost on the link or a silence. Behind it:
                    // the count went back, a reboot.
                    Some(old) if earliest_end > old.newest_end => {
                        self.stats.gaps += 1;
                        Timeline { shift_s: old.shift_s, newest_end: first }
                    }
                    Some(old) => {
                        self.stats.new_epochs += 1;
                        old.next_epoch(pose, fs, first, c.epoch_gap_s)
                    }
                });
                accepted = chain;
            }
        }
        let Some(timeline) = state.timeline.as_mut() else {
            return Ok(());
        };
        for f in &accepted {
            timeline.newest_end = timeline.newest_end.max(frame_end(f));
            let time = |index: f64| pose.sample_time(index, fs) + timeline.shift_s;
            let s = f.header.sample_index as f64;
            let span = f64::from(frame_span(f));
            if span > 0.0 {
                sink(Released::Audio { array_id: id, from_s: time(s), to_s: time(s + span) });
            }
            // An output describes the samples [index, index + span): it is stamped at their
            // middle.
            let mut quality_scale = 1.0;
            if let Body::Doa(d) = &f.body {
                state.recent_pairs.push(d.pairs_used);
                let site_mics = pose.mic_positions_m.len();
                let mics = state.mics.or((site_mics >= 2).then_some(site_mics));
                let working = state.recent_pairs.max().unwrap_or(0);
                quality_scale = working_pairs_scale(mics.map(pair_count), working);
            }
            if let Some(mut input) =
                input_of(id, f.header.sample_index, &f.body, time(s + 0.5 * span), quality_scale)
            {
                // The site's calibration of this array's zenith (crate::zenith).
                if let Input::Bearing(b) = &mut input {
                    b.zenith_rad = pose.zenith_correction.correct(b.zenith_rad);
                }
                if input.t() < state.released_until {
                    self.stats.late += 1;
                } else {
                    state.held.push(input);
                }
            }
        }
        let newest = timeline.newest_s(pose, fs);
        self.now = self.now.max(newest);
        let until = newest - c.reorder_s;
        self.stats.inputs += release(state, id, until, sink);
        Ok(())
    }

    /// Releases everything still held (the end of the stream). Frames outside the window that
    /// were never confirmed are counted and dropped.
    pub fn finish(&mut self, sink: &mut impl FnMut(Released)) {
        let mut ids: Vec<u16> = self.arrays.keys().copied().collect();
        ids.sort_unstable();
        for id in ids {
            let state = self.arrays.get_mut(&id).expect("listed");
            self.stats.out_of_window += state.pending.len() as u64;
            state.pending.clear();
            self.stats.inputs += release(state, id, f64::INFINITY, sink);
        }
    }
}

/// Releases the held inputs stamped at or before `until` in stamp order, then says so;
/// returns how many.
fn release(
    state: &mut ArrayState,
    array_id: u16,
    until: f64,
    sink: &mut impl FnMut(Released),
) -> u64 {
    if until <= state.released_until {
        return 0;
    }
    let (mut out, keep): (Vec<Input>, Vec<Input>) =
        std::mem::take(&mut state.held).into_iter().partition(|i| i.t() <= until);
    state.held = keep;
    out.sort_by(|a, b| a.t().total_cmp(&b.t()));
    let n = out.len() as u64;
    for input in out {
        sink(Released::Input(input));
    }
    state.released_until = until;
    if until.is_finite() {
        sink(Released::Until { array_id, t: until });
    }
    n
}

/// Checks a `Hello` against the site file and the array's earlier `Hello`s; sets the rate.
fn check_hello(
    id: u16,
    hello: &Hello,
    state: &mut ArrayState,
    site: &Site,
    site_mics: &[[f64; 2]],
) -> Result<(), IntakeError> {
    let rate = hello.sample_rate_hz;
    match (site.sample_rate_hz, state.rate_hz) {
        (Some(expected), _) if expected != rate => {
            return Err(IntakeError::SampleRate {
                array: id,
                hello_hz: rate,
                expected: format!("the site file says {expected} Hz"),
            });
        }
        (None, Some(earlier)) if earlier != rate => {
            return Err(IntakeError::SampleRate {
                array: id,
                hello_hz: rate,
                expected: format!("an earlier Hello announced {earlier} Hz"),
            });
        }
        (None, _) if !PLAUSIBLE_RATES_HZ.contains(&rate) => {
            return Err(IntakeError::SampleRate {
                array: id,
                hello_hz: rate,
                expected: format!(
                    "outside {}–{} Hz and the site file gives none",
                    PLAUSIBLE_RATES_HZ.start(),
                    PLAUSIBLE_RATES_HZ.end()
                ),
            });
        }
        _ => state.rate_hz = Some(rate),
    }
    if !site_mics.is_empty() {
        let hello_mics: Vec<[f64; 2]> = (0..hello.mic_positions_decimm.len())
            .filter_map(|i| hello.mic_position_m(i))
            // At the wire's 0.1 mm, as the Hello gave them.
            .map(|p| p.map(crate::site::at_wire_resolution))
            .collect();
        if !crate::site::same_microphones(&hello_mics, site_mics) {
            return Err(IntakeError::Geometry {
                array: id,
                hello: hello_mics,
                site: site_mics.to_vec(),
            });
        }
    }
    Ok(())
}

/// Samples a frame describes (`Doa`, `Peaks`, `Mfcc`, `Snippet`; 0 for the others).
fn frame_span(frame: &Frame) -> u32 {
    match &frame.body {
        Body::Doa(d) => d.span_samples,
        Body::Peaks(p) => p.span_samples,
        Body::Mfcc(m) => m.span_samples,
        Body::Snippet(x) => (x.samples.len() * usize::from(x.decimation)) as u32,
        _ => 0,
    }
}

/// The factor that turns a `Doa` frame's quality (the chip's mean over all `pairs` of the
/// array, times the share the robust fit kept) into the mean over the array's *working* pairs:
/// `pairs / working`, `working` the most pairs that carried weight in any of its last
/// [`crate::status::MIC_HEALTH_WINDOW`] fits ([`RecentPairs`], which the microphone-health
/// flag reads too). A dead microphone leaves its n − 1 pairs without a peak in
/// every frame, which would lower every frame's quality by that share (a third on a 6-mic
/// array) and, below the LoS test's minimum, call every bearing of a working array out of line
/// of sight. A pair that lost its peak in one frame (noise, an obstruction) still counts
/// against that frame: the count is the array's, not the frame's. 1 when every pair works,
/// when no frame counted its pairs (`pairs_used` 0: firmware that does not) or when the pair
/// count is unknown.
fn working_pairs_scale(pairs: Option<usize>, working: u8) -> f64 {
    match pairs {
        Some(n) if working > 0 && usize::from(working) < n => n as f64 / f64::from(working),
        _ => 1.0,
    }
}

/// Index of the sample after the last one a frame describes (its sample index for a frame
/// without a span).
pub(crate) fn frame_end(frame: &Frame) -> u64 {
    frame.header.sample_index.saturating_add(u64::from(frame_span(frame)))
}

/// The tracker input a frame carries, stamped `t`: wire units become radians and linear
/// amplitudes; a `Doa` frame's quality is multiplied by `quality_scale` (at most 1,
/// [`working_pairs_scale`]).
fn input_of(
    array_id: u16,
    sample_index: u64,
    body: &Body,
    t: f64,
    quality_scale: f64,
) -> Option<Input> {
    match body {
        Body::Doa(d) => Some(Input::Bearing(Bearing {
            t,
            array_id,
            azimuth_rad: f64::from(d.azimuth_rad()),
            zenith_rad: f64::from(d.zenith_rad()),
            residual: f64::from(d.residual_samples()),
            quality: (f64::from(d.quality()) * quality_scale).min(1.0),
        })),
        Body::Peaks(p) => Some(Input::Spectrum(Spectrum {
            t,
            array_id,
            peaks: p
                .peaks
                .iter()
                // "No rotor signature": no groups (the chip's detection decision stands).
                .filter(|q| p.is_rotor() && q.freq_hz() > 0.0)
                .map(|q| BpfPeak {
                    hz: f64::from(q.freq_hz()),
                    amplitude: 10f64.powf(f64::from(q.amplitude_db()) / 20.0),
                })
                .collect(),
        })),
        Body::Beacon(b) => Some(Input::Beacon(BeaconHeard {
            t,
            array_id,
            arrival_samples: b.arrival_samples(sample_index),
            quality: f64::from(b.quality) / 255.0,
        })),
        Body::Snippet(x) => Some(Input::Snippet(SnippetHeard {
            t,
            array_id,
            sample_index,
            decimation: u32::from(x.decimation.max(1)),
            values: (0..x.samples.len()).map(|j| x.value(j)).collect(),
        })),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::site::ArrayPose;
    use aim_wire::{Doa, Header, Peak, Peaks};

    /// A 0.5 s Peaks frame with one rotor group at 328.25 Hz (BPF 328.25 Hz, quality 200).
    fn rotor_peaks() -> Peaks {
        let mut peaks = heapless::Vec::new();
        peaks.push(Peak::new(328.25, -20.0, 1.0)).unwrap();
        Peaks {
            span_samples: 8000,
            bpf_chz: 32825,
            peaks,
            detection: aim_wire::Detection::Rotor,
            quality: [200].into_iter().collect(),
        }
    }

    fn collect(intake: &mut Intake, frame: &Frame, out: &mut Vec<Released>) {
        intake.push(frame, &mut |r| out.push(r)).unwrap();
    }

    /// The site's zenith correction (crate::zenith) is applied to every bearing of its array,
    /// and only of its array: here 5° read low at 50–70°, so a frame reading 57.3° (1 rad)
    /// arrives at 62.3°, its azimuth untouched; the other array's frame as sent.
    #[test]
    fn the_sites_zenith_correction_is_applied_to_its_arrays_bearings() {
        let mut pose = ArrayPose::new(3, [0.0; 3], 0.0, 0.0, 0.0);
        pose.zenith_correction =
            crate::zenith::ZenithCorrection::from_degrees(&[[50.0, -5.0], [70.0, -5.0]]).unwrap();
        let other = ArrayPose::new(4, [1.0, 0.0, 0.0], 0.0, 0.0, 0.0);
        let site = Site { arrays: vec![pose, other], room: None, sample_rate_hz: Some(16_000) };
        let mut intake = Intake::new(site, IntakeConfig::default());
        let mut out = Vec::new();
        let doa = Doa { span_samples: 1600, ..Doa::new(0.5, 1.0, 0.25, 0.4) };
        for id in [3u8, 4] {
            for k in 0..3u64 {
                let header = Header { array_id: id, seq: k as u16, sample_index: 1600 * k };
                collect(&mut intake, &Frame { header, body: Body::Doa(doa) }, &mut out);
            }
        }
        intake.finish(&mut |r| out.push(r));
        let sent_zen = f64::from(doa.zenith_rad());
        let sent_az = f64::from(doa.azimuth_rad());
        let mut seen = [0, 0];
        for r in &out {
            if let Released::Input(Input::Bearing(b)) = r {
                let want = if b.array_id == 3 { sent_zen + 5f64.to_radians() } else { sent_zen };
                assert!((b.zenith_rad - want).abs() < 1e-12, "{b:?}");
                assert!((b.azimuth_rad - sent_az).abs() < 1e-12, "{b:?}");
                seen[usize::from(b.array_id == 4)] += 1;
            }
        }
        assert_eq!(seen, [3, 3], "{out:?}");
    }

    /// A dead microphone of a 6-mic array leaves 10 of its 15 pairs with a peak in every frame:
    /// the frames' quality becomes the mean over those 10 (0.4 · 15/10 = 0.6), the array's
    /// count taken from its `Hello`. A frame where one more pair lost its peak (9) keeps that
    /// loss against it (the array still has 10 working pairs); once a frame of all 15 pairs
    /// came, nothing is scaled. No count (0) or no known array: as the chip sent it.
    #[test]
    fn a_doa_frames_quality_is_over_the_arrays_working_pairs() {
        assert!((working_pairs_scale(Some(15), 10) - 1.5).abs() < 1e-12);
        assert_eq!(working_pairs_scale(Some(15), 15), 1.0);
        assert_eq!(working_pairs_scale(Some(15), 0), 1.0);
        assert_eq!(working_pairs_scale(None, 10), 1.0);
        let site = Site {
            arrays: vec![ArrayPose::new(3, [0.0; 3], 0.0, 0.0, 0.0)],
            room: None,
            sample_rate_hz: None,
        };
        let mut intake = Intake::new(site, IntakeConfig::default());
        let mut out = Vec::new();
        let header = |sample_index| Header { array_id: 3, seq: 0, sample_index };
        let six: Vec<[f32; 2]> = (0..6)
            .map(|k| {
                let a = k as f32 * std::f32::consts::FRAC_PI_3;
                [0.0463 * a.cos(), 0.0463 * a.sin()]
            })
            .collect();
        let hello = Hello::new([0, 1, 0], 16_000, 1024, &six);
        collect(&mut intake, &Frame { header: header(0), body: Body::Hello(hello) }, &mut out);
        for (k, used) in [10u8, 10, 9, 10, 15, 10].into_iter().enumerate() {
            let doa = Doa { span_samples: 1600, pairs_used: used, ..Doa::new(0.5, 1.0, 0.25, 0.4) };
            let frame = Frame { header: header(16_000 + 1600 * k as u64), body: Body::Doa(doa) };
            collect(&mut intake, &frame, &mut out);
        }
        intake.finish(&mut |r| out.push(r));
        let q: Vec<f64> = out
            .iter()
            .filter_map(|r| match r {
                Released::Input(Input::Bearing(b)) => Some(b.quality),
                _ => None,
            })
            .collect();
        let sent = f64::from(Doa::new(0.5, 1.0, 0.25, 0.4).quality());
        let want = [1.5 * sent, 1.5 * sent, 1.5 * sent, 1.5 * sent, sent, sent];
        assert_eq!(q.len(), want.len(), "{out:?}");
        for (got, want) in q.iter().zip(want) {
            assert!((got - want).abs() < 1e-12, "{q:?}");
        }
        // No Hello: the site file's microphones count.
        let mut pose = ArrayPose::new(3, [0.0; 3], 0.0, 0.0, 0.0);
        pose.mic_positions_m = six.iter().map(|p| [f64::from(p[0]), f64::from(p[1])]).collect();
        let site = Site { arrays: vec![pose], room: None, sample_rate_hz: None };
        let mut intake = Intake::new(site, IntakeConfig::default());
        let mut out = Vec::new();
        for k in 0..3u64 {
            let doa = Doa { span_samples: 1600, pairs_used: 10, ..Doa::new(0.5, 1.0, 0.25, 0.4) };
            collect(
                &mut intake,
                &Frame { header: header(1600 * k), body: Body::Doa(doa) },
                &mut out,
            );
        }
        intake.finish(&mut |r| out.push(r));
        let scaled = out.iter().all(|r| match r {
            Released::Input(Input::Bearing(b)) => (b.quality - 1.5 * sent).abs() < 1e-12,
            _ => true,
        });
        assert!(scaled && out.iter().any(|r| matches!(r, Released::Input(_))), "{out:?}");
    }

    #[test]
    fn units_times_and_order() {
        let mut pose = ArrayPose::new(3, [0.0; 3], 0.0, 0.0, 0.0);
        pose.clock_offset_s = 1.0;
        let site = Site { arrays: vec![pose], room: None, sample_rate_hz: None };
        let mut intake = Intake::new(site, IntakeConfig::default());
        let mut out = Vec::new();
        let header = |sample_index| Header { array_id: 3, seq: 0, sample_index };
        let hello = Hello::new([0, 1, 0], 16_000, 1024, &[[0.0, 0.0]]);
        collect(&mut intake, &Frame { header: header(0), body: Body::Hello(hello) }, &mut out);
        let doa = |i| Frame {
            header: header(i),
            body: Body::Doa(Doa { span_samples: 1600, ..Doa::new(0.5, 1.0, 0.25, 0.8) }),
        };
        collect(&mut intake, &doa(16_000), &mut out);
        assert!(out.is_empty(), "the first time base waits for three frames that agree");
        // A Peaks frame of 0.5 s ending with the next Doa: stamped before it.
        let p = rotor_peaks();
        collect(&mut intake, &doa(17_600), &mut out);
        collect(&mut intake, &Frame { header: header(11_200), body: Body::Peaks(p) }, &mut out);
        intake.finish(&mut |r| out.push(r));
        let inputs: Vec<&Input> = out
            .iter()
            .filter_map(|r| match r {
                Released::Input(i) => Some(i),
                _ => None,
            })
            .collect();
        assert_eq!(inputs.len(), 3);
        // The Peaks frame (stamped 1 + (11 200 + 4 000) / 16 000 = 1.95 s) comes first,
        // then the Doa frames at 1 + 16 800 / 16 000 = 2.05 s and 2.15 s.
        let Input::Spectrum(s) = inputs[0] else { panic!("{inputs:?}") };
        assert!((s.t - 1.95).abs() < 1e-12, "{}", s.t);
        assert!((s.peaks[0].hz - 328.25).abs() < 1e-4 && (s.peaks[0].amplitude - 0.1).abs() < 1e-6);
        let Input::Bearing(b) = inputs[1] else { panic!("{inputs:?}") };
        assert!((b.t - 2.05).abs() < 1e-12, "{}", b.t);
        assert!((b.azimuth_rad - 0.5).abs() < 2e-4 && (b.zenith_rad - 1.0).abs() < 2e-4);
        assert!((b.residual - 0.25).abs() < 1e-6 && (b.quality - 0.8).abs() < 0.004);
        assert!((inputs[2].t() - 2.15).abs() < 1e-12);
        // Audio spans come with the frames.
        assert!(out.iter().any(|r| matches!(r, Released::Audio { array_id: 3, from_s, to_s }
            if (from_s - 2.0).abs() < 1e-12 && (to_s - 2.1).abs() < 1e-12)));
        let stranger = Frame { header: Header { array_id: 9, ..header(0) }, ..doa(0) };
        collect(&mut intake, &stranger, &mut out);
        assert_eq!(intake.stats().unknown_array, 1);
        assert_eq!(intake.stats().hellos, 1);
    }

    #[test]
    fn a_frame_without_rotor_signature_carries_no_groups() {
        let p = rotor_peaks();
        let Some(Input::Spectrum(s)) = input_of(1, 0, &Body::Peaks(p.clone()), 0.0, 1.0) else {
            panic!()
        };
        assert_eq!(s.peaks.len(), 1);
        let none = Peaks { detection: aim_wire::Detection::NoRotor, ..p.clone() };
        let Some(Input::Spectrum(s)) = input_of(1, 0, &Body::Peaks(none), 0.0, 1.0) else {
            panic!()
        };
        assert!(s.peaks.is_empty(), "no rotor signature carries no groups");
        // An older frame (no decision) with a BPF still counts as a rotor.
        let older =
            Peaks { detection: aim_wire::Detection::Unstated, quality: heapless::Vec::new(), ..p };
        let Some(Input::Spectrum(s)) = input_of(1, 0, &Body::Peaks(older), 0.0, 1.0) else {
            panic!()
        };
        assert_eq!(s.peaks.len(), 1);
    }

    /// A board started 100 s before another (its count 100 s ahead) is placed where the link
    /// says its frames are, next to the other array's; boards within the window keep their
    /// own clocks.
    #[test]
    fn a_board_started_at_another_time_is_placed_by_the_link() {
        let site = Site {
            arrays: vec![
                ArrayPose::new(1, [0.0; 3], 0.0, 0.0, 0.0),
                ArrayPose::new(2, [3.0, 0.0, 0.0], 0.0, 0.0, 0.0),
                ArrayPose::new(3, [6.0, 0.0, 0.0], 0.0, 0.0, 0.0),
            ],
            room: None,
            sample_rate_hz: Some(48_000),
        };
        let mut intake = Intake::new(site, IntakeConfig::default());
        let doa = |array_id, sample_index| Frame {
            header: Header { array_id, seq: 0, sample_index },
            body: Body::Doa(Doa { span_samples: 8192, ..Doa::new(0.5, 1.0, 0.25, 0.8) }),
        };
        let mut bearings: Vec<(u16, f64)> = Vec::new();
        let mut sink = |r: Released| {
            if let Released::Input(Input::Bearing(b)) = r {
                bearings.push((b.array_id, b.t));
            }
        };
        // Link order: the three boards' frames as they end; array 2 counts from 100 s, array 3
        // from 0.5 s (within the window).
        for k in 0..30u64 {
            for (id, from) in [(1u8, 0u64), (2, 4_800_000), (3, 24_000)] {
                intake.push(&doa(id, from + 8192 * k), &mut sink).unwrap();
            }
        }
        intake.finish(&mut sink);
        let last = |id: u16| bearings.iter().filter(|b| b.0 == id).map(|b| b.1).fold(0.0, f64::max);
        assert!((last(2) - last(1)).abs() < 0.5, "{} against {}", last(2), last(1));
        assert!((last(3) - last(1) - 0.5).abs() < 1e-9, "{} against {}", last(3), last(1));
        assert_eq!(intake.stats().aligned_to_link, 1);
        // Array 2's sample 0 was put 100 s before array 1's, as the link places it.
        assert!((intake.shift_s(2).unwrap() + 100.0).abs() < 0.5, "{:?}", intake.shift_s(2));
        assert_eq!((intake.shift_s(1), intake.shift_s(3)), (Some(0.0), Some(0.0)));
        assert_eq!(intake.shift_s(4), None);
    }

    #[test]
    fn a_span_longer_than_allowed_is_set_aside() {
        let site = Site {
            arrays: vec![ArrayPose::new(1, [0.0; 3], 0.0, 0.0, 0.0)],
            room: None,
            sample_rate_hz: Some(48_000),
        };
        let mut intake = Intake::new(site, IntakeConfig::default());
        let frame = Frame {
            header: Header { array_id: 1, seq: 0, sample_index: 0 },
            body: Body::Doa(Doa { span_samples: 96_000, ..Doa::new(0.5, 1.0, 0.25, 0.8) }),
        };
        intake.push(&frame, &mut |_| panic!("released")).unwrap();
        assert_eq!(intake.stats().bad_span, 1);
    }
}
