//! Clock tree: 480 MHz core, and an audio clock that gives exactly 48 kHz.
//!
//! Source: the 8 MHz clock the ST-LINK drives into OSC_IN on the NUCLEO-H743ZI2 (HSE bypass).
//!
//! Core: PLL1, 8 MHz / 2 = 4 MHz × 240 = 960 MHz VCO, / 2 = 480 MHz (needs VOS0, rev V parts).
//!
//! Neither is assumed: [`ClockPlan::probe`], before `embassy_stm32::init`, reads the silicon
//! revision (DBGMCU_IDCODE REV_ID: `0x2003` = revision V runs at 480 MHz; revision Y `0x1003`
//! and any other value stop at 400 MHz, VOS1: PLL1 × 200) and starts the HSE in bypass mode,
//! waiting [`HSE_TIMEOUT_US`] for HSERDY (embassy would wait forever: a board whose ST-LINK
//! clock is missing, e.g. a solder bridge changed or the MCO off, would hang before `main`
//! logs anything). Without HSE it runs from the 64 MHz HSI with the same PLL outputs
//! (PLL1: 64 MHz / 16 = 4 MHz, as from HSE; PLL3: 64 MHz / 25 = 2.56 MHz × 120 = 307.2 MHz /
//! 5 = 61.44 MHz), so the sample rate is nominally still 48 kHz but only as exact as the HSI's
//! trim, and says so: the chip revision, the clock source and the core clock are in the defmt
//! log and in every `Hello` (`chip_revision`, `clock_source`, `sysclk_hz`).
//!
//! Audio: the SAI needs 256 × 48 kHz = 12.288 MHz (8 slots × 32 bit), i.e. 2¹⁷·3·5³ Hz.
//! From 8 MHz = 2⁹·5⁶ Hz the PLL ratio is 768/125, and a PLL output is
//! `8 MHz × (N + FRACN/8192) / (M × P)`: the fractional part only adds powers of two, so
//! the 5³ must come from M × P. 49.152 MHz (= 4 × 12.288) would need M × P a multiple of 125,
//! which either puts the reference below 1 MHz (M = 25) or the VCO above 960 MHz (M = 5,
//! P = 25: 1228.8 MHz); 49.152 MHz is therefore *not* exactly reachable from this board's
//! 8 MHz, integer or fractional. 61.44 MHz = 5 × 12.288 MHz is, with integers only:
//!
//! PLL3: 8 MHz / M 5 = 1.6 MHz (range 1–2 MHz, medium VCO) × N 192 = 307.2 MHz VCO,
//! / P 5 = 61.44 MHz → SAI1 kernel clock; SAI MCKDIV 5 → MCLK 12.288 MHz = 256 × 48 kHz;
//! frame of 8 × 32 = 256 bit clocks → bit clock 12.288 MHz, frame sync 48 000 Hz exactly
//! (relative to the ST-LINK crystal).
use aim_wire::{ClockSource, Hello};
use core::sync::atomic::{AtomicU32, Ordering};
use embassy_stm32::pac;
use embassy_stm32::rcc::{
    AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllDiv, PllMul, PllPreDiv, PllSource, Sysclk,
    VoltageScale,
};
use embassy_stm32::sai::MasterClockDivider;
use embassy_stm32::time::Hertz;

use crate::config::{SAMPLE_RATE_HZ, SLOT_BITS, TDM_SLOTS};

/// HSE frequency: the ST-LINK's 8 MHz MCO on the NUCLEO-H743ZI2, Hz.
pub const HSE_HZ: u32 = 8_000_000;
/// Core clock (PLL1 P) on revision V silicon, Hz; [`sysclk_hz`] is the one the board runs at.
pub const SYSCLK_HZ: u32 = HSE_HZ / 2 * 240 / 2;
/// Core clock on silicon before revision V (the VOS1 maximum), Hz.
pub const SYSCLK_BEFORE_REV_V_HZ: u32 = HSE_HZ / 2 * 200 / 2;
/// REV_ID of DBGMCU_IDCODE on revision V, the first STM32H743 revision rated for 480 MHz
/// (ST errata sheet ES0392; revision Y reads `0x1003`).
pub const REV_V: u16 = 0x2003;
/// The internal RC oscillator, Hz (HSIDIV = 1).
pub const HSI_HZ: u32 = 64_000_000;
/// How long start-up waits for HSERDY after enabling the HSE in bypass mode, µs. An external
/// clock is ready within a few cycles; a crystal would take ~2 ms.
pub const HSE_TIMEOUT_US: u32 = 10_000;
/// SAI1 kernel clock (PLL3 P), Hz.
pub const SAI_KERNEL_HZ: u32 = HSE_HZ / 5 * 192 / 5;
/// SAI master clock divider (MCKDIV).
pub const SAI_MCKDIV: u32 = 5;
/// SAI bit clock, Hz: one frame of `TDM_SLOTS × SLOT_BITS` bits per sample.
pub const SAI_BIT_CLOCK_HZ: u32 = SAMPLE_RATE_HZ * TDM_SLOTS as u32 * SLOT_BITS;

