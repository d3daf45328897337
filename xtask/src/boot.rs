//! `cargo xtask boot`: proves that every board image can start, without a board.
//!
//! For the firmware and each hardware-in-the-loop binary (release, `thumbv7em-none-eabihf`), and
//! for the PDM build of both (features `pdm`: the firmware and the `pdm_*` HIL binaries):
//! 1. the layout check of [`crate::image_layout`] on the ELF (zero-init and load ranges, regions,
//!    vector table, stack guard, DMA buffers);
//! 2. an emulated start of the same ELF on the STM32H743 memory map
//!    (`tools/boot/emulate_start.py`, the unicorn engine): from the reset vector to `main`'s
//!    first peripheral access, failing on any access outside a mapped region; then on through
//!    the chip and clock probe to embassy's init, with and without an external clock and on
//!    revisions V and Y (the probe must not hang and must choose HSE/HSI, 480/400 MHz).
use std::{
    path::{Path, PathBuf},
    process::Command,
};

use anyhow::{bail, Context, Result};

use crate::{budget::target_dir, cargo, image_layout};

/// The board's target triple.
const TARGET: &str = "thumbv7em-none-eabihf";

/// The features of the PDM board images (4 PDM microphones; see firmware/README.md), for a
/// cargo command that selects both board packages.
pub const PDM_FEATURES: [&str; 3] = [
    "--no-default-features",
    "--features",
    "aim-firmware/pdm,aim-firmware/mics-4,aim-hil-tests/pdm",
];

/// HIL binaries named `pdm_*` need the PDM build (`required-features = ["pdm"]`).
fn is_pdm_binary(name: &str) -> bool {
    name.starts_with("pdm_")
}

/// The binaries of the hardware-in-the-loop package, from its `src/bin/` folder.
fn hil_binaries(root: &Path) -> Result<Vec<String>> {
    let dir = root.join("tests/hil/src/bin");
    let mut names = Vec::new();
    for entry in std::fs::read_dir(&dir).with_context(|| format!("listing {}", dir.display()))? {
        let path = entry?.path();
        if path.extension().is_some_and(|e| e == "rs") {
            if let Some(stem) = path.file_stem().and_then(|s| s.to_str()) {
                names.push(stem.to_string());
            }
        }
    }
    names.sort();
    Ok(names)
}

/// Builds the board images and returns their ELF paths (the firmware first): the default
/// build (8 TDM microphones) of the firmware and of every HIL binary but the `pdm_*` ones, then
/// the PDM build of the firmware and of the `pdm_*` binaries, copied to `release/pdm/` (the
/// two builds share the output names).
pub fn build_images(root: &Path) -> Result<Vec<PathBuf>> {
    let release = target_dir(root)?.join(TARGET).join("release");
    let pdm_dir = release.join("pdm");
    let (pdm_bins, tdm_bins): (Vec<String>, Vec<String>) =
        hil_binaries(root)?.into_iter().partition(|name| is_pdm_binary(name));
    // PDM first, so that `release/aim-firmware` is the default build afterwards.
    let mut args = vec!["build", "--release", "-p", "aim-firmware", "-p", "aim-hil-tests"];
    args.extend(["--target", TARGET, "--bin", "aim-firmware"]);
    for name in &pdm_bins {
        args.extend(["--bin", name.as_str()]);
    }
    args.extend(PDM_FEATURES);
    cargo(root, &args)?;
    std::fs::create_dir_all(&pdm_dir).with_context(|| format!("creating {}", pdm_dir.display()))?;
    let mut pdm_images = Vec::new();
    for name in std::iter::once("aim-firmware").chain(pdm_bins.iter().map(String::as_str)) {
        let (from, to) = (release.join(name), pdm_dir.join(name));
        std::fs::copy(&from, &to)
            .with_context(|| format!("copying {} to {}", from.display(), to.display()))?;
        pdm_images.push(to);
    }

    cargo(
        root,
        &["build", "--release", "-p", "aim-firmware", "-p", "aim-hil-tests", "--target", TARGET],
    )?;
    let mut images = vec![release.join("aim-firmware")];
    images.extend(tdm_bins.into_iter().map(|name| release.join(name)));
    images.extend(pdm_images);
    for image in &images {
        if !image.is_file() {
            bail!("the build succeeded but {} is not there", image.display());
        }
    }
    Ok(images)
}

/// Checks the layout of each image and emulates its start (both, so that a broken image shows
/// what the board would do); fails if either finds a fault.
pub fn check_images(root: &Path, images: &[PathBuf]) -> Result<()> {
    let mut broken = 0;
    for image in images {
        let bytes = std::fs::read(image).with_context(|| format!("reading {}", image.display()))?;
        let report =
            image_layout::check(&bytes).with_context(|| format!("checking {}", image.display()))?;
        eprintln!("layout: {}", image.display());
        for fact in &report.facts {
            eprintln!("  ok   {fact}");
        }
        for violation in &report.violations {
            eprintln!("  FAIL {violation}");
        }
        broken += usize::from(!report.violations.is_empty());
    }
    let script = root.join("tools/boot/emulate_start.py");
    eprintln!("$ python3 {} <{} images>", script.display(), images.len());
    let status = Command::new("python3").arg(&script).args(images).status().context(
        "running python3 (the emulated start needs python3 with unicorn and pyelftools)",
    )?;
    match (broken, status.success()) {
        (0, true) => Ok(()),
        (0, false) => bail!("the emulated start failed ({status})"),
        (n, emulated) => bail!(
            "{n} of {} board images cannot start (layout){}",
            images.len(),
            if emulated { "" } else { "; the emulated start failed too" }
        ),
    }
}

/// `cargo xtask boot [ELF...]`: the given images, or (none given) every board image, built.
pub fn run(root: &Path, elfs: &[String]) -> Result<()> {
    let images = if elfs.is_empty() {
        build_images(root)?
    } else {
        elfs.iter().map(PathBuf::from).collect()
    };
    check_images(root, &images)
}
