//! AIM array board firmware (work in progress).
#![no_std]
#![no_main]

use embassy_executor::Spawner;
use embassy_time::Timer;
use {defmt_rtt as _, panic_probe as _};

#[embassy_executor::main]
async fn main(_spawner: Spawner) {
    let _p = embassy_stm32::init(embassy_stm32::Config::default());
    defmt::info!("aim-firmware up");
    loop {
        Timer::after_secs(1).await;
    }
}
