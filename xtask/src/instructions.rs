//! Instruction counts and RAM of the DSP on QEMU's Cortex-M4F model, as budget lines.
//!
//! The `cost` binary of `tests/qemu` runs the pipeline on golden input, marking stage
//! boundaries with probes (`aim_golden::probe`); the `insn_probe` plugin counts every executed
//! guest instruction exactly and charges it to the probe last entered, and writes the totals of
//! each section. The guest prints, in the same order, `section <name> <samples>
//! <sample_rate_hz>` per section and `ram <name> <bytes>` lines. Instructions per second of audio
//! = instructions × sample rate / samples.
use std::{collections::BTreeMap, path::Path};

use aim_golden::probe::{Probe, SLOTS};
use anyhow::{bail, Context, Result};
use object::{Object, ObjectSymbol};
use serde::Deserialize;

use crate::{budget::Line, qemu::Binaries};

/// An instruction budget (`[[instructions]]` in `budget.toml`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstructionBudget {
    /// Name printed in the budget line.
    pub name: String,
    /// Section of the cost run (`4mic`, `6mic`, `8mic`, `reference`).
    pub section: String,
    /// Probe name (`fft`, `phat`, `inverse`, `doa`, `bpf`, `other`, `encode`, `rfft1024`), or
    /// `pipeline` for the whole pipeline (every pipeline stage together).
    pub stage: String,
    /// Largest allowed value, in `unit`.
    pub limit: u64,
    /// `instr/s` (per second of audio) or `instr` (per section, e.g. one reference call).
    pub unit: String,
}

/// A RAM budget measured on the target (`[[target_ram]]` in `budget.toml`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RamBudget {
    /// Name printed in the budget line.
    pub name: String,
    /// The `ram <measure> <bytes>` line of the cost binary.
    pub measure: String,
    /// Largest allowed value, bytes.
    pub limit: u64,
    /// `bytes`.
    pub unit: String,
}

/// Instruction counts of one section of the cost run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Section {
    /// Section name.
    pub name: String,
    /// Audio samples (per microphone) the section processed.
    pub samples: u64,
    /// Sample rate of that audio, Hz.
    pub sample_rate_hz: u64,
    /// Instructions charged to each probe.
    pub instructions: BTreeMap<&'static str, u64>,
}

impl Section {
    /// Instructions of `stage` (a probe name, or `pipeline` for all pipeline stages).
    pub fn stage(&self, stage: &str) -> Option<u64> {
        if stage == "pipeline" {
            let pipeline = Probe::ALL.iter().filter(|p| p.is_pipeline());
            return Some(pipeline.filter_map(|p| self.instructions.get(p.name())).sum());
        }
        Probe::ALL.iter().find(|p| p.name() == stage)?;
        Some(self.instructions.get(stage).copied().unwrap_or(0))
    }

    /// `instructions` per second of this section's audio, rounded to nearest.
    pub fn per_second(&self, instructions: u64) -> u64 {
        let scaled = u128::from(instructions) * u128::from(self.sample_rate_hz);
        let samples = u128::from(self.samples.max(1));
        ((scaled + samples / 2) / samples) as u64
    }
}

/// Everything the cost run measured.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Report {
    /// Instruction counts, in run order.
    pub sections: Vec<Section>,
    /// RAM figures (`ram <name> <bytes>`), bytes.
    pub ram: BTreeMap<String, u64>,
}

/// Builds the plugin, runs the cost binary under it and parses what both wrote.
pub fn measure(root: &Path, binaries: &Binaries) -> Result<Report> {
    let plugin = crate::qemu::build_plugin(root)?;
    let elf = std::fs::read(&binaries.cost)
        .with_context(|| format!("reading {}", binaries.cost.display()))?;
    let table = probe_table_address(&elf)?;
    let counts_path = plugin.with_file_name("cost-counts.txt");
    let args = format!(
        "{},base={table:#x},slots={SLOTS},dump={},out={}",
        plugin.display(),
        Probe::Dump.id(),
        counts_path.display()
    );
    let run = crate::qemu::run(&binaries.cost, Some(&args))?;
    let counts = std::fs::read_to_string(&counts_path)
        .with_context(|| format!("reading the plugin's output {}", counts_path.display()))?;
    parse(&run.stdout, &counts)
}

