//! HIL: frames leave USART3 at the line rate, intact, without drops.
//!
//! Encodes 600 frames (Hello, Doa, Peaks, Health in turn, from synthetic `aim_dsp` outputs)
//! through the firmware's `FrameSink` and uplink task (USART3 TX on PD8, DMA1 stream 1, the
//! ST-LINK virtual COM port). Checks:
//! - each frame, encoded on the target with `aim_wire::from_dsp`, decodes on the target to the
//!   frame it came from (header and body);
//! - USART3's baud rate, from its kernel clock and BRR, is within 1 % of 921 600;
//! - all frames are sent: none dropped, none unencodable, no USART error;
//! - the transfer takes between 99 % and 115 % of the line time of its bytes (10 bits per byte
//!   at the measured baud rate): DMA keeps the line busy, and nothing was lost or repeated.
//!
//! On the host, `aim frames --serial /dev/ttyACM0` shows the same frames (see README.md).
#![no_std]
#![no_main]

use aim_dsp::{Doa, Health, Output, Peak, Peaks};
use aim_firmware::config::{UPLINK_BAUD, UPLINK_QUEUE_FRAMES};
use aim_firmware::processing::{self, FrameSink};
use aim_firmware::stats::{read, COUNTERS};
use aim_firmware::uplink::{self, UPLINK_QUEUE};
use aim_hil_tests::{board, check_range, pass};
use aim_wire::from_dsp::{self, FirmwareCounters};
use aim_wire::{Encoder, MAX_ENCODED_LEN};
use cortex_m_rt::entry;
use embassy_executor::{Executor, InterruptExecutor};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_time::{Duration, Instant, Timer};
use static_cell::StaticCell;
use {defmt_rtt as _, panic_probe as _};

const FRAMES: u32 = 600;

static EXECUTOR_UPLINK: InterruptExecutor = InterruptExecutor::new();
static EXECUTOR_THREAD: StaticCell<Executor> = StaticCell::new();

#[interrupt]
unsafe fn UART4() {
    // SAFETY: UART4 is unused; its vector only runs this executor.
    unsafe { EXECUTOR_UPLINK.on_interrupt() }
}

/// The `i`-th synthetic pipeline output (`None`: a `Hello`).
fn output(i: u32) -> Option<Output> {
    let sample_index = u64::from(i) * 1024;
    let x = i as f32;
    match i % 4 {
        0 => None,
        1 => Some(Output::Doa(Doa {
            sample_index,
            span_samples: 8192,
            azimuth_rad: -3.0 + 0.01 * x,
            zenith_rad: 0.002 * x,
            residual: 0.25,
            quality: 0.8,
            pairs_used: 28,
        })),
        2 => {
            let mut peaks = [Peak::default(); 4];
            peaks[0] = Peak { hz: 150.0 + x, amplitude: 0.05, harmonicity: 0.9, quality: 0.8 };
            peaks[1] = Peak { hz: 210.0 + x, amplitude: 0.01, harmonicity: 0.6, quality: 0.5 };
            Some(Output::Peaks(Peaks {
                rotor: true,
                sample_index,
                span_samples: 24_576,
                bpf_hz: 150.0 + x,
                count: 2,
                peaks,
            }))
        }
        _ => Some(Output::Health(Health {
            sample_index,
            blocks: i,
            clipped_samples: i / 7,
            peak_dbfs: -20.0,
            block_exponent: 3,
            mics: 4,
            mic_rms_dbfs: [-40.0; aim_dsp::MAX_MICS],
            mic_dc_dbfs: [-90.0; aim_dsp::MAX_MICS],
        })),
    }
}

