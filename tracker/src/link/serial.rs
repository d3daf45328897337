//! Serial ports as every `aim` command opens them, and [`Link`]: a serial port that survives
//! its cable.
//!
//! Raw mode, 8 data bits, no parity, one stop bit, no flow control (the board's USART3 settings;
//! `serialport` sets raw mode on open, so no byte is translated), exclusive access, and a read
//! timeout so that a quiet port lets the caller look at the clock.
//!
//! Unplugging the board (or its USB cable) makes the port's reads fail: a hang-up (`POLLHUP`,
//! which `serialport` reports as `BrokenPipe`), `EIO`, `ENXIO` or an end of file. [`Link`]
//! turns that into a [`PortLost`] error, never a `BrokenPipe` (which the exit status reserves
//! for a closed stdout), or, when reconnecting, says so on stderr and reopens the port by its
//! path until it is back or the give-up time has passed.

use std::io::{self, Read};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use anyhow::Context as _;

use super::source::is_retryable;

/// The board's default uplink rate, baud.
pub const DEFAULT_BAUD: u32 = 921_600;

/// How long one read waits for a byte before it returns a timeout (which readers retry).
pub const READ_TIMEOUT: Duration = Duration::from_millis(100);

/// How often a lost port is tried again.
pub const REOPEN_INTERVAL: Duration = Duration::from_millis(250);

/// Opens the serial port at `path` (`/dev/ttyACM0`, `COM3`, a pseudo-terminal) at `baud`.
pub fn open(path: &str, baud: u32) -> anyhow::Result<Box<dyn serialport::SerialPort>> {
    check_baud(baud)?;
    serialport::new(path, baud)
        .data_bits(serialport::DataBits::Eight)
        .parity(serialport::Parity::None)
        .stop_bits(serialport::StopBits::One)
        .flow_control(serialport::FlowControl::None)
        .timeout(READ_TIMEOUT)
        .open()
        .with_context(|| format!("opening serial port {path} at {baud} baud"))
}

/// Rejects baud rates no UART runs at (0, or beyond 20 Mbaud).
pub fn check_baud(baud: u32) -> anyhow::Result<()> {
    if !(1..=20_000_000).contains(&baud) {
        anyhow::bail!("--baud must be 1 to 20000000, not {baud}");
    }
    Ok(())
}

/// The serial port went away (unplugged, hung up, failed) and did not come back.
#[derive(Debug, thiserror::Error)]
#[error("serial port {port} lost ({cause}){}", gave_up_note(*.gave_up_after))]
pub struct PortLost {
    /// The port's path.
    pub port: String,
    /// What the failed read said.
    pub cause: String,
    /// How long it was tried again before giving up (None: not tried).
    pub gave_up_after: Option<Duration>,
}

fn gave_up_note(after: Option<Duration>) -> String {
    match after {
        Some(d) => format!(", not back after {:.1} s", d.as_secs_f64()),
        None => String::new(),
    }
}

/// Whether an error (anywhere in its chain, also inside an `io::Error`) is a [`PortLost`].
pub fn is_port_lost(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        cause.downcast_ref::<PortLost>().is_some()
            || cause
                .downcast_ref::<io::Error>()
                .and_then(|e| e.get_ref())
                .is_some_and(|inner| inner.downcast_ref::<PortLost>().is_some())
    })
}

/// What [`Link`] does when its port is lost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reconnect {
    /// Reopen the port by its path when it returns.
    pub enabled: bool,
    /// Give up once the port has been away this long.
    pub give_up: Duration,
}

/// Parses a give-up time in seconds from a flag, rejecting non-finite, negative and absurd
/// (beyond 30 days) values.
pub fn give_up_from_secs(seconds: f64, flag: &str) -> anyhow::Result<Duration> {
    if !(seconds.is_finite() && (0.0..=30.0 * 86_400.0).contains(&seconds)) {
        anyhow::bail!("{flag} must be 0 to 2592000 seconds (30 days), not {seconds:?}");
    }
    Ok(Duration::from_secs_f64(seconds))
}

