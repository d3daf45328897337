//! `cargo xtask budget`: resource budgets from `budget.toml`, measured and enforced.
use std::{
    fmt,
    path::{Path, PathBuf},
};

use anyhow::{bail, Context, Result};
use serde::Deserialize;

use crate::elf_size::{self, Regions};

/// The contents of `budget.toml`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Budget {
    /// Which firmware image the size budgets measure.
    pub firmware: Firmware,
    /// Address ranges that count as flash and as RAM.
    pub regions: Regions,
    /// Flash and static-RAM budgets of the firmware image.
    #[serde(default)]
    pub size: Vec<SizeBudget>,
    /// Instruction budgets per second of audio, measured on QEMU's Cortex-M4F model.
    #[serde(default)]
    pub instructions: Vec<crate::instructions::InstructionBudget>,
    /// RAM budgets measured on QEMU's Cortex-M4F model (the DSP's working memory).
    #[serde(default)]
    pub target_ram: Vec<crate::instructions::RamBudget>,
}

/// The firmware image: package and target triple.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Firmware {
    /// Cargo package (its binary has the same name).
    pub package: String,
    /// Target triple.
    pub target: String,
}

/// One size budget.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SizeBudget {
    /// Name printed in the budget line.
    pub name: String,
    /// What is measured.
    pub measure: SizeMeasure,
    /// Cargo features of the measured build; empty (the default): the firmware's default
    /// build. Non-empty: `--no-default-features --features <these>` (e.g. the PDM build).
    #[serde(default)]
    pub features: Vec<String>,
    /// Largest allowed value, in `unit`.
    pub limit: u64,
    /// Unit of `limit` and of the measurement (bytes).
    pub unit: String,
}

/// What a size budget measures.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SizeMeasure {
    /// Bytes stored in flash.
    Flash,
    /// Bytes of statically allocated RAM.
    Ram,
}

impl Budget {
    /// Reads `budget.toml` at the workspace root.
    pub fn load(root: &Path) -> Result<Self> {
        let path = root.join("budget.toml");
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("reading {}", path.display()))?;
        Self::parse(&text).with_context(|| format!("in {}", path.display()))
    }

    /// Parses the text of a budget file; errors name the line.
    pub fn parse(text: &str) -> Result<Self> {
        toml::from_str(text).map_err(|e| {
            let line = e.span().map(|s| text[..s.start].lines().count().max(1));
            match line {
                Some(line) => anyhow::anyhow!("line {line}: {}", e.message()),
                None => anyhow::anyhow!("{}", e.message()),
            }
        })
    }
}

/// One measured budget, printed as `budget: <name> <measured> <limit> <unit> ok|OVER`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Line {
    /// Budget name.
    pub name: String,
    /// Measured value.
    pub measured: u64,
    /// Limit.
    pub limit: u64,
    /// Unit of both.
    pub unit: String,
}

impl Line {
    /// Whether the measurement is within its limit.
    pub fn ok(&self) -> bool {
        self.measured <= self.limit
    }
}

impl fmt::Display for Line {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let verdict = if self.ok() { "ok" } else { "OVER" };
        write!(f, "budget: {} {} {} {} {verdict}", self.name, self.measured, self.limit, self.unit)
    }
}

/// Builds the firmware in release for its target (with `features`, see
/// [`SizeBudget::features`]) and returns the path of its ELF.
pub fn build_firmware(root: &Path, firmware: &Firmware, features: &[String]) -> Result<PathBuf> {
    let mut args =
        vec!["build", "--release", "-p", &firmware.package, "--target", &firmware.target];
    let list = features.join(",");
    if !features.is_empty() {
        args.extend(["--no-default-features", "--features", &list]);
    }
    crate::cargo(root, &args)?;
    let elf = target_dir(root)?.join(&firmware.target).join("release").join(&firmware.package);
    if !elf.is_file() {
        bail!("the build succeeded but {} is not there", elf.display());
    }
    Ok(elf)
}

