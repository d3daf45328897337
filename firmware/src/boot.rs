//! What a start reports: why the board reset (RCC_RSR and the retained fault record), how many
//! times it started since power-on, who it is (the 96-bit unique ID), and what it runs on (the
//! silicon revision and the clock source and speed, [`crate::clocks::ClockPlan`]). All of it goes into
//! every `Hello`, so a host notices a reboot (a new boot count, the sample index going back)
//! and two boards claiming one array id (two unique IDs under one id).
use aim_wire::{Hello, ResetCause};
use embassy_stm32::pac;

use crate::clocks::ClockPlan;
use crate::fault::{self, Fault, MESSAGE_LEN};

/// The start of this run, read once at start-up by [`StartReport::take`].
#[derive(Debug, Clone)]
pub struct StartReport {
    /// Why the board started.
    pub reset_cause: ResetCause,
    /// Starts since power-on, this one included.
    pub boot_count: u32,
    /// The chip's 96-bit unique ID (RM0433 §61.1, at 0x1FF1_E800), bytes as stored.
    pub unique_id: [u8; aim_wire::UNIQUE_ID_LEN],
    /// The panic or fault message the previous run recorded before resetting (empty if none).
    pub message: heapless::String<MESSAGE_LEN>,
    /// The raw RCC_RSR flags, for the log.
    pub rsr: u32,
    /// The silicon revision and the clock tree chosen for it; `embassy_stm32::init` takes
    /// [`ClockPlan::embassy_config`].
    pub clock: ClockPlan,
}

/// The reset flags of RCC_RSR, in the order they decide the cause (a power-on also sets the
/// brown-out and pin flags, a software or watchdog reset also the pin flag).
fn cause_from_flags(rsr: pac::rcc::regs::Rsr, fault: Fault) -> ResetCause {
    if rsr.iwdg1rstf() {
        ResetCause::Watchdog
    } else if rsr.wwdg1rstf() {
        ResetCause::WindowWatchdog
    } else if rsr.lpwrrstf() {
        ResetCause::LowPower
    } else if rsr.sftrstf() {
        match fault {
            Fault::Panic => ResetCause::Panic,
            Fault::HardFault => ResetCause::Fault,
            Fault::None => ResetCause::Software,
        }
    } else if rsr.porrstf() {
        ResetCause::PowerOn
    } else if rsr.borrstf() {
        ResetCause::BrownOut
    } else if rsr.pinrstf() {
        ResetCause::Pin
    } else {
        ResetCause::Unknown
    }
}

impl StartReport {
    /// Reads and clears the reset flags, takes the previous run's record from the retained
    /// cell and starts this run's (see [`fault::start_boot`]), then reads the silicon revision
    /// and starts the HSE ([`ClockPlan::probe`]). Call once, first thing in `main`, before
    /// `embassy_stm32::init`.
    pub fn take() -> Self {
        let rsr = pac::RCC.rsr().read();
        pac::RCC.rsr().modify(|w| w.set_rmvf(true));
        // After a power-on or brown-out the RAM holds nothing of the previous run.
        let power_on = rsr.porrstf() || rsr.borrstf();
        let (previous, boot_count) = fault::start_boot(power_on);
        let fault = previous.map_or(Fault::None, |p| p.fault());
        let mut message = heapless::String::new();
        if let Some(p) = &previous {
            // Cannot fail: the record holds at most MESSAGE_LEN bytes.
            let _ = message.push_str(p.message());
        }
        Self {
            reset_cause: cause_from_flags(rsr, fault),
            boot_count,
            unique_id: embassy_stm32::uid::uid(),
            message,
            rsr: rsr.0,
            clock: ClockPlan::probe(),
        }
    }

    /// Writes the start fields of `hello`.
    pub fn fill_hello(&self, hello: &mut Hello) {
        hello.reset_cause = self.reset_cause.code();
        hello.boot_count = self.boot_count;
        hello.unique_id = self.unique_id;
        hello.set_panic_message(&self.message);
        self.clock.fill_hello(hello);
    }

    /// Logs the report over defmt.
    pub fn log(&self) {
        defmt::info!(
            "start: reset cause {=str} (RCC_RSR {=u32:#010x}), boot {=u32} since power-on, unique id {=[u8]:02x}",
            self.reset_cause.name(),
            self.rsr,
            self.boot_count,
            self.unique_id[..]
        );
        self.clock.log();
        if !self.message.is_empty() {
            defmt::warn!("the previous run ended with: {=str}", self.message.as_str());
        }
    }
}
