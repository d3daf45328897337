//! What the operator sees of the arrays while tracking: per array, frames, sequence gaps,
//! restarts, the board's own `Health` counters, the last frame's age, and whether its direction
//! fits look like a microphone has died; the link's CRC and framing errors; frames from arrays
//! the site file does not list (a warning once per array, then counted).
//!
//! [`Status`] watches the frames [`crate::session::Session`] is given (it changes nothing in
//! their path); `aim track` prints [`Status::line`] on stderr every `--status-every` seconds
//! and both `aim track` and `aim replay` put [`Status::to_json`] into their final statistics.
//!
//! The `Health` counters are cumulative since the board started; across a restart (a counter
//! going down) the totals keep what the previous boot had reached, so nothing reported is lost.
//!
//! **Microphone health**, from two kinds of evidence:
//! - *levels* (`Health` frames of firmware that sends [`aim_wire::MicLevels`]): a microphone
//!   whose DC-removed level stays more than [`SILENT_BELOW_LOUDEST_DB`] under the array's
//!   loudest microphone for [`SILENT_INTERVALS`] `Health` intervals in a row is faulty: *stuck*
//!   when its DC level is above [`STUCK_DC_DBFS`] (a constant word the front end's high-pass
//!   removes), *dead* otherwise (silent). This names the microphone.
//! - *direction fits* (any firmware): a `Doa` frame says how many pairs carried weight in the
//!   fit (`pairs_used`). A silent microphone makes every pair it belongs to incoherent, so the
//!   fit loses those n − 1 of the n(n−1)/2 pairs on every frame; [`MicHealth::suspect`] also
//!   flags an array whose recent fits all used at most n(n−1)/2 − (n−1) pairs (host-sim's
//!   `dead_mics` test: 10 of 15 on every fit, a healthy array 15). A microphone stuck at a
//!   constant keeps its pairs (PHAT normalises the constant's leakage into a "signal"), so only
//!   the levels catch it.
use std::collections::BTreeMap;

use aim_wire::{Body, Frame, Health, LinkStats, MicLevels};
use serde_json::{json, Value};

/// Direction fits looked at for the microphone-health flag.
pub const MIC_HEALTH_WINDOW: usize = 32;
/// A microphone this far under the array's loudest one is silent, dB (a working array's
/// microphones hear the same sound within a few dB).
pub const SILENT_BELOW_LOUDEST_DB: f32 = 30.0;
/// `Health` intervals (about 1 s each) a microphone must be silent in a row to be flagged.
pub const SILENT_INTERVALS: u32 = 3;
/// A silent microphone with a DC level above this is stuck at a constant, not dead, dBFS.
pub const STUCK_DC_DBFS: f32 = -60.0;

/// What is wrong with a microphone, as its levels show it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MicFault {
    /// No signal and no DC: disconnected, unpowered or broken.
    Dead,
    /// A constant word: no signal but a DC level.
    Stuck,
}

impl MicFault {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            MicFault::Dead => "dead",
            MicFault::Stuck => "stuck",
        }
    }
}

/// The `Health` counters that count since the board started, summed over its boots.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BoardCounters {
    /// Audio DMA ring overruns.
    pub ring_overruns: u64,
    /// SAI FIFO overruns.
    pub sai_overruns: u64,
    /// Capture chunks dropped because the DSP was late (overloads).
    pub dsp_overloads: u64,
    /// Frames the board dropped because its uplink queue was full.
    pub uplink_drops: u64,
    /// Uplink UART transmit errors.
    pub uart_errors: u64,
    /// Gaps in the sample clock handed to the DSP.
    pub sample_gaps: u64,
    /// Audio frames lost in those gaps.
    pub frames_lost: u64,
}

impl BoardCounters {
    fn of(h: &Health) -> Self {
        Self {
            ring_overruns: h.dma_overruns.into(),
            sai_overruns: h.sai_overruns.into(),
            dsp_overloads: h.dsp_overloads.into(),
            uplink_drops: h.dropped_frames.into(),
            uart_errors: h.uart_errors.into(),
            sample_gaps: h.gaps.into(),
            frames_lost: h.frames_lost.into(),
        }
    }

    fn fields(&self) -> [u64; 7] {
        [
            self.ring_overruns,
            self.sai_overruns,
            self.dsp_overloads,
            self.uplink_drops,
            self.uart_errors,
            self.sample_gaps,
            self.frames_lost,
        ]
    }

