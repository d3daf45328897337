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
    /// Publish an array's frames from its serial port on the Zenoh bus.
    Gateway(cmd::gateway::Args),
    /// Is a drone in a recording, and which type: train, evaluate, classify.
    Id(cmd::id::Args),
    /// Calibrate the arrays' zenith from a recording against a reference track.
    Calibrate(cmd::calibrate::Args),
}

fn main() -> std::process::ExitCode {
    let result = match Cli::parse().command {
        Command::Record(args) => cmd::record::run(args),
        Command::Frames(args) => cmd::frames::run(args),
        Command::Replay(args) => cmd::replay::run(args),
        Command::Track(args) => cmd::track::run(args),
        Command::Gateway(args) => cmd::gateway::run(args),
        Command::Id(args) => cmd::id::run(args),
        Command::Calibrate(args) => cmd::calibrate::run(args),
    };
    aim_tracker::exit::exit_code(result)
}
