//! Prints the parity report (`aim_golden::report`) computed on the Cortex-M4F model.
//! `cargo xtask qemu` compares it line by line with the same report computed on the host.
#![no_std]
#![no_main]

use aim_golden::aim_dsp::Pipeline;
use aim_qemu_m4f::{fail, succeed, Out};
use cortex_m_rt::entry;

#[entry]
fn main() -> ! {
    let mut out = Out::open();
    let Some(pipeline) = cortex_m::singleton!(: Pipeline = Pipeline::empty()) else { fail() };
    match aim_golden::report::write_parity(&mut out, pipeline) {
        Ok(()) => succeed(),
        Err(_) => fail(),
    }
}
