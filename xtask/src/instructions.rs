//! Instruction counts and RAM of the DSP on QEMU's Cortex-M4F model, as budget lines.
//!
//! The `cost` binary of `tests/qemu` runs the pipeline on golden input; the `insn_probe` plugin
//! counts every executed guest instruction exactly and charges it to an id
//! (`aim_golden::probe::Probe`). Ids switch in two ways: the guest calls its probe table
//! (explicit points: input synthesis, pipeline, reference FFT, end of section), and the code of
//! each DSP stage switches to that stage's id, found from the ELF's debug information (inline
//! chains from `addr2line -i`), so the pipeline needs no hooks. Out-of-line shared code
//! (microfft's butterflies, libm) is charged to the stage that called it.
//!
//! The guest prints, in the plugin's section order, `section <name> <samples> <sample_rate_hz>`
//! per section and `ram <name> <bytes>` lines. Instructions per second of audio =
//! instructions × sample rate / samples.
use std::{collections::BTreeMap, path::Path};

use aim_golden::probe::{Probe, SLOTS};
use anyhow::{bail, Context, Result};
use object::{Object, ObjectSection, ObjectSymbol};
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
    let mut map = probe_table_ranges(&elf)?;
    map.extend(stage_ranges(&binaries.cost, &elf)?);
    let map_path = plugin.with_file_name("cost-map.txt");
    let map_text: String =
        map.iter().map(|r| format!("{:#x} {:#x} {}\n", r.start, r.end, r.probe.id())).collect();
    std::fs::write(&map_path, map_text)
        .with_context(|| format!("writing {}", map_path.display()))?;
    let counts_path = plugin.with_file_name("cost-counts.txt");
    let args = format!(
        "{},map={},ids={SLOTS},dump={},out={}",
        plugin.display(),
        map_path.display(),
        Probe::Dump.id(),
        counts_path.display()
    );
    let run = crate::qemu::run(&binaries.cost, Some(&args))?;
    let counts = std::fs::read_to_string(&counts_path)
        .with_context(|| format!("reading the plugin's output {}", counts_path.display()))?;
    let report = parse(&run.stdout, &counts)?;
    report.check_stages()?;
    Ok(report)
}

/// Guest addresses `start..end` whose code switches the plugin to `probe`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Range {
    /// First address.
    pub start: u64,
    /// One past the last address.
    pub end: u64,
    /// What the instructions from there on are charged to.
    pub probe: Probe,
}

/// The guest's probe table (symbol `aim_probe_table`): one 2-byte `bx lr` slot per probe id.
fn probe_table_ranges(elf: &[u8]) -> Result<Vec<Range>> {
    let file = object::File::parse(elf).context("parsing the cost ELF")?;
    let symbol = file
        .symbols()
        .find(|s| s.name() == Ok("aim_probe_table"))
        .context("the cost ELF has no symbol `aim_probe_table`")?;
    let base = symbol.address() & !1;
    Ok(Probe::ALL
        .iter()
        .map(|&probe| {
            let start = base + 2 * probe.id() as u64;
            Range { start, end: start + 2, probe }
        })
        .collect())
}

/// The code of each DSP stage in the cost ELF, from its debug information: every 2-byte step of
/// the executable sections is looked up with `addr2line -i` (inlined functions included) and
/// classified by [`classify`]; code that belongs to no stage (microfft, libm, the guest's own
/// code) is left out, so the plugin charges it to whichever stage ran it.
fn stage_ranges(path: &Path, elf: &[u8]) -> Result<Vec<Range>> {
    let file = object::File::parse(elf).context("parsing the cost ELF")?;
    let mut addresses = Vec::new();
    for section in file.sections() {
        if section.kind() == object::SectionKind::Text {
            addresses.extend((section.address()..section.address() + section.size()).step_by(2));
        }
    }
    let chains = addr2line(path, &addresses)?;
    let mut ranges: Vec<Range> = Vec::new();
    for (&address, chain) in addresses.iter().zip(&chains) {
        let Some(probe) = classify(chain) else { continue };
        match ranges.last_mut() {
            Some(last) if last.end == address && last.probe == probe => last.end = address + 2,
            _ => ranges.push(Range { start: address, end: address + 2, probe }),
        }
    }
    Ok(ranges)
}

