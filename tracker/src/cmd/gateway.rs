//! `aim gateway --serial PORT`: publish an array's frames on the Zenoh bus.
//!
//! Every frame decoded from the port goes out as its wire bytes on `aim/array/<id>/frames`
//! (`<id>`: the array id in the frame's header, the one its `Hello` announces), where any
//! number of `aim track --zenoh` and `aim record --zenoh` on any machine of the bus receive it.
//! Damaged frames are counted here and not published. The port is a serial
//! [`aim_tracker::link::serial::Link`] as in `aim track` (unplugging, `--reconnect`); the
//! gateway ends on Ctrl-C (status 130) or a port lost for good (status 3), printing its
//! statistics line (`{"kind":"gateway",...}`) on every exit path.

#[cfg(feature = "zenoh")]
use std::collections::BTreeMap;

#[cfg(feature = "zenoh")]
use aim_tracker::exit::note;
use aim_tracker::link;

/// Arguments of `aim gateway`.
#[derive(clap::Args)]
pub struct Args {
    /// Serial port of the array board.
    #[arg(long)]
    serial: String,
    /// Baud rate.
    #[arg(long, default_value_t = link::serial::DEFAULT_BAUD)]
    baud: u32,
    /// Publish only frames of this array id (frames of another id are counted and dropped: a
    /// board with an unexpected id); default: every frame, under the id its header carries.
    #[arg(long)]
    array: Option<u8>,
    #[command(flatten)]
    reconnect: super::ReconnectArgs,
    #[command(flatten)]
    bus: super::bus::BusArgs,
}

/// Runs `aim gateway`.
#[cfg(not(feature = "zenoh"))]
pub fn run(_args: Args) -> anyhow::Result<()> {
    Err(super::bus::unavailable())
}

/// Runs `aim gateway`.
#[cfg(feature = "zenoh")]
pub fn run(args: Args) -> anyhow::Result<()> {
    use aim_tracker::exit::Interrupted;
    use aim_tracker::link::bus::{frames_key, FramePublisher};
    use anyhow::Context as _;
    use zenoh::Wait as _;

    let session = args.bus.open()?;
    let peers = session.info().peers_zid().wait().count();
    let mut publisher = FramePublisher::new(session.clone());
    let mut source = link::FrameSource::new(args.reconnect.open(&args.serial, args.baud)?);
    // Scripts and tests wait for this line before they send: the port and the bus are open.
    note(&format!(
        "gateway: publishing the frames of {} at {} baud on aim/array/<id>/frames ({peers} peers)",
        args.serial, args.baud
    ));
    let mut other_ids: BTreeMap<u8, u64> = BTreeMap::new();
    let result = loop {
        match source.next_outcome() {
            Ok(Some(Ok(frame))) => {
                let id = frame.header.array_id;
                if args.array.is_some_and(|want| want != id) {
                    let n = other_ids.entry(id).or_default();
                    if *n == 0 {
                        note(&format!(
                            "warning: frames of array {id} on {} (expected {}): not published",
                            args.serial,
                            args.array.unwrap_or_default()
                        ));
                    }
                    *n += 1;
                    continue;
                }
                match publisher.publish(&frame) {
                    Ok(true) => note(&format!("gateway: array {id} on {}", frames_key(id))),
                    Ok(false) => {}
                    Err(e) => break Err(e),
                }
            }
            Ok(Some(Err(_))) => {} // counted in the link statistics
            Ok(None) => break Ok(()),
            Err(e) => break Err(anyhow::Error::from(e).context(format!("reading {}", args.serial))),
        }
    };
    let published: BTreeMap<String, u64> =
        publisher.published().iter().map(|(id, n)| (id.to_string(), *n)).collect();
    let dropped: BTreeMap<String, u64> =
        other_ids.iter().map(|(id, n)| (id.to_string(), *n)).collect();
    note(
        &serde_json::json!({
            "kind": "gateway",
            "link": link::json::stats(source.stats()),
            "published": published,
            "other_ids_dropped": dropped,
        })
        .to_string(),
    );
    // Closing sends what is still queued before the process ends.
    session.close().wait().map_err(|e| anyhow::anyhow!("{e}")).context("closing the bus")?;
    result?;
    if source.get_mut().interrupted() {
        return Err(Interrupted.into());
    }
    Ok(())
}
