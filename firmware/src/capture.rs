//! Audio capture: SAI1 block A receives TDM (8 slots × 32 bit, 48 kHz) into a circular DMA ring
//! in AXI SRAM; the capture task moves each half-ring (a chunk of `CHUNK_FRAMES` frames) into a
//! free slot of a zero-copy queue and hands the slot to the DSP task.
//!
//! The one copy is the ring-buffer driver's read, which also tracks the DMA position and so
//! detects overruns; from there the DSP task works on the slot in place. The capture task runs
//! on an interrupt executor, so the ring is emptied within microseconds of each half-transfer
//! even while the DSP task is in the middle of a block.
//!
//! Every chunk carries the sample index of its first frame on the array's clock, so every loss
//! reaches the DSP as a gap (`aim_dsp::Pipeline::gap`) instead of silently shifting time:
//!
//! - **DSP overload**: the DSP task has not freed a queue slot when a chunk is ready. The chunk
//!   is read out of the ring and discarded (counted in `dsp_overloads`); capture goes on, and
//!   the next chunk's index is one chunk later: an exact gap.
//! - **DMA ring overrun** (the ring wrapped before it was read; `dma_overruns`) and **SAI FIFO
//!   overrun** (the SAI's own overrun flag, read and cleared after every chunk;
//!   `sai_overruns`): the SAI and its DMA are torn down and rebuilt. The DMA then restarts at
//!   the ring's first word, which is slot 0 of a frame, so microphone `i` stays slot `i`
//!   (embassy's ring would otherwise resume mid-frame). The index of the first frame after the
//!   restart comes from the time elapsed since the previous start ([`CaptureClock`]): the SAI
//!   clock and the time driver both run from the ST-LINK's 8 MHz, so it is exact to the
//!   start-up latency of the SAI (a few µs, under one frame of 20.8 µs).
use embassy_stm32::peripherals::{DMA1_CH0, PE2, PE4, PE5, PE6, SAI1};
use embassy_stm32::sai::{self, Sai};
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::zerocopy_channel;
use embassy_time::Instant;
use static_cell::StaticCell;

use crate::clocks::SAI_MASTER_CLOCK_DIVIDER;
use crate::config::{
    CAPTURE_QUEUE_CHUNKS, CHUNK_FRAMES, CHUNK_WORDS, SAMPLE_RATE_HZ, SLOT_BITS, TDM_SLOTS,
};
use crate::stats::{bump, COUNTERS};
use crate::Irqs;

/// One chunk of captured audio and where it sits on the array's sample clock.
#[derive(Debug)]
#[repr(C)]
pub struct Chunk {
    /// Interleaved TDM words: frame-major, `TDM_SLOTS` words per frame, each a 24-bit sample
    /// left-justified (MSB first) in its 32-bit slot.
    pub words: [u32; CHUNK_WORDS],
    /// Sample index of the chunk's first frame (frames since capture first started). Chunks
    /// arrive in order; a jump larger than `CHUNK_FRAMES` from the previous chunk is a gap.
    pub first_frame: u64,
}

/// Words the capture task reads from the ring at a time when it discards a chunk.
const DISCARD_WORDS: usize = 256;
const _: () = assert!(CHUNK_WORDS.is_multiple_of(DISCARD_WORDS));

/// The capture side's sample clock: the index of the next frame, and the time and index of the
/// last (re)start of the SAI, from which a restart's index is computed.
#[derive(Debug, Default)]
pub struct CaptureClock {
    next_frame: u64,
    anchor: Option<(Instant, u64)>,
}

impl CaptureClock {
    /// A clock before the first start.
    pub const fn new() -> Self {
        Self { next_frame: 0, anchor: None }
    }

    /// The SAI (re)started at `now`: its first frame gets the index the elapsed time since the
    /// last start gives (never less than the next index not yet handed out).
    pub fn started(&mut self, now: Instant) {
        let index = match self.anchor {
            None => 0,
            Some((then, index)) => {
                index + frames_in((now - then).as_micros()).max(self.next_frame - index)
            }
        };
        self.next_frame = index;
        self.anchor = Some((now, index));
    }

    /// Whether the ring must have wrapped unseen: at `now`, the SAI has clocked more frames
    /// since the last start than the ring holds beyond the next index to hand out. (embassy's
    /// ring detects an overrun by counting DMA completions in the DMA interrupt; when the
    /// capture task's interrupts are held off for more than a ring's time, completions merge
    /// and a wrap can go unseen. The time cannot be fooled.) Half a chunk of margin covers the
    /// start-up latency and timer rounding.
    pub fn overran(&self, now: Instant) -> bool {
        match self.anchor {
            None => false,
            Some((then, index)) => {
                let clocked = index + frames_in((now - then).as_micros());
                clocked > self.next_frame + (RING_WORDS / TDM_SLOTS + CHUNK_FRAMES / 2) as u64
            }
        }
    }

    /// Hands out the index of the next chunk's first frame and advances by one chunk.
    pub fn take_chunk(&mut self) -> u64 {
        let first = self.next_frame;
        self.next_frame += CHUNK_FRAMES as u64;
        first
    }
}