/// Runs `addr2line -a -i -f -C` (GNU binutils) on `addresses`; returns, per address, the
/// function names of its inline chain, innermost first.
fn addr2line(path: &Path, addresses: &[u64]) -> Result<Vec<Vec<String>>> {
    use std::io::Write;
    let mut child = std::process::Command::new("addr2line")
        .args(["-a", "-i", "-f", "-C", "-e"])
        .arg(path)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .context("running addr2line (GNU binutils; installed with gcc)")?;
    let mut stdin = child.stdin.take().context("addr2line stdin")?;
    let input: String = addresses.iter().map(|a| format!("{a:#x}\n")).collect();
    let writer = std::thread::spawn(move || stdin.write_all(input.as_bytes()));
    let output = child.wait_with_output().context("reading addr2line's output")?;
    writer.join().map_err(|_| anyhow::anyhow!("addr2line input thread panicked"))??;
    if !output.status.success() {
        bail!("addr2line failed ({})", output.status);
    }
    let text = String::from_utf8_lossy(&output.stdout);
    let mut chains: Vec<Vec<String>> = Vec::with_capacity(addresses.len());
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        if line.starts_with("0x") {
            chains.push(Vec::new());
        } else if let Some(chain) = chains.last_mut() {
            chain.push(line.to_owned());
            lines.next(); // the file:line of this function
        }
    }
    if chains.len() != addresses.len() {
        bail!("addr2line answered {} of {} addresses", chains.len(), addresses.len());
    }
    Ok(chains)
}

/// Functions that are a stage, or part of one, wherever they are inlined: the innermost of
/// these in an inline chain decides.
const STAGE_FUNCTIONS: [(&str, Probe); 21] = [
    ("aim_wire::", Probe::Encode),
    ("aim_dsp::gcc_phat::phat_band", Probe::Phat),
    ("aim_dsp::gcc_phat::phat_unit", Probe::Phat),
    ("aim_dsp::gcc_phat::accumulate_cross", Probe::Phat),
    ("aim_dsp::gcc_phat::weight_by_coherence", Probe::Inverse),
    ("aim_dsp::gcc_phat::estimate_delay", Probe::Inverse),
    ("aim_dsp::gcc_phat::correlation", Probe::Inverse),
    ("aim_dsp::doa::", Probe::Doa),
    ("aim_dsp::bpf::", Probe::Bpf),
    ("aim_dsp::idframe::", Probe::Features),
    // The detector only: the waveform (`beacon::waveform_at`) is also the golden input's
    // synthesis, which must not count as detection (it runs at configuration in the pipeline).
    ("aim_dsp::beacon::Detector::", Probe::Beacon),
    ("aim_dsp::beacon::Picker::", Probe::Beacon),
    ("aim_dsp::beacon::refine", Probe::Beacon),
    ("aim_dsp::snippet::", Probe::Snippet),
    ("aim_dsp::pipeline::Pipeline::emit_snippets", Probe::Snippet),
    // The pipeline's steps: what they do outside the functions above.
    ("aim_dsp::pipeline::Pipeline::spatial_block", Probe::Fft),
    // The spatial path's Q15 conversion (its only caller): without this line it counted as
    // `other` or `fft` as the compiler's inline records happened to fall.
    ("aim_dsp::frontend::to_q15", Probe::Fft),
    ("aim_dsp::pipeline::Pipeline::estimate_direction", Probe::Doa),
    ("aim_dsp::pipeline::Pipeline::spectral_block", Probe::Bpf),
    ("aim_dsp::pipeline::", Probe::PipelineOther),
    ("aim_dsp::frontend::", Probe::PipelineOther),
];

