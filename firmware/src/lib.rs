//! AIM array board firmware: the hardware glue around `aim-dsp` and `aim-wire`.
//!
//! Nothing here computes anything worth testing on a host: the signal processing is
//! `aim_dsp::Pipeline`, the frame format and the mapping of DSP outputs to frames are
//! `aim_wire` (so the simulator produces the same bytes). This crate owns what only the board
//! has: clocks, SAI + DMA capture, USART + DMA uplink, executors, watchdog, cycle counting.
//! It is a library so that the hardware-in-the-loop binaries in `tests/hil` run exactly this
//! code; the firmware binary is `src/main.rs`.
//!
//! Data flow:
//!
//! ```text
//! SAI1 A --DMA1 S0--> ring (AXI SRAM) --capture task (interrupt executor, P6)--> chunk queue
//!   (each chunk stamped with its first frame's sample index; losses become gaps)
//!   --> processing task (thread mode): Pipeline::gap/push, DWT cycles, watchdog, encode
//!   --> uplink queue (drop oldest) --> uplink task (interrupt executor) --DMA1 S1--> USART3
//! ```
#![no_std]

pub mod boot;
pub mod capture;
#[cfg(feature = "pdm")]
pub mod capture_pdm;
pub mod clocks;
pub mod config;
pub mod dma_buffer;
pub mod fault;
pub mod processing;
pub mod stats;
pub mod uplink;

use embassy_stm32::{bind_interrupts, dma, peripherals};

bind_interrupts!(
    /// The DMA streams' interrupt handlers: stream 0 serves SAI1 A, stream 1 USART3 TX.
    pub struct Irqs {
        DMA1_STREAM0 => dma::InterruptHandler<peripherals::DMA1_CH0>;
        DMA1_STREAM1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    }
);

/// Enables the instruction cache (the data cache stays off, so the DMA buffers in AXI SRAM
/// need no maintenance; the DSP state beside them in AXI SRAM is therefore read uncached, see
/// firmware/README.md "Memory"), installs the MPU stack guard
/// ([`fault::install_stack_guard`]) and starts the DWT cycle counter. Call once at start-up,
/// after `embassy_stm32::init`.
pub fn init_core(mut core: cortex_m::Peripherals) -> stats::CycleCounter {
    core.SCB.enable_icache();
    fault::install_stack_guard(&mut core.MPU);
    stats::CycleCounter::start(&mut core.DCB, &mut core.DWT)
}

/// Stops the independent watchdog while a debugger halts the core, so that stepping through
/// the firmware with a probe does not reset it.
pub fn freeze_watchdog_in_debug() {
    embassy_stm32::pac::DBGMCU.apb4fzr1().modify(|w| w.set_iwdg1(true));
}
