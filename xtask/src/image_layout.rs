//! `cargo xtask boot` part 1: can this STM32H743 image start? Checked on the ELF's symbols,
//! sections and program headers, before any emulation.
//!
//! What cortex-m-rt's reset handler does first, and what must therefore hold:
//! - it loads SP from word 0 of the vector table and jumps to word 1 (the reset handler): the
//!   vector table must sit at the start of flash, the reset handler in flash, the initial
//!   stack pointer in DTCM;
//! - it zeroes `[__sbss, __ebss)` word by word: that range must lie inside one RAM region (a
//!   range that spans a reserved hole bus-faults before `main`, the fault of issue 13, when
//!   `memory.x` inserted `.axisram` after `.bss` and so pushed `__ebss` into AXI SRAM);
//! - it copies `[__sidata, __sidata + (__edata − __sdata))` from flash to `[__sdata, __edata)`:
//!   the source inside flash, the destination inside one RAM region.
//!
//! And what the firmware needs beyond start-up:
//! - `.data`, `.bss` and the stack in DTCM (the fastest RAM, not reachable by DMA1/DMA2);
//! - every DMA buffer (`.axisram`, see `firmware/src/dma_buffer.rs`) in D1 (AXI) or D2 SRAM,
//!   the RAMs DMA1/DMA2 reach;
//! - the zero-filled-by-code sections (`.axisram`, and `.dsp_state`, the DSP state too large
//!   for DTCM) `NOLOAD` (no file contents: nothing stored in flash, nothing loaded) in an
//!   on-chip RAM, and outside `[__sbss, __ebss)` and `[__sdata, __edata)` (the reset handler
//!   neither zeroes nor copies them: `axisram_buffer!` / `dsp_state!` zero each static once);
//! - a stack guard: the firmware's MPU guard region (`firmware/src/fault.rs`: the image holds
//!   the marker symbol `AIM_STACK_GUARD_BYTES`, and the guard `[align_up(_stack_end, 32), +32)`
//!   lies in DTCM above every static and below the initial stack pointer), so that an overflow
//!   faults instead of silently overwriting the statics;
//! - every allocated section inside one region, no two overlapping, every loaded byte stored in
//!   flash.
use std::ops::Range;

use anyhow::{bail, Context, Result};
use object::{
    elf, read::elf::ProgramHeader as _, Endianness, Object, ObjectSection, ObjectSymbol,
    SectionFlags, SectionKind,
};

/// One region of the STM32H743's memory map (RM0433 §2.3.2, "Memory map").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Region {
    /// Name as in `memory.x` and the reference manual.
    pub name: &'static str,
    /// First address.
    pub start: u64,
    /// Size, bytes.
    pub len: u64,
}

impl Region {
    fn contains(&self, range: &Range<u64>) -> bool {
        range.start >= self.start && range.end <= self.start + self.len && range.start <= range.end
    }
}

/// The STM32H743's memories a linked image may use.
pub const STM32H743: [Region; 8] = [
    Region { name: "ITCM", start: 0x0000_0000, len: 0x1_0000 },
    Region { name: "FLASH", start: 0x0800_0000, len: 0x20_0000 },
    Region { name: "DTCM", start: 0x2000_0000, len: 0x2_0000 },
    Region { name: "AXISRAM", start: 0x2400_0000, len: 0x8_0000 },
    // SRAM1, SRAM2 and SRAM3 are contiguous: one D2 region for the check.
    Region { name: "SRAM1-3", start: 0x3000_0000, len: 0x4_8000 },
    Region { name: "SRAM4", start: 0x3800_0000, len: 0x1_0000 },
    Region { name: "BKPSRAM", start: 0x3880_0000, len: 0x1000 },
    // Only for completeness of "inside one region": nothing of ours is linked here.
    Region { name: "SYSTEM", start: 0x1FF0_0000, len: 0x2_0000 },
];

