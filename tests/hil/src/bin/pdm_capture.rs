//! HIL (feature `pdm`): SAI1's PDM interface and the decimator deliver 48 000 frames per second
//! of four live, distinct microphones, without overruns.
//!
//! Runs the firmware's PDM capture task (`aim_firmware::capture_pdm`, interrupt executor) and a
//! thread-mode consumer that inspects every chunk the decimator wrote. After 1 s of settling
//! (the decimator's and the microphones' start-up) it measures for 5 s and checks:
//! - the PDM interface is configured as the module documents: PDMCR has PDMEN, MICNBR = 1 (two
//!   pairs), CKEN1 and CKEN2; PE2/PE5/PE6/PE4 are on AF2 (SAI1_CK1/CK2/D1/D2), not the TDM
//!   functions' AF6 the embassy constructor gives them;
//! - both PDM clocks run: PE2 (CK1) and PE5 (CK2), sampled through GPIOE's IDR (the input
//!   buffer stays on in alternate-function mode) 100 000 times with interrupts off, change level
//!   in ≥ 10 % of the samples, and, when the sampling is faster than a half period (163 ns,
//!   timed with the DWT), the counted edges give 3.072 MHz ± 2 %;
//! - frame rate 48 000 Hz ± 0.1 % (chunks over `embassy_time`; one chunk in 5 s is 0.11 %, so
//!   the window counts 937 or 938 chunks) and no DMA overrun;
//! - every microphone alive and not stuck: a PDM line that is not driven (no microphone, a
//!   broken wire: the pull-down reads 0) or stuck at 1 decimates to a constant, so each
//!   microphone's 24-bit samples must span ≥ [`MIN_SPAN`] LSB in ≥ 90 % of the chunks, and its
//!   mean must stay within a quarter of full scale (an idle PDM microphone sits near density
//!   1/2, i.e. near 0);
//! - the two microphones of a data line are distinct: fewer than 10 % of their samples equal
//!   (a wrong edge selection or byte order would hand both slots the same bits).
//!
//! Needs four PDM microphones wired as `firmware/README.md` ("PDM microphones") says, in a
//! normally quiet room (their self-noise alone spans hundreds of LSB). Build and run with
//! `cargo run -p aim-hil-tests --release --target thumbv7em-none-eabihf --no-default-features
//! --features pdm --bin pdm_capture`.
#![no_std]
#![no_main]

use aim_firmware::capture::{self, ChunkReceiver};
use aim_firmware::capture_pdm::{self, PdmCapture, PDM_PAIRS, PDM_PINS_GPIOE, PDM_PIN_AF};
use aim_firmware::config::{CHUNK_FRAMES, MIC_COUNT, SAMPLE_RATE_HZ, TDM_SLOTS};
use aim_firmware::stats::{read, CycleCounter, COUNTERS};
use aim_hil_tests::{board, check_range, pass, pin_clock};
use cortex_m_rt::entry;
use embassy_executor::{Executor, InterruptExecutor};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_time::{Duration, Instant};
use static_cell::StaticCell;
use {defmt_rtt as _, panic_probe as _};

/// Settling time before the measurement.
const SETTLE: Duration = Duration::from_secs(1);
/// Measurement window.
const WINDOW: Duration = Duration::from_secs(5);
/// Smallest span (max − min) of a live microphone's 24-bit samples in one chunk, LSB.
const MIN_SPAN: i32 = 16;
/// Largest |mean| of a microphone's samples over the window: a quarter of full scale, LSB.
const MAX_MEAN: i64 = 1 << 21;
/// The PDM clock on CK1 and CK2, Hz.
const PDM_CLOCK_HZ: u64 = capture_pdm::PDM_CLOCK_HZ as u64;

static EXECUTOR_CAPTURE: InterruptExecutor = InterruptExecutor::new();
static EXECUTOR_THREAD: StaticCell<Executor> = StaticCell::new();
static CYCLES: StaticCell<CycleCounter> = StaticCell::new();

#[interrupt]
unsafe fn UART4() {
    // SAFETY: UART4 is unused; its vector only runs this executor.
    unsafe { EXECUTOR_CAPTURE.on_interrupt() }
}

/// What the window saw of one microphone.
#[derive(Default, Clone, Copy)]
struct MicStats {
    /// Chunks whose samples spanned at least `MIN_SPAN`.
    live_chunks: u32,
    /// Sum of the samples (24-bit), for the mean.
    sum: i64,
    /// Samples equal to the other microphone of the same data line.
    equal_to_partner: u32,
}

/// The 24-bit sample of microphone `mic` in frame `frame` of a chunk (left-justified words).
fn sample(words: &[u32], frame: usize, mic: usize) -> i32 {
    (words[frame * TDM_SLOTS + mic] as i32) >> 8
}

