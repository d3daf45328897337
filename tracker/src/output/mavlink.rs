//! Fixes to an autopilot (PX4, ArduPilot) as MAVLink 2 `VISION_POSITION_ESTIMATE` messages,
//! with a `HEARTBEAT` every second, through the `mavlink` crate (common dialect).
//!
//! Each fix becomes one message ([`vision_position_estimate`]):
//! - `x`, `y`, `z`: the position in the local NED frame of the site's `[origin]`
//!   ([`Origin`]): metres north, east and down of the origin;
//! - `usec`: the instant the fix describes ([`Fix::t`], the tracker's time base), µs;
//! - `covariance`: the upper triangle (21 values, row-major) of the 6×6 pose covariance over
//!   (x, y, z, roll, pitch, yaw); the position block is the fix's covariance turned into NED
//!   (m²); an acoustic tracker does not see the attitude, so every attitude entry is NaN
//!   ("unknown"), and so are `roll`, `pitch` and `yaw` (the autopilot must take its heading from
//!   elsewhere: see README);
//! - `reset_counter`: the tracker's restarts ([`Fix::resets`], modulo 256): it changes when
//!   the track starts afresh after a silence of the array or a reboot's new epoch.
//!
//! A fix no rotor signature supports ([`Fix::heard`] false: the bearings may be of a machine
//! or a fan) is not sent, only counted as withheld and said once on stderr
//! ([`MavlinkOut::send_unheard`] sends it anyway).
//!
//! The sender is system [`DEFAULT_SYSTEM_ID`] (the vehicle's, as a companion computer is),
//! component `MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY` (197). A send that fails (no listener on
//! a UDP port yet, a serial write error) is counted and said once on stderr; tracking goes on.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use ::mavlink::dialects::common::{
    MavAutopilot, MavComponent, MavMessage, MavModeFlag, MavState, MavType, HEARTBEAT_DATA,
    VISION_POSITION_ESTIMATE_DATA,
};
use ::mavlink::{MavConnection, MavHeader, MavlinkVersion};

use super::ned::Origin;
use crate::tracker::Fix;

/// The vehicle's MAVLink system id the messages carry unless told otherwise.
pub const DEFAULT_SYSTEM_ID: u8 = 1;
/// Time between two heartbeats.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);

/// Index in the 21-value upper triangle (row-major) of a 6×6 matrix of entry (`i`, `j`),
/// `i ≤ j < 6`: the rows before `i` hold 6, 5, … values.
pub fn upper_triangle_index(i: usize, j: usize) -> usize {
    debug_assert!(i <= j && j < 6);
    6 * i - i * i.saturating_sub(1) / 2 + (j - i)
}

/// The message for `fix` in the NED frame of `origin` (`None` for a fix whose position,
/// covariance or time is not finite, or whose time is before 0).
pub fn vision_position_estimate(
    fix: &Fix,
    origin: &Origin,
) -> Option<VISION_POSITION_ESTIMATE_DATA> {
    let finite = fix.position.iter().all(|v| v.is_finite())
        && fix.covariance.iter().flatten().all(|v| v.is_finite())
        && fix.t.is_finite()
        && fix.t >= 0.0;
    if !finite {
        return None;
    }
    let p = origin.to_ned(fix.position);
    let c = origin.covariance_to_ned(&fix.covariance);
    let mut covariance = [f32::NAN; 21];
    for i in 0..3 {
        for j in i..3 {
            covariance[upper_triangle_index(i, j)] = c[i][j] as f32;
        }
    }
    Some(VISION_POSITION_ESTIMATE_DATA {
        usec: (fix.t * 1e6).round() as u64,
        x: p[0] as f32,
        y: p[1] as f32,
        z: p[2] as f32,
        roll: f32::NAN,
        pitch: f32::NAN,
        yaw: f32::NAN,
        covariance,
        reset_counter: (fix.resets % 256) as u8,
    })
}

/// The heartbeat of a position source that is no autopilot.
pub fn heartbeat() -> HEARTBEAT_DATA {
    HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    }
}

type Link = ::mavlink::Connection<MavMessage>;