#[embassy_executor::task]
async fn produce() {
    let config = processing::dsp_config();
    let hello = aim_wire::Body::Hello(from_dsp::hello(&config, [0, 1, 0]));
    let counters = FirmwareCounters { cycles_per_block: 123_456, ..Default::default() };
    let array_id = aim_firmware::config::array_id(&embassy_stm32::uid::uid());
    let mut sink = FrameSink::new(array_id);
    // A second encoder with the same array id stamps the same sequence numbers: its bytes are
    // the bytes the sink queues.
    let mut check = Encoder::new(array_id);
    let mut buffer = [0u8; MAX_ENCODED_LEN];
    let mut bytes: u64 = 0;

    let start = Instant::now();
    for i in 0..FRAMES {
        while UPLINK_QUEUE.len() >= UPLINK_QUEUE_FRAMES - 1 {
            Timer::after_micros(100).await;
        }
        let (sample_index, body) = match output(i) {
            None => (u64::from(i) * 1024, hello.clone()),
            Some(out) => from_dsp::body(&out, &counters),
        };
        let expected = check.frame(sample_index, body.clone());
        let len = match check.encode(sample_index, body.clone(), &mut buffer) {
            Ok(len) => len,
            Err(_) => defmt::panic!("FAIL frame {=u32} did not encode", i),
        };
        // Decode the bytes with the deframer a host uses.
        let mut decoder: aim_wire::Deframer = aim_wire::Deframer::new();
        let mut decoded = 0;
        for frame in decoder.feed(&buffer[..len]) {
            match frame {
                Ok(frame) if frame == expected => decoded += 1,
                _ => defmt::panic!("FAIL frame {=u32} did not decode to itself", i),
            }
        }
        if decoded != 1 {
            defmt::panic!("FAIL frame {=u32}: {=u32} frames decoded, expected 1", i, decoded);
        }
        bytes += len as u64;
        match output(i) {
            None => sink.send(sample_index, hello.clone()),
            Some(out) => sink.send_output(&out, &counters),
        }
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    while read(&COUNTERS.frames_sent) < FRAMES && Instant::now() < deadline {
        Timer::after_micros(100).await;
    }
    let micros = (Instant::now() - start).as_micros();

    check_range(
        "frames sent",
        u64::from(read(&COUNTERS.frames_sent)),
        u64::from(FRAMES),
        u64::from(FRAMES),
    );
    check_range("frames dropped", u64::from(read(&COUNTERS.frames_dropped)), 0, 0);
    check_range("frames unencodable", u64::from(read(&COUNTERS.frames_unencodable)), 0, 0);
    check_range("USART errors", u64::from(read(&COUNTERS.uart_errors)), 0, 0);

    let kernel = u64::from(embassy_stm32::rcc::frequency::<embassy_stm32::peripherals::USART3>().0);
    let brr = u64::from(embassy_stm32::pac::USART3.brr().read().brr());
    let presc = embassy_stm32::pac::USART3.presc().read().prescaler().to_bits();
    let divider = [1u64, 2, 4, 6, 8, 10, 12, 16, 32, 64, 128, 256][usize::from(presc).min(11)];
    let over8 = embassy_stm32::pac::USART3.cr1().read().over8()
        == embassy_stm32::pac::usart::vals::Over8::OVERSAMPLING8;
    // With OVER8 the BRR holds USARTDIV with bits 2:0 shifted right by one.
    let usartdiv = if over8 { (brr & !0xF) | ((brr & 0x7) << 1) } else { brr };
    let baud = kernel / divider * if over8 { 2 } else { 1 } / usartdiv.max(1);
    defmt::info!("USART3: kernel {=u64} Hz, BRR {=u64}, baud {=u64}", kernel, brr, baud);
    let nominal = u64::from(UPLINK_BAUD);
    check_range("baud rate", baud, nominal - nominal / 100, nominal + nominal / 100);

    let line_micros = bytes * 10 * 1_000_000 / baud;
    defmt::info!("{=u64} bytes in {=u64} µs; line time {=u64} µs", bytes, micros, line_micros);
    check_range("transfer time, µs", micros, line_micros * 99 / 100, line_micros * 115 / 100);
    pass("frame_output");
}

#[entry]
fn main() -> ! {
    let (p, _cycles) = board();
    let uart = match uplink::uplink_uart(p.USART3, p.PD8, p.DMA1_CH1) {
        Ok(uart) => uart,
        Err(_) => defmt::panic!("FAIL USART3 configuration rejected"),
    };
    interrupt::UART4.set_priority(Priority::P6);
    let spawner = EXECUTOR_UPLINK.start(interrupt::UART4);
    spawner.spawn(defmt::unwrap!(uplink::uplink_task(uart)));
    EXECUTOR_THREAD.init(Executor::new()).run(|spawner| {
        spawner.spawn(defmt::unwrap!(produce()));
    })
}
