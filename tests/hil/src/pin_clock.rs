//! A clock on a GPIOE pin, seen with no wiring: in alternate-function mode a pin's input buffer
//! stays on, so GPIOE's IDR shows it toggling. Used for SAI1's MCLK and PDM clocks.

use aim_firmware::clocks::sysclk_hz;
use aim_firmware::stats::CycleCounter;

use crate::check_range;

/// IDR samples per measurement.
pub const SAMPLES: u32 = 100_000;

/// Samples GPIOE pin `pin` [`SAMPLES`] times with interrupts off; returns the level changes
/// and the cycles taken.
pub fn sample(cycles: &CycleCounter, pin: usize) -> (u32, u32) {
    cortex_m::interrupt::free(|_| {
        let idr = embassy_stm32::pac::GPIOE.idr();
        let mut last = idr.read().idr(pin);
        let mut changes = 0;
        let start = cycles.now();
        for _ in 0..SAMPLES {
            let level = idr.read().idr(pin);
            changes += u32::from(level != last);
            last = level;
        }
        (changes, cycles.since(start))
    })
}

/// Checks the clock on GPIOE pin `pin` (named `name` in the log) toggles: over [`SAMPLES`]
/// samples at least a tenth change level (`changes_label` names that check). When a sample
/// interval is under `max_interval_ps` (half the clock's period: every edge is counted), its
/// frequency (`hz_label`) must be within 2 % of `expected_hz`; otherwise the log says the
/// sampling was too slow and that one check is skipped.
pub fn check(
    cycles: &CycleCounter,
    name: &str,
    pin: usize,
    changes_label: &str,
    hz_label: &str,
    expected_hz: u64,
    max_interval_ps: u64,
) {
    let (changes, spent) = sample(cycles, pin);
    let interval_ps =
        u64::from(spent) * 1_000_000_000_000 / u64::from(sysclk_hz()) / u64::from(SAMPLES);
    defmt::info!(
        "{=str}: {=u32} level changes in {=u32} samples, {=u64} ps per sample",
        name,
        changes,
        SAMPLES,
        interval_ps
    );
    check_range(changes_label, u64::from(changes), u64::from(SAMPLES / 10), u64::from(SAMPLES));
    if interval_ps < max_interval_ps {
        let hz = u64::from(changes) * u64::from(sysclk_hz()) / 2 / u64::from(spent.max(1));
        check_range(hz_label, hz, expected_hz * 98 / 100, expected_hz * 102 / 100);
    } else {
        defmt::warn!(
            "{=str}: sampling too slow to count the clock's edges: frequency not checked",
            name
        );
    }
}