/// Audio frames in `micros` µs at the sample rate, rounded to the nearest frame.
pub const fn frames_in(micros: u64) -> u64 {
    (micros * SAMPLE_RATE_HZ as u64 + 500_000) / 1_000_000
}

/// Why capture stopped (and was restarted).
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum CaptureStop {
    /// The embassy SAI driver failed: the DMA ring overran.
    Ring(sai::Error),
    /// The SAI's FIFO overrun flag was set (and has been cleared).
    SaiFifoOverrun,
}
/// DMA ring length in words: two chunks (the DMA's half and full transfer points).
pub const RING_WORDS: usize = 2 * CHUNK_WORDS;

/// The capture side of the chunk queue.
pub type ChunkSender = zerocopy_channel::Sender<'static, CriticalSectionRawMutex, Chunk>;
/// The DSP side of the chunk queue.
pub type ChunkReceiver = zerocopy_channel::Receiver<'static, CriticalSectionRawMutex, Chunk>;

/// Creates the chunk queue (slots in AXI SRAM). Call once.
pub fn chunk_queue() -> (ChunkSender, ChunkReceiver) {
    static QUEUE: StaticCell<zerocopy_channel::Channel<'static, CriticalSectionRawMutex, Chunk>> =
        StaticCell::new();
    let slots = crate::axisram_buffer!(Chunk, CAPTURE_QUEUE_CHUNKS);
    QUEUE.init(zerocopy_channel::Channel::new(slots)).split()
}

/// The SAI1 configuration: block A master receiver, free protocol, TDM 8 × 32-bit slots.
///
/// Frame sync: active high, one bit clock wide, one bit before slot 0 (the TDM convention of
/// TDM MEMS microphones and multi-channel ADCs in "I2S/TDM" mode); data MSB first, sampled on
/// the rising edge of SCK.
pub fn sai_config() -> sai::Config {
    let mut config = sai::Config::default();
    config.mode = sai::Mode::Master;
    config.tx_rx = sai::TxRx::Receiver;
    config.protocol = sai::Protocol::Free;
    config.slot_size = sai::SlotSize::Channel32;
    config.slot_count = sai::word::U4(TDM_SLOTS as u8);
    config.slot_enable = (1u16 << TDM_SLOTS) - 1;
    config.first_bit_offset = sai::word::U5(0);
    config.data_size = sai::DataSize::Data32;
    config.stereo_mono = sai::StereoMono::Stereo;
    config.bit_order = sai::BitOrder::MsbFirst;
    config.frame_sync_offset = sai::FrameSyncOffset::BeforeFirstBit;
    config.frame_sync_polarity = sai::FrameSyncPolarity::ActiveHigh;
    config.frame_sync_active_level_length = sai::word::U7(1);
    config.frame_sync_definition = sai::FrameSyncDefinition::StartOfFrame;
    config.frame_length = (TDM_SLOTS as u32 * SLOT_BITS) as u16;
    config.clock_strobe = sai::ClockStrobe::Rising;
    config.master_clock_divider = SAI_MASTER_CLOCK_DIVIDER;
    config.nodiv = false;
    config.fifo_threshold = sai::FifoThreshold::Quarter;
    config
}

/// The capture hardware: SAI1 block A on PE5 (SCK), PE4 (FS), PE6 (SD), PE2 (MCLK), DMA1
/// stream 0, and the DMA ring.
pub struct SaiCapture {
    sai: Peri<'static, SAI1>,
    sck: Peri<'static, PE5>,
    fs: Peri<'static, PE4>,
    sd: Peri<'static, PE6>,
    mclk: Peri<'static, PE2>,
    dma: Peri<'static, DMA1_CH0>,
    ring: &'static mut [u32; RING_WORDS],
    discard: &'static mut [u32; DISCARD_WORDS],
    clock: CaptureClock,
}

/// The pins and channels [`SaiCapture`] needs.
#[allow(missing_docs)]
pub struct SaiPins {
    pub sai: Peri<'static, SAI1>,
    pub sck: Peri<'static, PE5>,
    pub fs: Peri<'static, PE4>,
    pub sd: Peri<'static, PE6>,
    pub mclk: Peri<'static, PE2>,
    pub dma: Peri<'static, DMA1_CH0>,
}

/// Moves SAI1, its pins and its DMA stream out of the `embassy_stm32::Peripherals` `$p`:
/// the board's capture pinout, in one place.
#[macro_export]
macro_rules! sai_pins {
    ($p:ident) => {
        $crate::capture::SaiPins {
            sai: $p.SAI1,
            sck: $p.PE5,
            fs: $p.PE4,
            sd: $p.PE6,
            mclk: $p.PE2,
            dma: $p.DMA1_CH0,
        }
    };
}

