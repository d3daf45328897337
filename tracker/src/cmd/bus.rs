//! The Zenoh bus flags that `aim gateway`, `aim track --zenoh` and `aim record --zenoh` share.
//!
//! The flags exist in every build so that `--help` shows them; an `aim` built without the
//! `zenoh` feature refuses them with a message saying how to build one with it.

/// Where a Zenoh session connects and listens.
#[derive(clap::Args, Clone, Debug)]
pub struct BusArgs {
    /// Connect to this Zenoh endpoint (repeatable), e.g. `tcp/192.168.1.10:7447` for a
    /// `zenohd` router; the session waits up to 10 s for the peers named here.
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Listen on this Zenoh endpoint (repeatable), e.g. `tcp/0.0.0.0:7447`.
    #[arg(long, value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Find peers by UDP multicast scouting (Zenoh's default; `false` where there is none).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set, value_name = "BOOL")]
    pub multicast: bool,
    /// A Zenoh configuration file (JSON5) to start from; the flags above are applied on top.
    #[arg(long, value_name = "FILE")]
    pub zenoh_config: Option<std::path::PathBuf>,
}

#[cfg(feature = "zenoh")]
impl BusArgs {
    /// The session options of the flags.
    pub fn options(&self) -> aim_tracker::link::bus::BusOptions {
        aim_tracker::link::bus::BusOptions {
            config: self.zenoh_config.clone(),
            connect: self.connect.clone(),
            listen: self.listen.clone(),
            multicast: self.multicast,
        }
    }

    /// Opens the session.
    pub fn open(&self) -> anyhow::Result<zenoh::Session> {
        aim_tracker::link::bus::open(&self.options())
    }
}

/// The error of a bus command in an `aim` built without the `zenoh` feature.
#[cfg(not(feature = "zenoh"))]
pub fn unavailable() -> anyhow::Error {
    anyhow::anyhow!(
        "this aim was built without the Zenoh bus; build it with \
         `cargo build --release -p aim-tracker --features zenoh`"
    )
}
