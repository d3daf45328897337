//! `host-sim`: the acoustic world simulator's command line.
use clap::{Parser, Subcommand};

mod cmd;

/// AIM acoustic world simulator: simulate flights, run the on-chip DSP on audio, evaluate tracks.
#[derive(Parser)]
#[command(version, about, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a scenario: write one WAV per array, the truth and the site file.
    Simulate(cmd::simulate::Args),
    /// Run the on-chip pipeline on a recording and print its outputs (one line each; JSON with
    /// `--jsonl`).
    Analyze(cmd::analyze::Args),
    /// Simulate, run the pipeline and the tracker, and report the error against the truth.
    Fly(cmd::fly::Args),
    /// Run a suite of scenario families × seeds (both filters, all cores) and tabulate the
    /// errors as mean ± sd over seeds.
    Bench(cmd::bench::Args),
    /// Write a labelled dataset of simulated drone and no-drone recordings for `aim id`.
    IdDataset(cmd::id_dataset::Args),
    /// Score the BPF detector on realistic simulated drones and non-drone sources.
    BpfBench(cmd::bpf_bench::Args),
}

fn main() -> std::process::ExitCode {
    let result = match Cli::parse().command {
        Command::Simulate(args) => cmd::simulate::run(args),
        Command::Analyze(args) => cmd::analyze::run(args),
        Command::Fly(args) => cmd::fly::run(args),
        Command::Bench(args) => cmd::bench::run(args),
        Command::IdDataset(args) => cmd::id_dataset::run(args),
        Command::BpfBench(args) => cmd::bpf_bench::run(args),
    };
    aim_tracker::exit::exit_code(result)
}
