//! Unplugging and replugging the board under `aim record`, `aim frames --serial` and
//! `aim track`, with pseudo-terminals standing in for it: closing the master is the unplug
//! (the port hangs up), a new pty behind the same path (a symlink, as udev's
//! `/dev/serial/by-id/…` names are) is the replug. Linux only (openpty).
#![cfg(target_os = "linux")]

use std::io::{BufRead, BufReader, Read, Write};
use std::os::fd::OwnedFd;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStderr, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use aim_wire::{Body, Doa, Frame, Header, Hello, MAX_ENCODED_LEN};

/// How long any step may take before the test fails (never reached when things work).
const PATIENCE: Duration = Duration::from_secs(30);

/// Doa frames of array 1 from `seq0` on, one per 8192 samples at 48 kHz (0.17 s).
fn doa_frames(seq0: u16, n: u16) -> Vec<u8> {
    let mut out = Vec::new();
    for seq in seq0..seq0 + n {
        let frame = Frame {
            header: Header { array_id: 1, seq, sample_index: u64::from(seq) * 8192 },
            body: Body::Doa(Doa {
                span_samples: 8192,
                pairs_used: 15,
                ..Doa::new(0.8, 1.1, 0.2, 0.9)
            }),
        };
        out.extend(wire(&frame));
    }
    out
}

fn wire(frame: &Frame) -> Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED_LEN];
    let n = aim_wire::encode(frame, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn hello() -> Vec<u8> {
    wire(&Frame {
        header: Header { array_id: 1, seq: 0, sample_index: 0 },
        body: Body::Hello(Hello::new([0, 1, 0], 48_000, 1024, &[[0.0463, 0.0]])),
    })
}

/// Held while a pty is made and while a child is spawned (see [`Board::plug`]).
static SPAWN: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Spawns `command` while no pty is being made.
fn spawn(command: &mut Command) -> Child {
    let _spawning = SPAWN.lock().unwrap_or_else(|e| e.into_inner());
    command.spawn().unwrap()
}

/// The board: a pty pair behind a stable path (a symlink to the slave).
struct Board {
    link: PathBuf,
    master: Option<std::fs::File>,
    slave: Option<OwnedFd>,
}

impl Board {
    fn new(name: &str) -> Self {
        let link = Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("tty-{name}-{}", std::process::id()));
        let mut board = Board { link, master: None, slave: None };
        board.plug();
        board
    }

    fn path(&self) -> &str {
        self.link.to_str().unwrap()
    }

    /// A new pty, and the stable path pointed at its slave (atomically).
    fn plug(&mut self) {
        // openpty's descriptors are inherited by children: a child `aim` of another test
        // holding this master would keep the port from hanging up. Close-on-exec, set before
        // any other test spawns.
        let _spawning = SPAWN.lock().unwrap_or_else(|e| e.into_inner());
        let pair = nix::pty::openpty(None, None).expect("openpty");
        for fd in [&pair.master, &pair.slave] {
            nix::fcntl::fcntl(fd, nix::fcntl::FcntlArg::F_SETFD(nix::fcntl::FdFlag::FD_CLOEXEC))
                .expect("close-on-exec");
        }
        let slave = nix::unistd::ttyname(&pair.slave).expect("ttyname of the pty slave");
        let tmp = self.link.with_extension("new");
        let _ = std::fs::remove_file(&tmp);
        std::os::unix::fs::symlink(&slave, &tmp).unwrap();
        std::fs::rename(&tmp, &self.link).unwrap();
        self.master = Some(std::fs::File::from(pair.master));
        self.slave = Some(pair.slave);
    }

    /// Closes the pty: the reader's port hangs up.
    fn unplug(&mut self) {
        let _ = std::fs::remove_file(&self.link);
        self.master = None;
        self.slave = None;
    }

    /// Whether `child` has the pty's slave open (no "ready" line to wait for otherwise).
    fn held_by(&self, child: &Child) -> bool {
        let Ok(slave) = std::fs::canonicalize(&self.link) else { return false };
        let Ok(fds) = std::fs::read_dir(format!("/proc/{}/fd", child.id())) else { return false };
        fds.flatten().any(|fd| std::fs::read_link(fd.path()).is_ok_and(|p| p == slave))
    }

    fn send(&mut self, bytes: &[u8]) {
        let master = self.master.as_mut().expect("plugged in");
        master.write_all(bytes).unwrap();
        master.flush().unwrap();
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.link);
    }
}