    fn from_fields(f: [u64; 7]) -> Self {
        Self {
            ring_overruns: f[0],
            sai_overruns: f[1],
            dsp_overloads: f[2],
            uplink_drops: f[3],
            uart_errors: f[4],
            sample_gaps: f[5],
            frames_lost: f[6],
        }
    }
}

/// Microphone pairs of an array of `mics` microphones: n(n − 1)/2.
pub fn pair_count(mics: usize) -> usize {
    mics * mics.saturating_sub(1) / 2
}

/// `pairs_used` of an array's newest direction fits (`Doa` frames), oldest first, at most
/// [`MIC_HEALTH_WINDOW`]: the microphone-health flag reads them, and the intake takes their
/// largest as the array's working pairs.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RecentPairs(std::collections::VecDeque<u8>);

impl RecentPairs {
    /// Adds the newest fit's `pairs_used`, forgetting the oldest beyond the window.
    pub fn push(&mut self, pairs_used: u8) {
        if self.0.len() == MIC_HEALTH_WINDOW {
            self.0.pop_front();
        }
        self.0.push_back(pairs_used);
    }

    /// Most pairs any of the fits used (None before any fit).
    pub fn max(&self) -> Option<u8> {
        self.0.iter().copied().max()
    }

    /// Whether the window holds [`MIC_HEALTH_WINDOW`] fits.
    pub fn is_full(&self) -> bool {
        self.0.len() == MIC_HEALTH_WINDOW
    }
}

/// The microphone-health evidence of one array (see the module docs).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MicHealth {
    /// Microphones of the array (from the site file).
    pub mics: usize,
    /// `pairs_used` of the newest direction fits.
    recent_pairs: RecentPairs,
    /// Per microphone (slot order): `Health` intervals in a row it was silent in, and its
    /// newest DC level, dBFS.
    silent: Vec<(u32, i16)>,
}

impl MicHealth {
    /// Pairs of the array.
    pub fn pairs(&self) -> usize {
        pair_count(self.mics)
    }

    fn push(&mut self, pairs_used: u8) {
        self.recent_pairs.push(pairs_used);
    }

    fn push_levels(&mut self, levels: &MicLevels) {
        let n = usize::from(levels.count).min(levels.rms_ddbfs.len());
        if n < 2 {
            return;
        }
        self.silent.resize(n, (0, 0));
        let loudest = levels.rms_ddbfs[..n].iter().copied().max().unwrap_or(i16::MIN);
        for (i, s) in self.silent.iter_mut().enumerate() {
            let under_db = (f32::from(loudest) - f32::from(levels.rms_ddbfs[i])) / 10.0;
            *s = if under_db > SILENT_BELOW_LOUDEST_DB {
                (s.0.saturating_add(1), levels.dc_ddbfs[i])
            } else {
                (0, levels.dc_ddbfs[i])
            };
        }
    }

    /// Microphones (slot indices) their levels show faulty, with the fault.
    pub fn faults(&self) -> Vec<(usize, MicFault)> {
        self.silent
            .iter()
            .enumerate()
            .filter(|(_, s)| s.0 >= SILENT_INTERVALS)
            .map(|(i, s)| {
                let stuck = f32::from(s.1) / 10.0 > STUCK_DC_DBFS;
                (i, if stuck { MicFault::Stuck } else { MicFault::Dead })
            })
            .collect()
    }

    /// Most pairs any of the recent fits used (None before any fit).
    pub fn recent_max_pairs(&self) -> Option<u8> {
        self.recent_pairs.max()
    }

    /// Whether a microphone looks dead or stuck: a full window of fits, none of which used
    /// more than the pairs left without one microphone (arrays of 3 or more microphones).
    pub fn suspect(&self) -> bool {
        let n = self.mics;
        n >= 3
            && self.recent_pairs.is_full()
            && self.recent_max_pairs().is_some_and(|m| usize::from(m) <= self.pairs() - (n - 1))
    }

    /// Whether anything points at a faulty microphone: its levels, or the direction fits.
    pub fn flagged(&self) -> bool {
        self.suspect() || !self.faults().is_empty()
    }

    /// The faulty microphones as text (`"mic 2 dead, mic 4 stuck"`), or the fits' evidence.
    pub fn describe(&self) -> String {
        let faults = self.faults();
        if faults.is_empty() {
            return format!(
                "its last {MIC_HEALTH_WINDOW} direction fits used at most {} of its {} \
                 microphone pairs: a microphone looks dead or stuck (these frames do not say \
                 which one)",
                self.recent_max_pairs().unwrap_or(0),
                self.pairs()
            );
        }
        let list: Vec<String> =
            faults.iter().map(|(i, f)| format!("microphone {i} {}", f.name())).collect();
        format!(
            "{} (more than {SILENT_BELOW_LOUDEST_DB} dB under the loudest microphone for \
             {SILENT_INTERVALS} s or more)",
            list.join(", ")
        )
    }
}