/// Cargo's target directory for this workspace (honours `CARGO_TARGET_DIR`).
pub(crate) fn target_dir(root: &Path) -> Result<PathBuf> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--no-deps"])
        .current_dir(root)
        .output()
        .context("running cargo metadata")?;
    if !out.status.success() {
        bail!("cargo metadata failed: {}", String::from_utf8_lossy(&out.stderr));
    }
    let meta: serde_json::Value =
        serde_json::from_slice(&out.stdout).context("parsing cargo metadata")?;
    let dir =
        meta["target_directory"].as_str().context("cargo metadata has no target_directory")?;
    Ok(PathBuf::from(dir))
}

/// Measures every budget, prints one line each, and fails if any is over.
pub fn run(root: &Path) -> Result<()> {
    let budget = Budget::load(root)?;
    // One build per feature set; the default build last, so that the firmware ELF left in
    // `release/` afterwards is the default one.
    let mut builds: Vec<&[String]> = Vec::new();
    for b in &budget.size {
        if !builds.contains(&b.features.as_slice()) {
            builds.push(&b.features);
        }
    }
    builds.sort_by_key(|features| features.is_empty());
    let mut sizes = Vec::new();
    for features in builds {
        let elf = build_firmware(root, &budget.firmware, features)?;
        eprintln!(
            "firmware ELF ({}, features {features:?}): {}",
            budget.firmware.target,
            elf.display()
        );
        let data = std::fs::read(&elf).with_context(|| format!("reading {}", elf.display()))?;
        let size = elf_size::measure(&data, &budget.regions)
            .with_context(|| format!("measuring {}", elf.display()))?;
        sizes.push((features, size));
    }
    let mut lines: Vec<Line> = budget
        .size
        .iter()
        .map(|b| {
            let size = &sizes.iter().find(|(f, _)| *f == b.features.as_slice()).expect("built").1;
            Line {
                name: b.name.clone(),
                measured: match b.measure {
                    SizeMeasure::Flash => size.flash,
                    SizeMeasure::Ram => size.ram,
                },
                limit: b.limit,
                unit: b.unit.clone(),
            }
        })
        .collect();
    if !budget.instructions.is_empty() || !budget.target_ram.is_empty() {
        let binaries = crate::qemu::build(root)?;
        let measured = crate::instructions::measure(root, &binaries)?;
        lines.extend(measured.lines(&budget.instructions, &budget.target_ram)?);
    }
    report(&lines)
}

/// Prints the lines and fails if any is over its limit.
pub fn report(lines: &[Line]) -> Result<()> {
    for line in lines {
        println!("{line}");
    }
    let over: Vec<&str> = lines.iter().filter(|l| !l.ok()).map(|l| l.name.as_str()).collect();
    if !over.is_empty() {
        bail!("over budget: {}", over.join(", "));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_projects_budget_file_parses() {
        let root = crate::workspace_root();
        let budget = Budget::load(&root).unwrap();
        assert_eq!(budget.firmware.target, "thumbv7em-none-eabihf");
        assert!(budget.size.iter().any(|b| matches!(b.measure, SizeMeasure::Flash)));
        // The PDM build has its own size lines.
        assert!(budget.size.iter().any(|b| b.features == ["pdm", "mics-4"]));
    }

    #[test]
    fn a_bad_budget_file_names_the_line() {
        let text = "[firmware]\npackage = \"x\"\ntarget = \"y\"\n[regions]\nflash = []\nram = []\n\
                    [[size]]\nname = \"a\"\nmeasure = \"eeprom\"\nlimit = 1\nunit = \"bytes\"\n";
        let error = format!("{:#}", Budget::parse(text).unwrap_err());
        assert!(error.contains("line 9"), "{error}");
    }

    #[test]
    fn lines_print_in_the_contract_form() {
        let ok = Line { name: "flash".into(), measured: 10, limit: 10, unit: "bytes".into() };
        let over = Line { name: "ram".into(), measured: 11, limit: 10, unit: "bytes".into() };
        assert_eq!(ok.to_string(), "budget: flash 10 10 bytes ok");
        assert_eq!(over.to_string(), "budget: ram 11 10 bytes OVER");
        assert!(report(std::slice::from_ref(&ok)).is_ok());
        assert!(report(&[ok, over]).is_err());
    }
}
