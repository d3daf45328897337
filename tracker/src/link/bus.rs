//! The Zenoh bus: arrays' frames and the tracker's fixes between processes and machines.
//!
//! - `aim gateway` reads one array's serial link and publishes every decoded frame, as its
//!   wire bytes (`0x00`, COBS, `0x00`: one frame per sample), on [`frames_key`]
//!   `aim/array/<id>/frames` with [`FramePublisher`].
//! - `aim track --zenoh` and `aim record --zenoh` subscribe to [`FRAMES_ALL`]
//!   (`aim/array/*/frames`, any number of arrays and gateways) through a [`FrameFeed`]: a
//!   [`std::io::Read`] of the samples' bytes in arrival order, so the frames go through the
//!   same [`super::FrameSource`] and intake as a serial port's, and a recording of the feed is
//!   an ordinary recording (`aim replay` reads it).
//! - Fixes go out as the JSON line `aim track` prints, on [`fix_key`] `aim/track/<name>/fix`.
//!
//! Sessions ([`open`]) are peers: on one machine (or one LAN with multicast) they find each
//! other with no router; `--connect`/`--listen` name endpoints (`tcp/HOST:PORT`) where
//! multicast is not available, e.g. a `zenohd` router for a building. Reliability is Zenoh's
//! reliable mode over TCP, so a frame reaches every subscriber connected when it is published,
//! once and in the order its gateway published it.

use std::collections::HashMap;
use std::io::{self, Read};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::time::Duration;

use aim_wire::{Frame, MAX_ENCODED_LEN};
use anyhow::{anyhow, Context as _};
use zenoh::Wait as _;

/// The key expression of every array's frames.
pub const FRAMES_ALL: &str = "aim/array/*/frames";

/// How long a read of a quiet [`FrameFeed`] waits before it returns `TimedOut` (the caller
/// checks its deadline and Ctrl-C, then reads again).
pub const QUIET_READ: Duration = Duration::from_millis(200);

/// How long opening a session waits for the peers named by `--connect`, ms.
pub const CONNECT_WAIT_MS: u64 = 10_000;

/// The key the frames of array `array_id` are published on: `aim/array/<id>/frames`.
pub fn frames_key(array_id: u8) -> String {
    format!("aim/array/{array_id}/frames")
}

/// The key a tracker named `name` publishes its fixes on: `aim/track/<name>/fix`. The name is
/// one chunk of a key: not empty, no `/`, and none of Zenoh's special characters `*$?#`.
pub fn fix_key(name: &str) -> anyhow::Result<String> {
    if name.is_empty() || name.contains(['/', '*', '$', '?', '#']) {
        anyhow::bail!(
            "tracker name {name:?} cannot be a key chunk: give a non-empty name without / * $ ? #"
        );
    }
    Ok(format!("aim/track/{name}/fix"))
}

/// Where a session connects and listens.
#[derive(Clone, Debug, Default)]
pub struct BusOptions {
    /// A Zenoh configuration file (JSON5) to start from, instead of the defaults.
    pub config: Option<PathBuf>,
    /// Endpoints to connect to, e.g. `tcp/192.168.1.10:7447` (a router or another peer).
    pub connect: Vec<String>,
    /// Endpoints to listen on, e.g. `tcp/0.0.0.0:7447`.
    pub listen: Vec<String>,
    /// Find peers by UDP multicast scouting (Zenoh's default; off where the network has none).
    pub multicast: bool,
}

impl BusOptions {
    /// The Zenoh configuration these options describe (peer mode).
    pub fn config(&self) -> anyhow::Result<zenoh::Config> {
        let mut config = match &self.config {
            Some(path) => zenoh::Config::from_file(path)
                .map_err(|e| anyhow!("{e}"))
                .with_context(|| format!("Zenoh configuration {}", path.display()))?,
            None => zenoh::Config::default(),
        };
        let set = |config: &mut zenoh::Config, key: &str, value: String| {
            config
                .insert_json5(key, &value)
                .map_err(|e| anyhow!("{e}"))
                .with_context(|| format!("setting the Zenoh option {key} to {value}"))
        };
        if self.config.is_none() {
            set(&mut config, "mode", "\"peer\"".into())?;
        }
        if !self.connect.is_empty() {
            set(&mut config, "connect/endpoints", endpoints_json(&self.connect, "--connect")?)?;
            // `open` returns once the named peers have sent their declarations (who subscribes
            // to what), so the first frames published reach them; at most this long.
            if self.config.is_none() {
                set(&mut config, "scouting/delay", CONNECT_WAIT_MS.to_string())?;
            }
        }
        if !self.listen.is_empty() {
            set(&mut config, "listen/endpoints", endpoints_json(&self.listen, "--listen")?)?;
        }
        if !self.multicast {
            set(&mut config, "scouting/multicast/enabled", "false".into())?;
        }
        Ok(config)
    }
}

/// `["tcp/a:1","tcp/b:2"]`, each endpoint checked by Zenoh's parser.
fn endpoints_json(endpoints: &[String], flag: &str) -> anyhow::Result<String> {
    for e in endpoints {
        e.parse::<zenoh::config::EndPoint>().map_err(|err| {
            anyhow!("{flag} {e:?} is not a Zenoh endpoint such as tcp/127.0.0.1:7447: {err}")
        })?;
    }
    serde_json::to_string(endpoints).context("endpoints as JSON")
}

