//! The Zenoh bus end to end, as separate processes on localhost in peer mode with no router:
//! two `aim gateway`s read two arrays' frames from pseudo-terminals (standing in for the
//! boards' serial ports) and publish them; `aim track --zenoh` tracks from the bus and
//! publishes its fixes; `aim record --zenoh` records the bus; this test subscribes to the
//! fixes. Oracles: the frames sent (the recording holds each exactly once, in each array's
//! order) and `aim replay` of array 1's bytes (the fixes, line for line; array 2 is not in the
//! tracker's site file, so it only shows in the tracker's counts). Multicast scouting is off: the peers are named by
//! `--connect`/`--listen` so that the test does not depend on the network's multicast.
//! Needs the `zenoh` feature (`cargo test -p aim-tracker --features zenoh`); Linux (openpty).
#![cfg(all(target_os = "linux", feature = "zenoh"))]

mod common;
mod procs;

use std::io::Write;
use std::process::Command;
use std::time::Instant;

use aim_tracker::link::bus::{fix_key, frames_key, BusOptions, FRAMES_ALL};
use procs::{free_port, Proc, PATIENCE};
use zenoh::Wait as _;

fn aim(args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_aim"));
    c.args(args);
    c
}

#[test]
fn gateway_tracker_and_recorder_on_the_bus_equal_aim_replay() {
    let mut seq = 0;
    let frames = common::link(0, 6 * common::FS, &mut seq, 23);
    let mut seq2 = 500;
    let mut frames2 = common::link(0, 5 * common::FS, &mut seq2, 29);
    for f in &mut frames2 {
        f.header.array_id = 2;
    }
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("zenoh-bus");
    std::fs::create_dir_all(&dir).unwrap();
    let site = dir.join("hall.toml");
    let sent = dir.join("sent.aimraw");
    let recorded = dir.join("recorded.aimraw");
    std::fs::write(&site, common::SITE_TOML).unwrap();
    std::fs::write(&sent, common::bytes(&frames)).unwrap();
    let _ = std::fs::remove_file(&recorded);

    let replayed: Vec<String> =
        common::aim_replay(&sent, &site).lines().map(str::to_owned).collect();
    assert!(replayed.len() > 20, "{replayed:?}");

    // This test's own peer: the subscriber of the fixes.
    let (port_test, port_track, port_record) = (free_port(), free_port(), free_port());
    let endpoint = |port: u16| format!("tcp/127.0.0.1:{port}");
    let mut config = zenoh::Config::default();
    config.insert_json5("mode", "\"peer\"").unwrap();
    config.insert_json5("scouting/multicast/enabled", "false").unwrap();
    config.insert_json5("listen/endpoints", &format!("[\"{}\"]", endpoint(port_test))).unwrap();
    let bus = zenoh::open(config).wait().unwrap();
    let fixes = bus.declare_subscriber("aim/track/*/fix").wait().unwrap();

    let mut recorder = Proc::spawn(
        "aim record --zenoh",
        aim(&["record", "--zenoh", "--multicast", "false", "--listen", &endpoint(port_record)])
            .arg("--frames")
            .arg((frames.len() + frames2.len()).to_string())
            .arg("--out")
            .arg(&recorded),
    );
    recorder.wait_for("recording aim/array/*/frames");
    let mut tracker = Proc::spawn(
        "aim track --zenoh",
        aim(&[
            "track",
            "--zenoh",
            "--multicast",
            "false",
            "--status-every",
            "0.2",
            "--name",
            "hall",
        ])
        .args(["--listen", &endpoint(port_track), "--connect", &endpoint(port_test)])
        .arg("--site")
        .arg(&site),
    );
    let ready = tracker.wait_for("tracking aim/array/*/frames");
    assert!(ready.ends_with("fixes on aim/track/hall/fix"), "{ready}");

    // One gateway per array, each on a pseudo-terminal of its own.
    let mut boards = Vec::new();
    for (array, sent) in [(1, &frames), (2, &frames2)] {
        let pair = nix::pty::openpty(None, None).expect("openpty");
        let path = nix::unistd::ttyname(&pair.slave).expect("ttyname of the pty slave");
        let master = std::fs::File::from(pair.master.try_clone().unwrap());
        let slave = pair.slave.try_clone().unwrap();
        drop(pair);
        let mut gateway = Proc::spawn(
            &format!("aim gateway of array {array}"),
            aim(&["gateway", "--reconnect", "false", "--multicast", "false"])
                .args(["--serial", path.to_str().unwrap(), "--array", &array.to_string()])
                .args(["--connect", &endpoint(port_track), "--connect", &endpoint(port_record)]),
        );
        // The port is raw and the gateway has both subscribers' declarations: only then send.
        let ready = gateway.wait_for("gateway: publishing");
        // Both subscribers at least (the other gateway may have found it too: gossip).
        let peers: usize =
            ready.rsplit('(').next().unwrap().trim_end_matches(" peers)").parse().unwrap();
        assert!(peers >= 2, "{ready}");
        boards.push((gateway, master, slave, sent));
    }
    for (_, master, _, sent) in &mut boards {
        master.write_all(&common::bytes(sent)).unwrap();
    }

    // The recorder stops by itself after as many frames as were sent: each arrived once, in
    // its array's order.
    let (code, said) = recorder.finish();
    assert_eq!(code, Some(0), "{said}");
    let bytes = std::fs::read(&recorded).unwrap();
    let got: Vec<aim_wire::Frame> =
        aim_tracker::link::FrameSource::new(&bytes[..]).map(Result::unwrap).collect();
    for (array, sent) in [(1, &frames), (2, &frames2)] {
        let of_array: Vec<_> = got.iter().filter(|f| f.header.array_id == array).cloned().collect();
        assert_eq!(
            &of_array, sent,
            "array {array}: the recording is not the frames sent, once each"
        );
    }
    assert_eq!(got.len(), frames.len() + frames2.len());

    // The tracker has every frame too when its fixes up to the last live one are out; then it
    // is stopped (SIGTERM, its Ctrl-C path) and sends the last fixes of the stream.
    let live = {
        let mut session = aim_tracker::session::Session::new(
            aim_tracker::tracker::Tracker::new(
                common::site(),
                aim_tracker::profile::Profile::dji_mini_2(),
                aim_tracker::filter::FilterKind::Aim,
                aim_tracker::tracker::TrackerConfig::default(),
            )
            .unwrap(),
            common::site(),
            aim_tracker::intake::IntakeConfig::default(),
        );
        frames.iter().map(|f| session.push(f).unwrap().len()).sum::<usize>()
    };
    assert!(live > 0 && live < replayed.len());
    let mut received: Vec<String> = Vec::new();
    let deadline = Instant::now() + PATIENCE;
    let next = |received: &mut Vec<String>, what: &str| {
        let left = deadline.saturating_duration_since(Instant::now());
        let sample = fixes
            .recv_timeout(left)
            .unwrap_or_else(|e| panic!("{what}: the subscription ended ({e})"))
            .unwrap_or_else(|| {
                panic!("{what}: no fix within {PATIENCE:?} after {}", received.len())
            });
        assert_eq!(sample.key_expr().as_str(), "aim/track/hall/fix");
        received.push(sample.payload().try_to_string().unwrap().into_owned());
    };
    while received.len() < live {
        next(&mut received, "the live fixes");
    }
    // Array 2's frames travel on their own gateway's session and may still be on the way:
    // stop the tracker only once its status line counts every frame of both arrays.
    let (array1, array2) = (
        format!("array 1: {} frames,", frames.len()),
        format!("unknown array 2: {} frames", frames2.len()),
    );
    tracker.wait_until("a status line with every frame", |line| {
        line.starts_with("status ") && line.contains(&array1) && line.ends_with(&array2)
    });
    tracker.terminate();
    while received.len() < replayed.len() {
        next(&mut received, "the last fixes after SIGTERM");
    }
    let (code, said) = tracker.finish();
    assert_eq!(code, Some(130), "Ctrl-C/SIGTERM status; {said}");
    let stats =
        said.lines().find(|l| l.starts_with('{') && l.contains("\"kind\":\"stats\"")).expect(&said);
    let stats: serde_json::Value = serde_json::from_str(stats).unwrap();
    // Every frame of both arrays reached the tracker (array 2 is not in its site: counted).
    assert_eq!(stats["link"]["frames"], frames.len() + frames2.len(), "{stats}");
    assert_eq!(stats["unknown_arrays"]["2"], frames2.len(), "{stats}");
    assert_eq!(received, replayed, "fixes on the bus differ from aim replay");
    let printed: Vec<String> = tracker.stdout.iter().collect();
    assert_eq!(printed, replayed, "aim track --zenoh printed other fixes than aim replay");
    assert!(fixes.try_recv().unwrap().is_none(), "a fix arrived twice");

    // The boards go away: each gateway ends with its statistics (every frame published).
    for (array, (mut gateway, master, slave, sent)) in (1..).zip(boards) {
        drop(master);
        drop(slave);
        let (_, said) = gateway.finish();
        let stats = said.lines().find(|l| l.starts_with("{\"kind\":\"gateway\"")).expect(&said);
        let stats: serde_json::Value = serde_json::from_str(stats).unwrap();
        assert_eq!(stats["published"][array.to_string()], sent.len(), "{stats}");
        assert_eq!(stats["link"]["crc_errors"], 0, "{stats}");
    }
}

// The bus's key and endpoint rules (here rather than in the library's unit tests: CI builds the
// library's tests without the feature, and this binary with it).

#[test]
fn keys_are_the_documented_ones_and_bad_names_are_refused() {
    assert_eq!(frames_key(3), "aim/array/3/frames");
    assert_eq!(fix_key("hall").unwrap(), "aim/track/hall/fix");
    for bad in ["", "a/b", "*", "x$", "q?", "#"] {
        let e = fix_key(bad).unwrap_err().to_string();
        assert!(e.contains("cannot be a key chunk"), "{e}");
    }
    let all: zenoh::key_expr::KeyExpr = FRAMES_ALL.try_into().unwrap();
    let one: zenoh::key_expr::KeyExpr = frames_key(200).try_into().unwrap();
    assert!(all.intersects(&one));
}

#[test]
fn a_bad_endpoint_is_named() {
    let options = BusOptions { connect: vec!["nonsense".into()], ..BusOptions::default() };
    let e = format!("{:#}", options.config().unwrap_err());
    assert!(e.contains("--connect \"nonsense\" is not a Zenoh endpoint"), "{e}");
    let options = BusOptions { listen: vec!["tcp/127.0.0.1:7447".into()], ..Default::default() };
    options.config().unwrap();
}
