//! One module per `aim` subcommand: its arguments and its `run`.
pub mod bus;
pub mod calibrate;
pub mod frames;
pub mod gateway;
pub mod id;
pub mod record;
pub mod replay;
pub mod serve;
pub mod track;

use aim_tracker::link::{self, serial::Link};

/// The serial link of an array board, as `aim record` and `aim track` take it.
#[derive(clap::Args)]
pub struct SerialArgs {
    /// Serial port of the array board (`/dev/ttyACM0`, `COM3`, a stable name such as
    /// `/dev/serial/by-id/…` survives replugging best). `aim track` takes it repeated, one
    /// per board.
    #[arg(long, required_unless_present = "zenoh", conflicts_with = "zenoh")]
    pub serial: Vec<String>,
    /// Baud rate.
    #[arg(long, default_value_t = link::serial::DEFAULT_BAUD)]
    pub baud: u32,
    #[command(flatten)]
    pub reconnect: ReconnectArgs,
    /// Read the frames of every array on the Zenoh bus (`aim/array/*/frames`, published by
    /// `aim gateway`) instead of a serial port.
    #[arg(long)]
    pub zenoh: bool,
    #[command(flatten)]
    pub bus: bus::BusArgs,
}

/// What a serial command does when its port is lost (the board unplugged).
#[derive(clap::Args)]
pub struct ReconnectArgs {
    /// Reopen the port by its path when it comes back after a loss (`--reconnect false`: end
    /// at the first loss, exit status 3).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set, value_name = "BOOL")]
    pub reconnect: bool,
    /// Give up (exit status 3) once a lost port has been away this long, s.
    #[arg(long, default_value_t = 600.0, value_name = "SECONDS")]
    pub give_up: f64,
}

impl ReconnectArgs {
    /// Opens `port` at `baud` as a [`Link`] with this policy, ended by Ctrl-C / SIGTERM.
    pub fn open(&self, port: &str, baud: u32) -> anyhow::Result<Link> {
        let give_up = link::serial::give_up_from_secs(self.give_up, "--give-up")?;
        let policy = link::serial::Reconnect { enabled: self.reconnect, give_up };
        let stop = link::serial::interrupt_flag()?;
        Ok(Link::open(port, baud, policy)?.stop_on(stop))
    }
}

impl SerialArgs {
    /// Opens the port raw, 8N1, at the baud rate, reconnecting as the flags say.
    pub fn open(&self) -> anyhow::Result<Link> {
        self.reconnect.open(self.port()?, self.baud)
    }

    /// The `--serial` port (absent only with `--zenoh`); more than one is an error here.
    pub fn port(&self) -> anyhow::Result<&str> {
        match self.serial.as_slice() {
            [one] => Ok(one),
            [] => anyhow::bail!("give --serial PORT or --zenoh"),
            many => anyhow::bail!(
                "this command reads one board: give one --serial, not {} ({})",
                many.len(),
                many.join(", ")
            ),
        }
    }
}