// The arithmetic above, checked by the compiler: every division is exact and FS = 48 kHz.
const _: () = assert!(HSE_HZ.is_multiple_of(5) && (HSE_HZ / 5 * 192).is_multiple_of(5));
const _: () = assert!(HSE_HZ / 5 >= 1_000_000 && HSE_HZ / 5 <= 2_000_000);
const _: () = assert!(HSE_HZ / 5 * 192 >= 150_000_000 && HSE_HZ / 5 * 192 <= 420_000_000);
const _: () = assert!(SAI_KERNEL_HZ.is_multiple_of(SAI_MCKDIV));
// With NODIV = 0 the SAI divides MCLK by 256 to get FS; the frame is 256 bit clocks long.
const _: () = assert!(SAI_KERNEL_HZ / SAI_MCKDIV == 256 * SAMPLE_RATE_HZ);
const _: () = assert!(TDM_SLOTS as u32 * SLOT_BITS == 256);
const _: () = assert!(SAI_BIT_CLOCK_HZ == 12_288_000);
const _: () = assert!(SYSCLK_HZ == 480_000_000);
const _: () = assert!(SYSCLK_BEFORE_REV_V_HZ == 400_000_000);
// The HSI fallback gives the same PLL1 reference (4 MHz) and SAI kernel clock, exactly.
const _: () = assert!(HSI_HZ / 16 == HSE_HZ / 2);
const _: () = assert!(HSI_HZ.is_multiple_of(25) && (HSI_HZ / 25 * 120).is_multiple_of(5));
const _: () = assert!(HSI_HZ / 25 >= 2_000_000 && HSI_HZ / 25 * 120 <= 420_000_000);
const _: () = assert!(HSI_HZ / 25 * 120 / 5 == SAI_KERNEL_HZ);

/// The SAI MCKDIV register value matching [`SAI_MCKDIV`].
pub const SAI_MASTER_CLOCK_DIVIDER: MasterClockDivider = MasterClockDivider::DIV5;

/// What start-up found out about the chip and its clock, and the clock tree it chose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockPlan {
    /// DBGMCU_IDCODE REV_ID (silicon revision: [`REV_V`] = 0x2003).
    pub revision: u16,
    /// DBGMCU_IDCODE DEV_ID (0x450 for the STM32H742/743/750/753).
    pub device: u16,
    /// The clock PLL1 and PLL3 run from.
    pub source: ClockSource,
    /// The core clock chosen for this revision, Hz.
    pub sysclk_hz: u32,
}

/// The core clock of this run, Hz ([`SYSCLK_HZ`] until [`ClockPlan::probe`] ran).
static SYSCLK: AtomicU32 = AtomicU32::new(SYSCLK_HZ);

/// The core clock the board runs at, Hz: 480 MHz on revision V, 400 MHz before it.
pub fn sysclk_hz() -> u32 {
    SYSCLK.load(Ordering::Relaxed)
}

/// Enables the HSE in bypass mode and waits up to [`HSE_TIMEOUT_US`] for HSERDY (the core runs
/// from the 64 MHz HSI after reset). Returns whether it became ready; if not, the HSE is
/// switched off again.
fn start_hse_bypass() -> bool {
    let rcc = pac::RCC;
    if rcc.cr().read().hserdy() {
        return true;
    }
    // HSEBYP may only change while the HSE is off.
    rcc.cr().modify(|w| w.set_hseon(false));
    rcc.cr().modify(|w| w.set_hsebyp(true));
    rcc.cr().modify(|w| w.set_hseon(true));
    for _ in 0..HSE_TIMEOUT_US {
        if rcc.cr().read().hserdy() {
            return true;
        }
        cortex_m::asm::delay(HSI_HZ / 1_000_000);
    }
    let ready = rcc.cr().read().hserdy();
    if !ready {
        rcc.cr().modify(|w| w.set_hseon(false));
    }
    ready
}

