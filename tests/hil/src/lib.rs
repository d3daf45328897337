//! Shared parts of the board's hardware-in-the-loop binaries (`src/bin/*.rs`).
//!
//! Each binary checks one measurable property of the real board with the firmware's own code
//! (`aim_firmware`): the capture rate of SAI1 + DMA, the DSP time per block from the DWT cycle
//! counter, the frame output on USART3. It prints its measurements over defmt/RTT, then
//! [`pass`] (breakpoint: probe-rs stops, exit code 0) or fails with `defmt::panic!`
//! (panic-probe → HardFault: probe-rs reports it and exits non-zero).
#![no_std]

pub mod pin_clock;
pub mod signal;

/// Reports success and stops the core on a breakpoint, which ends the `probe-rs run` session
/// with exit code 0.
pub fn pass(test: &str) -> ! {
    defmt::info!("PASS {=str}", test);
    loop {
        cortex_m::asm::bkpt();
    }
}

/// Checks `value` lies in `[low, high]`; fails the test with `what` otherwise.
pub fn check_range(what: &str, value: u64, low: u64, high: u64) {
    if value < low || value > high {
        defmt::panic!("FAIL {=str}: {=u64} outside [{=u64}, {=u64}]", what, value, low, high);
    }
    defmt::info!("ok {=str}: {=u64} in [{=u64}, {=u64}]", what, value, low, high);
}

/// Brings the board up exactly as the firmware does: silicon revision and HSE probed
/// (`ClockPlan::probe`: 480 MHz on revision V, 400 MHz before it; HSE bypass or HSI), clocks
/// (checked), I-cache, MPU stack guard, DWT. Timing checks use
/// `aim_firmware::clocks::sysclk_hz()`, the core clock chosen here.
pub fn board() -> (embassy_stm32::Peripherals, aim_firmware::stats::CycleCounter) {
    let plan = aim_firmware::clocks::ClockPlan::probe();
    let p = embassy_stm32::init(plan.embassy_config());
    plan.log();
    let Some(core) = cortex_m::Peripherals::take() else {
        defmt::panic!("FAIL core peripherals already taken");
    };
    let cycles = aim_firmware::init_core(core);
    if let Err(measured) = aim_firmware::clocks::check_sai_kernel_clock() {
        defmt::panic!(
            "FAIL SAI1 kernel clock {=u32} Hz, expected {=u32} Hz",
            measured,
            aim_firmware::clocks::SAI_KERNEL_HZ
        );
    }
    (p, cycles)
}

/// The DTCM stack, between the MPU stack guard above the static data
/// (`aim_firmware::fault::stack_bottom`) and the initial stack pointer (`_stack_start`):
/// painted before a measurement, scanned after.
pub mod stack {
    const PAINT: u32 = 0x5AC3_5AC3;

    fn bounds() -> (usize, usize) {
        use aim_firmware::fault;
        (fault::stack_bottom() as usize, fault::stack_top() as usize)
    }

    /// Stack size available to the firmware, bytes.
    pub fn size() -> usize {
        let (end, start) = bounds();
        start - end
    }

    /// Fills the unused stack (from its lowest address up to 256 bytes below the current stack
    /// pointer) with a pattern.
    pub fn paint() {
        let (end, _) = bounds();
        let sp = cortex_m::register::msp::read() as usize;
        let mut p = end;
        while p + 256 < sp {
            // SAFETY: the words between the stack guard and the stack pointer are unused stack:
            // nothing lives there, and this loop's own frame is above `sp - 256`.
            unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
            p += 4;
        }
    }

    /// The deepest stack use since [`paint`], bytes (from the top of the stack).
    pub fn high_water() -> usize {
        let (end, start) = bounds();
        let mut p = end;
        // SAFETY: reads of stack words that [`paint`] wrote or the program used since.
        while p < start && unsafe { core::ptr::read_volatile(p as *const u32) } == PAINT {
            p += 4;
        }
        start - p
    }
}
