//! PDM capture (cargo feature `pdm`): SAI1's PDM interface clocks the microphones at
//! 3.072 MHz and de-interleaves their one-bit streams into bytes (one byte per microphone per
//! 8 clocks) in a circular DMA ring; the capture task decimates each half-ring with
//! `aim_dsp::pdm::PdmDecimator` straight into a slot of the chunk queue, as the same 48 kHz
//! TDM words (24-bit, left-justified, microphone `i` in slot `i`) the TDM capture delivers.
//! The processing task, the pipeline and everything after it are unchanged.
//!
//! Why SAI1's PDM interface and not the DFSDM: the STM32H743's DFSDM1 has 8 input channels but
//! only 4 digital filters, so at most 4 microphones can be filtered at once, each on its own
//! filter and conversion timing; embassy-stm32 0.6 has no DFSDM driver (the metapac carries no
//! register block for it). SAI1's PDM interface samples every microphone on one clock, hands
//! the raw bits to one DMA stream, and the decimation is `aim_dsp` code: tested on the host
//! against a floating-point reference and bit-identical on the Cortex-M (QEMU parity).
//!
//! How many microphones, on this board: **4**, for two reasons, each sufficient for 8.
//! - SAI1's PDM interface on the STM32H743 has data lines D1, D2 and D3 only: its alternate
//!   function map (stm32-metapac 21.0.0, the crate this firmware links, generated from ST's
//!   CubeMX pin database: `src/chips/metadata_0448.rs` for STM32H743ZI/ZG, LQFP144, peripheral
//!   `SAI1`) lists CK1 = PE2, CK2 = PE5, D1 = PB2/PC1/PD6/PE6, D2 = PE4, D3 = PC5/PF10, all AF2,
//!   and **no D4 on any pin**; the other H743 packages (`metadata_0443` … `0447`: LQFP100 to
//!   TFBGA240) list the same or fewer, so no STM32H743 package brings out D4. SAI4's PDM
//!   interface has the same pins (AF10; `CK1` only on PE2, `CK2` only on PE5), so it cannot add a
//!   fourth line beside SAI1's. 8 PDM microphones on SAI1 need D4; this chip has at most 6.
//! - The SAI's internal bit clock must be `2 · pairs · 3.072 MHz` (one bit of every microphone
//!   per PDM clock, 64 PDM clocks per 48 kHz sample): 12.288 MHz for 2 pairs is 61.44 MHz / 5
//!   (the kernel clock of `clocks`); 18.432 MHz (3 pairs) and 24.576 MHz (4 pairs) need the
//!   factor 5³ in the PLL's M·P times MCKDIV (8 MHz = 2⁹·5⁶, 48 kHz·64 = 2¹⁴·3·5³), so with M = 5
//!   (1.6 MHz reference; below 2 MHz only the 150–420 MHz VCO is allowed, RM0433 PLLxRGE and
//!   embassy's `rcc/h.rs`) the VCO would be 460.8 or 614.4 MHz, and with any other M (1–8, as
//!   the reference must stay ≥ 1 MHz) it would be a multiple of 2.304 or 3.072 GHz; FRACN adds
//!   only multiples of 1/8192. No exact 48 kHz for 6 microphones from the ST-LINK's 8 MHz.
//!
//! So this build supports **4 PDM microphones** (2 pairs, data lines D1 and D2, both clock
//! outputs) at exactly 48 kHz; `pdm` with `mics-6` or `mics-8` stops the build with this reason.
//! The decimator itself serves up to 8 (the QEMU cost check runs 8). An 8-microphone PDM board
//! needs a part whose SAI brings out D4 (none of the chips in stm32-metapac 21 lists a SAI1 D4
//! pin; the STM32MP15x does: SAI1_D4 on PC5, e.g. Seeed's SoM-STM32MP157C pin table) and an
//! audio clock with 5³ in it (a 24.576 MHz oscillator on I2S_CKIN, or a
//! 12.288 MHz / 24.576 MHz HSE), or 8 TDM microphones on this board (the default build). The
//! DFSDM is no way to 8 either: DFSDM1 has 8 input channels but 4 digital filters (metapac:
//! interrupts DFSDM1_FLT0–FLT3, no register block), so at most 4 microphones are filtered at
//! once.
//!
//! Pins, in their PDM roles (AF2): PE2 SAI1_CK1 (PDM clock, microphones 0–1), PE5 SAI1_CK2
//! (PDM clock, microphones 2–3), PE6 SAI1_D1 (microphones 0 on the rising, 1 on the falling
//! edge), PE4 SAI1_D2 (microphones 2 and 3). embassy-stm32 0.6 models neither the PDM pins nor
//! SAI_PDMCR, so the block is built with the TDM constructor on the same pins, which puts them
//! on their TDM functions (MCLK_A, SCK_A, FS_A, SD_A: **AF6**, not AF2); [`set_pdm_pin_functions`]
//! then switches the four pins to AF2 (CK1, CK2, D1, D2), and PDMCR is written directly
//! between the SAI's reset and its configuration, as RM0433 requires (PDMEN before SAIEN).
//! Byte order of a frame (D1 rising, D1 falling, D2 rising, D2 falling = microphones 0–3) is
//! RM0433's description and has not yet been checked on a board (`tests/hil` `pdm_capture`).
#[cfg(any(feature = "mics-8", feature = "mics-6"))]
compile_error!(
    "PDM microphones on the NUCLEO-H743ZI2: 4 at most (no SAI1_D4 pin on any STM32H743 \
     package, and 3 pairs need an 18.432 MHz bit clock the 8 MHz HSE cannot give exactly); \
     build with --no-default-features --features pdm,mics-4 (see firmware/src/capture_pdm.rs)"
);

