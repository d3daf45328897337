//! HIL: the TDM format end to end: slot *i* of every frame arrives as word *i* of the frame,
//! all 32 bits, frame after frame.
//!
//! Wiring: one jumper from PE3 (SAI1_SD_B, CN9 pin 22) to PE6 (SAI1_SD_A, CN9 pin 20), with
//! the microphones' SD disconnected. SAI1 block A is the firmware's receiver (same
//! `capture::sai_config`, master, clocks on PE5/PE4); block B transmits synchronously on A's
//! clocks a known pattern: slot `s` of frame `n` carries `s << 28 | (n mod 2²⁰) << 8` (a 24-bit
//! sample, left-justified, as a microphone sends it). After 100 ms of warm-up, 1 s of
//! received words is checked: each word's slot nibble equals its position in the frame
//! (slot mapping, MSB first, 32-bit slots), its low byte is zero, and the frame counter of
//! every frame is the previous one's plus one (no frame lost, repeated or split between the
//! DMA rings); no receive overrun.
#![no_std]
#![no_main]

use aim_firmware::capture::{sai_config, RING_WORDS};
use aim_firmware::config::{CHUNK_FRAMES, CHUNK_WORDS, SAMPLE_RATE_HZ, TDM_SLOTS};
use aim_firmware::Irqs;
use aim_hil_tests::{board, check_range, pass};
use cortex_m_rt::entry;
use embassy_executor::{Executor, InterruptExecutor};
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::SAI1;
use embassy_stm32::sai::{self, Sai};
use embassy_stm32::{bind_interrupts, dma, interrupt, peripherals};
use static_cell::StaticCell;
use {defmt_rtt as _, panic_probe as _};

bind_interrupts!(struct TxIrqs {
    DMA1_STREAM2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
});

const COUNTER_MASK: u32 = (1 << 20) - 1;

static EXECUTOR_TX: InterruptExecutor = InterruptExecutor::new();
static EXECUTOR_THREAD: StaticCell<Executor> = StaticCell::new();

#[interrupt]
unsafe fn UART4() {
    // SAFETY: UART4 is unused; its vector only runs this executor.
    unsafe { EXECUTOR_TX.on_interrupt() }
}

/// The word block B sends in slot `slot` of frame `frame`.
fn pattern(slot: usize, frame: u32) -> u32 {
    ((slot as u32) << 28) | ((frame & COUNTER_MASK) << 8)
}

#[embassy_executor::task]
async fn transmit(mut tx: Sai<'static, SAI1, u32>) {
    let mut words = [0u32; CHUNK_WORDS];
    let mut frame: u32 = 0;
    loop {
        for f in words.chunks_exact_mut(TDM_SLOTS) {
            for (slot, w) in f.iter_mut().enumerate() {
                *w = pattern(slot, frame);
            }
            frame = frame.wrapping_add(1);
        }
        if let Err(error) = tx.write(&words).await {
            defmt::panic!("FAIL block B transmit: {}", error);
        }
    }
}

#[embassy_executor::task]
async fn receive(mut rx: Sai<'static, SAI1, u32>) {
    let mut words = [0u32; CHUNK_WORDS];
    let warm_up = SAMPLE_RATE_HZ as usize / 10 / CHUNK_FRAMES;
    let checked = SAMPLE_RATE_HZ as usize / CHUNK_FRAMES;
    let (mut wrong_slot, mut wrong_low_byte, mut gaps) = (0u64, 0u64, 0u64);
    let mut previous: Option<u32> = None;
    for chunk in 0..warm_up + checked {
        if let Err(error) = rx.read(&mut words).await {
            defmt::panic!("FAIL block A receive: {}", error);
        }
        if chunk < warm_up {
            continue;
        }
        for f in words.chunks_exact(TDM_SLOTS) {
            for (slot, &w) in f.iter().enumerate() {
                if (w >> 28) as usize != slot {
                    wrong_slot += 1;
                }
                if w & 0xFF != 0 {
                    wrong_low_byte += 1;
                }
            }
            let counter = (f[0] >> 8) & COUNTER_MASK;
            if let Some(p) = previous {
                if counter != (p + 1) & COUNTER_MASK {
                    gaps += 1;
                }
            }
            previous = Some(counter);
        }
    }
    defmt::info!(
        "checked {=usize} frames; first word of the last frame {=u32:#x}",
        checked * CHUNK_FRAMES,
        words[0]
    );
    check_range("words in the wrong slot", wrong_slot, 0, 0);
    check_range("words with a non-zero low byte", wrong_low_byte, 0, 0);
    check_range("frame counter gaps", gaps, 0, 0);
    pass("tdm_loopback");
}

#[entry]
fn main() -> ! {
    let (p, _cycles) = board();
    let (block_a, block_b) = sai::split_subblocks(p.SAI1);
    let rx_ring = aim_firmware::axisram_buffer!(u32, RING_WORDS);
    let tx_ring = aim_firmware::axisram_buffer!(u32, RING_WORDS);

    let mut rx = Sai::new_asynchronous_with_mclk(
        block_a,
        p.PE5,
        p.PE6,
        p.PE4,
        p.PE2,
        p.DMA1_CH0,
        &mut rx_ring[..],
        Irqs,
        sai_config(),
    );
    if let Err(error) = rx.start() {
        defmt::panic!("FAIL block A start: {}", error);
    }
    let mut tx_config = sai_config();
    tx_config.tx_rx = sai::TxRx::Transmitter;
    tx_config.sync_input = sai::SyncInput::Internal;
    let tx = Sai::new_synchronous(block_b, p.PE3, p.DMA1_CH2, &mut tx_ring[..], TxIrqs, tx_config);

    interrupt::UART4.set_priority(Priority::P6);
    let spawner = EXECUTOR_TX.start(interrupt::UART4);
    spawner.spawn(defmt::unwrap!(transmit(tx)));
    EXECUTOR_THREAD.init(Executor::new()).run(|spawner| {
        spawner.spawn(defmt::unwrap!(receive(rx)));
    })
}
