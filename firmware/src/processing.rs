//! The processing task: runs `aim_dsp::Pipeline` on each captured chunk, times it with the DWT
//! cycle counter, feeds the independent watchdog, and turns the DSP outputs into `aim-wire`
//! frames (with `aim_wire::from_dsp`, the same mapping the simulator uses, so both send the
//! same bytes) for the uplink queue.
use aim_dsp::{ConfigError, Output, Pipeline};
use aim_wire::from_dsp::{self, FirmwareCounters};
use embassy_stm32::peripherals::IWDG1;
use embassy_stm32::wdg::IndependentWatchdog;

use crate::boot::StartReport;
use crate::capture::{Chunk, ChunkReceiver};
use crate::config::{self, CHUNK_FRAMES, HELLO_INTERVAL_SAMPLES};
use crate::stats::{bump, read, CycleCounter, CycleStats, COUNTERS};
use crate::uplink::{EncodedFrame, MAX_FRAME_BYTES, UPLINK_QUEUE};

/// Most DSP outputs one chunk can produce (one block ends per chunk at most: DoA, peaks,
/// health); more are counted in `outputs_overflowed`.
const MAX_OUTPUTS_PER_CHUNK: usize = 8;

/// The DSP configuration for this board (geometry and rates from [`config`]).
pub fn dsp_config() -> aim_dsp::Config {
    aim_dsp::Config::new(config::geometry(), config::SAMPLE_RATE_HZ)
}

/// The pipeline, in a static in AXI SRAM, configured in place (call once).
///
/// `Pipeline` is ≈ 127 KB and the stack ≈ 12 KB, so it must never exist as a value: neither
/// `Pipeline::new` (returns it by value) nor `StaticCell::init_with(Pipeline::empty)` (the
/// compiler builds the value in the caller's frame, then copies it: a 114 KB stack frame in
/// `main`, measured in the disassembly). Nor does it fit in DTCM beside the other statics and
/// the stack (`.bss` overflowed DTCM by 5.4 KB): it is a zero-filled static in AXI SRAM
/// ([`dsp_state!`](crate::dsp_state): no stack, no flash, no start-up zeroing), and
/// `configure` then sets it up.
pub fn pipeline() -> &'static mut Pipeline {
    let pipeline = crate::dsp_state!(Pipeline);
    if let Err(error) = pipeline.configure(&dsp_config()) {
        config_rejected(&error);
    }
    pipeline
}

/// Stops with the reason the DSP refused the board's configuration: the values go to the
/// defmt log, a fixed text to the panic (so the retained record and the next `Hello` name
/// it). (defmt, not `core::fmt`, for the values: float formatting alone would cost 20 KB of
/// flash.)
fn config_rejected(error: &ConfigError) -> ! {
    match *error {
        ConfigError::MicCount(n) => {
            defmt::error!("DSP config: {} microphones", n);
            panic!("DSP config: microphone count");
        }
        ConfigError::SampleRate(hz) => {
            defmt::error!("DSP config: sample rate {} Hz", hz);
            panic!("DSP config: sample rate");
        }
        ConfigError::BlockLen(n) => {
            defmt::error!("DSP config: block length {}", n);
            panic!("DSP config: block length");
        }
        ConfigError::TdmSlots { slots, mics } => {
            defmt::error!("DSP config: {} TDM slots for {} microphones", slots, mics);
            panic!("DSP config: TDM slots");
        }
        ConfigError::ApertureTooLarge { aperture_m } => {
            defmt::error!("DSP config: aperture {} m too large", aperture_m);
            panic!("DSP config: aperture too large");
        }
        _ => panic!("DSP config rejected"),
    }
}

/// Reinterprets captured TDM words as the `i32` samples the pipeline takes (left-justified
/// 24-bit two's complement: the bits are the same, only the type differs).
pub fn tdm_words(chunk: &Chunk) -> &[i32] {
    let words = &chunk.words;
    // SAFETY: u32 and i32 have the same size and alignment, and every bit pattern is a valid
    // value of both; the returned slice borrows `chunk`.
    unsafe { core::slice::from_raw_parts(words.as_ptr().cast::<i32>(), words.len()) }
}

/// Stamps frames with this array's id and sequence numbers, encodes them, and queues them.
pub struct FrameSink {
    encoder: aim_wire::Encoder,
}

impl FrameSink {
    /// A sink for frames of array `array_id` (the board's: [`config::array_id`]).
    pub const fn new(array_id: u8) -> Self {
        Self { encoder: aim_wire::Encoder::new(array_id) }
    }

    /// Encodes `body` and queues it (dropping the oldest queued frame if the queue is full).
    pub fn send(&mut self, sample_index: u64, body: aim_wire::Body) {
        let encoder = &mut self.encoder;
        Self::queue(|buffer| encoder.encode(sample_index, body, buffer));
    }

    /// Encodes one pipeline output (with the firmware's counters, for `Health`) and queues it.
    pub fn send_output(&mut self, output: &Output, counters: &FirmwareCounters) {
        let encoder = &mut self.encoder;
        Self::queue(|buffer| from_dsp::encode_output(encoder, output, counters, buffer));
    }

    fn queue(encode: impl FnOnce(&mut [u8]) -> Result<usize, aim_wire::EncodeError>) {
        let mut frame = EncodedFrame::new();
        // Cannot fail: the length is the capacity.
        let _ = frame.resize(MAX_FRAME_BYTES, 0);
        match encode(&mut frame) {
            Ok(len) => {
                frame.truncate(len);
                UPLINK_QUEUE.push_drop_oldest(frame);
            }
            Err(aim_wire::EncodeError::BufferTooSmall { needed, available }) => {
                bump(&COUNTERS.frames_unencodable);
                defmt::warn!("frame needs {} bytes, buffer has {}", needed, available);
            }
            Err(_) => {
                bump(&COUNTERS.frames_unencodable);
                defmt::warn!("frame payload did not serialise");
            }
        }
    }
}

