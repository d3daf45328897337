//! Child processes for the multi-process tests: readiness lines on stderr, stdout lines, and
//! timeouts that fail with what the process said.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

/// How long any one wait of these tests may take before it fails (a loaded CI machine builds
/// while it tests; nothing here is a speed assertion).
pub const PATIENCE: Duration = Duration::from_secs(120);

/// A running `aim` (or other) process with its output read by threads.
pub struct Proc {
    pub name: String,
    pub child: Child,
    pub stderr: Receiver<String>,
    pub stdout: Receiver<String>,
    /// Every stderr line seen so far (for failure messages).
    pub said: Vec<String>,
}

fn lines(r: impl std::io::Read + Send + 'static) -> Receiver<String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(r).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

impl Proc {
    /// Starts `command` with piped stdout and stderr.
    pub fn spawn(name: &str, command: &mut Command) -> Proc {
        let mut child = command
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("starting {name}: {e}"));
        let stderr = lines(child.stderr.take().unwrap());
        let stdout = lines(child.stdout.take().unwrap());
        Proc { name: name.into(), child, stderr, stdout, said: Vec::new() }
    }

    /// Waits for a stderr line starting with `prefix`; returns it. Fails if the process ends
    /// first or [`PATIENCE`] passes.
    pub fn wait_for(&mut self, prefix: &str) -> String {
        self.wait_until(&format!("{prefix:?}"), |line| line.starts_with(prefix))
    }

    /// Waits for a stderr line for which `is_it` holds (`what` names it in the failure);
    /// returns it. Fails if the process ends first or [`PATIENCE`] passes.
    pub fn wait_until(&mut self, what: &str, is_it: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + PATIENCE;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.stderr.recv_timeout(left) {
                Ok(line) => {
                    self.said.push(line.clone());
                    if is_it(&line) {
                        return line;
                    }
                }
                Err(e) => panic!(
                    "{} never said {what} ({e:?}); it said:\n{}",
                    self.name,
                    self.said.join("\n")
                ),
            }
        }
    }

    /// Sends SIGTERM (the Ctrl-C path of every `aim` command).
    pub fn terminate(&self) {
        let pid = nix::unistd::Pid::from_raw(self.child.id() as i32);
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).unwrap();
    }

    /// Waits for the process to end; returns its exit code and the rest of its stderr. Fails
    /// (killing it) after [`PATIENCE`].
    pub fn finish(&mut self) -> (Option<i32>, String) {
        let deadline = Instant::now() + PATIENCE;
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                let rest: Vec<String> = self.stderr.iter().collect();
                self.said.extend(rest);
                return (status.code(), self.said.join("\n"));
            }
            if Instant::now() > deadline {
                let _ = self.child.kill();
                panic!("{} did not end; it said:\n{}", self.name, self.said.join("\n"));
            }
            // Collect what it says meanwhile (and poll its end every 50 ms).
            if let Ok(line) = self.stderr.recv_timeout(Duration::from_millis(50)) {
                self.said.push(line);
            }
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        // A failed test leaves no process behind.
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// A free TCP port on 127.0.0.1 (bound, then released for a child to listen on).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}