/// Reads the child's stderr line by line on a thread.
fn stderr_lines(stderr: ChildStderr) -> mpsc::Receiver<String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// Waits for a stderr line containing `needle`; returns every line seen until it.
fn wait_for(lines: &mpsc::Receiver<String>, needle: &str) -> Vec<String> {
    let deadline = Instant::now() + PATIENCE;
    let mut seen = Vec::new();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match lines.recv_timeout(left) {
            Ok(line) => {
                let done = line.contains(needle);
                seen.push(line);
                if done {
                    return seen;
                }
            }
            Err(_) => panic!("no stderr line with {needle:?}; saw {seen:?}"),
        }
    }
}

fn wait_until(what: &str, mut ok: impl FnMut() -> bool) {
    let deadline = Instant::now() + PATIENCE;
    while !ok() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn interrupt(child: &Child) {
    let pid = nix::unistd::Pid::from_raw(child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).unwrap();
}

fn wait_exit(child: &mut Child) -> std::process::ExitStatus {
    let deadline = Instant::now() + PATIENCE;
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status;
        }
        if Instant::now() > deadline {
            child.kill().unwrap();
            panic!("the child did not exit");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn record_survives_an_unplug_and_keeps_every_byte() {
    let mut board = Board::new("record");
    let out = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("unplug-{}.aimraw", std::process::id()));
    let mut child = spawn(
        Command::new(env!("CARGO_BIN_EXE_aim"))
            .args(["record", "--serial", board.path(), "--give-up", "60", "--out"])
            .arg(&out)
            .stderr(Stdio::piped()),
    );
    let lines = stderr_lines(child.stderr.take().unwrap());
    wait_for(&lines, "recording ");

    let before = [hello(), doa_frames(1, 40)].concat();
    board.send(&before);
    let file_len = || std::fs::metadata(&out).map_or(0, |m| m.len() as usize);
    wait_until("the first part in the file", || file_len() == before.len());

    board.unplug();
    wait_for(&lines, "serial port lost");
    assert!(child.try_wait().unwrap().is_none(), "aim record ended at the unplug");
    std::thread::sleep(Duration::from_millis(400)); // away a while: reopening fails meanwhile
    board.plug();
    wait_for(&lines, "serial port back");

    let after = doa_frames(41, 40);
    board.send(&after);
    let all = [before.clone(), after.clone()].concat();
    wait_until("the second part in the file", || file_len() == all.len());

    interrupt(&child);
    let status = wait_exit(&mut child);
    let rest: Vec<String> = lines.iter().collect();
    assert_eq!(status.code(), Some(130), "{rest:?}");
    let summary = rest.iter().find(|l| l.starts_with("recorded ")).expect("summary line");
    assert!(
        summary.starts_with(&format!("recorded {} bytes (81 frames, 0 damaged", all.len())),
        "{summary}"
    );
    assert!(summary.contains("lost 1 time"), "{summary}");
    assert_eq!(std::fs::read(&out).unwrap(), all, "every byte before and after");
    let _ = std::fs::remove_file(&out);
}

#[test]
fn without_reconnect_an_unplug_is_exit_3_with_the_summary() {
    let mut board = Board::new("noreconnect");
    let out = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("unplug-nr-{}.aimraw", std::process::id()));
    let mut child = spawn(
        Command::new(env!("CARGO_BIN_EXE_aim"))
            .args(["record", "--serial", board.path(), "--reconnect", "false", "--out"])
            .arg(&out)
            .stderr(Stdio::piped()),
    );
    let lines = stderr_lines(child.stderr.take().unwrap());
    wait_for(&lines, "recording ");
    let sent = doa_frames(0, 10);
    board.send(&sent);
    wait_until("the bytes in the file", || {
        std::fs::metadata(&out).map_or(0, |m| m.len() as usize) == sent.len()
    });
    board.unplug();
    let status = wait_exit(&mut child);
    let said: Vec<String> = lines.iter().collect();
    assert_eq!(status.code(), Some(3), "{said:?}");
    assert!(said
        .iter()
        .any(|l| l.starts_with(&format!("recorded {} bytes (10 frames", sent.len()))));
    assert!(said.iter().any(|l| l.starts_with("error: ") && l.contains("serial port")), "{said:?}");
    assert_eq!(std::fs::read(&out).unwrap(), sent);
    let _ = std::fs::remove_file(&out);
}

