//! How the command-line tools (`aim`, `host-sim`) end: errors are for people.

use std::process::ExitCode;

/// Turns a command's result into its exit status. An error prints as one line on stderr,
/// `error: <message>: <causes>`, without a backtrace, and exits 1. An error caused by writing
/// to a pipe whose reader has gone (`aim replay … | head`) is not a failure: it exits 0.
pub fn exit_code(result: anyhow::Result<()>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) if is_broken_pipe(&error) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
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
}
