//! Serial ports as every `aim` command opens them.
//!
//! Raw mode, 8 data bits, no parity, one stop bit, no flow control (the board's USART3 settings;
//! `serialport` sets raw mode on open, so no byte is translated), exclusive access, and a read
//! timeout so that a quiet port lets the caller look at the clock.

use std::time::Duration;

use anyhow::Context as _;

/// The board's default uplink rate, baud.
pub const DEFAULT_BAUD: u32 = 921_600;

/// How long one read waits for a byte before it returns a timeout (which readers retry).
pub const READ_TIMEOUT: Duration = Duration::from_millis(100);

/// Opens the serial port at `path` (`/dev/ttyACM0`, `COM3`, a pseudo-terminal) at `baud`.
pub fn open(path: &str, baud: u32) -> anyhow::Result<Box<dyn serialport::SerialPort>> {
    serialport::new(path, baud)
        .data_bits(serialport::DataBits::Eight)
        .parity(serialport::Parity::None)
        .stop_bits(serialport::StopBits::One)
        .flow_control(serialport::FlowControl::None)
        .timeout(READ_TIMEOUT)
        .open()
        .with_context(|| format!("opening serial port {path} at {baud} baud"))
}
