//! HIL: SAI1 drives MCLK (12.288 MHz) on PE2 when, and only when, MCKEN is set.
//!
//! MCKEN (bit 27 of SAI_ACR1) is set by a raw register write (`capture::enable_mclk_output`:
//! embassy-stm32 0.6 has no setting for it), so this checks the write took and does what
//! RM0433 says, with no wiring: PE2's input buffer stays on in alternate-function mode, so
//! GPIOE's IDR shows the pin toggling. Runs the firmware's capture task, then:
//! - MCKEN reads back as set;
//! - PE2 toggles: over 100 000 IDR samples at least 10 000 level changes (a 12.288 MHz clock
//!   sampled at any rate above 1 MHz changes level in a large share of the samples);
//! - with MCKEN cleared, PE2 does not toggle at all (the pin is not driven by something else);
//! - frequency, when the sampling is fast enough to count every half period (sample interval
//!   under 40 ns = one MCLK half period, measured with the DWT): level changes / 2 per second
//!   within 2 % of 12.288 MHz. If the core samples more slowly, the log says so and this one
//!   check is skipped (the toggle checks still stand).
#![no_std]
#![no_main]

use aim_firmware::capture::{self, ChunkReceiver, SaiCapture};
use aim_firmware::stats::CycleCounter;
use aim_hil_tests::{board, check_range, pass, pin_clock};
use cortex_m_rt::entry;
use embassy_executor::{Executor, InterruptExecutor};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_time::Timer;
use static_cell::StaticCell;
use {defmt_rtt as _, panic_probe as _};

/// MCLK, Hz.
const MCLK_HZ: u64 = 12_288_000;

static EXECUTOR_CAPTURE: InterruptExecutor = InterruptExecutor::new();
static EXECUTOR_THREAD: StaticCell<Executor> = StaticCell::new();
static CYCLES: StaticCell<CycleCounter> = StaticCell::new();

#[interrupt]
unsafe fn UART4() {
    // SAFETY: UART4 is unused; its vector only runs this executor.
    unsafe { EXECUTOR_CAPTURE.on_interrupt() }
}

#[embassy_executor::task]
async fn consume(mut chunks: ChunkReceiver) {
    loop {
        chunks.receive().await;
        chunks.receive_done();
    }
}

#[embassy_executor::task]
async fn measure(cycles: &'static CycleCounter) {
    Timer::after_millis(100).await; // the capture task has started the SAI
    check_range("MCKEN set", u64::from(capture::mclk_output_enabled()), 1, 1);

    // One MCLK half period is 40.7 ns: sampling faster counts every edge.
    pin_clock::check(
        cycles,
        "MCKEN on, PE2",
        2,
        "PE2 level changes, MCKEN on",
        "MCLK frequency, Hz",
        MCLK_HZ,
        40_000,
    );

    embassy_stm32::pac::SAI1.ch(0).cr1().modify(|w| w.0 &= !capture::MCKEN);
    let (changes_off, _) = pin_clock::sample(cycles, 2);
    capture::enable_mclk_output();
    defmt::info!("MCKEN off: {=u32} level changes", changes_off);
    check_range("PE2 level changes, MCKEN off", u64::from(changes_off), 0, 0);
    pass("mclk");
}

#[entry]
fn main() -> ! {
    let (p, cycles) = board();
    let cycles: &'static CycleCounter = CYCLES.init(cycles);
    let (chunk_tx, chunk_rx) = capture::chunk_queue();
    let sai = SaiCapture::new(aim_firmware::sai_pins!(p));

    interrupt::UART4.set_priority(Priority::P6);
    let spawner = EXECUTOR_CAPTURE.start(interrupt::UART4);
    spawner.spawn(defmt::unwrap!(capture::capture_task(sai, chunk_tx)));

    EXECUTOR_THREAD.init(Executor::new()).run(|spawner| {
        spawner.spawn(defmt::unwrap!(consume(chunk_rx)));
        spawner.spawn(defmt::unwrap!(measure(cycles)));
    })
}
