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
    aim_wire::{
        from_dsp::{self, FirmwareCounters},
        Encoder, MAX_ENCODED_LEN,
    },
    pdm::PdmSignal,
    probe::Probe,
    report::{self, CHUNK_FRAMES, MAX_TDM_SLOTS},
    scenario::{Scenario, COST},
    signal::Signal,
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
        measure(out, pipeline, scenario, "", &mut scenario.signal())?;
    }
    // The 8-microphone array with PDM microphones: decimator + the same pipeline.
    let scenario = &COST[2];
    let mics = scenario.config().tdm_slots;
    let mut pdm = PdmInput {
        pdm: PdmSignal::new(scenario.signal(), mics),
        decimator: PdmDecimator::new(mics, mics),
        bytes: [0; CHUNK_FRAMES * BYTES_PER_OUTPUT * MAX_TDM_SLOTS],
    };
    measure(out, pipeline, scenario, "-pdm", &mut pdm)?;
    writeln!(out, "ram pdm-decimator {}", core::mem::size_of::<PdmDecimator>())?;

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

/// Warms the pipeline up for two BPF hops, then measures `measured_samples` of golden input
/// from `signal` (section `<scenario><suffix>`).
fn measure(
    out: &mut Out,
    pipeline: &mut Pipeline,
    scenario: &Scenario,
    suffix: &str,
    signal: &mut dyn Input,
) -> core::fmt::Result {
    let config = scenario.config();
    if pipeline.configure(&config).is_err() {
        writeln!(out, "error: scenario {} does not configure", scenario.name)?;
        fail();
    }
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
    writeln!(out, "section warmup-{}{suffix} {warm_up} {}", scenario.name, config.sample_rate_hz)?;
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
    writeln!(out, "ram stack-{}{suffix} {stack}", scenario.name)?;
    // Working memory of the DSP: the pipeline itself plus the deepest stack of the measured
    // loop (input synthesis, `push` with its sink, the encode path): an upper bound for `push`.
    writeln!(
        out,
        "ram dsp-{}{suffix} {}",
        scenario.name,
        core::mem::size_of::<Pipeline>() + stack
    )?;
    writeln!(out, "section {}{suffix} {} {}", scenario.name, end - start, config.sample_rate_hz)?;
    probe(Probe::Dump);
    Ok(())
}

/// Where a measured section's TDM words come from.
trait Input {
    /// Writes the next chunk of words (charged to `input`, or to the probes it switches to).
    fn fill(&mut self, words: &mut [i32]);
    /// Index of the next frame `fill` writes.
    fn sample_index(&self) -> u64;
}

impl Input for Signal {
    fn fill(&mut self, words: &mut [i32]) {
        Signal::fill(self, words);
    }
    fn sample_index(&self) -> u64 {
        Signal::sample_index(self)
    }
}

/// PDM microphones: the golden PDM bytes of a chunk (synthesis charged to `input`), then the
/// decimator (charged to `pdm`), which writes the words.
struct PdmInput {
    pdm: PdmSignal,
    decimator: PdmDecimator,
    bytes: [u8; CHUNK_FRAMES * BYTES_PER_OUTPUT * MAX_TDM_SLOTS],
}

impl Input for PdmInput {
    fn fill(&mut self, words: &mut [i32]) {
        let bytes = &mut self.bytes[..CHUNK_FRAMES * self.pdm.frame_bytes()];
        self.pdm.fill(bytes);
        probe(Probe::Pdm);
        let slots = self.decimator.mics();
        if self.decimator.push(bytes, words, slots) != Ok(CHUNK_FRAMES) {
            fail();
        }
    }
    fn sample_index(&self) -> u64 {
        self.pdm.sample_index()
    }
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