/// An open MAVLink output: fixes go out with [`Self::send`]; a thread sends the heartbeat
/// until the output is dropped.
pub struct MavlinkOut {
    link: Arc<Link>,
    header: MavHeader,
    origin: Origin,
    failures: Arc<AtomicU64>,
    sent: AtomicU64,
    withheld: AtomicU64,
    send_unheard: bool,
    stop: Arc<AtomicBool>,
    heartbeat: Option<std::thread::JoinHandle<()>>,
}

impl std::fmt::Debug for MavlinkOut {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MavlinkOut").field("origin", &self.origin).finish()
    }
}

/// The address forms `--mavlink` takes.
pub const ADDRESS_FORMS: &str = "udpout:HOST:PORT or serial:PORT:BAUD";

impl MavlinkOut {
    /// Opens `address` (`udpout:HOST:PORT` or `serial:PORT:BAUD`) for MAVLink 2 as system
    /// `system_id`, positions in the NED frame of `origin`; the first heartbeat goes out now.
    pub fn open(address: &str, origin: Origin, system_id: u8) -> anyhow::Result<Self> {
        if !(address.starts_with("udpout:") || address.starts_with("serial:")) {
            anyhow::bail!("--mavlink {address}: give {ADDRESS_FORMS}");
        }
        if address.starts_with("udpout:") {
            // Port 0 opens but every send fails: refused here rather than counted later.
            let port = address.rsplit(':').next().and_then(|p| p.parse::<u16>().ok());
            if port.is_none_or(|p| p == 0) {
                anyhow::bail!("--mavlink {address}: the port must be 1 to 65535");
            }
        }
        let mut link: Link = ::mavlink::connect(address)
            .map_err(|e| anyhow::anyhow!("--mavlink {address}: cannot open: {e}"))?;
        link.set_protocol_version(MavlinkVersion::V2);
        let link = Arc::new(link);
        let header = MavHeader {
            system_id: system_id.into(),
            component_id: MavComponent::MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY as u8,
            sequence: 0,
        };
        let failures = Arc::new(AtomicU64::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let heartbeat = {
            let (link, failures, stop) = (link.clone(), failures.clone(), stop.clone());
            std::thread::Builder::new()
                .name("mavlink-heartbeat".into())
                .spawn(move || {
                    let message = MavMessage::HEARTBEAT(heartbeat());
                    while !stop.load(Ordering::Relaxed) {
                        if let Err(e) = link.send(&header, &message) {
                            note_failure(&failures, &e);
                        }
                        // Sleep in short steps so a drop ends the thread promptly.
                        let mut left = HEARTBEAT_PERIOD;
                        while !left.is_zero() && !stop.load(Ordering::Relaxed) {
                            let step = left.min(Duration::from_millis(50));
                            std::thread::sleep(step);
                            left -= step;
                        }
                    }
                })
                .map_err(|e| anyhow::anyhow!("--mavlink: cannot start the heartbeat: {e}"))?
        };
        Ok(Self {
            link,
            header,
            origin,
            failures,
            sent: AtomicU64::new(0),
            withheld: AtomicU64::new(0),
            send_unheard: false,
            stop,
            heartbeat: Some(heartbeat),
        })
    }

    /// Sends the fixes no rotor signature supports too (for a drone whose rotors the chip's
    /// detector does not recognise).
    pub fn send_unheard(mut self, yes: bool) -> Self {
        self.send_unheard = yes;
        self
    }

    /// Sends `fix` (a fix that is not finite is skipped; one no rotor signature supports is
    /// withheld and counted, unless [`Self::send_unheard`]).
    pub fn send(&self, fix: &Fix) {
        if !fix.heard && !self.send_unheard {
            if self.withheld.fetch_add(1, Ordering::Relaxed) == 0 {
                crate::exit::note(
                    "note: MAVLink: fixes without a rotor signature in the last 5 s are withheld \
                     (counted; --mavlink-send-unheard sends them)",
                );
            }
            return;
        }
        let Some(data) = vision_position_estimate(fix, &self.origin) else { return };
        match self.link.send(&self.header, &MavMessage::VISION_POSITION_ESTIMATE(data)) {
            Ok(_) => {
                self.sent.fetch_add(1, Ordering::Relaxed);
            }
            Err(e) => note_failure(&self.failures, &e),
        }
    }

    /// Messages sent with [`Self::send`], fixes withheld (not [`Fix::heard`]), and sends
    /// (fixes and heartbeats) that failed.
    pub fn counts(&self) -> (u64, u64, u64) {
        (
            self.sent.load(Ordering::Relaxed),
            self.withheld.load(Ordering::Relaxed),
            self.failures.load(Ordering::Relaxed),
        )
    }
}

impl Drop for MavlinkOut {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.heartbeat.take() {
            let _ = h.join();
        }
    }
}