/// Size of the firmware's MPU stack guard region, bytes (`aim_firmware::fault::STACK_GUARD_BYTES`).
const GUARD_BYTES: u64 = 32;

fn region(name: &str) -> Region {
    *STM32H743.iter().find(|r| r.name == name).expect("a region of STM32H743")
}

/// The region that holds all of `range`, if one does.
fn region_of(range: &Range<u64>) -> Option<Region> {
    STM32H743.iter().copied().find(|r| r.contains(range))
}

/// The on-chip RAMs (where a section zero-filled at run time may live).
const ON_CHIP_RAM: [&str; 5] = ["DTCM", "AXISRAM", "SRAM1-3", "SRAM4", "BKPSRAM"];

/// Output sections that the firmware zero-fills at run time (not the reset handler): DMA
/// buffers and the DSP state.
const ZERO_FILLED_BY_CODE: [&str; 2] = [".axisram", ".dsp_state"];

/// Whether section `name` is `base` or one of its subsections (`base.*`).
fn is_section(name: &str, base: &str) -> bool {
    name.strip_prefix(base).is_some_and(|rest| rest.is_empty() || rest.starts_with('.'))
}

/// Whether two address ranges share a byte.
fn overlap(a: &Range<u64>, b: &Range<u64>) -> bool {
    a.start < b.end && b.start < a.end
}

/// An allocated section of an image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Section {
    /// Name, e.g. `.bss`.
    pub name: String,
    /// Address range (virtual, where the code sees it).
    pub range: Range<u64>,
    /// `SHT_NOBITS`: no contents in the file (`.bss`, `NOLOAD` sections).
    pub nobits: bool,
}

/// The result of the layout check: what was found, and each rule broken.
#[derive(Debug, Default)]
pub struct Report {
    /// Human-readable facts, one per line (printed by `cargo xtask boot`).
    pub facts: Vec<String>,
    /// Broken rules, one per line; empty when the image can start.
    pub violations: Vec<String>,
}

fn hex(range: &Range<u64>) -> String {
    format!("{:#010x}..{:#010x}", range.start, range.end)
}

/// What the layout rules look at, read from an ELF (see [`read`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// Address of `.vector_table`.
    pub vector_table: u64,
    /// Word 0 of the vector table: the initial stack pointer.
    pub initial_sp: u64,
    /// Word 1 of the vector table: the reset vector (Thumb bit set).
    pub reset_vector: u64,
    /// Value of cortex-m-rt's `Reset` symbol (a Thumb function: bit 0 may be set).
    pub reset: u64,
    /// `__sbss..__ebss`, zeroed by the reset handler.
    pub bss: Range<u64>,
    /// `__sdata..__edata`, copied by the reset handler.
    pub data: Range<u64>,
    /// `__sidata`: where `.data`'s initial values are stored.
    pub sidata: u64,
    /// `_stack_end`: the end of the statics, where the stack's lowest address may be.
    pub stack_end: u64,
    /// The image holds `AIM_STACK_GUARD_BYTES`, the marker of the firmware's MPU stack guard.
    pub stack_guard: bool,
    /// Allocated sections with a size.
    pub sections: Vec<Section>,
    /// `PT_LOAD` segments with file contents: physical (load) address range.
    pub loads: Vec<Range<u64>>,
}