#[test]
fn frames_serial_prints_its_statistics_on_ctrl_c() {
    let mut board = Board::new("frames");
    let mut child = spawn(
        Command::new(env!("CARGO_BIN_EXE_aim"))
            .args(["frames", "--serial", board.path()])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    let _lines = stderr_lines(child.stderr.take().unwrap());
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    wait_until("aim frames to open the port", || board.held_by(&child));
    board.send(&doa_frames(0, 5));
    let mut line = String::new();
    for _ in 0..5 {
        line.clear();
        stdout.read_line(&mut line).unwrap();
        assert!(line.contains("\"kind\":\"doa\""), "{line}");
    }
    board.unplug();
    std::thread::sleep(Duration::from_millis(300));
    interrupt(&child);
    let status = wait_exit(&mut child);
    let mut rest = String::new();
    stdout.read_to_string(&mut rest).unwrap();
    assert_eq!(status.code(), Some(130));
    let stats: serde_json::Value = serde_json::from_str(rest.trim()).unwrap();
    assert_eq!(stats["kind"], "stats");
    assert_eq!(stats["frames"], 5);
}

#[test]
fn track_keeps_tracking_after_the_port_comes_back() {
    let mut board = Board::new("track");
    let site = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("unplug-site-{}.toml", std::process::id()));
    std::fs::write(&site, "[[array]]\nid = 1\nposition = [0.0, 0.0, 0.0]\n").unwrap();
    let mut child = spawn(
        Command::new(env!("CARGO_BIN_EXE_aim"))
            .args(["track", "--serial", board.path(), "--site"])
            .arg(&site)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    let lines = stderr_lines(child.stderr.take().unwrap());
    let stdout = child.stdout.take().unwrap();
    let (tx, fixes) = mpsc::channel::<serde_json::Value>();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            let _ = tx.send(serde_json::from_str(&line).expect("a JSON fix"));
        }
    });
    wait_until("aim track to open the port", || board.held_by(&child));
    // 40 bearings, 6.8 s of the array's clock.
    board.send(&[hello(), doa_frames(1, 40)].concat());
    let last_t = |fixes: &mpsc::Receiver<serde_json::Value>, above: f64| {
        let deadline = Instant::now() + PATIENCE;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let fix = fixes.recv_timeout(left).expect("fixes go on");
            let t = fix["t"].as_f64().unwrap();
            assert!(fix["x"].as_f64().unwrap().is_finite());
            if t > above {
                return t;
            }
        }
    };
    last_t(&fixes, 6.0);
    board.unplug();
    wait_for(&lines, "serial port lost");
    board.plug();
    wait_for(&lines, "serial port back");
    // The next 40 bearings: fixes past 7 s appear only if tracking went on.
    board.send(&doa_frames(41, 40));
    let t = last_t(&fixes, 12.0);
    assert!(t > 12.0);
    interrupt(&child);
    let status = wait_exit(&mut child);
    let said: Vec<String> = lines.iter().collect();
    assert_eq!(status.code(), Some(130), "{said:?}");
    let stats = said.iter().find(|l| l.contains("\"kind\":\"stats\"")).expect("stats on stderr");
    assert!(stats.contains("\"frames\":81"), "{stats}");
    let _ = std::fs::remove_file(&site);
}