use aim_dsp::pdm::{PdmDecimator, BYTES_PER_OUTPUT};
use embassy_stm32::peripherals::{DMA1_CH0, PE2, PE4, PE5, PE6, SAI1};
use embassy_stm32::sai::{self, Sai};
use embassy_stm32::Peri;

use crate::capture::{CaptureClock, ChunkSender, SaiPins};
use crate::clocks::{SAI_KERNEL_HZ, SAI_MASTER_CLOCK_DIVIDER, SAI_MCKDIV};
use crate::config::{CHUNK_FRAMES, MIC_COUNT, SAMPLE_RATE_HZ, TDM_SLOTS};
use crate::stats::{bump, COUNTERS};
use crate::Irqs;
use embassy_time::Instant;

/// Microphone pairs (data lines) of the PDM interface.
pub const PDM_PAIRS: usize = MIC_COUNT.div_ceil(2);
/// Bytes per PDM byte period: one per microphone of the enabled pairs.
pub const PDM_STRIDE: usize = 2 * PDM_PAIRS;
/// PDM clock on CK1/CK2, Hz: 64 bits per 48 kHz sample.
pub const PDM_CLOCK_HZ: u32 = SAMPLE_RATE_HZ * aim_dsp::pdm::DECIMATION as u32;
/// The SAI's internal bit clock: every microphone's bit of one PDM clock period, Hz.
pub const PDM_BIT_CLOCK_HZ: u32 = PDM_CLOCK_HZ * PDM_STRIDE as u32;
/// PDM bytes per capture chunk (`CHUNK_FRAMES` frames of 48 kHz).
pub const CHUNK_PDM_BYTES: usize = CHUNK_FRAMES * BYTES_PER_OUTPUT * PDM_STRIDE;
/// DMA ring length in bytes: two chunks.
pub const RING_PDM_BYTES: usize = 2 * CHUNK_PDM_BYTES;

// The SAI divides its kernel clock by MCKDIV (NODIV = 1) to the bit clock, exactly.
const _: () = assert!(SAI_KERNEL_HZ / SAI_MCKDIV == PDM_BIT_CLOCK_HZ);
const _: () = assert!(SAI_KERNEL_HZ.is_multiple_of(SAI_MCKDIV));
const _: () = assert!(PDM_STRIDE <= TDM_SLOTS && PDM_PAIRS >= 1 && PDM_PAIRS <= 2);

