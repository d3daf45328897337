//! The site's place in the world for outputs that want a local north–east–down (NED) frame
//! (MAVLink's `LOCAL_NED`): an optional `[origin]` table of the site file.
//!
//! ```toml
//! [origin]
//! position = [2.0, 3.0, 0.0]    # site metres: the NED origin (e.g. the take-off spot)
//! x_axis_from_north_deg = 90.0  # heading of the site's +x axis, clockwise from north, degrees
//! ```
//! The site frame is right-handed with z up, so its +y axis points 90° anticlockwise of +x
//! (heading `x_axis_from_north_deg − 90°`). A site laid out with x east and y north, as the
//! site format's "world ENU" reads, has `x_axis_from_north_deg = 90`.
//!
//! With ψ the heading of +x and `d = p − origin` in site metres:
//! north = d_x·cos ψ + d_y·sin ψ, east = d_x·sin ψ − d_y·cos ψ, down = −d_z.

use std::path::Path;

use serde::Deserialize;

use crate::config::{line_of, parse_toml, read_text, ConfigError};
use crate::site::MAX_COORDINATE_M;

/// A site's NED origin and heading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Origin {
    /// The NED origin, site metres.
    pub position: [f64; 3],
    /// Heading of the site's +x axis, clockwise from north, radians.
    pub x_axis_from_north_rad: f64,
}

#[derive(Deserialize)]
struct File {
    origin: Option<toml::Spanned<OriginEntry>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OriginEntry {
    position: Option<toml::Spanned<crate::config::Coords<3>>>,
    x_axis_from_north_deg: Option<toml::Spanned<f64>>,
}

impl Origin {
    /// The `[origin]` table of the site file at `path`, or an error naming the file (and the
    /// line) when it is missing or wrong.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        Self::parse(&read_text(path)?, path)
    }

    /// The `[origin]` table of site TOML `text` (`path` names it in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        let file: File = parse_toml(text, path)?;
        let err = |span: std::ops::Range<usize>, message: String| ConfigError {
            path: path.to_path_buf(),
            line: Some(line_of(text, span.start)),
            message,
        };
        let Some(entry) = file.origin else {
            return Err(ConfigError {
                path: path.to_path_buf(),
                line: None,
                message: "no [origin] table: a local NED frame needs the site's origin and the \
                          heading of its x axis, e.g.\n[origin]\nposition = [0.0, 0.0, 0.0]\n\
                          x_axis_from_north_deg = 90.0"
                    .into(),
            });
        };
        let o = entry.get_ref();
        let Some(heading) = &o.x_axis_from_north_deg else {
            return Err(err(
                entry.span(),
                "[origin] needs `x_axis_from_north_deg` (heading of the site's +x axis, \
                 clockwise from north, degrees; 90 when x points east)"
                    .into(),
            ));
        };
        let deg = *heading.get_ref();
        if !(deg.is_finite() && deg.abs() <= 360.0) {
            return Err(err(
                heading.span(),
                format!("x_axis_from_north_deg must be within ±360 degrees (got {deg:?})"),
            ));
        }
        let position = match &o.position {
            Some(p) => {
                let v = p.get_ref().0;
                if !v.iter().all(|x| x.is_finite() && x.abs() <= MAX_COORDINATE_M) {
                    return Err(err(
                        p.span(),
                        format!(
                            "origin position must be finite and within {MAX_COORDINATE_M} m of \
                             the site's origin (got {v:?})"
                        ),
                    ));
                }
                v
            }
            None => [0.0; 3],
        };
        Ok(Self { position, x_axis_from_north_rad: deg.to_radians() })
    }

    /// The rotation from site axes to NED axes (row-major: `ned = R · site`).
    pub fn rotation(&self) -> [[f64; 3]; 3] {
        let (s, c) = self.x_axis_from_north_rad.sin_cos();
        [[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]]
    }

    /// A site position (m) in the NED frame (m: north, east, down).
    pub fn to_ned(&self, p: [f64; 3]) -> [f64; 3] {
        let d = [p[0] - self.position[0], p[1] - self.position[1], p[2] - self.position[2]];
        mul(&self.rotation(), d)
    }

    /// A site covariance (m², row-major 3×3) in the NED frame: R·C·Rᵀ.
    pub fn covariance_to_ned(&self, c: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
        let r = self.rotation();
        std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                (0..3).map(|k| (0..3).map(|l| r[i][k] * c[k][l] * r[j][l]).sum::<f64>()).sum()
            })
        })
    }
}

fn mul(r: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    const ARRAY: &str = "[[array]]\nid = 1\nposition = [0.0, 0.0, 0.0]\n";

    fn origin(table: &str) -> Result<Origin, ConfigError> {
        Origin::parse(&format!("{ARRAY}{table}"), Path::new("site.toml"))
    }

    #[test]
    fn x_east_y_north_is_enu_to_ned() {
        let o =
            origin("[origin]\nposition = [1.0, 2.0, 0.5]\nx_axis_from_north_deg = 90.0\n").unwrap();
        // 3 m east, 4 m north, 1.5 m up of the origin.
        let ned = o.to_ned([4.0, 6.0, 2.0]);
        for (got, want) in ned.iter().zip([4.0, 3.0, -1.5]) {
            assert!((got - want).abs() < 1e-12, "{ned:?}");
        }
    }

    #[test]
    fn a_rotated_site_keeps_lengths_and_handedness() {
        let o = origin("[origin]\nx_axis_from_north_deg = 30.0\n").unwrap();
        // +x points 30° east of north; +y 60° west of north.
        let x = o.to_ned([1.0, 0.0, 0.0]);
        let y = o.to_ned([0.0, 1.0, 0.0]);
        let rad = 30f64.to_radians();
        assert!((x[0] - rad.cos()).abs() < 1e-12 && (x[1] - rad.sin()).abs() < 1e-12);
        assert!((y[0] - rad.sin()).abs() < 1e-12 && (y[1] + rad.cos()).abs() < 1e-12);
        // NED is right-handed like the site frame: the turn between them has determinant +1.
        let r = o.rotation();
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        assert!((det - 1.0).abs() < 1e-12, "NED from a right-handed z-up frame: det {det}");
        // Covariance: trace kept, σx² ≠ σy² gives a north–east correlation.
        let c = o.covariance_to_ned(&[[4.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.25]]);
        assert!((c[0][0] + c[1][1] + c[2][2] - 5.25).abs() < 1e-12);
        assert!((c[0][1] - c[1][0]).abs() < 1e-12 && c[0][1].abs() > 0.1);
        assert!((c[2][2] - 0.25).abs() < 1e-12);
    }

    #[test]
    fn bad_origins_name_file_and_line() {
        let e = origin("").unwrap_err();
        assert!(e.to_string().starts_with("site.toml: no [origin] table"), "{e}");
        let e = origin("[origin]\nposition = [0.0, 0.0, 0.0]\n").unwrap_err();
        assert_eq!(e.line, Some(4), "{e}");
        assert!(e.message.contains("x_axis_from_north_deg"), "{e}");
        let e = origin("[origin]\nx_axis_from_north_deg = 1e9\n").unwrap_err();
        assert_eq!(e.line, Some(5), "{e}");
        let e = origin("[origin]\nx_axis_from_north_deg = 0.0\nposition = [nan, 0.0, 0.0]\n")
            .unwrap_err();
        assert_eq!(e.line, Some(6), "{e}");
        let e = origin("[origin]\nx_axis_from_north = 0.0\n").unwrap_err();
        assert!(e.to_string().starts_with("site.toml:5:"), "{e}");
        assert!(e.message.contains("x_axis_from_north"), "{e}");
    }
}
