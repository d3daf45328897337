//! How the command-line tools (`aim`, `host-sim`) end: errors are for people, and the exit
//! status says what happened.
//!
//! | status | meaning |
//! |---|---|
//! | 0 | done: the input ended, the asked duration or frame count was reached, or stdout's reader went away (`aim … \| head`) |
//! | 1 | an error (bad input, a file that cannot be read or written, …), described on stderr |
//! | 2 | bad command line (from the argument parser) |
//! | 3 | the serial port was lost (unplugged) and did not come back; what was read is kept and the summary printed |
//! | 130 | interrupted (Ctrl-C, SIGTERM) after printing the summary |

use std::io::Write as _;
use std::process::ExitCode;

/// Exit status of a lost serial port that did not come back.
pub const PORT_LOST: u8 = 3;
/// Exit status of a run ended by Ctrl-C or SIGTERM (128 + SIGINT, as shells report it).
pub const INTERRUPTED: u8 = 130;

/// A command stopped by Ctrl-C or SIGTERM (after printing its summary).
#[derive(Debug, thiserror::Error)]
#[error("interrupted")]
pub struct Interrupted;

/// Writes one line to stderr, ignoring failure: a closed stderr (`aim … 2>&1 | head -1`)
/// must not panic the way `eprintln!` does.
pub fn note(line: &str) {
    let _ = writeln!(std::io::stderr().lock(), "{line}");
}

/// Turns a command's result into its exit status (see the module table). An error prints as
/// one line on stderr, `error: <message>: <causes>`, without a backtrace.
pub fn exit_code(result: anyhow::Result<()>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) if error.chain().any(|c| c.is::<Interrupted>()) => {
            note("interrupted");
            ExitCode::from(INTERRUPTED)
        }
        Err(error) if crate::link::serial::is_port_lost(&error) => {
            note(&format!("error: {error:#}"));
            ExitCode::from(PORT_LOST)
        }
        Err(error) if is_broken_pipe(&error) => ExitCode::SUCCESS,
        Err(error) => {
            note(&format!("error: {error:#}"));
            ExitCode::FAILURE
        }
    }
}

/// Whether the error comes from writing to a pipe whose reader has gone.
fn is_broken_pipe(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::serial::PortLost;
    use anyhow::Context as _;

    #[test]
    fn a_broken_pipe_under_context_is_success_and_other_errors_fail() {
        let pipe = std::io::Error::from(std::io::ErrorKind::BrokenPipe);
        let result: anyhow::Result<()> = Err(pipe).context("writing to stdout");
        assert_eq!(exit_code(result), ExitCode::SUCCESS);
        let other = std::io::Error::from(std::io::ErrorKind::NotFound);
        let result: anyhow::Result<()> = Err(other).context("opening recording");
        assert_eq!(exit_code(result), ExitCode::FAILURE);
    }

    #[test]
    fn a_lost_port_and_an_interrupt_have_their_own_status() {
        let lost =
            PortLost { port: "/dev/ttyACM0".into(), cause: "hang-up".into(), gave_up_after: None };
        let io = std::io::Error::new(std::io::ErrorKind::NotConnected, lost);
        let result: anyhow::Result<()> = Err(io).context("reading /dev/ttyACM0");
        assert_eq!(exit_code(result), ExitCode::from(PORT_LOST));
        let result: anyhow::Result<()> = Err(Interrupted.into());
        assert_eq!(exit_code(result), ExitCode::from(INTERRUPTED));
    }
}
