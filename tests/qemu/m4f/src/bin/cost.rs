//! Runs the checked computations between probes, for the `insn_probe` QEMU plugin.
//!
//! Prints one `section <name> <samples> <sample_rate_hz>` line per measured section (before the
//! section's `Dump` probe, in the same order as the plugin's sections), and
//! `ram <name> <bytes>` lines.
#![no_std]
#![no_main]

use core::fmt::Write;

use aim_golden::{probe::Probe, report};
use aim_qemu_m4f::{fail, probe, succeed, Out};
use cortex_m_rt::entry;

#[entry]
fn main() -> ! {
    let mut out = Out::open();
    if run(&mut out).is_err() {
        fail();
    }
    succeed()
}

fn run(out: &mut Out) -> core::fmt::Result {
    // Reference figure: one microfft rfft_1024 on golden input.
    let mut x = [0f32; 1024];
    probe(Probe::Input);
    report::reference_rfft_input(&mut x);
    probe(Probe::ReferenceRfft);
    let spectrum = microfft::real::rfft_1024(&mut x);
    probe(Probe::Untracked);
    core::hint::black_box(spectrum);
    writeln!(out, "section reference 1024 {}", report::SAMPLE_RATE_HZ)?;
    probe(Probe::Dump);
    Ok(())
}