/// The SAI1 block A configuration for the PDM interface: master receiver, free protocol, a
/// frame of one 8-bit slot per microphone (8 PDM clocks), MSB (earliest bit) first, bit clock
/// = kernel clock / MCKDIV (NODIV).
pub fn pdm_sai_config() -> sai::Config {
    let mut config = sai::Config::default();
    config.mode = sai::Mode::Master;
    config.tx_rx = sai::TxRx::Receiver;
    config.protocol = sai::Protocol::Free;
    config.data_size = sai::DataSize::Data8;
    config.slot_size = sai::SlotSize::DataSize;
    config.slot_count = sai::word::U4(PDM_STRIDE as u8);
    config.slot_enable = (1u16 << PDM_STRIDE) - 1;
    config.first_bit_offset = sai::word::U5(0);
    config.bit_order = sai::BitOrder::MsbFirst;
    config.stereo_mono = sai::StereoMono::Stereo;
    config.frame_sync_offset = sai::FrameSyncOffset::OnFirstBit;
    config.frame_sync_polarity = sai::FrameSyncPolarity::ActiveHigh;
    config.frame_sync_active_level_length = sai::word::U7(1);
    config.frame_sync_definition = sai::FrameSyncDefinition::StartOfFrame;
    config.frame_length = (8 * PDM_STRIDE) as u16;
    config.clock_strobe = sai::ClockStrobe::Rising;
    config.master_clock_divider = SAI_MASTER_CLOCK_DIVIDER;
    config.nodiv = true;
    config.fifo_threshold = sai::FifoThreshold::Quarter;
    config
}

/// Enables SAI1's PDM interface for [`PDM_PAIRS`] pairs and their clock outputs (SAI_PDMCR:
/// PDMEN, MICNBR, CKEN1/CKEN2). Call after the SAI's reset and before the block is enabled.
fn enable_pdm_interface() {
    embassy_stm32::pac::SAI1.pdmcr().write(|w| {
        w.set_micnbr((PDM_PAIRS - 1) as u8);
        for clock in 0..PDM_PAIRS {
            w.set_cken(clock, true);
        }
        w.set_pdmen(true);
    });
}

/// The alternate function of SAI1_CK1/CK2/D1/D2 on PE2/PE5/PE6/PE4 (stm32-metapac 21,
/// `metadata_0448.rs`; the TDM signals MCLK_A/SCK_A/SD_A/FS_A of the same pins are AF6).
pub const PDM_PIN_AF: u8 = 2;
/// The GPIOE pins of the PDM interface: CK1, CK2, D1, D2.
pub const PDM_PINS_GPIOE: [usize; 4] = [2, 5, 6, 4];

/// Moves PE2, PE4, PE5 and PE6 from the TDM functions embassy's constructor gave them (AF6) to
/// the PDM interface's (AF2: CK1, D2, CK2, D1). Call after the SAI driver is built, every time
/// (a rebuilt driver sets AF6 again). Their mode (alternate function), speed and pulls stay as
/// embassy set them.
pub fn set_pdm_pin_functions() {
    embassy_stm32::pac::GPIOE.afr(0).modify(|w| {
        for pin in PDM_PINS_GPIOE {
            w.set_afr(pin, PDM_PIN_AF);
        }
    });
}

/// The PDM capture hardware: SAI1 block A in PDM mode on PE2/PE5 (CK1/CK2), PE6/PE4 (D1/D2),
/// DMA1 stream 0, the DMA ring, the bytes of one chunk and the decimator.
pub struct PdmCapture {
    sai: Peri<'static, SAI1>,
    ck2: Peri<'static, PE5>,
    d2: Peri<'static, PE4>,
    d1: Peri<'static, PE6>,
    ck1: Peri<'static, PE2>,
    dma: Peri<'static, DMA1_CH0>,
    ring: &'static mut [u8; RING_PDM_BYTES],
    bytes: &'static mut [u8; CHUNK_PDM_BYTES],
    decimator: PdmDecimator,
    /// The array's sample clock (frame indices of the chunks, gaps after a restart).
    clock: CaptureClock,
}