/// Reads the [`Image`] of an ELF as cortex-m-rt links it.
pub fn read(elf_bytes: &[u8]) -> Result<Image> {
    let file = object::File::parse(elf_bytes).context("not an ELF file")?;
    let symbol = |name: &str| -> Result<u64> {
        file.symbols()
            .find(|s| s.name() == Ok(name))
            .map(|s| s.address())
            .with_context(|| format!("symbol `{name}` missing: not a cortex-m-rt image?"))
    };
    let vector_table = file.section_by_name(".vector_table").context("no .vector_table section")?;
    let words = vector_table.data().context("reading .vector_table")?;
    if words.len() < 8 {
        bail!(".vector_table holds {} bytes, fewer than SP and the reset vector", words.len());
    }
    let word = |i: usize| {
        u64::from(u32::from_le_bytes([
            words[4 * i],
            words[4 * i + 1],
            words[4 * i + 2],
            words[4 * i + 3],
        ]))
    };
    let mut sections = Vec::new();
    for section in file.sections() {
        let allocated = matches!(section.flags(),
            SectionFlags::Elf { sh_flags } if sh_flags & u64::from(elf::SHF_ALLOC) != 0);
        if allocated && section.size() > 0 {
            let name = section.name().unwrap_or("?").to_string();
            let range = section.address()..section.address() + section.size();
            let nobits = matches!(section.kind(), SectionKind::UninitializedData);
            sections.push(Section { name, range, nobits });
        }
    }
    let object::File::Elf32(elf32) = &file else {
        bail!("not a 32-bit ELF: not a Cortex-M image");
    };
    let endian = Endianness::Little;
    let loads = elf32
        .elf_program_headers()
        .iter()
        .filter(|h| h.p_type(endian) == elf::PT_LOAD && h.p_filesz(endian) > 0)
        .map(|h| {
            let lma = u64::from(h.p_paddr(endian));
            lma..lma + u64::from(h.p_filesz(endian))
        })
        .collect();
    Ok(Image {
        vector_table: vector_table.address(),
        initial_sp: word(0),
        reset_vector: word(1),
        reset: symbol("Reset")?,
        bss: symbol("__sbss")?..symbol("__ebss")?,
        data: symbol("__sdata")?..symbol("__edata")?,
        sidata: symbol("__sidata")?,
        stack_end: symbol("_stack_end")?,
        stack_guard: symbol("AIM_STACK_GUARD_BYTES").is_ok(),
        sections,
        loads,
    })
}

/// Checks an STM32H743 firmware image (an ELF as cortex-m-rt links it).
pub fn check(elf_bytes: &[u8]) -> Result<Report> {
    Ok(rules(&read(elf_bytes)?))
}

