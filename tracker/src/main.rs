//! `aim`: the host tracker's command line.
use clap::{Parser, Subcommand};

mod cmd;

/// AIM host tracker: reads array frames and prints drone positions.
#[derive(Parser)]
#[command(version, about, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Store the raw byte stream of a serial port in a file.
    Record(cmd::record::Args),
    /// Decode frames from a recording (or `-` for stdin) and print them as JSON lines.
    Frames(cmd::frames::Args),
    /// Track from a recording of frames and print one JSON fix per line.
    Replay(cmd::replay::Args),
    /// Track live from a serial port and print one JSON fix per line.
    Track(cmd::track::Args),
}

fn main() -> std::process::ExitCode {
    let result = match Cli::parse().command {
        Command::Record(args) => cmd::record::run(args),
        Command::Frames(args) => cmd::frames::run(args),
        Command::Replay(args) => cmd::replay::run(args),
        Command::Track(args) => cmd::track::run(args),
    };
    // Errors are for people: the message and its causes, one line, no backtrace.
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // A reader that stopped reading (`aim replay … | head`) is not a failure.
        Err(error) if is_broken_pipe(&error) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            std::process::ExitCode::FAILURE
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