/// What is known of one array of the site.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ArrayStatus {
    /// Frames received.
    pub frames: u64,
    /// Times its sequence number jumped forward by more than one.
    pub seq_gaps: u64,
    /// Frames missing according to those jumps.
    pub frames_missed: u64,
    /// Times its sequence number went back or repeated (restarts, most likely).
    pub seq_resets: u64,
    /// `Hello` frames announcing a boot count other than the previous one (announced reboots).
    pub reboots: u64,
    /// Samples at full scale, summed over its `Health` intervals.
    pub clipped_samples: u64,
    /// Largest peak level of the newest `Health`, dBFS.
    pub peak_dbfs: Option<f64>,
    /// Its boards' loss counters, over every boot.
    pub board: BoardCounters,
    /// Counters of the boots before the current one.
    earlier_boots: BoardCounters,
    /// The current boot's counters as last reported.
    current_boot: BoardCounters,
    last_seq: Option<u16>,
    last_boot: Option<u32>,
    /// When its newest frame arrived, s on the caller's clock.
    pub last_frame_at_s: Option<f64>,
    /// Microphone-health evidence.
    pub mic: MicHealth,
}

impl ArrayStatus {
    fn observe(&mut self, frame: &Frame, now_s: f64) {
        self.frames += 1;
        self.last_frame_at_s = Some(now_s);
        let seq = frame.header.seq;
        if let Some(last) = self.last_seq {
            match seq.wrapping_sub(last) {
                1 => {}
                d @ 2..0x8000 => {
                    self.seq_gaps += 1;
                    self.frames_missed += u64::from(d - 1);
                }
                _ => self.seq_resets += 1,
            }
        }
        self.last_seq = Some(seq);
        match &frame.body {
            Body::Hello(h) if h.boot_count != 0 => {
                if self.last_boot.is_some_and(|b| b != h.boot_count) {
                    self.reboots += 1;
                }
                self.last_boot = Some(h.boot_count);
            }
            Body::Health(h) => {
                let now = BoardCounters::of(h);
                // A counter that went down: the board restarted; keep what the old boot had.
                let restarted =
                    now.fields().iter().zip(self.current_boot.fields()).any(|(n, c)| *n < c);
                if restarted {
                    let sum = self.earlier_boots.fields();
                    let cur = self.current_boot.fields();
                    self.earlier_boots =
                        BoardCounters::from_fields(std::array::from_fn(|i| sum[i] + cur[i]));
                }
                self.current_boot = now;
                let (e, c) = (self.earlier_boots.fields(), now.fields());
                self.board = BoardCounters::from_fields(std::array::from_fn(|i| e[i] + c[i]));
                self.clipped_samples += u64::from(h.clipped_samples);
                self.peak_dbfs = Some(f64::from(h.peak_ddbfs) / 10.0);
                self.mic.push_levels(&h.mic_levels);
            }
            Body::Doa(d) => self.mic.push(d.pairs_used),
            _ => {}
        }
    }

    /// As JSON (`now_s`: the caller's clock, for the last frame's age; None leaves it out).
    pub fn to_json(&self, now_s: Option<f64>) -> Value {
        let b = &self.board;
        let mut v = json!({
            "frames": self.frames,
            "seq_gaps": self.seq_gaps,
            "frames_missed": self.frames_missed,
            "seq_resets": self.seq_resets,
            "reboots": self.reboots,
            "ring_overruns": b.ring_overruns,
            "sai_overruns": b.sai_overruns,
            "dsp_overloads": b.dsp_overloads,
            "uplink_drops": b.uplink_drops,
            "uart_errors": b.uart_errors,
            "sample_gaps": b.sample_gaps,
            "frames_lost": b.frames_lost,
            "clipped_samples": self.clipped_samples,
            "mic_suspect": self.mic.flagged(),
            "mic_faults": self.mic.faults().iter().map(|(i, f)| json!({"mic": i, "fault": f.name()})).collect::<Vec<_>>(),
        });
        if let (Some(now), Some(at)) = (now_s, self.last_frame_at_s) {
            v["last_frame_age_s"] = json!(((now - at).max(0.0) * 10.0).round() / 10.0);
        }
        if let Some(m) = self.mic.recent_max_pairs() {
            v["pairs_used_max"] = json!(m);
            v["pairs"] = json!(self.mic.pairs());
        }
        v
    }
}