impl ClockPlan {
    /// Reads the silicon revision and starts the HSE (bounded wait), and chooses the clock
    /// tree: 480 MHz on revision V, 400 MHz otherwise; HSE bypass, or the HSI if the HSE did
    /// not start. Call once, before `embassy_stm32::init` (with [`ClockPlan::embassy_config`]).
    pub fn probe() -> Self {
        let idc = pac::DBGMCU.idc().read();
        let (revision, device) = (idc.rev_id(), idc.dev_id());
        let source = if start_hse_bypass() { ClockSource::HseBypass } else { ClockSource::Hsi };
        let sysclk_hz = if revision == REV_V { SYSCLK_HZ } else { SYSCLK_BEFORE_REV_V_HZ };
        SYSCLK.store(sysclk_hz, Ordering::Relaxed);
        Self { revision, device, source, sysclk_hz }
    }

    /// The embassy clock configuration for this plan (see the module docs for the arithmetic).
    pub fn rcc_config(&self) -> embassy_stm32::rcc::Config {
        let mut rcc = embassy_stm32::rcc::Config::default();
        let (source, pll1_prediv, pll3_prediv, pll3_mul) = match self.source {
            ClockSource::Hsi => {
                rcc.hse = None;
                (PllSource::HSI, PllPreDiv::DIV16, PllPreDiv::DIV25, PllMul::MUL120)
            }
            _ => {
                rcc.hse = Some(Hse { freq: Hertz(HSE_HZ), mode: HseMode::Bypass });
                (PllSource::HSE, PllPreDiv::DIV2, PllPreDiv::DIV5, PllMul::MUL192)
            }
        };
        let full_speed = self.sysclk_hz == SYSCLK_HZ;
        rcc.pll1 = Some(Pll {
            source,
            prediv: pll1_prediv,
            mul: if full_speed { PllMul::MUL240 } else { PllMul::MUL200 },
            fracn: None,
            divp: Some(PllDiv::DIV2),
            divq: None,
            divr: None,
        });
        rcc.pll3 = Some(Pll {
            source,
            prediv: pll3_prediv,
            mul: pll3_mul,
            fracn: None,
            divp: Some(PllDiv::DIV5),
            divq: None,
            divr: None,
        });
        rcc.sys = Sysclk::PLL1_P;
        // VOS0 (480 MHz) exists on revision V only; VOS1 allows 400 MHz.
        rcc.voltage_scale = if full_speed { VoltageScale::Scale0 } else { VoltageScale::Scale1 };
        rcc.d1c_pre = AHBPrescaler::DIV1; // CPU 480 (400) MHz
        rcc.ahb_pre = AHBPrescaler::DIV2; // AXI/AHB 240 (200) MHz
        rcc.apb1_pre = APBPrescaler::DIV2; // 120 (100) MHz: USART3 kernel clock
        rcc.apb2_pre = APBPrescaler::DIV2;
        rcc.apb3_pre = APBPrescaler::DIV2;
        rcc.apb4_pre = APBPrescaler::DIV2;
        rcc.mux.sai1sel = embassy_stm32::pac::rcc::vals::Saisel::PLL3_P;
        rcc
    }

    /// The full embassy configuration for this plan.
    pub fn embassy_config(&self) -> embassy_stm32::Config {
        let mut config = embassy_stm32::Config::default();
        config.rcc = self.rcc_config();
        config
    }

    /// Writes the chip and clock fields of `hello`.
    pub fn fill_hello(&self, hello: &mut Hello) {
        hello.chip_revision = self.revision;
        hello.clock_source = self.source.code();
        hello.sysclk_hz = self.sysclk_hz;
    }

    /// Logs the plan over defmt (a warning when it is not the full-speed, crystal-exact one).
    pub fn log(&self) {
        let letter = aim_wire::stm32h7_revision_name(self.revision).unwrap_or("?");
        defmt::info!(
            "chip: DEV_ID {=u16:#05x}, REV_ID {=u16:#06x} (revision {=str}); clock {=str}, core {=u32} Hz",
            self.device,
            self.revision,
            letter,
            self.source.name(),
            self.sysclk_hz
        );
        if self.revision != REV_V {
            defmt::warn!("not revision V silicon: running at 400 MHz (VOS1), not 480 MHz");
        }
        if self.source != ClockSource::HseBypass {
            defmt::warn!(
                "HSE (ST-LINK 8 MHz) not ready within {=u32} us: running from the HSI; the sample rate is only as exact as the HSI",
                HSE_TIMEOUT_US
            );
        }
    }
}

/// Checks, after `embassy_stm32::init`, that the clock tree came up as computed; `Err` carries
/// the measured SAI kernel clock in Hz.
pub fn check_sai_kernel_clock() -> Result<(), u32> {
    let measured = embassy_stm32::rcc::frequency::<embassy_stm32::peripherals::SAI1>().0;
    if measured == SAI_KERNEL_HZ {
        Ok(())
    } else {
        Err(measured)
    }
}
