//! Audio capture: SAI1 block A receives TDM (8 slots × 32 bit, 48 kHz) into a circular DMA ring
//! in AXI SRAM; the capture task moves each half-ring (a chunk of `CHUNK_FRAMES` frames) into a
//! free slot of a zero-copy queue and hands the slot to the DSP task.
//!
//! The one copy is the ring-buffer driver's read, which also tracks the DMA position and so
//! detects overruns; from there the DSP task works on the slot in place. The capture task runs
//! on an interrupt executor, so the ring is emptied within microseconds of each half-transfer
//! even while the DSP task is in the middle of a block.
//!
//! On an overrun the SAI and its DMA are torn down and rebuilt: the DMA then restarts at the
//! ring's first word, which is slot 0 of a frame, so microphone `i` stays slot `i` (embassy's
//! ring would otherwise resume mid-frame).
use embassy_stm32::peripherals::{DMA1_CH0, PE2, PE4, PE5, PE6, SAI1};
use embassy_stm32::sai::{self, Sai};
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::zerocopy_channel;
use static_cell::StaticCell;

use crate::clocks::SAI_MASTER_CLOCK_DIVIDER;
use crate::config::{CAPTURE_QUEUE_CHUNKS, CHUNK_WORDS, SLOT_BITS, TDM_SLOTS};
use crate::stats::{bump, COUNTERS};
use crate::Irqs;

/// One chunk of interleaved TDM words: frame-major, `TDM_SLOTS` words per frame, each a 24-bit
/// sample left-justified (MSB first) in its 32-bit slot.
pub type Chunk = [u32; CHUNK_WORDS];
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
        }
    }

    /// Starts SAI1 and its DMA and streams chunks into `queue` until the driver fails; returns
    /// the error. The SAI is disabled again when this returns.
    pub async fn run(&mut self, queue: &mut ChunkSender) -> sai::Error {
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
        enable_mclk_output();
        if let Err(error) = started {
            return error;
        }
        loop {
            let slot = queue.send().await;
            if let Err(error) = sai.read(&mut slot[..]).await {
                return error;
            }
            queue.send_done();
            bump(&COUNTERS.chunks_captured);
        }
    }
}

/// Drives MCLK (12.288 MHz) on PE2 for ADCs that need a master clock: bit 27 of SAI_ACR1,
/// MCKEN (RM0433, STM32H743 revision V), which embassy-stm32 0.6 / stm32-metapac 21 do not
/// model. The bit clock and frame sync do not depend on it.
fn enable_mclk_output() {
    const MCKEN: u32 = 1 << 27;
    embassy_stm32::pac::SAI1.ch(0).cr1().modify(|w| w.0 |= MCKEN);
}

/// Captures forever: runs [`SaiCapture::run`], and on every failure counts an overrun, logs it
/// and restarts the driver.
#[embassy_executor::task]
pub async fn capture_task(mut capture: SaiCapture, mut queue: ChunkSender) {
    loop {
        let error = capture.run(&mut queue).await;
        bump(&COUNTERS.dma_overruns);
        defmt::warn!("capture: {}, restarting SAI1", error);
    }
}