impl PdmCapture {
    /// Takes the capture pins (the TDM pinout, see the module docs) and places the DMA ring
    /// and the chunk's bytes in AXI SRAM. Call once.
    pub fn new(pins: SaiPins) -> Self {
        Self {
            sai: pins.sai,
            ck2: pins.sck,
            d2: pins.fs,
            d1: pins.sd,
            ck1: pins.mclk,
            dma: pins.dma,
            ring: crate::axisram_buffer!(u8, RING_PDM_BYTES),
            bytes: crate::axisram_buffer!(u8, CHUNK_PDM_BYTES),
            decimator: PdmDecimator::new(MIC_COUNT, PDM_STRIDE),
            clock: CaptureClock::new(),
        }
    }

    /// Starts SAI1 in PDM mode and its DMA, and streams decimated chunks into `queue` until the
    /// driver fails; returns the error. The SAI is disabled again when this returns.
    pub async fn run(&mut self, queue: &mut ChunkSender) -> sai::Error {
        let (block_a, _block_b) = sai::split_subblocks(self.sai.reborrow());
        enable_pdm_interface();
        let mut sai = Sai::new_asynchronous_with_mclk(
            block_a,
            self.ck2.reborrow(),
            self.d1.reborrow(),
            self.d2.reborrow(),
            self.ck1.reborrow(),
            self.dma.reborrow(),
            &mut self.ring[..],
            Irqs,
            pdm_sai_config(),
        );
        set_pdm_pin_functions();
        if let Err(error) = sai.start() {
            return error;
        }
        self.clock.started(Instant::now());
        // After a restart the decimator's history is from before the gap: start afresh.
        self.decimator = PdmDecimator::new(MIC_COUNT, PDM_STRIDE);
        loop {
            if let Err(error) = sai.read(&mut self.bytes[..]).await {
                return error;
            }
            let slot = queue.send().await;
            let words = words_mut(&mut slot.words);
            match self.decimator.push(&self.bytes[..], words, TDM_SLOTS) {
                Ok(_) => {
                    slot.first_frame = self.clock.take_chunk();
                    queue.send_done();
                    bump(&COUNTERS.chunks_captured);
                }
                // Cannot happen (the sizes are constants checked above); if it did, the chunk
                // is not sent and the pipeline sees a gap rather than garbage.
                Err(_) => defmt::error!("PDM decimator refused a chunk"),
            }
        }
    }
}

/// A queue slot as the `i32` words the decimator writes (24-bit samples left-justified: the
/// bits are the same, only the type differs; the processing task reads them back as `i32`).
fn words_mut(chunk: &mut [u32]) -> &mut [i32] {
    // SAFETY: u32 and i32 have the same size and alignment and every bit pattern is valid for
    // both; the returned slice mutably borrows `chunk`, so nothing else can see it meanwhile.
    unsafe { core::slice::from_raw_parts_mut(chunk.as_mut_ptr().cast::<i32>(), chunk.len()) }
}

// One chunk of PDM bytes makes exactly one chunk of TDM words.
const _: () = assert!(CHUNK_PDM_BYTES / (BYTES_PER_OUTPUT * PDM_STRIDE) == CHUNK_FRAMES);

/// Captures forever: runs [`PdmCapture::run`], and on every failure counts an overrun, logs it
/// and restarts the driver.
#[embassy_executor::task]
pub async fn capture_task(mut capture: PdmCapture, mut queue: ChunkSender) {
    loop {
        let error = capture.run(&mut queue).await;
        bump(&COUNTERS.dma_overruns);
        defmt::warn!("PDM capture: {}, restarting SAI1", error);
    }
}
