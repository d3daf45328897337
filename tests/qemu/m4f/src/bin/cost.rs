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
    aim_dsp::{
        pdm::{PdmDecimator, BYTES_PER_OUTPUT},
        Output, Pipeline,
    },
    pdm::PdmSignal,
    aim_wire::{
        from_dsp::{self, FirmwareCounters},
        Encoder, MAX_ENCODED_LEN,
    },
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
    // The 8-microphone array with PDM microphones: decimator + the same pipeline.
    measure_pdm(out, pipeline, &COST[2])?;

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
    // As in the firmware: the sink keeps the outputs of a chunk, which are encoded into frames
    // after `push` (charged to `encode`, not to the pipeline).
    let mut encoder = Encoder::new(1);
    let counters = FirmwareCounters::default();
    let mut bytes = 0usize;
    let mut encode = |pending: &mut Pending| {
        let mut frame = [0u8; MAX_ENCODED_LEN];
        for output in pending.outputs[..pending.len].iter().flatten() {
            bytes +=
                from_dsp::encode_output(&mut encoder, output, &counters, &mut frame).unwrap_or(0);
        }
        pending.len = 0;
    };
    let mut pending = Pending { outputs: [None; MAX_OUTPUTS_PER_CHUNK], len: 0 };
    // Warm-up (the BPF analysis window fills first): a section of its own, so that the
    // plugin's stage ranges do not charge it to the measured section.
    let warm_up = scenario.measured_samples() as u64 / 8;
    while signal.sample_index() < warm_up {
        probe(Probe::Input);
        signal.fill(words);
        probe(Probe::PipelineOther);
        pipeline.push(words, &mut |output| pending.keep(output));
        probe(Probe::Untracked);
        encode(&mut pending);
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
        pipeline.push(words, &mut |output| pending.keep(output));
        probe(Probe::Encode);
        encode(&mut pending);
        probe(Probe::Untracked);
    }
    let stack = gauge.used();
    core::hint::black_box(bytes);
    writeln!(out, "ram stack-{} {stack}", scenario.name)?;
    // Working memory of the DSP: the pipeline itself plus the deepest stack of the measured
    // loop (input synthesis, `push` with its sink, the encode path): an upper bound for `push`.
    writeln!(out, "ram dsp-{} {}", scenario.name, core::mem::size_of::<Pipeline>() + stack)?;
    writeln!(out, "section {} {} {}", scenario.name, end - start, config.sample_rate_hz)?;
    probe(Probe::Dump);
    Ok(())
}

/// As [`measure`], with PDM microphones: per chunk, the golden PDM bytes (synthesis charged to
/// `input`), the decimator (`pdm`), then the pipeline on its words. Section `<name>-pdm`.
fn measure_pdm(out: &mut Out, pipeline: &mut Pipeline, scenario: &Scenario) -> core::fmt::Result {
    let config = scenario.config();
    if pipeline.configure(&config).is_err() || config.tdm_slots != config.geometry.positions().len()
    {
        writeln!(out, "error: scenario {} does not configure for PDM", scenario.name)?;
        fail();
    }
    let mics = config.tdm_slots;
    let mut pdm = PdmSignal::new(scenario.signal(), mics);
    let mut decimator = PdmDecimator::new(mics, mics);
    let mut bytes = [0u8; CHUNK_FRAMES * BYTES_PER_OUTPUT * MAX_TDM_SLOTS];
    let bytes = &mut bytes[..CHUNK_FRAMES * pdm.frame_bytes()];
    let mut words = [0i32; CHUNK_FRAMES * MAX_TDM_SLOTS];
    let words = &mut words[..CHUNK_FRAMES * mics];
    let mut pending = Pending { outputs: [None; MAX_OUTPUTS_PER_CHUNK], len: 0 };
    let mut chunk = |pdm: &mut PdmSignal, pending: &mut Pending| {
        probe(Probe::Input);
        pdm.fill(bytes);
        probe(Probe::Pdm);
        let frames = decimator.push(bytes, words, mics);
        probe(Probe::PipelineOther);
        pipeline.push(words, &mut |output| pending.keep(output));
        probe(Probe::Untracked);
        pending.len = 0;
        frames == Ok(CHUNK_FRAMES)
    };
    let warm_up = scenario.measured_samples() as u64 / 8;
    while pdm.sample_index() < warm_up {
        if !chunk(&mut pdm, &mut pending) {
            fail();
        }
    }
    writeln!(out, "section warmup-{}-pdm {warm_up} {}", scenario.name, config.sample_rate_hz)?;
    probe(Probe::Dump);
    let start = pdm.sample_index();
    let end = start + scenario.measured_samples() as u64;
    while pdm.sample_index() < end {
        if !chunk(&mut pdm, &mut pending) {
            fail();
        }
    }
    writeln!(out, "ram pdm-decimator {}", core::mem::size_of::<PdmDecimator>())?;
    writeln!(out, "section {}-pdm {} {}", scenario.name, end - start, config.sample_rate_hz)?;
    probe(Probe::Dump);
    Ok(())
}

/// Most outputs one chunk of 256 frames can complete (as in the firmware).
const MAX_OUTPUTS_PER_CHUNK: usize = 8;

/// The outputs of one `push`, waiting to be encoded.
struct Pending {
    outputs: [Option<Output>; MAX_OUTPUTS_PER_CHUNK],
    len: usize,
}

impl Pending {
    /// Keeps `output`; drops it if the chunk produced more than the firmware keeps.
    fn keep(&mut self, output: Output) {
        if let Some(slot) = self.outputs.get_mut(self.len) {
            *slot = Some(output);
            self.len += 1;
        }
    }
}
