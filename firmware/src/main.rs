//! AIM array board firmware (NUCLEO-H743ZI2): TDM microphones in, `aim-wire` frames out.
//!
//! Two executors, because capture must never wait for the DSP:
//! - an interrupt executor (vector `UART4`, unused by the board, priority 6) runs the capture
//!   task, which empties the SAI DMA ring within microseconds of each half-transfer, and the
//!   uplink task, which keeps USART3 busy;
//! - the thread-mode executor runs the processing task (`aim_dsp::Pipeline`), which may take
//!   several milliseconds per block and is preempted by the capture task whenever audio arrives.
//!
//! Everything below is start-up; the streaming loops live in the library (`capture`,
//! `processing`, `uplink`) and never `unwrap!`. A panic or fault anywhere is recorded, logged
//! and resets the board (`aim_firmware::fault`); the next `Hello` reports it.
#![no_std]
#![no_main]

use aim_firmware::boot::StartReport;
use aim_firmware::capture;
use aim_firmware::{clocks, config, processing, uplink};
use cortex_m_rt::entry;
use defmt_rtt as _;
use embassy_executor::{Executor, InterruptExecutor};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::wdg::IndependentWatchdog;
use static_cell::StaticCell;

aim_firmware::fault_handlers!();

static EXECUTOR_CAPTURE: InterruptExecutor = InterruptExecutor::new();
static EXECUTOR_THREAD: StaticCell<Executor> = StaticCell::new();

#[interrupt]
unsafe fn UART4() {
    // SAFETY: UART4 is not used by the firmware; its vector only runs this executor.
    unsafe { EXECUTOR_CAPTURE.on_interrupt() }
}

#[entry]
fn main() -> ! {
    // First: the reset flags and the retained fault record, before anything can overwrite them.
    let start = StartReport::take();
    let p = embassy_stm32::init(start.clock.embassy_config());
    let Some(core) = cortex_m::Peripherals::take() else {
        panic!("core peripherals taken twice");
    };
    let cycles = aim_firmware::init_core(core);
    if let Err(measured) = clocks::check_sai_kernel_clock() {
        panic!("SAI1 kernel clock {} Hz, expected {}", measured, clocks::SAI_KERNEL_HZ);
    }
    start.log();
    defmt::info!(
        "aim-firmware {}: array {}, {} mics, {} Hz, SAI bit clock {} Hz, core {} Hz",
        env!("CARGO_PKG_VERSION"),
        config::array_id(&start.unique_id),
        config::MIC_COUNT,
        config::SAMPLE_RATE_HZ,
        clocks::SAI_BIT_CLOCK_HZ,
        clocks::sysclk_hz()
    );

    // The pipeline is configured before the watchdog runs: configuration is one-off work
    // (the beacon detector's template: 19.2 M instructions, ≈ 40 ms; BENCHMARKS.md
    // "Firmware"), not the streaming loop the 500 ms watchdog guards.
    let pipeline = processing::pipeline();
    defmt::info!("DSP pipeline configured");

    aim_firmware::freeze_watchdog_in_debug();
    let mut watchdog = IndependentWatchdog::new(p.IWDG1, config::WATCHDOG_TIMEOUT_US);
    watchdog.unleash();

    let (chunk_tx, chunk_rx) = capture::chunk_queue();
    #[cfg(not(feature = "pdm"))]
    let sai = capture::SaiCapture::new(aim_firmware::sai_pins!(p));
    #[cfg(feature = "pdm")]
    let sai = aim_firmware::capture_pdm::PdmCapture::new(aim_firmware::sai_pins!(p));
    let Ok(uart) = uplink::uplink_uart(p.USART3, p.PD8, p.DMA1_CH1) else {
        panic!("USART3 configuration rejected");
    };
    let processing = processing::Processing::new(pipeline, cycles, watchdog, &start);

    interrupt::UART4.set_priority(Priority::P6);
    let spawner = EXECUTOR_CAPTURE.start(interrupt::UART4);
    #[cfg(not(feature = "pdm"))]
    let capture = capture::capture_task(sai, chunk_tx);
    #[cfg(feature = "pdm")]
    let capture = aim_firmware::capture_pdm::capture_task(sai, chunk_tx);
    let (Ok(capture), Ok(uplink)) = (capture, uplink::uplink_task(uart)) else {
        panic!("capture or uplink task spawned twice");
    };
    spawner.spawn(capture);
    spawner.spawn(uplink);

    let executor = EXECUTOR_THREAD.init(Executor::new());
    executor.run(|spawner| match processing::processing_task(processing, chunk_rx) {
        Ok(task) => spawner.spawn(task),
        Err(_) => panic!("processing task spawned twice"),
    })
}
