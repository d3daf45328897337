//! The live map: `aim track … --serve ADDR` and `aim replay … --serve ADDR` serve a page that
//! draws the site plan (room, arrays, obstacles), the track with its uncertainty ellipse, the
//! motion class and LoS state, and the arrays' BPF and DoA, updated live by server-sent events.
//!
//! - [`LiveMap`]: the HTTP server (tiny_http, one thread per event stream) and its events;
//! - [`plan`]: the site plan the page draws, from the site file;
//! - [`tap`]: a reader between the link and the intake that shows the page every frame (and
//!   paces a replay at the link's pace or a multiple of it), passing the bytes on unchanged.
//!
//! Routes: `/` the page (HTML and JS embedded in the binary, no network needed), `/plan.json`,
//! `/events` (`text/event-stream`: every event so far, then new ones as they come; events
//! `fix`, `doa`, `peaks`, and `end` once the stream has ended).

pub mod plan;
pub mod tap;

use std::io::Write as _;
use std::net::SocketAddr;
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex, PoisonError};

use anyhow::{anyhow, Context as _};
use serde_json::{json, Value};

use crate::tracker::Fix;

/// The page, embedded.
const PAGE: &str = include_str!("map.html");

/// Events kept for a page that connects late (the newest; about 3 h of fixes at 10 Hz with
/// their frames); older ones are dropped, the fix numbers still count them.
pub const BACKLOG_EVENTS: usize = 200_000;

/// Events and clients, shared by the tracking thread and the server's threads.
#[derive(Default)]
struct Hub {
    backlog: std::collections::VecDeque<Arc<str>>,
    clients: Vec<Sender<Arc<str>>>,
    fixes: u64,
    ended: bool,
}

impl Hub {
    fn publish(&mut self, event: &str, data: &Value) {
        let text: Arc<str> = format!("event: {event}\ndata: {data}\n\n").into();
        if self.backlog.len() == BACKLOG_EVENTS {
            self.backlog.pop_front();
        }
        self.backlog.push_back(text.clone());
        self.clients.retain(|c| c.send(text.clone()).is_ok());
    }
}

/// The live map's server; events sent with [`Self::fix`], [`Self::frame`] and [`Self::end`]
/// reach every page connected, and pages that connect later get them all first.
#[derive(Clone)]
pub struct LiveMap {
    hub: Arc<Mutex<Hub>>,
    addr: SocketAddr,
}

impl std::fmt::Debug for LiveMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveMap").field("addr", &self.addr).finish()
    }
}

