//! `aim frames`: decode frames from a recording, stdin or a serial port; print JSON lines.
//!
//! stdout: one JSON object per decoded frame (`aim_tracker::link::json::frame`), then one
//! `{"kind":"stats",...}` line with the link statistics. Damaged or unknown frames are
//! skipped and counted; `--errors` also describes each on stderr. A board that rebooted, or a
//! second board under an id already in use, adds a `{"kind":"reboot",...}` or
//! `{"kind":"duplicate_id",...}` line after its `Hello` and a warning on stderr.
//! The statistics line is
//! printed on every exit path: end of input, a read error, a lost serial port (exit status 3)
//! and, with `--serial`, Ctrl-C (exit status 130).

use std::collections::HashMap;
use std::io::Write;

use std::sync::atomic::Ordering;

use aim_tracker::exit::{note, Interrupted};
use aim_tracker::link::{self, FrameSource};
use aim_wire::Body;
use anyhow::Context as _;

/// Arguments of `aim frames`.
#[derive(clap::Args)]
pub struct Args {
    /// Recording made by `aim record` (or any raw capture of the link); `-` for stdin.
    #[arg(required_unless_present = "serial", conflicts_with = "serial")]
    input: Option<String>,
    /// Read a serial port live instead (until interrupted, or the port is lost for good).
    #[arg(long)]
    serial: Option<String>,
    /// Baud rate of `--serial`.
    #[arg(long, default_value_t = link::serial::DEFAULT_BAUD)]
    baud: u32,
    #[command(flatten)]
    reconnect: super::ReconnectArgs,
    /// Describe every frame that did not decode on stderr.
    #[arg(long)]
    errors: bool,
}

/// Runs `aim frames`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut stop = None;
    let (name, reader): (String, Box<dyn std::io::Read + Send>) = match (&args.serial, &args.input)
    {
        (Some(port), _) => {
            stop = Some(link::serial::interrupt_flag()?);
            (port.clone(), Box::new(args.reconnect.open(port, args.baud)?))
        }
        (None, Some(path)) => (path.clone(), link::open_input(path)?),
        (None, None) => anyhow::bail!("give a recording, `-` for stdin, or --serial PORT"),
    };
    let mut source = FrameSource::new(reader);
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let result = print_frames(&name, &mut source, &mut out, &args);
    // The statistics on every path but a closed stdout (nobody to print them to).
    let closed_stdout = result.as_ref().is_err_and(|e| {
        e.downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
    });
    if !closed_stdout {
        writeln!(out, "{}", link::json::stats(source.stats()))?;
        out.flush()?;
    }
    result?;
    if stop.is_some_and(|f| f.load(Ordering::SeqCst)) {
        return Err(Interrupted.into());
    }
    Ok(())
}

/// Prints every frame of `source` until it ends or fails.
fn print_frames<R: std::io::Read>(
    name: &str,
    source: &mut FrameSource<R>,
    out: &mut impl Write,
    args: &Args,
) -> anyhow::Result<()> {
    // Sample rate per array, from its latest Hello, to give times in seconds.
    let mut rates: HashMap<u8, u32> = HashMap::new();
    let mut boards = link::boards::Boards::new();
    let mut chunk = 0u64;
    while let Some(outcome) = source.next_outcome().with_context(|| format!("reading {name}"))? {
        chunk += 1;
        match outcome {
            Ok(frame) => {
                if let Body::Hello(hello) = &frame.body {
                    rates.insert(frame.header.array_id, hello.sample_rate_hz);
                }
                let rate = rates.get(&frame.header.array_id).copied();
                writeln!(out, "{}", link::json::frame(&frame, rate))?;
                for event in boards.observe(&frame) {
                    eprintln!("{name}: warning: {}", link::json::board_event(&event));
                    writeln!(out, "{}", link::json::board_event(&event))?;
                }
                if args.serial.is_some() {
                    out.flush()?;
                }
            }
            Err(e) if args.errors => note(&format!("{name}: chunk {chunk}: {e}")),
            Err(_) => {}
        }
    }
    Ok(())
}