/// Everything the processing task owns.
pub struct Processing {
    pipeline: &'static mut Pipeline,
    hello: aim_wire::Body,
    block_len: u64,
    sink: FrameSink,
    cycles: CycleCounter,
    watchdog: IndependentWatchdog<'static, IWDG1>,
}

impl Processing {
    /// Takes the configured pipeline ([`pipeline`]) and builds the `Hello` frame for this board:
    /// its geometry and rates, and its start (`start`: reset cause, boot count, unique ID, the
    /// last panic).
    pub fn new(
        pipeline: &'static mut Pipeline,
        cycles: CycleCounter,
        watchdog: IndependentWatchdog<'static, IWDG1>,
        start: &StartReport,
    ) -> Self {
        let config = dsp_config();
        let (major, minor, patch) = config::FIRMWARE_VERSION;
        let mut hello = from_dsp::hello(&config, [major, minor, patch]);
        start.fill_hello(&mut hello);
        Self {
            pipeline,
            hello: aim_wire::Body::Hello(hello),
            block_len: config.block_len as u64,
            sink: FrameSink::new(config::array_id(&start.unique_id)),
            cycles,
            watchdog,
        }
    }
}

/// The firmware's counters and the pipeline's gap statistics, as `Health` reports them.
fn firmware_counters(pipeline: &Pipeline, last_block_cycles: u32) -> FirmwareCounters {
    let gaps = pipeline.gap_stats();
    FirmwareCounters {
        cycles_per_block: last_block_cycles,
        dma_overruns: read(&COUNTERS.dma_overruns),
        dropped_frames: read(&COUNTERS.frames_dropped),
        queue_depth: UPLINK_QUEUE.len().min(usize::from(u8::MAX)) as u8,
        dsp_overloads: read(&COUNTERS.dsp_overloads),
        sai_overruns: read(&COUNTERS.sai_overruns),
        gaps: gaps.gaps,
        // Wraps like the other counters (after 24.9 h of lost audio).
        frames_lost: gaps.frames_lost as u32,
        outputs_dropped: gaps.outputs_dropped,
        outputs_overflowed: read(&COUNTERS.outputs_overflowed),
        uart_errors: read(&COUNTERS.uart_errors),
        frames_unencodable: read(&COUNTERS.frames_unencodable),
        chunks_captured: read(&COUNTERS.chunks_captured),
    }
}

/// Processes chunks forever. Per chunk: a gap in the sample index first goes to
/// `Pipeline::gap`, then `Pipeline::push` (timed), watchdog feed, frames out. `Hello` at start
/// and every [`HELLO_INTERVAL_SAMPLES`] of the array clock; the pipeline's periodic `Health`
/// is completed with the firmware's cycle count and loss counters.
#[embassy_executor::task]
pub async fn processing_task(mut state: Processing, mut chunks: ChunkReceiver) {
    // Sample index of the next frame the pipeline expects.
    let mut expected: u64 = 0;
    let mut next_hello: u64 = 0;
    // Cycles and frames of the block being accumulated, and cycles of the last complete block.
    let mut block_cycles: u32 = 0;
    let mut block_frames: u64 = 0;
    let mut last_block_cycles: u32 = 0;
    let mut interval = CycleStats::default();
    let mut outputs: heapless::Vec<Output, MAX_OUTPUTS_PER_CHUNK> = heapless::Vec::new();

    loop {
        if expected >= next_hello {
            state.sink.send(expected, state.hello.clone());
            next_hello = expected + HELLO_INTERVAL_SAMPLES;
        }

        let chunk = chunks.receive().await;
        if chunk.first_frame > expected {
            let lost = chunk.first_frame - expected;
            state.pipeline.gap(lost);
            defmt::warn!("gap of {} frames before sample {}", lost, chunk.first_frame);
            // The pipeline dropped the block in progress.
            block_cycles = 0;
            block_frames = 0;
        }
        expected = chunk.first_frame + CHUNK_FRAMES as u64;
        let start = state.cycles.now();
        state.pipeline.push(tdm_words(chunk), &mut |output| {
            if outputs.push(output).is_err() {
                bump(&COUNTERS.outputs_overflowed);
            }
        });
        let spent = state.cycles.since(start);
        chunks.receive_done();
        state.watchdog.pet();

        block_cycles = block_cycles.saturating_add(spent);
        block_frames += CHUNK_FRAMES as u64;
        if block_frames >= state.block_len {
            last_block_cycles = block_cycles;
            interval.record(block_cycles);
            block_cycles = 0;
            block_frames -= state.block_len;
        }

        for output in outputs.drain(..) {
            let counters = firmware_counters(state.pipeline, last_block_cycles);
            if let Output::Health(_) = output {
                defmt::info!(
                    "health: block cycles mean {} max {} over {} blocks; ring overruns {}, SAI overruns {}, DSP overloads {}, gaps {}, dropped {}, sent {}",
                    interval.mean(),
                    interval.max,
                    interval.count,
                    counters.dma_overruns,
                    counters.sai_overruns,
                    counters.dsp_overloads,
                    counters.gaps,
                    counters.dropped_frames,
                    read(&COUNTERS.frames_sent)
                );
                interval = CycleStats::default();
            }
            state.sink.send_output(&output, &counters);
        }
    }
}
