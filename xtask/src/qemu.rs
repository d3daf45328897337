//! `cargo xtask qemu`: the on-target half of the DSP checks, on QEMU's Cortex-M4F model
//! (`mps2-an386`).
//!
//! - Parity: the `parity` binary of `tests/qemu` prints the report of `aim_golden::report`
//!   (every pipeline output and encoded frame for the golden input, floats as bit patterns);
//!   this program computes the same report on the host and compares the two line by line.
//! - Cost: the `cost` binary runs the pipeline between probes; the `insn_probe` TCG plugin
//!   (`tests/qemu/plugin/insn_probe.c`) counts the instructions exactly
//!   ([`crate::instructions`] turns them into budget lines).
//!
//! `tests/qemu` is a cargo workspace of its own (its `memory.x` must win over the board's), so
//! cargo runs there, where `tests/qemu/.cargo/config.toml` selects the target.
use std::{
    io::Read,
    path::{Path, PathBuf},
    process::{Command, Stdio},
    thread,
    time::{Duration, Instant},
};

use anyhow::{bail, Context, Result};

/// The QEMU binaries, built for `thumbv7em-none-eabihf` in release.
#[derive(Debug)]
pub struct Binaries {
    /// Prints the parity report.
    pub parity: PathBuf,
    /// Runs the pipeline between probes.
    pub cost: PathBuf,
}

/// Longest a QEMU run may take before it is killed (a hung guest must fail CI, not stall it).
const QEMU_TIMEOUT: Duration = Duration::from_secs(240);

/// The `tests/qemu` workspace.
fn qemu_dir(root: &Path) -> PathBuf {
    root.join("tests").join("qemu")
}

/// Builds the QEMU binaries in release and returns their paths.
pub fn build(root: &Path) -> Result<Binaries> {
    let dir = qemu_dir(root);
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    eprintln!("$ (cd tests/qemu && cargo build --release --bins)");
    let status = Command::new(&cargo)
        .args(["build", "--release", "--bins"])
        .current_dir(&dir)
        // RUSTFLAGS would replace the link arguments of `.cargo/config.toml` (`-Tlink.x`).
        .env_remove("RUSTFLAGS")
        .status()
        .context("running cargo build in tests/qemu")?;
    if !status.success() {
        bail!("building the QEMU binaries in tests/qemu failed ({status})");
    }
    let release = crate::budget::target_dir(&dir)?.join("thumbv7em-none-eabihf").join("release");
    let binaries = Binaries { parity: release.join("parity"), cost: release.join("cost") };
    for elf in [&binaries.parity, &binaries.cost] {
        if !elf.is_file() {
            bail!("the build succeeded but {} is not there", elf.display());
        }
    }
    Ok(binaries)
}

/// What a QEMU run printed.
#[derive(Debug)]
pub struct Run {
    /// The guest's semihosting standard output.
    pub stdout: String,
    /// QEMU's and the guest's standard error.
    pub stderr: String,
}

/// Runs `elf` on `mps2-an386` with semihosting, plus `-plugin <plugin>` if given; fails if QEMU
/// cannot start, the guest exits non-zero, or it runs longer than [`QEMU_TIMEOUT`].
pub fn run(elf: &Path, plugin: Option<&str>) -> Result<Run> {
    let mut command = Command::new("qemu-system-arm");
    command.args([
        "-machine",
        "mps2-an386",
        "-cpu",
        "cortex-m4",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        "none",
        "-semihosting-config",
        "enable=on,target=native",
    ]);
    if let Some(plugin) = plugin {
        command.args(["-plugin", plugin]);
    }
    command.arg("-kernel").arg(elf);
    let name = elf.file_name().unwrap_or_default().to_string_lossy().into_owned();
    eprintln!("$ qemu-system-arm -machine mps2-an386 ... -kernel {name}");
    let mut child = command
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .context("starting qemu-system-arm (install it: apt-get install qemu-system-arm)")?;
    let stdout = drain(child.stdout.take().context("qemu stdout")?);
    let stderr = drain(child.stderr.take().context("qemu stderr")?);
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().context("waiting for qemu")? {
            break status;
        }
        if start.elapsed() > QEMU_TIMEOUT {
            // This process started the child: ending it by its handle is safe.
            let _ = child.kill();
            let _ = child.wait();
            bail!("{name} did not finish within {} s under QEMU", QEMU_TIMEOUT.as_secs());
        }
        thread::sleep(Duration::from_millis(20));
    };
    let run = Run {
        stdout: stdout.join().unwrap_or_default(),
        stderr: stderr.join().unwrap_or_default(),
    };
    if !status.success() {
        bail!("{name} failed under QEMU ({status}); its stderr:\n{}", run.stderr.trim_end());
    }
    Ok(run)
}

/// Reads a pipe to its end on a thread of its own (so that neither pipe can fill and block).
fn drain(mut pipe: impl Read + Send + 'static) -> thread::JoinHandle<String> {
    thread::spawn(move || {
        let mut bytes = Vec::new();
        let _ = pipe.read_to_end(&mut bytes);
        String::from_utf8_lossy(&bytes).into_owned()
    })
}

/// The parity report computed on the host.
pub fn host_report() -> String {
    let mut report = String::new();
    let mut pipeline = Box::new(aim_golden::aim_dsp::Pipeline::empty());
    aim_golden::report::write_parity(&mut report, &mut pipeline)
        .expect("writing to a String cannot fail");
    report
}

