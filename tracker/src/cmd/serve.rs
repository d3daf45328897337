//! The `--serve ADDR` flag of `aim track` and `aim replay`: the live map
//! ([`aim_tracker::serve`]).

use std::path::Path;
use std::sync::atomic::Ordering;

use aim_tracker::exit::note;
use aim_tracker::serve::{plan, LiveMap};
use aim_tracker::tracker::Fix;

/// Where the live map is served.
#[derive(clap::Args, Clone, Debug)]
pub struct ServeArgs {
    /// Serve the live map on this address, e.g. `127.0.0.1:8080` (open it in a browser;
    /// `0.0.0.0:8080` for other machines; port 0: a free port, said on stderr).
    #[arg(long, value_name = "ADDR")]
    pub serve: Option<String>,
}

impl ServeArgs {
    /// Starts the map of the site at `site` when `--serve` is given; says where on stderr.
    pub fn start(&self, site: &Path) -> anyhow::Result<Option<LiveMap>> {
        let Some(addr) = &self.serve else { return Ok(None) };
        let loaded = aim_tracker::site::Site::load(site)?;
        let map = LiveMap::start(addr, plan::plan_json(&loaded, site)?)?;
        // Scripts and tests wait for this line before they open the page.
        note(&format!("live map on http://{}/", map.addr()));
        Ok(Some(map))
    }
}

/// Shows `fix` on the map, if there is one.
pub fn show(map: &Option<LiveMap>, fix: &Fix) -> anyhow::Result<()> {
    if let Some(map) = map {
        map.fix(fix);
    }
    Ok(())
}

/// After a replay: keeps the map up until Ctrl-C / SIGTERM, then returns (status 0: the
/// replay itself was complete).
pub fn serve_until_interrupted(map: &LiveMap) -> anyhow::Result<()> {
    let stop = aim_tracker::link::serial::interrupt_flag()?;
    note(&format!("replay done; the live map stays on http://{}/ until Ctrl-C", map.addr()));
    while !stop.load(Ordering::SeqCst) {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    Ok(())
}
