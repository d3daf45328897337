//! Project automation, run as `cargo xtask <command>` (the alias lives in `.cargo/config.toml`).
//!
//! - `cargo xtask budget`: builds the firmware for the board, measures flash and static RAM
//!   from its ELF, and checks every budget in `budget.toml`, one line each:
//!   `budget: <name> <measured> <limit> <unit> ok|OVER`. Exits non-zero on any OVER.
//! - `cargo xtask qemu`: on QEMU's Cortex-M4F model (`tests/qemu`), checks that the DSP's
//!   output equals the host's bit for bit and prints the instructions of every DSP stage.
//! - `cargo xtask boot`: builds the board images (firmware and HIL binaries), checks that each can
//!   start (ELF layout, emulated start from reset to `main` on the STM32H743 memory map).
//! - `cargo xtask ci`: everything `.ci/run` checks once the tools are installed.
use std::{
    path::{Path, PathBuf},
    process::{Command, ExitCode},
};

use anyhow::{bail, Context, Result};

mod boot;
mod budget;
mod elf_size;
mod image_layout;
mod instructions;
mod qemu;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("boot") => boot::run(&workspace_root(), &args[1..]),
        Some("budget") => budget::run(&workspace_root()),
        Some("ci") => ci(&workspace_root()),
        Some("qemu") => qemu::run_all(&workspace_root()),
        Some("help" | "--help" | "-h") | None => {
            print!("{USAGE}");
            Ok(())
        }
        Some(other) => Err(anyhow::anyhow!("unknown command `{other}`\n\n{USAGE}")),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}

const USAGE: &str = "\
usage: cargo xtask <command>

commands:
  boot     build the board images; check their layout and emulate their start to main
           (`boot ELF...`: check those images instead, without building)
  budget   build the firmware and check flash, RAM and instruction budgets (budget.toml)
  qemu     QEMU Cortex-M4F: host/target bit parity, instructions per DSP stage
  ci       run every check of .ci/run (tests, fmt, clippy, firmware build, budgets)
";

/// The workspace root: the parent of this crate's folder.
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("xtask lives in the workspace").into()
}

/// Runs `cargo` with `args` in `dir`, echoing the command; fails if it fails.
pub(crate) fn cargo(dir: &Path, args: &[&str]) -> Result<()> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    eprintln!("$ cargo {}", args.join(" "));
    let status = Command::new(&cargo)
        .args(args)
        .current_dir(dir)
        .status()
        .with_context(|| format!("running cargo {}", args.join(" ")))?;
    if !status.success() {
        bail!("`cargo {}` failed ({status})", args.join(" "));
    }
    Ok(())
}

/// Runs cargo with clippy as the workspace crates' compiler (`clippy-driver` as
/// `RUSTC_WORKSPACE_WRAPPER`, lints denied as `cargo clippy -- -D warnings` denies them): each
/// workspace crate is linted and built in one pass, and the dependencies are built once, not
/// also checked as `cargo clippy` would. For the Zenoh bus's ~220 crates that check alone
/// took 5 min 55 s of a cold CI on 2 cores (BENCHMARKS.md, "CI time").
fn cargo_linted(dir: &Path, args: &[&str]) -> Result<()> {
    let out = Command::new("rustc")
        .args(["--print", "sysroot"])
        .current_dir(dir)
        .output()
        .context("running rustc --print sysroot")?;
    let sysroot = String::from_utf8(out.stdout).context("rustc's sysroot is not UTF-8")?;
    let driver = Path::new(sysroot.trim()).join("bin").join("clippy-driver");
    if !driver.is_file() {
        bail!("{} is missing: `rustup component add clippy`", driver.display());
    }
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    eprintln!(
        "$ RUSTC_WORKSPACE_WRAPPER=clippy-driver cargo {} (lints: -D warnings)",
        args.join(" ")
    );
    // The lint flags as cargo-clippy hands them to clippy-driver.
    let status = Command::new(&cargo)
        .args(args)
        .current_dir(dir)
        .env("RUSTC_WORKSPACE_WRAPPER", &driver)
        .env("CLIPPY_ARGS", "-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__")
        .status()
        .with_context(|| format!("running cargo {}", args.join(" ")))?;
    if !status.success() {
        bail!("`cargo {}` (linted by clippy) failed ({status})", args.join(" "));
    }
    Ok(())
}

/// The checks of `.ci/run`, in order, stopping at the first failure.
fn ci(root: &Path) -> Result<()> {
    let mut laps = Laps::new();
    // The README's test command.
    cargo(root, &["test"])?;
    laps.lap("cargo test");
    cargo(root, &["fmt", "--all", "--check"])?;
    cargo(root, &["clippy", "--all-targets", "--", "-D", "warnings"])?;
    laps.lap("fmt and clippy");
    // The Zenoh bus (tracker feature `zenoh`, off by default): lint it while building its
    // test, then run its multi-process test (gateway, tracker, recorder and a subscriber on
    // localhost) and its key and endpoint rules.
    let zenoh = ["-p", "aim-tracker", "--features", "zenoh"];
    // The feature's code is in the library and the `aim` binary, which the bus's test builds; its
    // unit tests are in that test too. The library's own unit tests and the other test binaries
    // are the same with the feature and linted by the clippy above (building them all here too
    // took 11 min 41 s of a cold CI, the library's unit tests alone about 2 min of CPU).
    cargo_linted(root, &[&["test"], &zenoh[..], &["--test", "zenoh_bus"]].concat())?;
    laps.lap("the Zenoh bus, linted, built and tested");
    // The board's crates: the firmware and its hardware-in-the-loop test binaries.
    let board = ["-p", "aim-firmware", "-p", "aim-hil-tests", "--target", "thumbv7em-none-eabihf"];
    cargo(root, &[&["clippy", "--release"], &board[..], &["--", "-D", "warnings"]].concat())?;
    // Every board image can start: its layout, then an emulated start to main.
    boot::run(root, &[])?;
    laps.lap("firmware clippy, board images and their start");
    // The PDM build of both (4 PDM microphones on SAI1's PDM interface, see
    // firmware/README.md); `boot` above built and started its images.
    let pdm_board = [&board[..], &boot::PDM_FEATURES[..]].concat();
    cargo(root, &[&["clippy", "--release"], &pdm_board[..], &["--", "-D", "warnings"]].concat())?;
    // Host output equals the Cortex-M4F model's bit for bit (the counts come with `budget`).
    qemu::check_sources(root)?;
    qemu::parity(&qemu::build(root)?)?;
    laps.lap("PDM clippy, golden vectors, QEMU parity");
    // Builds the firmware release ELF for the board, then measures it.
    budget::run(root)?;
    laps.lap("budgets");
    Ok(())
}

/// Wall time of each CI step, printed as it ends (`== … took N s`), so a slow CI says where.
struct Laps {
    last: std::time::Instant,
}

impl Laps {
    fn new() -> Self {
        Self { last: std::time::Instant::now() }
    }

    /// Prints the time since the previous lap (or the start) under `what`.
    fn lap(&mut self, what: &str) {
        let now = std::time::Instant::now();
        eprintln!("== {what} took {:.0} s", (now - self.last).as_secs_f64());
        self.last = now;
    }
}