fn check_configuration() {
    let pdmcr = embassy_stm32::pac::SAI1.pdmcr().read();
    check_range("PDMCR PDMEN", u64::from(pdmcr.pdmen()), 1, 1);
    check_range("PDMCR MICNBR (pairs - 1)", u64::from(pdmcr.micnbr()), 1, 1);
    for clock in 0..PDM_PAIRS {
        check_range("PDMCR CKENx", u64::from(pdmcr.cken(clock)), 1, 1);
    }
    let afr = embassy_stm32::pac::GPIOE.afr(0).read();
    for pin in PDM_PINS_GPIOE {
        defmt::info!("PE{=usize}: AF{=u8}", pin, afr.afr(pin));
        check_range("PDM pin alternate function", u64::from(afr.afr(pin)), 2, 2);
    }
    const _: () = assert!(PDM_PIN_AF == 2);
}

/// Checks the PDM clock on CK1 (PE2) and CK2 (PE5) toggles, at 3.072 MHz where measurable.
fn check_clocks(cycles: &CycleCounter) {
    for (name, pin) in [("CK1 (PE2)", 2), ("CK2 (PE5)", 5)] {
        // Half a period of 3.072 MHz is 162.8 ns: sampling faster counts every edge.
        pin_clock::check(
            cycles,
            name,
            pin,
            "PDM clock level changes",
            "PDM clock, Hz",
            PDM_CLOCK_HZ,
            162_000,
        );
    }
}

#[embassy_executor::task]
async fn consume(mut chunks: ChunkReceiver, cycles: &'static CycleCounter) {
    let start = Instant::now();
    let mut mics = [MicStats::default(); MIC_COUNT];
    let (mut chunks_seen, mut c0, mut o0, mut t0) = (0u32, 0u32, 0u32, start);
    let mut measuring = false;
    loop {
        let chunk = chunks.receive().await;
        let now = Instant::now();
        if !measuring && now - start >= SETTLE {
            measuring = true;
            check_configuration();
            check_clocks(cycles);
            (c0, o0, t0) =
                (read(&COUNTERS.chunks_captured), read(&COUNTERS.dma_overruns), Instant::now());
        }
        if measuring {
            chunks_seen += 1;
            for (mic, stats) in mics.iter_mut().enumerate() {
                let (mut low, mut high) = (i32::MAX, i32::MIN);
                let partner = mic ^ 1;
                for frame in 0..CHUNK_FRAMES {
                    let s = sample(&chunk.words, frame, mic);
                    low = low.min(s);
                    high = high.max(s);
                    stats.sum += i64::from(s);
                    stats.equal_to_partner += u32::from(s == sample(&chunk.words, frame, partner));
                }
                stats.live_chunks += u32::from(high - low >= MIN_SPAN);
            }
        }
        chunks.receive_done();

        if measuring && now - t0 >= WINDOW {
            let (c1, o1) = (read(&COUNTERS.chunks_captured), read(&COUNTERS.dma_overruns));
            let frames = u64::from(c1.wrapping_sub(c0)) * CHUNK_FRAMES as u64;
            let micros = (now - t0).as_micros();
            let rate_mhz = frames * 1_000_000_000 / micros;
            defmt::info!("{=u64} frames in {=u64} µs: {=u64} mHz", frames, micros, rate_mhz);
            let nominal = u64::from(SAMPLE_RATE_HZ) * 1000;
            check_range(
                "frame rate, mHz",
                rate_mhz,
                nominal - nominal / 1000,
                nominal + nominal / 1000,
            );
            check_range("DMA overruns", u64::from(o1.wrapping_sub(o0)), 0, 0);
            let samples = u64::from(chunks_seen) * CHUNK_FRAMES as u64;
            for (mic, stats) in mics.iter().enumerate() {
                let mean = stats.sum / samples as i64;
                defmt::info!(
                    "microphone {=usize}: live in {=u32} of {=u32} chunks, mean {=i64} LSB, {=u32} samples equal to microphone {=usize}",
                    mic,
                    stats.live_chunks,
                    chunks_seen,
                    mean,
                    stats.equal_to_partner,
                    mic ^ 1
                );
                check_range(
                    "live chunks (span >= 16 LSB)",
                    u64::from(stats.live_chunks),
                    u64::from(chunks_seen) * 9 / 10,
                    u64::from(chunks_seen),
                );
                check_range("|mean|, LSB", mean.unsigned_abs(), 0, MAX_MEAN as u64);
                check_range(
                    "samples equal to the pair partner",
                    u64::from(stats.equal_to_partner),
                    0,
                    samples / 10,
                );
            }
            pass("pdm_capture");
        }
    }
}

#[entry]
fn main() -> ! {
    let (p, cycles) = board();
    let cycles: &'static CycleCounter = CYCLES.init(cycles);
    let (chunk_tx, chunk_rx) = capture::chunk_queue();
    let pdm = PdmCapture::new(aim_firmware::sai_pins!(p));

    interrupt::UART4.set_priority(Priority::P6);
    let spawner = EXECUTOR_CAPTURE.start(interrupt::UART4);
    spawner.spawn(defmt::unwrap!(capture_pdm::capture_task(pdm, chunk_tx)));

    EXECUTOR_THREAD.init(Executor::new()).run(|spawner| {
        spawner.spawn(defmt::unwrap!(consume(chunk_rx, cycles)));
    })
}