/// The process-wide Ctrl-C / SIGTERM flag. The first call installs the handler; from then on
/// the signals set the flag instead of ending the process, and a [`Link`] given the flag
/// ends its stream (its reads return end of file) so that the command prints its summary.
pub fn interrupt_flag() -> anyhow::Result<Arc<AtomicBool>> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    if let Some(flag) = FLAG.get() {
        return Ok(flag.clone());
    }
    let flag = Arc::new(AtomicBool::new(false));
    let set = flag.clone();
    ctrlc::set_handler(move || set.store(true, Ordering::SeqCst))
        .context("installing the Ctrl-C handler")?;
    Ok(FLAG.get_or_init(|| flag).clone())
}

/// Opens the port a [`Link`] reads (a real port by path; tests give fakes).
pub type Opener = Box<dyn FnMut() -> anyhow::Result<Box<dyn Read + Send>> + Send>;

/// A serial port that survives unplugging: a [`Read`] whose hang-ups become [`PortLost`]
/// errors or, with [`Reconnect::enabled`], a wait (reads time out) until the port is back.
///
/// While the port is away, reads return `TimedOut` every [`REOPEN_INTERVAL`] so that callers
/// keep control (deadlines, Ctrl-C). Once the interrupt flag is set, reads return `Ok(0)`:
/// the stream ends as a file would. Notices (lost, back) go to stderr.
pub struct Link {
    name: String,
    opener: Opener,
    port: Option<Box<dyn Read + Send>>,
    policy: Reconnect,
    stop: Option<Arc<AtomicBool>>,
    lost_at: Option<(Instant, String)>,
    notice: Box<dyn FnMut(&str) + Send>,
    losses: u32,
    interrupted: bool,
}

impl Link {
    /// Opens the serial port at `path` at `baud` (an error if it cannot be opened now).
    pub fn open(path: &str, baud: u32, policy: Reconnect) -> anyhow::Result<Self> {
        let owned = path.to_string();
        let mut opener: Opener =
            Box::new(move || open(&owned, baud).map(|p| -> Box<dyn Read + Send> { Box::new(p) }));
        let port = opener()?;
        Ok(Self::with_opener(path, port, opener, policy))
    }

    /// A link reading `port` now and calling `opener` to reopen it after a loss.
    pub fn with_opener(
        name: &str,
        port: Box<dyn Read + Send>,
        opener: Opener,
        policy: Reconnect,
    ) -> Self {
        Self {
            name: name.to_string(),
            opener,
            port: Some(port),
            policy,
            stop: None,
            lost_at: None,
            notice: Box::new(crate::exit::note),
            losses: 0,
            interrupted: false,
        }
    }

    /// Ends the stream (reads return end of file) once `flag` is set.
    pub fn stop_on(mut self, flag: Arc<AtomicBool>) -> Self {
        self.stop = Some(flag);
        self
    }

    /// Sends the notices (port lost, port back) to `sink` instead of stderr.
    pub fn notices_to(mut self, sink: impl FnMut(&str) + Send + 'static) -> Self {
        self.notice = Box::new(sink);
        self
    }

    /// Whether the stream ended because the interrupt flag was set.
    pub fn interrupted(&self) -> bool {
        self.interrupted
    }

    /// How many times the port was lost so far.
    pub fn losses(&self) -> u32 {
        self.losses
    }

    fn stopped(&mut self) -> bool {
        if self.stop.as_ref().is_some_and(|f| f.load(Ordering::SeqCst)) {
            self.interrupted = true;
        }
        self.interrupted
    }

