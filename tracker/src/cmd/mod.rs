//! One module per `aim` subcommand: its arguments and its `run`.
pub mod frames;
pub mod record;
pub mod replay;
pub mod track;

use aim_tracker::link;

/// The serial link of an array board, as `aim record` and `aim track` take it.
#[derive(clap::Args)]
pub struct SerialArgs {
    /// Serial port of the array board (`/dev/ttyACM0`, `COM3`).
    #[arg(long)]
    pub serial: String,
    /// Baud rate.
    #[arg(long, default_value_t = link::serial::DEFAULT_BAUD)]
    pub baud: u32,
}

impl SerialArgs {
    /// Opens the port raw, 8N1, at the baud rate.
    pub fn open(&self) -> anyhow::Result<Box<dyn serialport::SerialPort>> {
        link::serial::open(&self.serial, self.baud)
    }
}
