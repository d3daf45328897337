//! `cargo xtask boot`: proves that every board image can start, without a board.
//!
//! For the firmware and each hardware-in-the-loop binary (release, `thumbv7em-none-eabihf`):
//! 1. the layout check of [`crate::image_layout`] on the ELF (zero-init and load ranges, regions,
//!    vector table, stack guard, DMA buffers);
//! 2. an emulated start of the same ELF on the STM32H743 memory map
//!    (`tools/boot/emulate_start.py`, the unicorn engine): from the reset vector to `main`'s
//!    first peripheral access, failing on any access outside a mapped region.
use std::{
    path::{Path, PathBuf},
    process::Command,
};

use anyhow::{bail, Context, Result};

use crate::{budget::target_dir, cargo, image_layout};

/// The board's target triple.
const TARGET: &str = "thumbv7em-none-eabihf";

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

/// Builds the board images and returns their ELF paths (the firmware first).
pub fn build_images(root: &Path) -> Result<Vec<PathBuf>> {
    cargo(
        root,
        &["build", "--release", "-p", "aim-firmware", "-p", "aim-hil-tests", "--target", TARGET],
    )?;
    let release = target_dir(root)?.join(TARGET).join("release");
    let mut images = vec![release.join("aim-firmware")];
    images.extend(hil_binaries(root)?.into_iter().map(|name| release.join(name)));
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