    /// The port failed with `cause`: drop it, say so, and either fail or start waiting.
    fn lose(&mut self, cause: String) -> io::Result<()> {
        self.port = None;
        self.losses += 1;
        if !self.policy.enabled {
            let msg = format!("{}: serial port lost ({cause})", self.name);
            (self.notice)(&msg);
            return Err(lost_error(PortLost {
                port: self.name.clone(),
                cause,
                gave_up_after: None,
            }));
        }
        let msg = format!(
            "{}: serial port lost ({cause}); waiting up to {:.0} s for it to return",
            self.name,
            self.policy.give_up.as_secs_f64()
        );
        (self.notice)(&msg);
        self.lost_at = Some((Instant::now(), cause));
        Ok(())
    }

    /// One attempt to get the lost port back; `TimedOut` while it is away.
    fn try_reopen(&mut self) -> io::Result<()> {
        let Some((since, cause)) = &self.lost_at else { return Ok(()) };
        let away = since.elapsed();
        if away >= self.policy.give_up {
            let lost = PortLost {
                port: self.name.clone(),
                cause: cause.clone(),
                gave_up_after: Some(away),
            };
            return Err(lost_error(lost));
        }
        match (self.opener)() {
            Ok(port) => {
                let msg = format!(
                    "{}: serial port back after {:.1} s; reading again",
                    self.name,
                    away.as_secs_f64()
                );
                (self.notice)(&msg);
                self.port = Some(port);
                self.lost_at = None;
                Ok(())
            }
            Err(_) => {
                // Sleep in short steps so that Ctrl-C is seen at once.
                let until = Instant::now() + REOPEN_INTERVAL;
                while Instant::now() < until && !self.stopped() {
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(io::Error::new(io::ErrorKind::TimedOut, "serial port away"))
            }
        }
    }
}

fn lost_error(lost: PortLost) -> io::Error {
    // Not `BrokenPipe`: that kind means "stdout's reader went away" to the exit status.
    io::Error::new(io::ErrorKind::NotConnected, lost)
}

/// How a failed read is named in the notices and in [`PortLost`].
fn describe(e: &io::Error) -> String {
    match e.kind() {
        io::ErrorKind::BrokenPipe => "hang-up".to_string(),
        _ => e.to_string(),
    }
}

impl Read for Link {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.stopped() {
            return Ok(0);
        }
        if self.port.is_none() {
            self.try_reopen()?;
            if self.stopped() {
                return Ok(0);
            }
        }
        let Some(port) = self.port.as_mut() else {
            return Err(io::Error::new(io::ErrorKind::TimedOut, "serial port away"));
        };
        match port.read(buf) {
            Ok(0) if buf.is_empty() => Ok(0),
            // A serial port never ends; end of file is a hang-up (a pty whose master closed).
            Ok(0) => {
                self.lose("end of file".into())?;
                Err(io::Error::new(io::ErrorKind::TimedOut, "serial port away"))
            }
            Ok(n) => Ok(n),
            Err(e) if is_retryable(&e) => Err(e),
            Err(e) => {
                self.lose(describe(&e))?;
                Err(io::Error::new(io::ErrorKind::TimedOut, "serial port away"))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    /// A port that delivers `data` then fails with `end`.
    struct Scripted {
        data: Vec<u8>,
        end: io::ErrorKind,
    }

    impl Read for Scripted {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            if self.data.is_empty() {
                return Err(io::Error::from(self.end));
            }
            let n = buf.len().min(self.data.len());
            buf[..n].copy_from_slice(&self.data[..n]);
            self.data.drain(..n);
            Ok(n)
        }
    }

    fn read_all(link: &mut Link, deadline: Duration) -> (Vec<u8>, Option<io::Error>) {
        let mut got = Vec::new();
        let mut buf = [0u8; 64];
        let until = Instant::now() + deadline;
        while Instant::now() < until {
            match link.read(&mut buf) {
                Ok(0) => return (got, None),
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) if is_retryable(&e) => {}
                Err(e) => return (got, Some(e)),
            }
        }
        (got, None)
    }

