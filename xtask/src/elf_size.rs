//! Flash and static RAM of an ELF image, from its section headers.
//!
//! Flash holds every allocated section that has contents (code, read-only data, the vector
//! table) plus the load image of initialised RAM sections (`.data`, whose initial values are
//! copied from flash at reset). Static RAM is every allocated section whose address lies in a
//! RAM region, with or without contents (`.data`, `.bss`, `.uninit`, DMA buffers). The stack
//! and heap are not sections and are not counted.
use anyhow::{Context, Result};
use object::{Object, ObjectSection, SectionFlags, SectionKind};
use serde::Deserialize;

/// Address ranges, each `[start, length]` in bytes.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Regions {
    /// Flash ranges.
    pub flash: Vec<[u64; 2]>,
    /// RAM ranges.
    pub ram: Vec<[u64; 2]>,
}

/// Measured image size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageSize {
    /// Bytes stored in flash.
    pub flash: u64,
    /// Bytes of static RAM.
    pub ram: u64,
}

fn within(ranges: &[[u64; 2]], address: u64) -> bool {
    ranges.iter().any(|&[start, len]| address >= start && address < start + len)
}

/// Measures an ELF image against the regions.
pub fn measure(elf: &[u8], regions: &Regions) -> Result<ImageSize> {
    let file = object::File::parse(elf).context("not an ELF file")?;
    let mut size = ImageSize { flash: 0, ram: 0 };
    for section in file.sections() {
        let allocated = match section.flags() {
            SectionFlags::Elf { sh_flags } => sh_flags & u64::from(object::elf::SHF_ALLOC) != 0,
            _ => false,
        };
        if !allocated || section.size() == 0 {
            continue;
        }
        let has_contents = !matches!(
            section.kind(),
            SectionKind::UninitializedData | SectionKind::UninitializedTls
        );
        if within(&regions.flash, section.address()) {
            size.flash += section.size();
        } else if within(&regions.ram, section.address()) {
            size.ram += section.size();
            if has_contents {
                size.flash += section.size();
            }
        }
    }
    Ok(size)
}