fn note_failure(failures: &AtomicU64, e: &dyn std::fmt::Display) {
    if failures.fetch_add(1, Ordering::Relaxed) == 0 {
        // One line: the library's error may be a multi-line debug dump.
        let e = e.to_string().split_whitespace().collect::<Vec<_>>().join(" ");
        crate::exit::note(&format!(
            "warning: MAVLink send failed ({e}); tracking goes on, further failures counted"
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::MotionClass;

    fn fix(position: [f64; 3], covariance: [[f64; 3]; 3], t: f64, resets: u32) -> Fix {
        Fix {
            t,
            available: t,
            position,
            velocity: [0.0; 3],
            sigma: std::array::from_fn(|i| covariance[i][i].sqrt()),
            covariance,
            resets,
            motion: MotionClass::Hover,
            los: true,
            drone: None,
            heard: true,
        }
    }

    #[test]
    fn upper_triangle_is_row_major() {
        let mut k = 0;
        for i in 0..6 {
            for j in i..6 {
                assert_eq!(upper_triangle_index(i, j), k, "({i}, {j})");
                k += 1;
            }
        }
        assert_eq!(k, 21);
    }

    #[test]
    fn a_fix_in_ned_with_its_covariance() {
        let origin =
            Origin { position: [1.0, 1.0, 0.0], x_axis_from_north_rad: 90f64.to_radians() };
        let c = [[0.04, 0.01, 0.0], [0.01, 0.09, 0.0], [0.0, 0.0, 0.25]];
        let m =
            vision_position_estimate(&fix([3.0, 5.0, 1.5], c, 12.345_678_9, 258), &origin).unwrap();
        // 4 m north, 2 m east, 1.5 m up.
        assert_eq!((m.x, m.y, m.z), (4.0, 2.0, -1.5));
        assert_eq!(m.usec, 12_345_679);
        assert_eq!(m.reset_counter, 2);
        // NED variances: north = site y, east = site x.
        assert!((m.covariance[0] - 0.09).abs() < 1e-7);
        assert!((m.covariance[1] - 0.01).abs() < 1e-7);
        assert!((m.covariance[6] - 0.04).abs() < 1e-7);
        assert!((m.covariance[11] - 0.25).abs() < 1e-7);
        assert_eq!((m.covariance[2], m.covariance[7]), (0.0, 0.0));
        assert!(m.covariance[3].is_nan() && m.covariance[15].is_nan() && m.covariance[20].is_nan());
        assert!(m.roll.is_nan() && m.pitch.is_nan() && m.yaw.is_nan());
    }

    #[test]
    fn non_finite_fixes_are_not_sent() {
        let origin = Origin { position: [0.0; 3], x_axis_from_north_rad: 0.0 };
        let c = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(vision_position_estimate(&fix([f64::NAN, 0.0, 0.0], c, 1.0, 0), &origin).is_none());
        assert!(vision_position_estimate(&fix([0.0; 3], c, -1.0, 0), &origin).is_none());
        let mut bad = c;
        bad[0][1] = f64::INFINITY;
        assert!(vision_position_estimate(&fix([0.0; 3], bad, 1.0, 0), &origin).is_none());
    }

    #[test]
    fn bad_addresses_are_refused() {
        let origin = Origin { position: [0.0; 3], x_axis_from_north_rad: 0.0 };
        let e = MavlinkOut::open("udp:127.0.0.1:14550", origin, 1).unwrap_err();
        assert!(e.to_string().contains("udpout:HOST:PORT"), "{e}");
        let e = MavlinkOut::open("serial:/nonexistent/tty:57600", origin, 1).unwrap_err();
        assert!(e.to_string().contains("cannot open"), "{e}");
        for port in ["0", "65536", "x", ""] {
            let e = MavlinkOut::open(&format!("udpout:127.0.0.1:{port}"), origin, 1).unwrap_err();
            assert!(e.to_string().contains("the port must be 1 to 65535"), "{port}: {e}");
        }
    }
}