/// Compares the host's report with the target's, line by line; the error names the first
/// difference.
pub fn compare(host: &str, target: &str) -> Result<usize> {
    let mut host_lines = host.lines();
    let mut target_lines = target.lines();
    let mut line = 0;
    loop {
        line += 1;
        match (host_lines.next(), target_lines.next()) {
            (None, None) => break,
            (Some(h), Some(t)) if h == t => {}
            (h, t) => bail!(
                "host and Cortex-M4F differ at line {line}:\n  host:   {}\n  target: {}",
                h.unwrap_or("<end of report>"),
                t.unwrap_or("<end of report>")
            ),
        }
    }
    if host.lines().last() != Some("end") {
        bail!("the parity report does not end with `end`: it was cut short");
    }
    Ok(line - 1)
}

/// Builds the plugin `tests/qemu/plugin/insn_probe.c` with the C compiler (`$CC` or `cc`) and
/// returns the path of the shared object.
pub fn build_plugin(root: &Path) -> Result<PathBuf> {
    let source = qemu_dir(root).join("plugin").join("insn_probe.c");
    let out_dir = crate::budget::target_dir(root)?.join("qemu-plugin");
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let out = out_dir.join("libinsn_probe.so");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let status = Command::new(&cc)
        .args(["-O2", "-Wall", "-Wextra", "-Werror", "-shared", "-fPIC", "-o"])
        .arg(&out)
        .arg(&source)
        .status()
        .with_context(|| format!("running the C compiler `{cc}` (install gcc)"))?;
    if !status.success() {
        bail!("compiling {} failed ({status})", source.display());
    }
    Ok(out)
}

/// The `tests/qemu` workspace's own checks, which the root workspace's `cargo fmt`, `clippy` and
/// `test` do not reach: rustfmt, clippy for the target, and the host tests of `aim-golden`.
pub fn check_sources(root: &Path) -> Result<()> {
    let dir = qemu_dir(root);
    // Not `--all`: that would also reach the path dependencies (aim-dsp, aim-wire, and with
    // them the root workspace), which the root's own checks cover.
    crate::cargo(&dir, &["fmt", "-p", "aim-golden", "-p", "aim-qemu-m4f", "--check"])?;
    crate::cargo(&dir, &["clippy", "--release", "--", "-D", "warnings"])?;
    crate::cargo(root, &["clippy", "-p", "aim-golden", "--all-targets", "--", "-D", "warnings"])?;
    crate::cargo(root, &["test", "-p", "aim-golden"])
}

/// `cargo xtask qemu`: parity, then the instruction counts of every stage.
pub fn run_all(root: &Path) -> Result<()> {
    let binaries = build(root)?;
    parity(&binaries)?;
    let report = crate::instructions::measure(root, &binaries)?;
    report.print();
    Ok(())
}

/// Runs the parity binary and compares its report with the host's.
pub fn parity(binaries: &Binaries) -> Result<()> {
    let target = run(&binaries.parity, None)?;
    let lines = compare(&host_report(), &target.stdout)
        .context("the Cortex-M4F output is not bit-identical to the host's")?;
    println!(
        "qemu: parity ok: {lines} lines of host output equal the Cortex-M4F output bit for bit"
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_reports_pass_and_the_first_difference_is_named() {
        assert_eq!(compare("a 1\nb 2\nend\n", "a 1\nb 2\nend\n").unwrap(), 3);
        let error = format!("{:#}", compare("a 1\nb 2\nend\n", "a 1\nb 3\nend\n").unwrap_err());
        assert!(error.contains("line 2") && error.contains("b 3"), "{error}");
        let short = format!("{:#}", compare("a 1\nend\n", "a 1\n").unwrap_err());
        assert!(short.contains("<end of report>"), "{short}");
        assert!(compare("a 1\n", "a 1\n").is_err(), "a report without `end` must fail");
    }

    #[test]
    fn the_host_report_is_deterministic_and_covers_every_scenario() {
        let report = host_report();
        assert_eq!(report, host_report());
        assert_eq!(report.lines().last(), Some("end"));
        assert_eq!(report.lines().filter(|l| l.starts_with("rfft ")).count(), 512);
        for scenario in &aim_golden::scenario::PARITY {
            let body: Vec<&str> = report
                .split(&format!("scenario {}\n", scenario.name))
                .nth(1)
                .unwrap_or_else(|| panic!("no scenario {}", scenario.name))
                .lines()
                .take_while(|l| !l.starts_with("scenario ") && *l != "end")
                .collect();
            for kind in ["doa ", "peaks ", "health ", "frame "] {
                assert!(body.iter().any(|l| l.starts_with(kind)), "{}: no {kind}", scenario.name);
            }
            // One frame per output plus the Hello: the encode path ran for every output.
            let outputs = body.iter().filter(|l| !l.starts_with("frame ")).count();
            assert_eq!(body.len(), 2 * outputs + 1, "{}", scenario.name);
            assert!(!body.iter().any(|l| l.contains("error")), "{}", scenario.name);
            // The golden tone's blade-passing frequency is 330 Hz (aim_golden::signal); the
            // detector reports it once its continuity test has held ("peaks INDEX rotor BPF").
            let rotor: Vec<&&str> =
                body.iter().filter(|l| l.starts_with("peaks ") && l.contains(" rotor ")).collect();
            assert!(!rotor.is_empty(), "{}: no rotor signature", scenario.name);
            for line in rotor {
                let bits = line.split(' ').nth(3).unwrap();
                let bpf = f32::from_bits(u32::from_str_radix(bits, 16).unwrap());
                assert!((bpf - 330.0).abs() < 1.0, "{}: {line}", scenario.name);
            }
        }
    }
}