/// Opens a Zenoh session with `options`.
pub fn open(options: &BusOptions) -> anyhow::Result<zenoh::Session> {
    let config = options.config()?;
    zenoh::open(config).wait().map_err(|e| anyhow!("{e}")).context("opening the Zenoh session")
}

/// Publishes frames, each on its array's [`frames_key`], as its wire bytes.
pub struct FramePublisher {
    session: zenoh::Session,
    publishers: HashMap<u8, zenoh::pubsub::Publisher<'static>>,
    published: HashMap<u8, u64>,
}

impl FramePublisher {
    /// A publisher on `session`.
    pub fn new(session: zenoh::Session) -> Self {
        Self { session, publishers: HashMap::new(), published: HashMap::new() }
    }

    /// Publishes `frame` (reliably, Zenoh's default, and blocking while the network is
    /// congested rather than dropping it); returns `true` when it is the first frame of its array.
    pub fn publish(&mut self, frame: &Frame) -> anyhow::Result<bool> {
        let id = frame.header.array_id;
        let mut wire = [0u8; MAX_ENCODED_LEN];
        let n = aim_wire::encode(frame, &mut wire)
            .map_err(|e| anyhow!("encoding a frame to publish: {e}"))?;
        let first = !self.publishers.contains_key(&id);
        if first {
            let publisher = self
                .session
                .declare_publisher(frames_key(id))
                .congestion_control(zenoh::qos::CongestionControl::Block)
                .wait()
                .map_err(|e| anyhow!("{e}"))
                .with_context(|| format!("declaring the publisher {}", frames_key(id)))?;
            self.publishers.insert(id, publisher);
        }
        self.publishers[&id]
            .put(wire[..n].to_vec())
            .wait()
            .map_err(|e| anyhow!("{e}"))
            .with_context(|| format!("publishing on {}", frames_key(id)))?;
        *self.published.entry(id).or_default() += 1;
        Ok(first)
    }

    /// Frames published so far per array id.
    pub fn published(&self) -> &HashMap<u8, u64> {
        &self.published
    }
}

/// The frames of every array on the bus as one byte stream, in arrival order: a
/// [`std::io::Read`] for [`super::FrameSource`] and [`super::record::record`].
///
/// Each sample holds whole frames, so samples of different arrays interleave at frame
/// boundaries. A quiet bus makes reads return `TimedOut` every [`QUIET_READ`]; once the stop
/// flag is set (Ctrl-C) reads return `Ok(0)`, the end of the stream, and
/// [`Self::interrupted`] says so.
pub struct FrameFeed {
    samples: Receiver<Vec<u8>>,
    current: super::frame_bytes::FrameBytes,
    stop: Option<Arc<AtomicBool>>,
    interrupted: bool,
    _subscriber: zenoh::pubsub::Subscriber<()>,
}

impl FrameFeed {
    /// Subscribes to [`FRAMES_ALL`] on `session`.
    pub fn subscribe(session: &zenoh::Session) -> anyhow::Result<Self> {
        let (tx, rx) = mpsc::channel::<Vec<u8>>();
        let subscriber = session
            .declare_subscriber(FRAMES_ALL)
            .callback(move |sample| {
                // Sent until the feed is dropped; afterwards there is no one to tell.
                let _ = tx.send(sample.payload().to_bytes().into_owned());
            })
            .wait()
            .map_err(|e| anyhow!("{e}"))
            .with_context(|| format!("subscribing to {FRAMES_ALL}"))?;
        Ok(Self {
            samples: rx,
            current: Default::default(),
            stop: None,
            interrupted: false,
            _subscriber: subscriber,
        })
    }

    /// Ends the stream once `flag` is set (the Ctrl-C flag of
    /// [`super::serial::interrupt_flag`]).
    pub fn stop_on(mut self, flag: Arc<AtomicBool>) -> Self {
        self.stop = Some(flag);
        self
    }

    /// Whether the stream ended because the stop flag was set.
    pub fn interrupted(&self) -> bool {
        self.interrupted
    }
}

impl Read for FrameFeed {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        loop {
            if self.stop.as_ref().is_some_and(|f| f.load(Ordering::SeqCst)) {
                self.interrupted = true;
                return Ok(0);
            }
            if !self.current.is_drained() {
                return Ok(self.current.read_into(buf));
            }
            match self.samples.recv_timeout(QUIET_READ) {
                Ok(sample) => self.current.set(sample),
                Err(RecvTimeoutError::Timeout) => {
                    return Err(io::Error::new(io::ErrorKind::TimedOut, "no frames on the bus"))
                }
                Err(RecvTimeoutError::Disconnected) => return Ok(0),
            }
        }
    }
}

/// Publishes text lines (the fixes' JSON) on one key.
pub struct LinePublisher {
    key: String,
    publisher: zenoh::pubsub::Publisher<'static>,
}

impl LinePublisher {
    /// A publisher of `key` on `session`.
    pub fn new(session: &zenoh::Session, key: String) -> anyhow::Result<Self> {
        let publisher = session
            .declare_publisher(key.clone())
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .wait()
            .map_err(|e| anyhow!("{e}"))
            .with_context(|| format!("declaring the publisher {key}"))?;
        Ok(Self { key, publisher })
    }

    /// The key it publishes on.
    pub fn key(&self) -> &str {
        &self.key
    }

    /// Publishes `line`.
    pub fn put(&self, line: &str) -> anyhow::Result<()> {
        self.publisher
            .put(line.to_owned())
            .wait()
            .map_err(|e| anyhow!("{e}"))
            .with_context(|| format!("publishing on {}", self.key))
    }
}
