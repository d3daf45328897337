//! The site plan the live map draws: the room, the arrays and the obstacles of a site file.

use std::path::Path;

use anyhow::Context as _;
use serde_json::{json, Value};

use crate::site::Site;

/// The plan of `site`, read from the file at `path` (obstacles are informative in a site file:
/// [`Site`] does not keep them, so they are read from the text here, by
/// [`crate::site::obstacles`]):
/// `{"site":"<file name>","room":{"min":[x,y,z],"max":[x,y,z]}|null,
/// "arrays":[{"id":..,"position":[x,y,z],"yaw_deg":..}],
/// "obstacles":[{"name":"..","min":[x,y,z],"max":[x,y,z]}]}` (world ENU metres).
pub fn plan_json(site: &Site, path: &Path) -> anyhow::Result<Value> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let obstacles: Vec<Value> = crate::site::obstacles(&text, path)?
        .into_iter()
        .map(|o| json!({ "name": o.name, "min": o.min, "max": o.max }))
        .collect();
    let arrays: Vec<Value> = site
        .arrays
        .iter()
        .map(|a| {
            // The array's +x in the world, projected on the floor: its yaw.
            let yaw = a.rotation[1][0].atan2(a.rotation[0][0]).to_degrees();
            json!({ "id": a.id, "position": a.position, "yaw_deg": (yaw * 10.0).round() / 10.0 })
        })
        .collect();
    Ok(json!({
        "site": path.file_name().map(|n| n.to_string_lossy().into_owned()),
        "room": site.room.map(|r| json!({ "min": r.min, "max": r.max })),
        "arrays": arrays,
        "obstacles": obstacles,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn room_arrays_and_obstacles_come_from_the_file() {
        let dir = std::env::temp_dir().join(format!("aim-plan-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("hall.toml");
        let text = "[[array]]\nid = 3\nposition = [1.0, 2.0, 0.0]\nyaw_deg = 90.0\n\n\
                    [room]\nsize = [10.0, 8.0, 4.0]\n\n\
                    [[obstacle]]\nname = \"shelf\"\nmin = [6.5, 7, 0.0]\nmax = [9.5, 7.5, 2.0]\nloss_db = 15.0\n";
        std::fs::write(&path, text).unwrap();
        let site = Site::load(&path).unwrap();
        let plan = plan_json(&site, &path).unwrap();
        assert_eq!(plan["site"], "hall.toml");
        assert_eq!(plan["room"]["max"], json!([10.0, 8.0, 4.0]));
        assert_eq!(plan["arrays"][0]["id"], 3);
        assert_eq!(plan["arrays"][0]["yaw_deg"], 90.0);
        assert_eq!(
            plan["obstacles"][0],
            json!({"name":"shelf","min":[6.5,7.0,0.0],"max":[9.5,7.5,2.0]})
        );

        std::fs::write(
            &path,
            "[[array]]\nid = 3\nposition = [1.0, 2.0, 0.0]\n[[obstacle]]\nmin = [1, 2]\n",
        )
        .unwrap();
        // The site file's own check refuses it first, by its line.
        let e = Site::load(&path).unwrap_err();
        assert_eq!(e.line, Some(5), "{e}");
        assert!(e.message.contains("invalid length 2, expected an array of 3 numbers"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
