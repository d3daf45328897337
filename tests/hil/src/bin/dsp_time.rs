//! HIL: the DSP keeps up with real time on the board, within its stack.
//!
//! Runs the firmware's `Pipeline` (configured as the firmware configures it, in its DTCM
//! static) on 3 s of a synthetic plane wave (`aim_hil_tests::signal`: broadband noise and a
//! 180 Hz harmonic series from azimuth 60°, zenith 50°), pushed in capture-sized chunks, and
//! measures with the DWT cycle counter the cycles per DSP block (the sum over the chunks of
//! a block, as the firmware's `Health` reports) and per push. Checks:
//! - sustained load: the mean block takes at most half of real time (1024 samples at 48 kHz =
//!   21.3 ms = 10.24 M cycles at 480 MHz → 5.12 M), leaving the rest for capture and uplink;
//! - no overrun: the longest single push (the block that also averages and estimates a DoA)
//!   fits in the slack of the capture queue, the time the other `CAPTURE_QUEUE_CHUNKS - 1`
//!   slots take to fill (7 × 5.33 ms = 17.9 M cycles); the DMA ring's spare half is margin;
//! - the stack high-water mark leaves at least 1 KiB of the DTCM stack unused;
//! - the pipeline works on the target: one DoA per `average_blocks` blocks (±1), within 5° of
//!   the source direction (integer sample delays limit the synthetic source to ≈ 2°), and a
//!   BPF within 1 Hz of 180 Hz.
#![no_std]
#![no_main]

use aim_dsp::Output;
use aim_firmware::clocks::sysclk_hz;
use aim_firmware::config::{
    CAPTURE_QUEUE_CHUNKS, CHUNK_FRAMES, CHUNK_WORDS, SAMPLE_RATE_HZ, TDM_SLOTS,
};
use aim_firmware::processing;
use aim_firmware::stats::CycleStats;
use aim_hil_tests::signal::{PlaneWave, BPF_HZ};
use aim_hil_tests::{board, check_range, pass, stack};
use cortex_m_rt::entry;
use {defmt_rtt as _, panic_probe as _};

const SECONDS: u64 = 3;
const AZIMUTH_DEG: f32 = 60.0;
const ZENITH_DEG: f32 = 50.0;

fn angle_error_cdeg(estimate_rad: f32, truth_deg: f32) -> u64 {
    let mut d = estimate_rad.to_degrees() - truth_deg;
    while d > 180.0 {
        d -= 360.0;
    }
    while d < -180.0 {
        d += 360.0;
    }
    (libm::fabsf(d) * 100.0) as u64
}

#[entry]
fn main() -> ! {
    let (_p, cycles) = board();
    stack::paint();

    let pipeline = processing::pipeline();
    let config = processing::dsp_config();
    let wave = PlaneWave::new(
        config.geometry.positions(),
        TDM_SLOTS,
        SAMPLE_RATE_HZ,
        AZIMUTH_DEG.to_radians(),
        ZENITH_DEG.to_radians(),
    );
    let block_len = config.block_len as u64;
    // In AXI SRAM like the firmware's capture slots (and off the 11 KB stack being measured).
    let words = aim_firmware::axisram_buffer!(i32, CHUNK_WORDS);

    let mut blocks = CycleStats::default();
    let mut pushes = CycleStats::default();
    let mut block_cycles: u32 = 0;
    let (mut doas, mut doa_az_err, mut doa_zen_err) = (0u64, 0u64, 0u64);
    let (mut peaks, mut bpf_err_chz) = (0u64, 0u64);

    let chunks = SECONDS * u64::from(SAMPLE_RATE_HZ) / CHUNK_FRAMES as u64;
    for chunk in 0..chunks {
        let first = chunk * CHUNK_FRAMES as u64;
        wave.fill(first, &mut words[..]);
        let start = cycles.now();
        pipeline.push(&words[..], &mut |output| match output {
            Output::Doa(d) => {
                doas += 1;
                doa_az_err = doa_az_err.max(angle_error_cdeg(d.azimuth_rad, AZIMUTH_DEG));
                doa_zen_err = doa_zen_err.max(angle_error_cdeg(d.zenith_rad, ZENITH_DEG));
            }
            Output::Peaks(p) => {
                peaks += 1;
                bpf_err_chz = bpf_err_chz.max((libm::fabsf(p.bpf_hz - BPF_HZ) * 100.0) as u64);
            }
            _ => {}
        });
        let spent = cycles.since(start);
        pushes.record(spent);
        block_cycles = block_cycles.saturating_add(spent);
        if (first + CHUNK_FRAMES as u64).is_multiple_of(block_len) {
            blocks.record(block_cycles);
            block_cycles = 0;
        }
    }

    let real_time = u64::from(sysclk_hz()) * block_len / u64::from(SAMPLE_RATE_HZ);
    let slack = u64::from(sysclk_hz()) * (CAPTURE_QUEUE_CHUNKS as u64 - 1) * CHUNK_FRAMES as u64
        / u64::from(SAMPLE_RATE_HZ);
    defmt::info!(
        "{=u32} blocks: cycles per block mean {=u32}, max {=u32}; per push max {=u32}; real time {=u64} cycles per block",
        blocks.count,
        blocks.mean(),
        blocks.max,
        pushes.max,
        real_time
    );
    check_range("mean cycles per block", u64::from(blocks.mean()), 1, real_time / 2);
    check_range("max cycles per push", u64::from(pushes.max), 1, slack);

    let used = stack::high_water() as u64;
    let size = stack::size() as u64;
    defmt::info!("stack: {=u64} of {=u64} bytes used", used, size);
    check_range("stack bytes used", used, 1, size.saturating_sub(1024));

    let expected_doas = u64::from(blocks.count) / u64::from(config.average_blocks);
    check_range("DoA outputs", doas, expected_doas.saturating_sub(1), expected_doas + 1);
    check_range("worst azimuth error, 0.01°", doa_az_err, 0, 500);
    check_range("worst zenith error, 0.01°", doa_zen_err, 0, 500);
    check_range("Peaks outputs", peaks, 1, u64::MAX);
    check_range("worst BPF error, 0.01 Hz", bpf_err_chz, 0, 100);
    pass("dsp_time");
}