/// Address of the guest's probe table (symbol `aim_probe_table`), without the Thumb bit.
fn probe_table_address(elf: &[u8]) -> Result<u64> {
    let file = object::File::parse(elf).context("parsing the cost ELF")?;
    let symbol = file
        .symbols()
        .find(|s| s.name() == Ok("aim_probe_table"))
        .context("the cost ELF has no symbol `aim_probe_table`")?;
    Ok(symbol.address() & !1)
}

/// Pairs the guest's `section` lines with the plugin's sections (same order) and collects the
/// `ram` lines.
pub fn parse(guest: &str, plugin: &str) -> Result<Report> {
    let mut sections = Vec::new();
    let mut ram = BTreeMap::new();
    for (number, line) in guest.lines().enumerate() {
        let fields: Vec<&str> = line.split_whitespace().collect();
        let bad = || format!("cost output line {}: cannot read `{line}`", number + 1);
        match fields.as_slice() {
            ["section", name, samples, rate] => sections.push(Section {
                name: (*name).to_owned(),
                samples: samples.parse().with_context(bad)?,
                sample_rate_hz: rate.parse().with_context(bad)?,
                instructions: BTreeMap::new(),
            }),
            ["ram", name, bytes] => {
                ram.insert((*name).to_owned(), bytes.parse().with_context(bad)?);
            }
            _ => bail!(bad()),
        }
    }
    let mut current: Option<usize> = None;
    for (number, line) in plugin.lines().enumerate() {
        let fields: Vec<&str> = line.split_whitespace().collect();
        let bad = || format!("plugin output line {}: cannot read `{line}`", number + 1);
        match fields.as_slice() {
            ["section", n] => {
                let n: usize = n.parse().with_context(bad)?;
                if n == 0 || n > sections.len() {
                    bail!("the plugin wrote section {n}, the guest announced {}", sections.len());
                }
                current = Some(n - 1);
            }
            ["probe", id, instructions, _entries] => {
                let section = current.with_context(|| format!("{}: before any section", bad()))?;
                let id: usize = id.parse().with_context(bad)?;
                let probe =
                    Probe::from_id(id).with_context(|| format!("{}: no probe {id}", bad()))?;
                let instructions: u64 = instructions.parse().with_context(bad)?;
                *sections[section].instructions.entry(probe.name()).or_insert(0) += instructions;
            }
            ["exit", _] => {}
            _ => bail!(bad()),
        }
    }
    if current.map_or(0, |c| c + 1) != sections.len() {
        bail!(
            "the guest announced {} sections but the plugin wrote {}",
            sections.len(),
            current.map_or(0, |c| c + 1)
        );
    }
    Ok(Report { sections, ram })
}

impl Report {
    /// The section called `name`.
    pub fn section(&self, name: &str) -> Option<&Section> {
        self.sections.iter().find(|s| s.name == name)
    }

    /// Prints every measured figure (all sections and stages, RAM), one `qemu:` line each.
    pub fn print(&self) {
        for section in &self.sections {
            let seconds = section.samples as f64 / section.sample_rate_hz.max(1) as f64;
            println!(
                "qemu: section {} ({} samples = {seconds:.3} s of audio at {} Hz)",
                section.name, section.samples, section.sample_rate_hz
            );
            let stages = Probe::ALL.iter().map(|p| p.name()).chain(["pipeline"]).filter(|name| {
                *name == "pipeline"
                    || (*name != Probe::Dump.name() && section.instructions.contains_key(name))
            });
            for stage in stages {
                let n = section.stage(stage).unwrap_or(0);
                if n == 0 && stage == "pipeline" {
                    continue;
                }
                println!(
                    "qemu:   {stage:<10} {n:>12} instr  {:>12} instr/s",
                    section.per_second(n)
                );
            }
        }
        for (name, bytes) in &self.ram {
            println!("qemu: ram {name} {bytes} bytes");
        }
    }