/// The arrays' and the link's state, as [`crate::session::Session`] sees it.
#[derive(Clone, Debug, Default)]
pub struct Status {
    arrays: BTreeMap<u16, ArrayStatus>,
    /// Frames per array id that the site file does not list.
    unknown: BTreeMap<u16, u64>,
    link: LinkStats,
    /// Warnings not yet handed out.
    warnings: Vec<String>,
    /// Arrays already flagged for a microphone.
    mic_warned: Vec<u16>,
}

impl Status {
    /// The status of the site's arrays: `(id, microphones)`.
    pub fn new(arrays: impl IntoIterator<Item = (u16, usize)>) -> Self {
        let arrays = arrays
            .into_iter()
            .map(|(id, mics)| {
                let mic = MicHealth { mics, ..MicHealth::default() };
                (id, ArrayStatus { mic, ..ArrayStatus::default() })
            })
            .collect();
        Self { arrays, ..Self::default() }
    }

    /// One frame as it arrives, at `now_s` on the caller's clock.
    pub fn observe(&mut self, frame: &Frame, now_s: f64) {
        let id = u16::from(frame.header.array_id);
        match self.arrays.get_mut(&id) {
            Some(a) => {
                a.observe(frame, now_s);
                if a.mic.flagged() && !self.mic_warned.contains(&id) {
                    self.mic_warned.push(id);
                    self.warnings.push(format!("array {id}: {}", a.mic.describe()));
                }
            }
            None => {
                let n = self.unknown.entry(id).or_insert(0);
                if *n == 0 {
                    self.warnings.push(format!(
                        "frames from array {id}, which the site file does not list: ignored \
                         (counted as unknown_array in the statistics)"
                    ));
                }
                *n += 1;
            }
        }
    }

    /// The link's counters now.
    pub fn set_link(&mut self, link: &LinkStats) {
        self.link = *link;
    }

    /// Warnings raised since the last call (each once: an unknown array, a microphone).
    pub fn take_warnings(&mut self) -> Vec<String> {
        std::mem::take(&mut self.warnings)
    }

    /// One array's state.
    pub fn array(&self, id: u16) -> Option<&ArrayStatus> {
        self.arrays.get(&id)
    }

    /// Frames of arrays the site file does not list, per id.
    pub fn unknown(&self) -> &BTreeMap<u16, u64> {
        &self.unknown
    }

    /// The one-line status of `aim track` at `now_s` (the caller's clock; `elapsed_s` since the
    /// start, for the line's lead).
    pub fn line(&self, now_s: f64, elapsed_s: f64) -> String {
        let mut s = format!("status {elapsed_s:.0} s:");
        for (id, a) in &self.arrays {
            let b = &a.board;
            let age = match a.last_frame_at_s {
                Some(at) => format!("last frame {:.1} s ago", (now_s - at).max(0.0)),
                None => "no frame yet".into(),
            };
            s += &format!(
                " | array {id}: {} frames, {} gaps ({} missed), {} resets, {} reboots, \
                 ring {} sai {} dsp {} uplink-drops {} uart {} clipped {}, {age}",
                a.frames,
                a.seq_gaps,
                a.frames_missed,
                a.seq_resets,
                a.reboots,
                b.ring_overruns,
                b.sai_overruns,
                b.dsp_overloads,
                b.uplink_drops,
                b.uart_errors,
                a.clipped_samples,
            );
            let faults = a.mic.faults();
            if !faults.is_empty() {
                for (i, f) in faults {
                    s += &format!(", MICROPHONE {i} {}", f.name().to_uppercase());
                }
            } else if a.mic.suspect() {
                s += ", MICROPHONE DEAD OR STUCK?";
            }
        }
        s += &format!(
            " | link: {} crc errors, {} framing errors",
            self.link.crc_errors, self.link.framing_errors
        );
        for (id, n) in &self.unknown {
            s += &format!(" | unknown array {id}: {n} frames");
        }
        s
    }