impl LiveMap {
    /// Serves the page for `plan` ([`plan::plan_json`]) on `addr` (`127.0.0.1:8080`; port 0
    /// picks a free one, see [`Self::addr`]) from a thread of its own, for the life of the
    /// process.
    pub fn start(addr: &str, plan: Value) -> anyhow::Result<Self> {
        let server = tiny_http::Server::http(addr)
            .map_err(|e| anyhow!("{e}"))
            .with_context(|| format!("serving the live map on {addr}"))?;
        let addr = server
            .server_addr()
            .to_ip()
            .ok_or_else(|| anyhow!("serving the live map on {addr}: not an IP address"))?;
        let hub = Arc::new(Mutex::new(Hub::default()));
        let served = hub.clone();
        let plan = Arc::new(plan.to_string());
        std::thread::spawn(move || {
            for request in server.incoming_requests() {
                handle(request, &served, &plan);
            }
        });
        Ok(Self { hub, addr })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    fn hub(&self) -> std::sync::MutexGuard<'_, Hub> {
        self.hub.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A fix: `{"n":..,"t":..,"x":..,"y":..,"z":..,"vx":..,"vy":..,"vz":..,"sx":..,"sy":..,
    /// "sz":..,"motion":"..","los":..,"heard":..}` (metres, m/s, s; `n` counts the fixes from 1;
    /// `s*`: the standard deviation of each coordinate; `heard`: [`Fix::heard`]).
    pub fn fix(&self, fix: &Fix) {
        let mut hub = self.hub();
        hub.fixes += 1;
        let r = |x: f64| if x.is_finite() { json!((x * 1e3).round() / 1e3) } else { Value::Null };
        let data = json!({
            "n": hub.fixes,
            "t": r(fix.t),
            "x": r(fix.position[0]), "y": r(fix.position[1]), "z": r(fix.position[2]),
            "vx": r(fix.velocity[0]), "vy": r(fix.velocity[1]), "vz": r(fix.velocity[2]),
            "sx": r(fix.sigma[0]), "sy": r(fix.sigma[1]), "sz": r(fix.sigma[2]),
            "motion": fix.motion.as_str(),
            "los": fix.los,
            "heard": fix.heard,
        });
        hub.publish("fix", &data);
    }

    /// A frame as `aim frames` prints it ([`crate::link::json::frame`]); only `Doa` and
    /// `Peaks` frames are sent (the DoA and BPF panels).
    pub fn frame(&self, frame: &aim_wire::Frame, sample_rate_hz: Option<u32>) {
        let kind = match frame.body {
            aim_wire::Body::Doa(_) => "doa",
            aim_wire::Body::Peaks(_) => "peaks",
            _ => return,
        };
        let data = crate::link::json::frame(frame, sample_rate_hz);
        self.hub().publish(kind, &data);
    }

    /// The stream has ended (a replay's end of file, Ctrl-C): pages stop listening.
    pub fn end(&self) {
        let mut hub = self.hub();
        let fixes = hub.fixes;
        hub.publish("end", &json!({ "fixes": fixes }));
        hub.ended = true;
        hub.clients.clear();
    }
}

/// Answers one request.
fn handle(request: tiny_http::Request, hub: &Arc<Mutex<Hub>>, plan: &Arc<String>) {
    let path = request.url().split('?').next().unwrap_or("").to_owned();
    let content = |body: &str, kind: &str| {
        tiny_http::Response::from_string(body).with_header(
            tiny_http::Header::from_bytes(&b"Content-Type"[..], kind.as_bytes())
                .expect("a valid header"),
        )
    };
    // A page that went away mid-answer costs its own answer only.
    let _ = match (request.method(), path.as_str()) {
        (tiny_http::Method::Get, "/") => request.respond(content(PAGE, "text/html; charset=utf-8")),
        (tiny_http::Method::Get, "/plan.json") => {
            request.respond(content(plan, "application/json"))
        }
        (tiny_http::Method::Get, "/events") => {
            let (backlog, rx) = {
                let mut hub = hub.lock().unwrap_or_else(PoisonError::into_inner);
                let backlog: Vec<Arc<str>> = hub.backlog.iter().cloned().collect();
                let rx = if hub.ended {
                    None
                } else {
                    let (tx, rx) = mpsc::channel();
                    hub.clients.push(tx);
                    Some(rx)
                };
                (backlog, rx)
            };
            std::thread::spawn(move || stream_events(request, backlog, rx));
            Ok(())
        }
        _ => request.respond(content("not found", "text/plain").with_status_code(404)),
    };
}

/// Writes an event stream: the backlog, then each new event, until the map ends or the page
/// goes away.
fn stream_events(
    request: tiny_http::Request,
    backlog: Vec<Arc<str>>,
    rx: Option<Receiver<Arc<str>>>,
) {
    let mut out = request.into_writer();
    let head = "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-cache\r\n\
                Connection: close\r\n\r\n";
    let mut send = |text: &str| out.write_all(text.as_bytes()).and_then(|()| out.flush());
    if send(head).is_err() {
        return;
    }
    // The backlog in one write per event would be slow for a long session: batch it.
    for chunk in backlog.chunks(256) {
        if send(&chunk.concat()).is_err() {
            return;
        }
    }
    if let Some(rx) = rx {
        for text in rx {
            if send(&text).is_err() {
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{BufRead, BufReader, Read, Write};
    use std::net::TcpStream;

    fn get(addr: SocketAddr, path: &str) -> TcpStream {
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(std::time::Duration::from_secs(20))).unwrap();
        write!(s, "GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").unwrap();
        s
    }

    fn fix(x: f64) -> Fix {
        Fix {
            t: 1.0,
            available: 1.3,
            position: [x, 2.0, 1.5],
            velocity: [0.0; 3],
            sigma: [0.5, 0.4, 0.3],
            covariance: [[0.25, 0.0, 0.0], [0.0, 0.16, 0.0], [0.0, 0.0, 0.09]],
            motion: crate::motion::MotionClass::Hover,
            los: true,
            drone: None,
            heard: true,
            resets: 0,
        }
    }

    #[test]
    fn page_plan_and_events_in_order_with_the_backlog_first() {
        let map = LiveMap::start("127.0.0.1:0", json!({"arrays": []})).unwrap();
        let mut page = String::new();
        get(map.addr(), "/").read_to_string(&mut page).unwrap();
        assert!(page.starts_with("HTTP/1.1 200") && page.contains("<canvas"), "{page}");
        let mut plan = String::new();
        get(map.addr(), "/plan.json").read_to_string(&mut plan).unwrap();
        assert!(plan.ends_with("{\"arrays\":[]}"), "{plan}");
        let mut missing = String::new();
        get(map.addr(), "/nothing").read_to_string(&mut missing).unwrap();
        assert!(missing.starts_with("HTTP/1.1 404"), "{missing}");

        map.fix(&fix(1.0)); // before the page connects: from the backlog
        let events = BufReader::new(get(map.addr(), "/events"));
        let mut lines = events.lines().map(|l| l.unwrap());
        assert_eq!(lines.next().unwrap(), "HTTP/1.1 200 OK");
        let data: Vec<String> = {
            map.fix(&fix(2.0)); // after: live
            map.end();
            lines.filter_map(|l| l.strip_prefix("data: ").map(str::to_owned)).collect()
        };
        assert_eq!(data.len(), 3, "{data:?}");
        let first: Value = serde_json::from_str(&data[0]).unwrap();
        let second: Value = serde_json::from_str(&data[1]).unwrap();
        assert_eq!((first["n"].as_u64(), first["x"].as_f64()), (Some(1), Some(1.0)));
        assert_eq!((second["n"].as_u64(), second["x"].as_f64()), (Some(2), Some(2.0)));
        assert_eq!((second["sx"].as_f64(), second["motion"].as_str()), (Some(0.5), Some("hover")));
        assert_eq!(data[2], "{\"fixes\":2}");
    }
}
