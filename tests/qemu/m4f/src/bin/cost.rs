//! Runs the pipeline between probes, for the `insn_probe` QEMU plugin.
//!
//! Prints one `section <name> <samples> <sample_rate_hz>` line per section (in the same order
//! as the plugin's sections; per configuration a `warmup-<name>` section, then `<name>`), and
//! `ram <name> <bytes>` lines: the pipeline's size, the peak stack depth of `Pipeline::push`,
//! and their sum.
#![no_std]
#![no_main]

use core::fmt::Write;

use aim_golden::{
    aim_dsp::Pipeline,
    probe::Probe,
    report::{self, CHUNK_FRAMES, MAX_TDM_SLOTS},
    scenario::{Scenario, COST},
};
use aim_qemu_m4f::{fail, probe, succeed, Out, StackGauge};
use cortex_m_rt::entry;

#[entry]
fn main() -> ! {
    let mut out = Out::open();
    let Some(pipeline) = cortex_m::singleton!(: Pipeline = Pipeline::empty()) else { fail() };
    if run(&mut out, pipeline).is_err() {
        fail();
    }
    succeed()
}

fn run(out: &mut Out, pipeline: &mut Pipeline) -> core::fmt::Result {
    writeln!(out, "ram pipeline {}", core::mem::size_of::<Pipeline>())?;
    for scenario in &COST {
        measure(out, pipeline, scenario)?;
    }

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

/// Warms the pipeline up for two BPF hops, then measures `measured_samples` of golden input.
fn measure(out: &mut Out, pipeline: &mut Pipeline, scenario: &Scenario) -> core::fmt::Result {
    let config = scenario.config();
    if pipeline.configure(&config).is_err() {
        writeln!(out, "error: scenario {} does not configure", scenario.name)?;
        fail();
    }
    let mut signal = scenario.signal();
    let mut words = [0i32; CHUNK_FRAMES * MAX_TDM_SLOTS];
    let words = &mut words[..CHUNK_FRAMES * config.tdm_slots];
    let mut outputs = 0u32;
    let mut sink = |_| outputs += 1;
    // Warm-up (the BPF analysis window fills first): a section of its own, so that the
    // plugin's stage ranges do not charge it to the measured section.
    let warm_up = scenario.measured_samples() as u64 / 8;
    while signal.sample_index() < warm_up {
        probe(Probe::Input);
        signal.fill(words);
        probe(Probe::PipelineOther);
        pipeline.push(words, &mut sink);
        probe(Probe::Untracked);
    }
    writeln!(out, "section warmup-{} {warm_up} {}", scenario.name, config.sample_rate_hz)?;
    probe(Probe::Dump);
    let start = signal.sample_index();
    let end = start + scenario.measured_samples() as u64;
    let gauge = StackGauge::paint(32 * 1024);
    while signal.sample_index() < end {
        probe(Probe::Input);
        signal.fill(words);
        probe(Probe::PipelineOther);
        pipeline.push(words, &mut sink);
        probe(Probe::Untracked);
    }
    let stack = gauge.used();
    core::hint::black_box(outputs);
    writeln!(out, "ram stack-{} {stack}", scenario.name)?;
    // Working memory of the DSP: the pipeline itself plus the deepest stack of `push`.
    writeln!(out, "ram dsp-{} {}", scenario.name, core::mem::size_of::<Pipeline>() + stack)?;
    writeln!(out, "section {} {} {}", scenario.name, end - start, config.sample_rate_hz)?;
    probe(Probe::Dump);
    Ok(())
}
