//! HIL: SAI1 block A delivers exactly 48 000 TDM frames per second through the DMA ring and
//! the capture task, without overruns.
//!
//! Runs the firmware's capture task (interrupt executor) and a thread-mode consumer that only
//! releases chunks, counts the chunks over 10 s of `embassy_time` and checks the frame rate is
//! 48 000 Hz ± 0.1 % (one chunk in 10 s is 0.053 %) with no overrun. Needs only the board: with
//! no microphones on PE6 the SAI still clocks and receives zeros. The time base and the audio
//! clock share the ST-LINK's 8 MHz, so this checks the PLL3/MCKDIV/frame configuration (a
//! wrong divider is off by percent), not the crystal.
#![no_std]
#![no_main]

use aim_firmware::capture::{self, ChunkReceiver, SaiCapture};
use aim_firmware::config::{CHUNK_FRAMES, SAMPLE_RATE_HZ};
use aim_firmware::stats::{read, COUNTERS};
use aim_hil_tests::{board, check_range, pass};
use cortex_m_rt::entry;
use embassy_executor::{Executor, InterruptExecutor};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_time::{Duration, Instant, Timer};
use static_cell::StaticCell;
use {defmt_rtt as _, panic_probe as _};

/// Measurement window.
const WINDOW: Duration = Duration::from_secs(10);

static EXECUTOR_CAPTURE: InterruptExecutor = InterruptExecutor::new();
static EXECUTOR_THREAD: StaticCell<Executor> = StaticCell::new();

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
async fn measure() {
    Timer::after_secs(1).await; // let the SAI and DMA settle
    let (c0, o0, t0) =
        (read(&COUNTERS.chunks_captured), read(&COUNTERS.dma_overruns), Instant::now());
    Timer::after(WINDOW).await;
    let (c1, o1, t1) =
        (read(&COUNTERS.chunks_captured), read(&COUNTERS.dma_overruns), Instant::now());

    let frames = u64::from(c1.wrapping_sub(c0)) * CHUNK_FRAMES as u64;
    let micros = (t1 - t0).as_micros();
    let rate_mhz = frames * 1_000_000_000 / micros; // millihertz
    defmt::info!("{=u64} frames in {=u64} µs: {=u64} mHz", frames, micros, rate_mhz);
    let nominal = u64::from(SAMPLE_RATE_HZ) * 1000;
    check_range("frame rate, mHz", rate_mhz, nominal - nominal / 1000, nominal + nominal / 1000);
    check_range("DMA overruns", u64::from(o1.wrapping_sub(o0)), 0, 0);
    pass("capture_rate");
}

#[entry]
fn main() -> ! {
    let (p, _cycles) = board();
    let (chunk_tx, chunk_rx) = capture::chunk_queue();
    let sai = SaiCapture::new(aim_firmware::sai_pins!(p));

    interrupt::UART4.set_priority(Priority::P6);
    let spawner = EXECUTOR_CAPTURE.start(interrupt::UART4);
    spawner.spawn(defmt::unwrap!(capture::capture_task(sai, chunk_tx)));

    EXECUTOR_THREAD.init(Executor::new()).run(|spawner| {
        spawner.spawn(defmt::unwrap!(consume(chunk_rx)));
        spawner.spawn(defmt::unwrap!(measure()));
    })
}
