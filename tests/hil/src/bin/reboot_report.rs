//! HIL: the watchdog resets a stalled board, a panic and a stack overflow reset it too, and
//! every start reports why in its `Hello` (reset cause, boot count, the recorded message).
//!
//! One binary, four starts; each start reads its [`StartReport`] (RCC_RSR and the retained
//! cell of `aim_firmware::fault`, whose handlers this binary uses, as the firmware does) and
//! does the next step:
//! 1. any other cause (the probe's reset, power-on): start the independent watchdog (500 ms)
//!    and stop feeding it;
//! 2. cause `watchdog`, within 1 s: check the boot count went up by one and the `Hello` the
//!    firmware would send (built by `StartReport::fill_hello`, encoded and decoded on the
//!    target) carries cause and count; then `panic!` on purpose;
//! 3. cause `panic`: check the count went up by one again and the message is this file's
//!    `panic!` (`bin/reboot_report.rs:<line> deliberate panic`), in the `Hello`
//!    too; then overflow the stack on purpose (unbounded recursion);
//! 4. cause `fault`: check the message says `stack overflow` (the MPU guard caught it and the
//!    hard-fault handler recorded it); PASS.
//!
//! The step's starting boot count is kept in the retained cell's count, so the checks need no
//! other state. probe-rs keeps reading RTT across the resets (the control block sits at the
//! same address every start); if it loses it, `probe-rs attach --chip STM32H743ZITx` on the
//! ELF shows the last start's PASS or FAIL. A FAIL here halts on a breakpoint loop instead of
//! panicking (a panic would reset and start the sequence again).
#![no_std]
#![no_main]

use aim_firmware::boot::StartReport;
use aim_firmware::config::WATCHDOG_TIMEOUT_US;
use aim_hil_tests::pass;
use aim_wire::{Body, Deframer, Encoder, Hello, ResetCause, MAX_ENCODED_LEN};
use cortex_m_rt::entry;
use defmt_rtt as _;
use embassy_stm32::wdg::IndependentWatchdog;

aim_firmware::fault_handlers!();

/// Boot count of step 1, kept in a second retained word so later steps know where they are.
#[unsafe(link_section = ".uninit.aim_hil_reboot")]
static mut FIRST_BOOT: core::mem::MaybeUninit<u32> = core::mem::MaybeUninit::uninit();

fn first_boot() -> u32 {
    // SAFETY: a word of RAM the reset keeps; volatile, as its content comes from an earlier run.
    unsafe { core::ptr::read_volatile(core::ptr::addr_of!(FIRST_BOOT).cast::<u32>()) }
}

fn set_first_boot(count: u32) {
    // SAFETY: as above; written once, in step 1, before any other use.
    unsafe { core::ptr::write_volatile(core::ptr::addr_of_mut!(FIRST_BOOT).cast::<u32>(), count) }
}

/// Fails without panicking (see the module docs): logs and halts.
fn fail(what: &str) -> ! {
    defmt::error!("FAIL {=str}", what);
    loop {
        cortex_m::asm::bkpt();
    }
}

fn check(ok: bool, what: &str) {
    if !ok {
        fail(what);
    }
    defmt::info!("ok {=str}", what);
}

/// The `Hello` this start would send, through the encoder and the host's deframer.
fn hello_round_trip(start: &StartReport) -> Hello {
    let mut hello = Hello::default();
    start.fill_hello(&mut hello);
    let mut buffer = [0u8; MAX_ENCODED_LEN];
    let Ok(len) = Encoder::new(1).encode(0, Body::Hello(hello.clone()), &mut buffer) else {
        fail("Hello did not encode");
    };
    let mut deframer: Deframer = Deframer::new();
    match deframer.feed(&buffer[..len]).next() {
        Some(Ok(frame)) if frame.body == Body::Hello(hello.clone()) => hello,
        _ => fail("Hello did not decode to itself"),
    }
}

/// Recurses until the stack overflows (the condition is opaque to the compiler, never true).
#[inline(never)]
fn recurse(depth: u32) -> u32 {
    if core::hint::black_box(depth) == u32::MAX {
        return 0;
    }
    let mut pad = [depth; 16];
    core::hint::black_box(&mut pad);
    recurse(depth + 1).wrapping_add(pad[3])
}

#[entry]
fn main() -> ! {
    let start = StartReport::take();
    let p = embassy_stm32::init(start.clock.embassy_config());
    let Some(core) = cortex_m::Peripherals::take() else { fail("core peripherals") };
    let _cycles = aim_firmware::init_core(core);
    start.log();

    match start.reset_cause {
        ResetCause::Watchdog => {
            check(start.boot_count == first_boot() + 1, "boot count +1 after the watchdog reset");
            let hello = hello_round_trip(&start);
            check(hello.reset_cause() == Some(ResetCause::Watchdog), "Hello: cause watchdog");
            check(hello.boot_count == start.boot_count, "Hello: boot count");
            check(hello.panic_message.is_empty(), "Hello: no panic message");
            check(hello.unique_id == embassy_stm32::uid::uid(), "Hello: unique id");
            check(hello.chip_revision == start.clock.revision, "Hello: chip revision");
            check(hello.clock_source == start.clock.source.code(), "Hello: clock source");
            check(hello.sysclk_hz == aim_firmware::clocks::sysclk_hz(), "Hello: core clock");
            defmt::info!("step 3: panic on purpose");
            panic!("deliberate panic");
        }
        ResetCause::Panic => {
            check(start.boot_count == first_boot() + 2, "boot count +1 after the panic");
            let hello = hello_round_trip(&start);
            check(hello.reset_cause() == Some(ResetCause::Panic), "Hello: cause panic");
            let message = hello.panic_message.as_str();
            check(message.starts_with("bin/reboot_report.rs:"), "message names this file");
            check(message.ends_with(" deliberate panic"), "message text kept");
            defmt::info!("step 4: stack overflow on purpose");
            let depth = recurse(0);
            fail(if depth > 0 { "recursion returned" } else { "recursion returned 0" });
        }
        ResetCause::Fault => {
            check(start.boot_count == first_boot() + 3, "boot count +1 after the fault");
            let hello = hello_round_trip(&start);
            check(hello.reset_cause() == Some(ResetCause::Fault), "Hello: cause fault");
            check(
                hello.panic_message.as_str().starts_with("hard fault: stack overflow"),
                "the MPU guard caught the overflow",
            );
            pass("reboot_report");
        }
        _ => {
            set_first_boot(start.boot_count);
            defmt::info!(
                "step 1: watchdog started, not fed: reset in {=u32} µs",
                WATCHDOG_TIMEOUT_US
            );
            let mut watchdog = IndependentWatchdog::new(p.IWDG1, WATCHDOG_TIMEOUT_US);
            watchdog.unleash();
            let waited = embassy_time::Instant::now();
            loop {
                if waited.elapsed().as_millis() > 2_000 {
                    fail("no watchdog reset within 2 s");
                }
            }
        }
    }
}