/// The DSP stage an instruction belongs to, from its inline chain (function names, innermost
/// first): the innermost function listed in [`STAGE_FUNCTIONS`] decides; `aim_wire` code is the
/// encode path. `None` for everything else, e.g. code called out of line (microfft's
/// butterflies, libm, postcard, a small aim-dsp helper): it is charged to the stage that runs
/// it.
pub fn classify(chain: &[String]) -> Option<Probe> {
    chain.iter().find_map(|function| {
        STAGE_FUNCTIONS
            .iter()
            .find(|(prefix, _)| function.starts_with(prefix))
            .map(|&(_, probe)| probe)
    })
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

    /// Fails if a section that ran the pipeline charged nothing to one of its stages: then
    /// [`classify`] no longer recognises aim-dsp's function names, and that stage's
    /// instructions went to `other`.
    pub fn check_stages(&self) -> Result<()> {
        const STAGES: [Probe; 8] = [
            Probe::Fft,
            Probe::Phat,
            Probe::Inverse,
            Probe::Doa,
            Probe::Bpf,
            Probe::Features,
            Probe::Beacon,
            Probe::Snippet,
        ];
        for section in &self.sections {
            if section.stage(Probe::PipelineOther.name()).unwrap_or(0) == 0 {
                continue; // not a pipeline section
            }
            for stage in STAGES {
                if section.stage(stage.name()).unwrap_or(0) == 0 {
                    bail!(
                        "section {}: no instructions in stage `{}`: the stage map of \
                         xtask/src/instructions.rs (fn classify) no longer matches aim-dsp's \
                         function names",
                        section.name,
                        stage.name()
                    );
                }
            }
        }
        Ok(())
    }

    /// Prints every measured figure (all sections but the warm-ups, every stage, RAM), one
    /// `qemu:` line each.
    pub fn print(&self) {
        for section in self.sections.iter().filter(|s| !s.name.starts_with("warmup-")) {
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
        // Phat, inverse and DoA got nothing although the pipeline ran: the map is stale.
        let error = format!("{:#}", report.check_stages().unwrap_err());
        assert!(error.contains("8mic") && error.contains("phat"), "{error}");
        let all = "section 1\nprobe 2 1 1\nprobe 3 1 1\nprobe 4 1 1\nprobe 5 1 1\n\
                   probe 6 1 1\nprobe 7 1 1\nprobe 11 1 1\nprobe 12 1 1\nprobe 13 1 1\n\
                   section 2\nprobe 8 48230 1\n";
        parse(GUEST, all).unwrap().check_stages().unwrap();
        // Without the features stage (the map lost `idframe::`): an error naming it.
        let no_features = all.replace("probe 11 1 1\n", "");
        let error =
            format!("{:#}", parse(GUEST, &no_features).unwrap().check_stages().unwrap_err());
        assert!(error.contains("features"), "{error}");
        // Without the snippet stage (the map lost `snippet::`): an error naming it.
        let no_snippet = all.replace("probe 13 1 1\n", "");
        let error = format!("{:#}", parse(GUEST, &no_snippet).unwrap().check_stages().unwrap_err());
        assert!(error.contains("snippet"), "{error}");
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
    fn code_is_charged_to_the_innermost_stage_function() {
        let chain = |names: &[&str]| names.iter().map(|n| (*n).to_owned()).collect::<Vec<_>>();
        let spatial = "aim_dsp::pipeline::Pipeline::spatial_block";
        let push = "aim_dsp::pipeline::Pipeline::push<cost::measure::{closure#0}>";
        assert_eq!(
            classify(&chain(&["microfft::real::rfft_1024", spatial, push])),
            Some(Probe::Fft)
        );
        assert_eq!(
            classify(&chain(&["aim_dsp::gcc_phat::phat_band", spatial, push])),
            Some(Probe::Phat)
        );
        assert_eq!(
            classify(&chain(&["aim_dsp::gcc_phat::correlation_derivatives"])),
            Some(Probe::Inverse)
        );
        assert_eq!(
            classify(&chain(&["libm::math::sqrtf::sqrtf", "aim_dsp::doa::fit", push])),
            Some(Probe::Doa)
        );
        assert_eq!(classify(&chain(&["aim_dsp::bpf::Decimator::push", push])), Some(Probe::Bpf));
        let spectral = "aim_dsp::pipeline::Pipeline::spectral_block";
        assert_eq!(
            classify(&chain(&["aim_dsp::idframe::IdExtractor::compute", spectral, push])),
            Some(Probe::Features)
        );
        assert_eq!(
            classify(&chain(&["aim_dsp::frontend::FrontEnd::remove_dc", push])),
            Some(Probe::PipelineOther)
        );
        // Out-of-line shared code and the guest's own code: charged to the caller.
        assert_eq!(classify(&chain(&["microfft::impls::cfft::CFft::compute_butterflies"])), None);
        assert_eq!(classify(&chain(&["aim_golden::signal::Signal::fill"])), None);
        // The beacon's waveform is the detector's only inside the detector: in the golden
        // input's synthesis it stays with the caller (`input`).
        let waveform = "aim_dsp::beacon::waveform_at";
        assert_eq!(classify(&chain(&[waveform, "aim_golden::signal::Signal::new"])), None);
        assert_eq!(
            classify(&chain(&[waveform, "aim_dsp::beacon::Detector::configure"])),
            Some(Probe::Beacon)
        );
        assert_eq!(
            classify(&chain(&["aim_dsp::beacon::Picker::take", "aim_dsp::beacon::Detector::push"])),
            Some(Probe::Beacon)
        );
        assert_eq!(
            classify(&chain(&["aim_dsp::snippet::quantize", "aim_dsp::pipeline::Pipeline::push"])),
            Some(Probe::Snippet)
        );
        // The encode path, inlined into the sink inside `push` or out of line.
        let closure = "cost::measure::{closure#0}";
        assert_eq!(
            classify(&chain(&["aim_wire::from_dsp::doa", closure, push])),
            Some(Probe::Encode)
        );
        assert_eq!(classify(&chain(&["aim_wire::crc32::crc32"])), Some(Probe::Encode));
        assert_eq!(classify(&chain(&[closure, push])), Some(Probe::PipelineOther));
        // A helper inlined into a stage belongs to that stage; out of line, to its caller.
        let rsqrt = "aim_dsp::gcc_phat::rsqrt";
        let phat = "aim_dsp::gcc_phat::phat_band";
        assert_eq!(classify(&chain(&[rsqrt, phat, spatial, push])), Some(Probe::Phat));
        assert_eq!(classify(&chain(&[rsqrt])), None);
        let estimate = "aim_dsp::pipeline::Pipeline::estimate_direction";
        assert_eq!(
            classify(&chain(&["aim_dsp::gcc_phat::weight_by_coherence", estimate, push])),
            Some(Probe::Inverse)
        );
        assert_eq!(classify(&chain(&["core::slice::fill", estimate, push])), Some(Probe::Doa));
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
