//! Clock tree: 480 MHz core, and an audio clock that gives exactly 48 kHz.
//!
//! Source: the 8 MHz clock the ST-LINK drives into OSC_IN on the NUCLEO-H743ZI2 (HSE bypass).
//!
//! Core: PLL1, 8 MHz / 2 = 4 MHz × 240 = 960 MHz VCO, / 2 = 480 MHz (needs VOS0, rev V parts).
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
use embassy_stm32::rcc::{
    AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllDiv, PllMul, PllPreDiv, PllSource, Sysclk,
    VoltageScale,
};
use embassy_stm32::sai::MasterClockDivider;
use embassy_stm32::time::Hertz;

use crate::config::{SAMPLE_RATE_HZ, SLOT_BITS, TDM_SLOTS};

/// HSE frequency: the ST-LINK's 8 MHz MCO on the NUCLEO-H743ZI2, Hz.
pub const HSE_HZ: u32 = 8_000_000;
/// Core clock (PLL1 P), Hz.
pub const SYSCLK_HZ: u32 = HSE_HZ / 2 * 240 / 2;
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

/// The SAI MCKDIV register value matching [`SAI_MCKDIV`].
pub const SAI_MASTER_CLOCK_DIVIDER: MasterClockDivider = MasterClockDivider::DIV5;

/// The embassy clock configuration for the board (see the module docs for the arithmetic).
pub fn rcc_config() -> embassy_stm32::rcc::Config {
    let mut rcc = embassy_stm32::rcc::Config::default();
    rcc.hse = Some(Hse { freq: Hertz(HSE_HZ), mode: HseMode::Bypass });
    rcc.pll1 = Some(Pll {
        source: PllSource::HSE,
        prediv: PllPreDiv::DIV2,
        mul: PllMul::MUL240,
        fracn: None,
        divp: Some(PllDiv::DIV2),
        divq: None,
        divr: None,
    });
    rcc.pll3 = Some(Pll {
        source: PllSource::HSE,
        prediv: PllPreDiv::DIV5,
        mul: PllMul::MUL192,
        fracn: None,
        divp: Some(PllDiv::DIV5),
        divq: None,
        divr: None,
    });
    rcc.sys = Sysclk::PLL1_P;
    rcc.voltage_scale = VoltageScale::Scale0;
    rcc.d1c_pre = AHBPrescaler::DIV1; // CPU 480 MHz
    rcc.ahb_pre = AHBPrescaler::DIV2; // AXI/AHB 240 MHz
    rcc.apb1_pre = APBPrescaler::DIV2; // 120 MHz (USART3 kernel clock)
    rcc.apb2_pre = APBPrescaler::DIV2;
    rcc.apb3_pre = APBPrescaler::DIV2;
    rcc.apb4_pre = APBPrescaler::DIV2;
    rcc.mux.sai1sel = embassy_stm32::pac::rcc::vals::Saisel::PLL3_P;
    rcc
}

/// The full embassy configuration for the board.
pub fn embassy_config() -> embassy_stm32::Config {
    let mut config = embassy_stm32::Config::default();
    config.rcc = rcc_config();
    config
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