impl SaiCapture {
    /// Takes the pins and places the DMA ring in AXI SRAM. Call once.
    pub fn new(pins: SaiPins) -> Self {
        Self {
            sai: pins.sai,
            sck: pins.sck,
            fs: pins.fs,
            sd: pins.sd,
            mclk: pins.mclk,
            dma: pins.dma,
            ring: crate::axisram_buffer!(u32, RING_WORDS),
            discard: crate::axisram_buffer!(u32, DISCARD_WORDS),
            clock: CaptureClock::new(),
        }
    }

    /// Starts SAI1 and its DMA and streams chunks into `queue` until the driver fails or the
    /// SAI overruns; returns why. The SAI is disabled again when this returns.
    pub async fn run(&mut self, queue: &mut ChunkSender) -> CaptureStop {
        let (block_a, _block_b) = sai::split_subblocks(self.sai.reborrow());
        let mut sai = Sai::new_asynchronous_with_mclk(
            block_a,
            self.sck.reborrow(),
            self.sd.reborrow(),
            self.fs.reborrow(),
            self.mclk.reborrow(),
            self.dma.reborrow(),
            &mut self.ring[..],
            Irqs,
            sai_config(),
        );
        // Start the DMA right after the SAI: its FIFO (8 words) holds one frame, so the DMA
        // must run within 20 µs or the first frames shift slots.
        let started = sai.start();
        self.clock.started(Instant::now());
        enable_mclk_output();
        if clear_fifo_overrun() {
            // Frames arrived before the DMA ran: counted and logged, not restarted (a start
            // that always overruns would otherwise never capture); `tests/hil` `tdm_loopback`
            // checks the slot order after start.
            bump(&COUNTERS.sai_overruns);
            defmt::warn!("capture: SAI FIFO overrun at start");
        }
        if let Err(error) = started {
            return CaptureStop::Ring(error);
        }
        loop {
            match queue.try_send() {
                Some(slot) => {
                    if let Err(error) = sai.read(&mut slot.words[..]).await {
                        return CaptureStop::Ring(error);
                    }
                    if clear_fifo_overrun() {
                        // The slot is not sent; the next `try_send` hands it out again.
                        return CaptureStop::SaiFifoOverrun;
                    }
                    if self.clock.overran(Instant::now()) {
                        return CaptureStop::Ring(sai::Error::Overrun);
                    }
                    slot.first_frame = self.clock.take_chunk();
                    queue.send_done();
                    bump(&COUNTERS.chunks_captured);
                }
                None => {
                    // DSP overload: read the chunk out of the ring and drop it; keep capturing.
                    for _ in 0..CHUNK_WORDS / DISCARD_WORDS {
                        if let Err(error) = sai.read(&mut self.discard[..]).await {
                            return CaptureStop::Ring(error);
                        }
                    }
                    if clear_fifo_overrun() {
                        return CaptureStop::SaiFifoOverrun;
                    }
                    if self.clock.overran(Instant::now()) {
                        return CaptureStop::Ring(sai::Error::Overrun);
                    }
                    self.clock.take_chunk();
                    bump(&COUNTERS.dsp_overloads);
                }
            }
        }
    }
}

/// Reads SAI1 A's FIFO overrun flag (OVRUDR) and clears it; true if it was set.
pub fn clear_fifo_overrun() -> bool {
    let ch = embassy_stm32::pac::SAI1.ch(0);
    if ch.sr().read().ovrudr() {
        ch.clrfr().write(|w| w.set_covrudr(true));
        true
    } else {
        false
    }
}

/// MCKEN, bit 27 of SAI_xCR1 (RM0433 rev 8, STM32H743 revision V): drives MCLK on its pin.
///
/// embassy-stm32 0.6 has no configuration for it: its `sai::Config` has no master-clock
/// enable, and the H743's register block in stm32-metapac 21 (`sai_v3_4pdm`) does not model
/// the bit (only the v4 blocks of newer families do). So it is set by a raw write after
/// embassy enabled the block; `tests/hil` `mclk` reads the bit back and counts PE2's edges.
pub const MCKEN: u32 = 1 << 27;

/// Drives MCLK (12.288 MHz) on PE2 for ADCs that need a master clock (see [`MCKEN`]). The bit
/// clock and frame sync do not depend on it.
pub fn enable_mclk_output() {
    embassy_stm32::pac::SAI1.ch(0).cr1().modify(|w| w.0 |= MCKEN);
}

/// Whether MCKEN reads back as set in SAI1 A's CR1.
pub fn mclk_output_enabled() -> bool {
    embassy_stm32::pac::SAI1.ch(0).cr1().read().0 & MCKEN != 0
}

/// Captures forever: runs [`SaiCapture::run`], and on every failure counts it, logs it and
/// restarts the driver.
#[embassy_executor::task]
pub async fn capture_task(mut capture: SaiCapture, mut queue: ChunkSender) {
    loop {
        let stop = capture.run(&mut queue).await;
        match stop {
            CaptureStop::Ring(_) => bump(&COUNTERS.dma_overruns),
            CaptureStop::SaiFifoOverrun => bump(&COUNTERS.sai_overruns),
        }
        defmt::warn!("capture: {}, restarting SAI1", stop);
    }
}