/// Applies the layout rules of this module's header to an image.
pub fn rules(image: &Image) -> Report {
    let mut report = Report::default();
    let mut rule = |ok: bool, fact: String, broken: String| {
        if ok {
            report.facts.push(fact);
        } else {
            report.violations.push(broken);
        }
    };
    let flash = region("FLASH");
    let dtcm = region("DTCM");
    let Image { vector_table, initial_sp, reset_vector, reset, .. } = *image;

    // Vector table: SP and the reset vector, as the core reads them at reset.
    rule(
        vector_table == flash.start,
        format!("vector table at {vector_table:#010x} (start of flash)"),
        format!(
            "vector table at {vector_table:#010x}, not at the start of flash {:#010x}",
            flash.start
        ),
    );
    rule(
        reset_vector & 1 == 1
            && reset_vector & !1 == reset & !1
            && flash.contains(&(reset & !1..(reset & !1) + 2)),
        format!("reset vector {reset_vector:#010x} → Reset in flash"),
        format!("reset vector {reset_vector:#010x} is not Thumb code of `Reset` ({reset:#010x}) in flash"),
    );
    rule(
        initial_sp > dtcm.start && initial_sp <= dtcm.start + dtcm.len && initial_sp % 8 == 0,
        format!("initial SP {initial_sp:#010x} in DTCM"),
        format!("initial SP {initial_sp:#010x} is not an 8-aligned address in DTCM"),
    );

    // The zero-init and the copy of cortex-m-rt's reset handler.
    let bss = &image.bss;
    rule(
        dtcm.contains(bss),
        format!("zero-init {} ({} bytes) in DTCM", hex(bss), bss.end - bss.start),
        format!(
            "zero-init range {} (__sbss..__ebss) is not inside DTCM {}: {}",
            hex(bss),
            hex(&(dtcm.start..dtcm.start + dtcm.len)),
            match region_of(bss) {
                Some(r) => format!("it lies in {}", r.name),
                None =>
                    "it spans regions and the reserved space between them (bus fault before main)"
                        .into(),
            }
        ),
    );
    let data = &image.data;
    let data_load = image.sidata..image.sidata + data.end.saturating_sub(data.start);
    rule(
        dtcm.contains(data),
        format!("initialised data {} in DTCM", hex(data)),
        format!("initialised data range {} (__sdata..__edata) is not inside DTCM", hex(data)),
    );
    rule(
        flash.contains(&data_load),
        format!("its load image {} in flash", hex(&data_load)),
        format!("the load image of .data {} is not inside flash", hex(&data_load)),
    );

    // Stack guard: the firmware's MPU region of 32 bytes at `_stack_end` rounded up to 32,
    // between the statics and the stack (`firmware/src/fault.rs`).
    let guard_base = (image.stack_end + GUARD_BYTES - 1) & !(GUARD_BYTES - 1);
    let guard = guard_base..guard_base + GUARD_BYTES;
    let statics_end = bss.end.max(data.end);
    rule(
        image.stack_guard
            && dtcm.contains(&guard)
            && guard.start >= statics_end
            && guard.end < initial_sp,
        format!(
            "stack guard {} (MPU, 32 bytes) between the statics (end {statics_end:#010x}) and \
             the stack (top {initial_sp:#010x})",
            hex(&guard)
        ),
        if image.stack_guard {
            format!(
                "the stack guard {} is not in DTCM between the statics (end {statics_end:#010x}) \
                 and the initial SP {initial_sp:#010x}",
                hex(&guard)
            )
        } else {
            "no stack guard: the image lacks `AIM_STACK_GUARD_BYTES` (aim_firmware::fault's \
             MPU guard, installed by `init_core`), so an overflow overwrites the statics silently"
                .into()
        },
    );

    // Every allocated section inside one region; DMA buffers in D1/D2 SRAM.
    for Section { name, range, .. } in &image.sections {
        let home = region_of(range);
        rule(
            home.is_some(),
            format!("section {name} {} in {}", hex(range), home.map_or("?", |r| r.name)),
            format!("section {name} {} is not inside one memory region", hex(range)),
        );
        if is_section(name, ".axisram") {
            let dma_ok = home.is_some_and(|r| r.name == "AXISRAM" || r.name == "SRAM1-3");
            rule(
                dma_ok,
                format!("DMA buffers ({name}) in D1/D2 SRAM"),
                format!("DMA buffers ({name}) at {} are not in AXI SRAM or SRAM1-3", hex(range)),
            );
        }
        if name == ".data" || name == ".bss" || name == ".uninit" {
            rule(
                home.is_some_and(|r| r.name == "DTCM"),
                format!("{name} in DTCM"),
                format!("{name} at {} is not in DTCM", hex(range)),
            );
        }
    }

    // Sections zero-filled by the firmware's code: NOLOAD, in on-chip RAM, out of reach of the
    // reset handler's zero loop and copy.
    for Section { name, range, nobits } in &image.sections {
        if !ZERO_FILLED_BY_CODE.iter().any(|base| is_section(name, base)) {
            continue;
        }
        let home = region_of(range);
        let ram = home.is_some_and(|r| ON_CHIP_RAM.contains(&r.name));
        let by_code = !overlap(range, bss) && !overlap(range, data);
        rule(
            *nobits && ram && by_code,
            format!(
                "{name} {} NOLOAD in {}, zero-filled by code (outside the reset handler's ranges)",
                hex(range),
                home.map_or("?", |r| r.name)
            ),
            format!(
                "{name} {} must be NOLOAD{}, in an on-chip RAM{} and outside __sbss..__ebss \
                 and __sdata..__edata{}",
                hex(range),
                if *nobits { "" } else { " (it has file contents)" },
                if ram { "" } else { " (it is not)" },
                if by_code { "" } else { " (it overlaps them: the reset handler writes it)" },
            ),
        );
    }

    // No two allocated sections share an address.
    let sections = &image.sections;
    let overlaps: Vec<String> = sections
        .iter()
        .enumerate()
        .flat_map(|(i, a)| sections[i + 1..].iter().map(move |b| (a, b)))
        .filter(|(a, b)| overlap(&a.range, &b.range))
        .map(|(a, b)| {
            format!(
                "sections {} {} and {} {} overlap",
                a.name,
                hex(&a.range),
                b.name,
                hex(&b.range)
            )
        })
        .collect();
    rule(
        overlaps.is_empty(),
        format!("{} allocated sections, no two overlapping", sections.len()),
        overlaps.join("; "),
    );

    // Every byte the loader stores goes to flash.
    for load in &image.loads {
        rule(
            flash.contains(load),
            format!("load segment {} in flash", hex(load)),
            format!("load segment {} (physical address) is not inside flash", hex(load)),
        );
    }
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    fn section(name: &str, range: Range<u64>, nobits: bool) -> Section {
        Section { name: name.into(), range, nobits }
    }

    /// A good image: statics at the start of DTCM, the guard above them, the stack at the top,
    /// DMA buffers and then the DSP state in AXI SRAM.
    fn good() -> Image {
        Image {
            vector_table: 0x0800_0000,
            initial_sp: 0x2002_0000,
            reset_vector: 0x0800_0299,
            reset: 0x0800_0298,
            bss: 0x2000_0010..0x2001_6050,
            data: 0x2000_0000..0x2000_0010,
            sidata: 0x0801_2000,
            stack_end: 0x2001_6060,
            stack_guard: true,
            sections: vec![
                section(".vector_table", 0x0800_0000..0x0800_0298, false),
                section(".text", 0x0800_0298..0x0801_0000, false),
                section(".data", 0x2000_0000..0x2000_0010, false),
                section(".bss", 0x2000_0010..0x2001_6050, true),
                section(".axisram", 0x2400_0000..0x2401_0000, true),
                section(".dsp_state", 0x2401_0000..0x2402_f1e0, true),
            ],
            loads: std::iter::once(0x0800_0000..0x0801_2010).collect(),
        }
    }

    #[test]
    fn a_startable_image_passes_every_rule() {
        let report = rules(&good());
        assert!(report.violations.is_empty(), "{:?}", report.violations);
    }

    #[test]
    fn the_issue_13_layout_is_caught() {
        // Read in the release ELF at fb5587a: `.axisram` inserted after `.bss` pushed __ebss
        // into AXI SRAM, so the zero loop ran through the reserved hole after DTCM.
        let image = Image { bss: 0x2000_0050..0x2401_4060, stack_end: 0x2401_4060, ..good() };
        let report = rules(&image);
        assert!(
            report
                .violations
                .iter()
                .any(|v| v.contains("zero-init") && v.contains("reserved space")),
            "{:?}",
            report.violations
        );
    }

    #[test]
    fn an_image_without_the_guard_or_with_it_in_the_stack_is_caught() {
        let report = rules(&Image { stack_guard: false, ..good() });
        assert!(
            report.violations.iter().any(|v| v.contains("no stack guard")),
            "{:?}",
            report.violations
        );
        // Statics ending above the initial SP: the guard cannot sit below the stack.
        let report = rules(&Image { initial_sp: 0x2001_0000, ..good() });
        assert!(
            report.violations.iter().any(|v| v.contains("the stack guard")),
            "{:?}",
            report.violations
        );
    }

    #[test]
    fn dma_buffers_in_dtcm_data_in_flash_and_a_load_outside_flash_are_caught() {
        let mut image = good();
        image.sections.push(section(".axisram", 0x2001_8000..0x2001_9000, true));
        image.sections.push(section(".data", 0x2400_0000..0x2400_0010, false));
        image.loads.push(0x2000_0000..0x2000_0010);
        let report = rules(&image);
        for needle in ["not in AXI SRAM", ".data at", "not inside flash"] {
            assert!(
                report.violations.iter().any(|v| v.contains(needle)),
                "{needle}: {:?}",
                report.violations
            );
        }
    }

    /// `good()` with its `.dsp_state` section replaced by `dsp_state`.
    fn with_dsp_state(dsp_state: Section) -> Report {
        let mut image = good();
        image.sections.retain(|s| s.name != ".dsp_state");
        image.sections.push(dsp_state);
        rules(&image)
    }

    fn caught(report: &Report, needle: &str) -> bool {
        report.violations.iter().any(|v| v.contains(needle))
    }

    #[test]
    fn dsp_state_loaded_zeroed_by_the_reset_handler_or_outside_ram_is_caught() {
        // With file contents (not NOLOAD): the image would store 127 KB of zeros.
        let report = with_dsp_state(section(".dsp_state", 0x2401_0000..0x2402_f1e0, false));
        assert!(caught(&report, "(it has file contents)"), "{:?}", report.violations);
        // Inside __sbss..__ebss: the reset handler would zero it (and it overlaps .bss).
        let report = with_dsp_state(section(".dsp_state", 0x2000_1000..0x2000_2000, true));
        assert!(caught(&report, "the reset handler writes it"), "{:?}", report.violations);
        assert!(caught(&report, "overlap"), "{:?}", report.violations);
        // In flash.
        let report = with_dsp_state(section(".dsp_state", 0x0802_0000..0x0802_1000, true));
        assert!(caught(&report, "(it is not)"), "{:?}", report.violations);
        // Across the end of AXI SRAM: in no region, so in no RAM.
        let report = with_dsp_state(section(".dsp_state.x", 0x2407_f000..0x2408_1000, true));
        assert!(caught(&report, "not inside one memory region"), "{:?}", report.violations);
        assert!(caught(&report, "(it is not)"), "{:?}", report.violations);
    }

    #[test]
    fn dsp_state_over_the_dma_buffers_is_caught() {
        let report = with_dsp_state(section(".dsp_state", 0x2400_f000..0x2402_f1e0, true));
        assert_eq!(report.violations.len(), 1, "{:?}", report.violations);
        assert!(caught(&report, "sections .axisram"), "{:?}", report.violations);
        assert!(caught(&report, "and .dsp_state"), "{:?}", report.violations);
    }

    #[test]
    fn zero_filled_sections_are_named_exactly() {
        assert!(is_section(".dsp_state", ".dsp_state"));
        assert!(is_section(".axisram.buffers", ".axisram"));
        assert!(!is_section(".axisramx", ".axisram"));
        assert!(!is_section(".bss", ".dsp_state"));
    }

    #[test]
    fn a_reset_vector_without_the_thumb_bit_is_caught() {
        let image = Image { reset_vector: 0x0800_0298, reset: 0x0800_0299, ..good() };
        assert!(rules(&image).violations.iter().any(|v| v.contains("reset vector")));
    }

    #[test]
    fn regions_do_not_overlap() {
        for (i, a) in STM32H743.iter().enumerate() {
            for b in &STM32H743[i + 1..] {
                let disjoint = a.start + a.len <= b.start || b.start + b.len <= a.start;
                assert!(disjoint, "{} and {} overlap", a.name, b.name);
            }
        }
    }

    #[test]
    fn a_range_across_the_dtcm_hole_is_in_no_region() {
        // The broken image of issue 13: __sbss in DTCM, __ebss in AXI SRAM.
        assert_eq!(region_of(&(0x2000_0050..0x2401_4060)), None);
        assert_eq!(region_of(&(0x2000_0050..0x2000_4060)).map(|r| r.name), Some("DTCM"));
    }
}
