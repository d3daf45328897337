//! A synthetic array link for the intake tests: the frames a board would send while a drone
//! hovers and drifts near it, in link order (each output when its span ends, as the firmware
//! sends them), and the site file that goes with them; and `aim replay` of a recording, the
//! oracle of the command-line tests.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

use aim_tracker::observation::angles_of;
use aim_tracker::profile::Profile;
use aim_tracker::site::Site;
use aim_wire::{Body, Doa, Frame, Header, Health, Hello, Peak, Peaks, MAX_ENCODED_LEN};

/// Sample rate of the synthetic array, Hz.
pub const FS: u64 = 48_000;
/// Samples per `Doa` frame (the firmware's 8 blocks of 1024 at 48 kHz).
pub const DOA_SPAN: u64 = 8192;
/// Samples per `Peaks` frame and its hop (the firmware's 0.512 s window every 0.256 s).
pub const PEAKS_SPAN: u64 = 24_576;
/// Hop of `Peaks` frames.
pub const PEAKS_HOP: u64 = 12_288;
/// The array id.
pub const ARRAY: u8 = 1;

/// The site file of the synthetic array.
pub const SITE_TOML: &str =
    "sample_rate_hz = 48000\n\n[[array]]\nid = 1\nposition = [0.0, 0.0, 0.0]\n";

/// The site.
pub fn site() -> Site {
    Site::parse(SITE_TOML, "site.toml".as_ref()).unwrap()
}

/// xorshift64* with Box–Muller.
pub struct Rng(pub u64);
impl Rng {
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal.
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * self.uniform()).cos()
    }
}

/// Where the drone is at `t` seconds of the array's clock: hovering 4 s, then drifting east at
/// 0.5 m/s, turning back every 8 s.
pub fn position(t: f64) -> [f64; 3] {
    let s = (t - 4.0).max(0.0);
    let phase = s % 16.0;
    let x = if phase < 8.0 { 0.5 * phase } else { 0.5 * (16.0 - phase) };
    [2.0 + x, 3.0, 1.8]
}

/// The frames an array sends for samples `[from, to)` of its clock, in link order, numbered
/// from `seq`: a `Hello` at `from` and every 5 s, `Doa` and `Peaks` frames when their spans end,
/// a `Health` frame per 49 152 samples.
pub fn link(from: u64, to: u64, seq: &mut u16, seed: u64) -> Vec<Frame> {
    let hover = Profile::dji_mini_2().hover_bpf_hz();
    let mut rng = Rng(seed | 1);
    // (end, order, frame body, start)
    let mut items: Vec<(u64, u8, Body, u64)> = Vec::new();
    let mut hello = from;
    while hello < to {
        items.push((hello, 0, Body::Hello(Hello::new([0, 1, 0], FS as u32, 1024, &[])), hello));
        hello += 5 * FS;
    }
    let mut start = from;
    while start + DOA_SPAN <= to {
        let t = (start + DOA_SPAN / 2) as f64 / FS as f64;
        let (az, zen) = angles_of(position(t));
        let doa = Doa {
            span_samples: DOA_SPAN as u32,
            pairs_used: 15,
            ..Doa::new(
                (az + 0.01 * rng.normal()) as f32,
                (zen + 0.01 * rng.normal()) as f32,
                0.2,
                0.8,
            )
        };
        items.push((start + DOA_SPAN, 1, Body::Doa(doa), start));
        start += DOA_SPAN;
    }
    let mut start = from;
    while start + PEAKS_SPAN <= to {
        let hz = hover * (1.0 + 2e-4 * rng.normal());
        let peaks = Peaks {
            span_samples: PEAKS_SPAN as u32,
            bpf_chz: (hz * 100.0) as u32,
            peaks: [Peak::new(hz as f32, -20.0, 0.9)].into_iter().collect(),
            detection: aim_wire::Detection::Rotor,
            quality: [230].into_iter().collect(),
        };
        items.push((start + PEAKS_SPAN, 2, Body::Peaks(peaks), start));
        start += PEAKS_HOP;
    }
    let mut start = from;
    while start + 49_152 <= to {
        let health = Health { blocks: 48, ..Health::default() };
        items.push((start + 49_152, 3, Body::Health(health), start));
        start += 49_152;
    }
    items.sort_by_key(|i| (i.0, i.1));
    items
        .into_iter()
        .map(|(_, _, body, sample_index)| {
            let header = Header { array_id: ARRAY, seq: *seq, sample_index };
            *seq = seq.wrapping_add(1);
            Frame { header, body }
        })
        .collect()
}

/// Waits, from `start`, until the audio `frame` describes has been sampled: when a board
/// sends it (the link's real pace).
pub fn wait_until_sent(frame: &Frame, start: std::time::Instant) {
    let end = match &frame.body {
        Body::Doa(d) => frame.header.sample_index + u64::from(d.span_samples),
        Body::Peaks(p) => frame.header.sample_index + u64::from(p.span_samples),
        _ => frame.header.sample_index,
    };
    let due = std::time::Duration::from_secs_f64(end as f64 / FS as f64);
    if let Some(wait) = due.checked_sub(start.elapsed()) {
        std::thread::sleep(wait);
    }
}

/// The frames on the wire.
pub fn bytes(frames: &[Frame]) -> Vec<u8> {
    let mut out = Vec::new();
    for f in frames {
        let mut buf = [0u8; MAX_ENCODED_LEN];
        let n = aim_wire::encode(f, &mut buf).unwrap();
        out.extend_from_slice(&buf[..n]);
    }
    out
}

/// Runs `aim replay RECORDING --site SITE` with `extra` arguments appended, to its end.
pub fn aim_replay_output(recording: &Path, site: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_aim"))
        .arg("replay")
        .arg(recording)
        .arg("--site")
        .arg(site)
        .args(extra)
        .output()
        .unwrap()
}

/// What `aim replay RECORDING --site SITE` prints (its JSON lines); fails the test with the
/// command's stderr if it fails.
pub fn aim_replay(recording: &Path, site: &Path) -> String {
    let replay = aim_replay_output(recording, site, &[]);
    assert!(replay.status.success(), "{}", String::from_utf8_lossy(&replay.stderr));
    String::from_utf8(replay.stdout).unwrap()
}

/// A pseudo-terminal pair standing in for a board: the master to write the board's bytes into,
/// the slave (kept open while the test lives) and its path. Both are close-on-exec copies (std
/// duplicates with `F_DUPFD_CLOEXEC`): a child `aim` must not inherit the master, or closing
/// ours would not hang up its side.
#[cfg(target_os = "linux")]
pub fn pty() -> (std::fs::File, std::os::fd::OwnedFd, std::path::PathBuf) {
    let pair = nix::pty::openpty(None, None).expect("openpty");
    let path = nix::unistd::ttyname(&pair.slave).expect("ttyname of the pty slave");
    let master = std::fs::File::from(pair.master.try_clone().unwrap());
    (master, pair.slave.try_clone().unwrap(), path)
}

/// The first line `who` (a child `aim`) writes on `stderr`, without its newline: commands say
/// there when their ports are open and raw. Read byte by byte, so the rest stays unread;
/// panics if the child exits first.
pub fn first_line(stderr: &mut impl std::io::Read, who: &str) -> String {
    let mut said = Vec::new();
    let mut byte = [0u8; 1];
    while !said.ends_with(b"\n") {
        assert_eq!(stderr.read(&mut byte).unwrap(), 1, "{who} exited early: {said:?}");
        said.push(byte[0]);
    }
    said.pop();
    String::from_utf8_lossy(&said).into_owned()
}