    #[test]
    fn a_hang_up_without_reconnect_is_port_lost_not_broken_pipe() {
        let port = Box::new(Scripted { data: b"abc".to_vec(), end: io::ErrorKind::BrokenPipe });
        let opener: Opener = Box::new(|| anyhow::bail!("no such port"));
        let notes = Arc::new(Mutex::new(Vec::<String>::new()));
        let sink = notes.clone();
        let policy = Reconnect { enabled: false, give_up: Duration::ZERO };
        let mut link = Link::with_opener("/dev/ttyTEST", port, opener, policy)
            .notices_to(move |l| sink.lock().unwrap().push(l.to_string()));
        let (got, err) = read_all(&mut link, Duration::from_secs(5));
        assert_eq!(got, b"abc");
        let err = err.expect("the loss is an error");
        assert_ne!(err.kind(), io::ErrorKind::BrokenPipe);
        let any = anyhow::Error::new(err).context("reading /dev/ttyTEST");
        assert!(is_port_lost(&any), "{any:#}");
        assert!(notes.lock().unwrap()[0].contains("serial port lost (hang-up)"));
    }

    #[test]
    fn a_lost_port_is_reopened_and_reading_goes_on() {
        let port = Box::new(Scripted { data: b"before".to_vec(), end: io::ErrorKind::BrokenPipe });
        let mut attempts = 0;
        let opener: Opener = Box::new(move || {
            attempts += 1;
            // Back at the third attempt, and only once.
            if attempts != 3 {
                anyhow::bail!("not there");
            }
            let after: Box<dyn Read + Send> =
                Box::new(Scripted { data: b"after".to_vec(), end: io::ErrorKind::Other });
            Ok(after)
        });
        let notes = Arc::new(Mutex::new(Vec::<String>::new()));
        let sink = notes.clone();
        let policy = Reconnect { enabled: true, give_up: Duration::from_millis(1500) };
        let mut link = Link::with_opener("p", port, opener, policy)
            .notices_to(move |l| sink.lock().unwrap().push(l.to_string()));
        let (got, err) = read_all(&mut link, Duration::from_secs(10));
        assert_eq!(got, b"beforeafter");
        // The second port fails too and never returns: the give-up time ends the stream.
        let any = anyhow::Error::new(err.expect("given up"));
        assert!(is_port_lost(&any) && any.to_string().contains("not back after"), "{any}");
        assert_eq!(link.losses(), 2);
        let notes = notes.lock().unwrap();
        assert!(notes[1].contains("serial port back after"), "{notes:?}");
    }

    #[test]
    fn the_interrupt_flag_ends_the_stream_while_the_port_is_away() {
        let port = Box::new(Scripted { data: Vec::new(), end: io::ErrorKind::BrokenPipe });
        let opener: Opener = Box::new(|| anyhow::bail!("away"));
        let flag = Arc::new(AtomicBool::new(false));
        let policy = Reconnect { enabled: true, give_up: Duration::from_secs(3600) };
        let mut link =
            Link::with_opener("p", port, opener, policy).stop_on(flag.clone()).notices_to(|_| {});
        let mut buf = [0u8; 8];
        assert_eq!(link.read(&mut buf).unwrap_err().kind(), io::ErrorKind::TimedOut);
        flag.store(true, Ordering::SeqCst);
        assert_eq!(link.read(&mut buf).unwrap(), 0);
        assert!(link.interrupted());
    }

    #[test]
    fn flags_out_of_range_are_rejected() {
        assert!(check_baud(0).is_err() && check_baud(921_600).is_ok());
        assert!(give_up_from_secs(f64::NAN, "--give-up").is_err());
        assert!(give_up_from_secs(-1.0, "--give-up").is_err());
        assert!(give_up_from_secs(1e300, "--give-up").is_err());
        assert_eq!(give_up_from_secs(2.5, "--give-up").unwrap(), Duration::from_millis(2500));
    }
}
