//! The processing task: runs `aim_dsp::Pipeline` on each captured chunk, times it with the DWT
//! cycle counter, feeds the independent watchdog, and turns the DSP outputs into `aim-wire`
//! frames (with `aim_wire::from_dsp`, the same mapping the simulator uses, so both send the
//! same bytes) for the uplink queue.
use aim_dsp::{ConfigError, Output, Pipeline};
use aim_wire::from_dsp::{self, FirmwareCounters};
use core::mem::MaybeUninit;
use embassy_stm32::peripherals::IWDG1;
use embassy_stm32::wdg::IndependentWatchdog;
use static_cell::ConstStaticCell;

use crate::capture::{Chunk, ChunkReceiver};
use crate::config::{self, ARRAY_ID, CHUNK_FRAMES, HELLO_INTERVAL_SAMPLES};
use crate::stats::{bump, read, CycleCounter, CycleStats, COUNTERS};
use crate::uplink::{EncodedFrame, MAX_FRAME_BYTES, UPLINK_QUEUE};

/// Most DSP outputs one chunk can produce (one block ends per chunk at most: DoA, peaks,
/// health); more are counted as dropped frames.
const MAX_OUTPUTS_PER_CHUNK: usize = 8;

/// The DSP configuration for this board (geometry and rates from [`config`]).
pub fn dsp_config() -> aim_dsp::Config {
    aim_dsp::Config::new(config::geometry(), config::SAMPLE_RATE_HZ)
}

/// The pipeline, in a static in DTCM, configured in place (call once).
///
/// `Pipeline` is ≈ 115 KB and the stack ≈ 12 KB, so it must never exist as a value: neither
/// `Pipeline::new` (returns it by value) nor `StaticCell::init_with(Pipeline::empty)` (the
/// compiler builds the value in the caller's frame, then copies it: a 114 KB stack frame in
/// `main`, measured in the disassembly). A static of zeroed bytes lands in `.bss`, which the
/// start-up code zeroes: no stack, no flash; `configure` then sets it up.
pub fn pipeline() -> &'static mut Pipeline {
    static PIPELINE: ConstStaticCell<MaybeUninit<Pipeline>> =
        ConstStaticCell::new(MaybeUninit::zeroed());
    // SAFETY: `take` hands out the static once (it panics the second time), and nothing has
    // written to it since the start-up code zeroed `.bss`.
    let pipeline = unsafe { crate::dma_buffer::assume_zeroed(PIPELINE.take()) };
    if let Err(error) = pipeline.configure(&dsp_config()) {
        config_rejected(&error);
    }
    pipeline
}

/// Stops with the reason the DSP refused the board's configuration. (defmt, not `core::fmt`:
/// float formatting alone would cost 20 KB of flash.)
fn config_rejected(error: &ConfigError) -> ! {
    match *error {
        ConfigError::MicCount(n) => defmt::panic!("DSP config: {} microphones", n),
        ConfigError::SampleRate(hz) => defmt::panic!("DSP config: sample rate {} Hz", hz),
        ConfigError::BlockLen(n) => defmt::panic!("DSP config: block length {}", n),
        ConfigError::TdmSlots { slots, mics } => {
            defmt::panic!("DSP config: {} TDM slots for {} microphones", slots, mics)
        }
        ConfigError::ApertureTooLarge { aperture_m } => {
            defmt::panic!("DSP config: aperture {} m too large", aperture_m)
        }
        _ => defmt::panic!("DSP config rejected: the geometry or a tunable (aim_dsp::ConfigError)"),
    }
}

/// Reinterprets captured TDM words as the `i32` samples the pipeline takes (left-justified
/// 24-bit two's complement: the bits are the same, only the type differs).
pub fn tdm_words(chunk: &Chunk) -> &[i32] {
    // SAFETY: u32 and i32 have the same size and alignment, and every bit pattern is a valid
    // value of both; the returned slice borrows `chunk`.
    unsafe { core::slice::from_raw_parts(chunk.as_ptr().cast::<i32>(), chunk.len()) }
}

/// Stamps frames with this array's id and sequence numbers, encodes them, and queues them.
pub struct FrameSink {
    encoder: aim_wire::Encoder,
}

impl FrameSink {
    /// A sink for this board's array id.
    pub const fn new() -> Self {
        Self { encoder: aim_wire::Encoder::new(ARRAY_ID) }
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

impl Default for FrameSink {
    fn default() -> Self {
        Self::new()
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
    /// Builds the pipeline (once) and the `Hello` frame for this board.
    pub fn new(cycles: CycleCounter, watchdog: IndependentWatchdog<'static, IWDG1>) -> Self {
        let config = dsp_config();
        let (major, minor, patch) = config::FIRMWARE_VERSION;
        let hello = aim_wire::Body::Hello(from_dsp::hello(&config, [major, minor, patch]));
        Self {
            pipeline: pipeline(),
            hello,
            block_len: config.block_len as u64,
            sink: FrameSink::new(),
            cycles,
            watchdog,
        }
    }
}

/// Processes chunks forever. Per chunk: `Pipeline::push` (timed), watchdog feed, frames out.
/// `Hello` at start and every [`HELLO_INTERVAL_SAMPLES`]; the pipeline's periodic `Health`
/// is completed with the firmware's cycle count and loss counters.
#[embassy_executor::task]
pub async fn processing_task(mut state: Processing, mut chunks: ChunkReceiver) {
    let mut samples: u64 = 0;
    let mut next_hello: u64 = 0;
    // Cycles of the chunks of the block being accumulated, and of the last complete block.
    let mut block_cycles: u32 = 0;
    let mut last_block_cycles: u32 = 0;
    let mut interval = CycleStats::default();
    let mut outputs: heapless::Vec<Output, MAX_OUTPUTS_PER_CHUNK> = heapless::Vec::new();

    loop {
        if samples >= next_hello {
            state.sink.send(samples, state.hello.clone());
            next_hello = samples + HELLO_INTERVAL_SAMPLES;
        }

        let chunk = chunks.receive().await;
        let start = state.cycles.now();
        state.pipeline.push(tdm_words(chunk), &mut |output| {
            if outputs.push(output).is_err() {
                bump(&COUNTERS.frames_dropped);
            }
        });
        let spent = state.cycles.since(start);
        chunks.receive_done();
        state.watchdog.pet();

        samples += CHUNK_FRAMES as u64;
        block_cycles = block_cycles.saturating_add(spent);
        if samples.is_multiple_of(state.block_len) {
            last_block_cycles = block_cycles;
            interval.record(block_cycles);
            block_cycles = 0;
        }

        for output in outputs.drain(..) {
            let counters = FirmwareCounters {
                cycles_per_block: last_block_cycles,
                dma_overruns: read(&COUNTERS.dma_overruns),
                dropped_frames: read(&COUNTERS.frames_dropped),
                queue_depth: UPLINK_QUEUE.len().min(usize::from(u8::MAX)) as u8,
            };
            if let Output::Health(_) = output {
                defmt::info!(
                    "health: block cycles mean {} max {} over {} blocks; overruns {}, dropped {}, sent {}",
                    interval.mean(),
                    interval.max,
                    interval.count,
                    counters.dma_overruns,
                    counters.dropped_frames,
                    read(&COUNTERS.frames_sent)
                );
                interval = CycleStats::default();
            }
            state.sink.send_output(&output, &counters);
        }
    }
}