    /// One budget line per instruction and RAM budget; an error if a budget names a section,
    /// stage, unit or RAM figure the run does not have.
    pub fn lines(
        &self,
        instructions: &[InstructionBudget],
        ram: &[RamBudget],
    ) -> Result<Vec<Line>> {
        let mut lines = Vec::new();
        for budget in instructions {
            let section = self.section(&budget.section).with_context(|| {
                format!("budget {}: the cost run has no section `{}`", budget.name, budget.section)
            })?;
            let n = section
                .stage(&budget.stage)
                .with_context(|| format!("budget {}: no stage `{}`", budget.name, budget.stage))?;
            let measured = match budget.unit.as_str() {
                "instr/s" => section.per_second(n),
                "instr" => n,
                other => bail!("budget {}: unit `{other}` is not instr/s or instr", budget.name),
            };
            lines.push(Line {
                name: budget.name.clone(),
                measured,
                limit: budget.limit,
                unit: budget.unit.clone(),
            });
        }
        for budget in ram {
            let measured = *self.ram.get(&budget.measure).with_context(|| {
                format!("budget {}: the cost run printed no `ram {}`", budget.name, budget.measure)
            })?;
            lines.push(Line {
                name: budget.name.clone(),
                measured,
                limit: budget.limit,
                unit: budget.unit.clone(),
            });
        }
        Ok(lines)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GUEST: &str = "section 8mic 96000 48000\nram pipeline-8mic 100000\n\
                         section reference 1024 48000\n";
    const PLUGIN: &str = "section 1\nprobe 0 10 1\nprobe 1 500 5\nprobe 2 1000 5\n\
                          probe 3 4000 5\nprobe 7 600 5\nsection 2\nprobe 8 48230 1\nexit 9\n";

    #[test]
    fn sections_pair_up_and_stages_add_to_the_pipeline() {
        let report = parse(GUEST, PLUGIN).unwrap();
        let s = report.section("8mic").unwrap();
        assert_eq!(s.stage("fft"), Some(4000));
        assert_eq!(s.stage("phat"), Some(0));
        assert_eq!(s.stage("nonsense"), None);
        // Input (1) and untracked (0) are not the pipeline's.
        assert_eq!(s.stage("pipeline"), Some(1000 + 4000 + 600));
        // 96 000 samples at 48 kHz = 2 s.
        assert_eq!(s.per_second(5600), 2800);
        assert_eq!(report.section("reference").unwrap().stage("rfft1024"), Some(48230));
        assert_eq!(report.ram["pipeline-8mic"], 100_000);
    }

    #[test]
    fn budgets_become_lines_and_unknown_names_are_errors() {
        let report = parse(GUEST, PLUGIN).unwrap();
        let budget = |section: &str, stage: &str, unit: &str| InstructionBudget {
            name: "b".into(),
            section: section.into(),
            stage: stage.into(),
            limit: 2800,
            unit: unit.into(),
        };
        let ram = [RamBudget {
            name: "r".into(),
            measure: "pipeline-8mic".into(),
            limit: 99_999,
            unit: "bytes".into(),
        }];
        let lines = report.lines(&[budget("8mic", "pipeline", "instr/s")], &ram).unwrap();
        assert_eq!(lines[0].to_string(), "budget: b 2800 2800 instr/s ok");
        assert_eq!(lines[1].to_string(), "budget: r 100000 99999 bytes OVER");
        assert!(report.lines(&[budget("2mic", "fft", "instr/s")], &[]).is_err());
        assert!(report.lines(&[budget("8mic", "fftt", "instr/s")], &[]).is_err());
        assert!(report.lines(&[budget("8mic", "fft", "cycles")], &[]).is_err());
    }

    #[test]
    fn mismatched_or_garbled_output_is_an_error() {
        assert!(parse(GUEST, "section 1\nprobe 0 10 1\n").is_err(), "one section missing");
        assert!(parse(GUEST, "probe 0 10 1\n").is_err(), "probe before a section");
        assert!(parse(GUEST, "section 1\nprobe 14 10 1\nsection 2\n").is_err(), "unknown id");
        assert!(parse("section 8mic lots 48000\n", "section 1\n").is_err());
        assert!(parse("hello\n", "").is_err());
    }
}
