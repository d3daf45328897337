//! HIL: capture survives a stalled DSP and a stalled capture task, and every loss reaches the
//! pipeline as a gap of the right length, on the right clock.
//!
//! Runs the firmware's capture task (interrupt executor) and, in thread mode, the firmware's
//! gap bookkeeping in front of its `Pipeline` (`processing::pipeline`), fed the captured
//! chunks (zeros without microphones: the DSP's work per block is the same). Two stalls on
//! purpose, 2 s apart:
//! 1. **DSP overload**: the consumer busy-waits 100 ms (the queue holds 42.7 ms). Expected:
//!    capture goes on and discards the chunks it cannot queue (`dsp_overloads` > 0), no DMA
//!    overrun; the jump in the chunks' sample index is exactly `dsp_overloads` chunks.
//! 2. **Ring overrun**: interrupts off for 20 ms, so the capture task cannot run while the
//!    ring (2 chunks, 10.7 ms) wraps. Expected: one DMA overrun, capture restarted, and the
//!    sample index after the restart taken from the elapsed time.
//!
//! At each check, 2 s after a stall, when the consumer has caught up: the latest chunk's
//! sample index agrees with the time since capture started (48 kHz, within 2 chunks: the
//! restart latency and the position of a chunk inside its 5.3 ms), and the pipeline's
//! `gap_stats` add up the same gaps and lost frames the consumer saw.
#![no_std]
#![no_main]

use aim_firmware::capture::{self, ChunkReceiver, SaiCapture};
use aim_firmware::config::{CHUNK_FRAMES, SAMPLE_RATE_HZ};
use aim_firmware::processing;
use aim_firmware::stats::{read, COUNTERS};
use aim_hil_tests::{board, check_range, pass};
use cortex_m_rt::entry;
use embassy_executor::{Executor, InterruptExecutor};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_time::{block_for, Duration, Instant};
use static_cell::StaticCell;
use {defmt_rtt as _, panic_probe as _};

static EXECUTOR_CAPTURE: InterruptExecutor = InterruptExecutor::new();
static EXECUTOR_THREAD: StaticCell<Executor> = StaticCell::new();

#[interrupt]
unsafe fn UART4() {
    // SAFETY: UART4 is unused; its vector only runs this executor.
    unsafe { EXECUTOR_CAPTURE.on_interrupt() }
}

/// Busy-waits `ms` with interrupts off: the capture task cannot run.
fn stall_capture(ms: u64) {
    cortex_m::interrupt::free(|_| {
        let cycles = u64::from(aim_firmware::clocks::sysclk_hz()) / 1000 * ms;
        // `delay` takes at least the cycles asked for; in chunks that fit its u32.
        for _ in 0..ms {
            cortex_m::asm::delay((cycles / ms) as u32);
        }
    });
}

#[embassy_executor::task]
async fn consume(mut chunks: ChunkReceiver) {
    let pipeline = processing::pipeline();
    let start = Instant::now();
    let mut expected: u64 = 0;
    let (mut gaps, mut lost) = (0u32, 0u64);
    let mut phase = 0;
    loop {
        let chunk = chunks.receive().await;
        let first = chunk.first_frame;
        if first > expected {
            gaps += 1;
            lost += first - expected;
            defmt::info!("gap of {=u64} frames before {=u64}", first - expected, first);
            pipeline.gap(first - expected);
        } else if first < expected {
            defmt::panic!("FAIL chunk index went back: {=u64} after {=u64}", first, expected);
        }
        expected = first + CHUNK_FRAMES as u64;
        // Frames the SAI has clocked since the consumer started (just after capture started)
        // against the index after this chunk: when the consumer keeps up, under two chunks.
        let clock_error =
            capture::frames_in((Instant::now() - start).as_micros()).abs_diff(expected);
        pipeline.push(processing::tdm_words(chunk), &mut |_| {});
        chunks.receive_done();

        let elapsed = Instant::now() - start;
        if phase == 0 && elapsed > Duration::from_secs(1) {
            phase = 1;
            defmt::info!("stall 1: DSP busy for 100 ms");
            block_for(Duration::from_millis(100));
        } else if phase == 1 && elapsed > Duration::from_secs(3) {
            let overloads = read(&COUNTERS.dsp_overloads);
            defmt::info!(
                "after stall 1: {=u32} chunks discarded, {=u32} gaps, {=u64} frames lost",
                overloads,
                gaps,
                lost
            );
            check_range("DSP overloads", u64::from(overloads), 8, 14);
            check_range(
                "DMA overruns after stall 1",
                u64::from(read(&COUNTERS.dma_overruns)),
                0,
                0,
            );
            check_range("gaps after stall 1", u64::from(gaps), 1, 1);
            check_range(
                "frames lost in stall 1",
                lost,
                u64::from(overloads) * CHUNK_FRAMES as u64,
                u64::from(overloads) * CHUNK_FRAMES as u64,
            );
            check_range(
                "clock error after stall 1, frames",
                clock_error,
                0,
                2 * CHUNK_FRAMES as u64,
            );
            phase = 2;
            defmt::info!("stall 2: capture task blocked for 20 ms");
            stall_capture(20);
        } else if phase == 2 && elapsed > Duration::from_secs(5) {
            let overruns = read(&COUNTERS.dma_overruns);
            defmt::info!("after stall 2: {=u32} DMA overruns, {=u32} gaps, {=u64} frames lost; clock error {=u64} frames", overruns, gaps, lost, clock_error);
            check_range("DMA overruns", u64::from(overruns), 1, 1);
            check_range("SAI FIFO overruns", u64::from(read(&COUNTERS.sai_overruns)), 0, 0);
            check_range("gaps", u64::from(gaps), 2, 2);
            // The restart's index came from the elapsed time: the clock still agrees.
            check_range(
                "clock error after stall 2, frames",
                clock_error,
                0,
                2 * CHUNK_FRAMES as u64,
            );
            let stats = pipeline.gap_stats();
            check_range("pipeline gaps", u64::from(stats.gaps), u64::from(gaps), u64::from(gaps));
            check_range("pipeline frames lost", stats.frames_lost, lost, lost);
            check_range(
                "pipeline outputs dropped",
                u64::from(stats.outputs_dropped),
                1,
                u64::from(4 * gaps),
            );
            let rate = expected * 1_000_000 / (Instant::now() - start).as_micros();
            check_range(
                "sample clock, Hz",
                rate,
                u64::from(SAMPLE_RATE_HZ) * 99 / 100,
                u64::from(SAMPLE_RATE_HZ) * 101 / 100,
            );
            pass("overrun_recovery");
        }
    }
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
    })
}