    /// Per array as JSON (`{"1": {...}}`), the unknown arrays' frame counts, for the final
    /// statistics (`now_s`: for the last frame's age, or None).
    pub fn to_json(&self, now_s: Option<f64>) -> Value {
        let arrays: serde_json::Map<String, Value> =
            self.arrays.iter().map(|(id, a)| (id.to_string(), a.to_json(now_s))).collect();
        let unknown: serde_json::Map<String, Value> =
            self.unknown.iter().map(|(id, n)| (id.to_string(), json!(n))).collect();
        json!({ "arrays": arrays, "unknown_arrays": unknown })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aim_wire::{Doa, Header, Hello};

    fn frame(id: u8, seq: u16, body: Body) -> Frame {
        Frame { header: Header { array_id: id, seq, sample_index: 0 }, body }
    }

    fn health(dma: u32, dsp: u32, drops: u32, clipped: u32) -> Body {
        Body::Health(Health {
            dma_overruns: dma,
            dsp_overloads: dsp,
            dropped_frames: drops,
            clipped_samples: clipped,
            peak_ddbfs: -31,
            ..Health::default()
        })
    }

    #[test]
    fn gaps_resets_reboots_and_board_counters_over_a_restart() {
        let mut s = Status::new([(1, 6)]);
        let hello = |boot| Body::Hello(Hello { boot_count: boot, ..Hello::default() });
        s.observe(&frame(1, 10, hello(1)), 0.0);
        s.observe(&frame(1, 11, health(2, 1, 0, 5)), 1.0);
        s.observe(&frame(1, 15, health(3, 1, 4, 0)), 2.0); // 3 frames lost
                                                           // The board restarts: sequence and counters from the start, a new boot count.
        s.observe(&frame(1, 0, hello(2)), 3.0);
        s.observe(&frame(1, 1, health(1, 0, 0, 7)), 4.0);
        let a = s.array(1).unwrap();
        assert_eq!((a.frames, a.seq_gaps, a.frames_missed, a.seq_resets), (5, 1, 3, 1));
        assert_eq!(a.reboots, 1);
        assert_eq!(a.clipped_samples, 12);
        // The first boot reached 3 ring overruns, 1 overload, 4 drops; the second 1, 0, 0.
        let b = a.board;
        assert_eq!((b.ring_overruns, b.dsp_overloads, b.uplink_drops), (4, 1, 4));
        let line = s.line(6.5, 6.5);
        assert!(
            line.contains("array 1: 5 frames, 1 gaps (3 missed), 1 resets, 1 reboots"),
            "{line}"
        );
        assert!(line.contains("ring 4 sai 0 dsp 1 uplink-drops 4 uart 0 clipped 12"), "{line}");
        assert!(line.contains("last frame 2.5 s ago"), "{line}");
        let j = s.to_json(Some(6.5));
        assert_eq!(j["arrays"]["1"]["uplink_drops"], 4);
        assert_eq!(j["arrays"]["1"]["last_frame_age_s"], 2.5);
        assert!(s.take_warnings().is_empty());
    }

    #[test]
    fn an_unknown_array_is_warned_once_then_counted() {
        let mut s = Status::new([(1, 6)]);
        for k in 0..3 {
            s.observe(&frame(7, k, health(0, 0, 0, 0)), 0.0);
        }
        let w = s.take_warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("array 7") && w[0].contains("does not list"), "{}", w[0]);
        assert_eq!(s.unknown()[&7], 3);
        assert!(s.line(0.0, 0.0).contains("unknown array 7: 3 frames"));
        assert_eq!(s.to_json(None)["unknown_arrays"]["7"], 3);
        assert!(s.take_warnings().is_empty());
    }

    /// Fits that lose every pair of one microphone (10 of 15 for six) raise the flag once a
    /// window is full; a healthy array (15 of 15 now and then) never does.
    #[test]
    fn a_microphone_missing_from_every_fit_is_flagged() {
        let doa = |pairs| Body::Doa(Doa { pairs_used: pairs, ..Doa::new(0.0, 0.5, 0.1, 0.9) });
        let mut dead = Status::new([(1, 6)]);
        let mut healthy = Status::new([(2, 6)]);
        for k in 0..(2 * MIC_HEALTH_WINDOW as u16) {
            dead.observe(&frame(1, k, doa(if k % 3 == 0 { 9 } else { 10 })), 0.0);
            healthy.observe(&frame(2, k, doa(if k % 5 == 0 { 15 } else { 12 })), 0.0);
            if k + 1 < MIC_HEALTH_WINDOW as u16 {
                assert!(!dead.array(1).unwrap().mic.suspect());
            }
        }
        assert!(dead.array(1).unwrap().mic.suspect());
        let w = dead.take_warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("at most 10 of its 15"), "{}", w[0]);
        assert!(!healthy.array(2).unwrap().mic.suspect());
        assert!(healthy.take_warnings().is_empty());
        assert!(dead.line(0.0, 0.0).contains("MICROPHONE DEAD OR STUCK?"));
    }
}
