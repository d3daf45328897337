//! The track against the truth, as a PNG and an SVG beside it: a plan view (x–y, metres) above,
//! height against time and position error against time below, each with axes, ticks, a title
//! and a legend. Truth black, track red (LoS fixes) and orange (NLoS fixes), arrays green,
//! obstacles grey; NLoS spans shaded on the time plots.
//!
//! Text uses the DejaVu Sans font bundled in `host-sim/assets/fonts` (its licence beside it),
//! registered with plotters' `ab_glyph` backend: no system font is needed.

use std::path::Path;
use std::sync::Once;

use aim_tracker::tracker::Fix;
use anyhow::Context as _;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::eval::metrics::truth_at;
use crate::site::Site;
use crate::truth::Truth;

/// Width and height of the image, pixels: plan view 900 × 900, two time plots 900 × 300.
const SIZE: (u32, u32) = (900, 1500);
/// The bundled font (DejaVu Sans, Bitstream Vera licence).
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
/// The family name the bundled font is registered under.
const FAMILY: &str = "sans-serif";

const TRACK_LOS: RGBColor = RGBColor(220, 0, 0);
const TRACK_NLOS: RGBColor = RGBColor(255, 150, 0);
const ARRAY: RGBColor = RGBColor(0, 160, 0);
const OBSTACLE: RGBColor = RGBColor(170, 170, 170);
const NLOS_SPAN: RGBColor = RGBColor(255, 235, 205);

fn register_font() -> anyhow::Result<()> {
    static ONCE: Once = Once::new();
    let mut result = Ok(());
    ONCE.call_once(|| {
        result = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT)
            .map_err(|_| anyhow::anyhow!("the bundled font does not parse"));
    });
    result
}

/// Draws the plot into `path` (PNG) and the same plot into `path` with extension `svg`.
pub fn plot_track(path: &Path, fixes: &[Fix], truth: &Truth, site: &Site) -> anyhow::Result<()> {
    register_font()?;
    let png = BitMapBackend::new(path, SIZE).into_drawing_area();
    draw(&png, fixes, truth, site).with_context(|| format!("drawing {}", path.display()))?;
    png.present()
        .map_err(|e| anyhow::anyhow!("{e}"))
        .with_context(|| format!("writing {}", path.display()))?;
    let svg_path = path.with_extension("svg");
    let svg = SVGBackend::new(&svg_path, SIZE).into_drawing_area();
    draw(&svg, fixes, truth, site).with_context(|| format!("drawing {}", svg_path.display()))?;
    svg.present()
        .map_err(|e| anyhow::anyhow!("{e}"))
        .with_context(|| format!("writing {}", svg_path.display()))?;
    Ok(())
}

/// A drawing error as an `anyhow` error (plotters' errors borrow the backend's error type).
fn err<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> anyhow::Error {
    anyhow::anyhow!("{e}")
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    fixes: &[Fix],
    truth: &Truth,
    site: &Site,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(err)?;
    let (plan, rest) = root.split_vertically(SIZE.0);
    let (height, error) = rest.split_vertically((SIZE.1 - SIZE.0) / 2);
    draw_plan(&plan, fixes, truth, site)?;
    let nlos = nlos_spans(fixes);
    let t0 = truth.rows.first().map_or(0.0, |r| r.t_s);
    let t1 = truth.rows.last().map_or(1.0, |r| r.t_s).max(t0 + 1.0);

    // Height against time.
    let zs: Vec<f64> = truth
        .rows
        .iter()
        .map(|r| r.position[2])
        .chain(fixes.iter().map(|f| f.position[2]))
        .collect();
    let (z0, z1) = bounds(&zs, 0.5);
    let mut chart = ChartBuilder::on(&height)
        .caption("Height against time", (FAMILY, 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(t0..t1, z0..z1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("height z (m)")
        .label_style((FAMILY, 14))
        .draw()
        .map_err(err)?;
    shade(&mut chart, &nlos, z0, z1)?;
    chart
        .draw_series(LineSeries::new(
            truth.rows.iter().map(|r| (r.t_s, r.position[2])),
            BLACK.stroke_width(2),
        ))
        .map_err(err)?
        .label("truth")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(
            fixes.iter().map(|f| (f.t, f.position[2])),
            TRACK_LOS.stroke_width(2),
        ))
        .map_err(err)?
        .label("track")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], TRACK_LOS.stroke_width(2)));
    legend(&mut chart)?;

    // 3-D position error against time.
    let errors: Vec<(f64, f64)> = fixes
        .iter()
        .filter_map(|f| {
            let (p, _, _) = truth_at(truth, f.t)?;
            let e = ((f.position[0] - p[0]).powi(2)
                + (f.position[1] - p[1]).powi(2)
                + (f.position[2] - p[2]).powi(2))
            .sqrt();
            e.is_finite().then_some((f.t, e))
        })
        .collect();
    let e1 = errors.iter().map(|&(_, e)| e).fold(1.0_f64, f64::max) * 1.05;
    let mut chart = ChartBuilder::on(&error)
        .caption("Position error against time", (FAMILY, 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(t0..t1, 0.0..e1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("3-D error (m)")
        .label_style((FAMILY, 14))
        .draw()
        .map_err(err)?;
    shade(&mut chart, &nlos, 0.0, e1)?;
    chart
        .draw_series(LineSeries::new(errors, TRACK_LOS.stroke_width(2)))
        .map_err(err)?
        .label("|track − truth|")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], TRACK_LOS.stroke_width(2)));
    legend(&mut chart)?;
    Ok(())
}

type Chart<'a, DB> = ChartContext<
    'a,
    DB,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

fn legend<'a, DB: DrawingBackend + 'a>(chart: &mut Chart<'a, DB>) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FAMILY, 14))
        .draw()
        .map_err(err)
}

/// Shades the NLoS spans `[t_start, t_end]` between `lo` and `hi`, with a legend entry.
fn shade<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    spans: &[(f64, f64)],
    lo: f64,
    hi: f64,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    if spans.is_empty() {
        return Ok(());
    }
    chart
        .draw_series(
            spans.iter().map(|&(a, b)| Rectangle::new([(a, lo), (b, hi)], NLOS_SPAN.filled())),
        )
        .map_err(err)?
        .label("NLoS (tracker's decision)")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], NLOS_SPAN.filled()));
    Ok(())
}

fn draw_plan<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    fixes: &[Fix],
    truth: &Truth,
    site: &Site,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    // A square region holding the room (or the data) with a margin: one metre is as long on
    // both axes.
    let mut xs: Vec<f64> = truth
        .rows
        .iter()
        .map(|r| r.position[0])
        .chain(fixes.iter().map(|f| f.position[0]))
        .collect();
    let mut ys: Vec<f64> = truth
        .rows
        .iter()
        .map(|r| r.position[1])
        .chain(fixes.iter().map(|f| f.position[1]))
        .collect();
    for a in &site.arrays {
        xs.push(a.position[0]);
        ys.push(a.position[1]);
    }
    if let Some(room) = &site.room {
        xs.extend([0.0, room.size[0]]);
        ys.extend([0.0, room.size[1]]);
    }
    let (x0, x1) = bounds(&xs, 0.5);
    let (y0, y1) = bounds(&ys, 0.5);
    let span = (x1 - x0).max(y1 - y0).max(1.0);
    let mut chart = ChartBuilder::on(area)
        .caption("AIM track against the truth: plan view", (FAMILY, 24))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(x0..x0 + span, y0..y0 + span)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("x east (m)")
        .y_desc("y north (m)")
        .label_style((FAMILY, 14))
        .draw()
        .map_err(err)?;
    if !site.obstacles.is_empty() {
        chart
            .draw_series(site.obstacles.iter().map(|o| {
                Rectangle::new([(o.min[0], o.min[1]), (o.max[0], o.max[1])], OBSTACLE.filled())
            }))
            .map_err(err)?
            .label("obstacles")
            .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], OBSTACLE.filled()));
    }
    chart
        .draw_series(LineSeries::new(
            truth.rows.iter().map(|r| (r.position[0], r.position[1])),
            BLACK.stroke_width(2),
        ))
        .map_err(err)?
        .label("truth")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    for (los, colour, label) in
        [(true, TRACK_LOS, "track (LoS)"), (false, TRACK_NLOS, "track (NLoS)")]
    {
        let segments: Vec<_> = fixes
            .windows(2)
            .filter(|w| w[1].los == los)
            .map(|w| {
                PathElement::new(
                    vec![
                        (w[0].position[0], w[0].position[1]),
                        (w[1].position[0], w[1].position[1]),
                    ],
                    colour.stroke_width(2),
                )
            })
            .collect();
        if segments.is_empty() {
            continue;
        }
        chart.draw_series(segments).map_err(err)?.label(label).legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
        });
    }
    chart
        .draw_series(site.arrays.iter().map(|a| {
            EmptyElement::at((a.position[0], a.position[1]))
                + Rectangle::new([(-6, -6), (6, 6)], ARRAY.filled())
        }))
        .map_err(err)?
        .label("arrays")
        .legend(|(x, y)| Rectangle::new([(x + 4, y - 6), (x + 16, y + 6)], ARRAY.filled()));
    legend(&mut chart)
}

/// The time spans over which the tracker declared NLoS, s.
fn nlos_spans(fixes: &[Fix]) -> Vec<(f64, f64)> {
    let mut spans: Vec<(f64, f64)> = Vec::new();
    for w in fixes.windows(2) {
        if w[1].los {
            continue;
        }
        match spans.last_mut() {
            Some(last) if last.1 == w[0].t => last.1 = w[1].t,
            _ => spans.push((w[0].t, w[1].t)),
        }
    }
    spans
}

/// Finite min and max with a margin, or (0, 1).
fn bounds(v: &[f64], margin: f64) -> (f64, f64) {
    let lo = v.iter().copied().filter(|x| x.is_finite()).fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().filter(|x| x.is_finite()).fold(f64::NEG_INFINITY, f64::max);
    if lo.is_finite() && hi.is_finite() {
        (lo - margin, hi + margin)
    } else {
        (0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nlos_spans_join_consecutive_nlos_fixes() {
        let fix = |t: f64, los: bool| Fix {
            t,
            position: [0.0; 3],
            velocity: [0.0; 3],
            sigma: [0.0; 3],
            covariance: [[0.0; 3]; 3],
            resets: 0,
            motion: aim_tracker::motion::MotionClass::Hover,
            los,
            drone: None,
            heard: true,
            available: t,
        };
        let fixes =
            [fix(0.0, true), fix(0.1, false), fix(0.2, false), fix(0.3, true), fix(0.4, false)];
        assert_eq!(nlos_spans(&fixes), vec![(0.0, 0.2), (0.3, 0.4)]);
    }

    /// One plot of a short flight past an obstacle, rendered: the SVG carries the titles, the
    /// axis names with their units, tick numbers on every axis and every legend entry as text
    /// (drawn with the bundled font: no system font is looked up); the PNG is a real image of
    /// the stated size.
    #[test]
    fn the_plot_has_titles_axes_ticks_and_legends() {
        let site: Site = toml::from_str(
            "sample_rate_hz = 48000\nspeed_of_sound_mps = 343.2\n[[array]]\nid = 1\n\
             geometry = \"respeaker-6mic\"\nposition = [5.0, 1.0, 0.1]\nyaw_deg = 0.0\n\
             [room]\nsize = [10.0, 8.0, 4.0]\n[[obstacle]]\nname = \"shelf\"\n\
             min = [4.0, 4.0, 0.0]\nmax = [6.0, 4.5, 2.0]\nloss_db = 15.0\n",
        )
        .unwrap();
        let row = |t: f64| crate::truth::TruthRow {
            t_s: t,
            position: [2.0 + 0.5 * t, 6.0, 2.0],
            velocity: [0.5, 0.0, 0.0],
            acceleration: [0.0; 3],
            yaw_rad: 0.0,
            roll_rad: 0.0,
            pitch_rad: 0.0,
            rotor_hz: vec![],
            los: vec![true],
        };
        let truth = Truth {
            blades: 2,
            array_ids: vec![1],
            clocks: vec![],
            airframe: None,
            rows: (0..=100).map(|k| row(k as f64 * 0.1)).collect(),
        };
        // Fixes 0.4 m off in y; NLoS from 4 s to 6 s.
        let fixes: Vec<Fix> = (0..=100)
            .map(|k| {
                let t = k as f64 * 0.1;
                Fix {
                    t,
                    available: t + 0.3,
                    position: [2.0 + 0.5 * t, 6.4, 2.0],
                    velocity: [0.5, 0.0, 0.0],
                    sigma: [0.3; 3],
                    covariance: [[0.09, 0.0, 0.0], [0.0, 0.09, 0.0], [0.0, 0.0, 0.09]],
                    resets: 0,
                    motion: aim_tracker::motion::MotionClass::Horizontal,
                    los: !(40..60).contains(&k),
                    drone: None,
                    heard: true,
                }
            })
            .collect();
        let dir = std::env::temp_dir().join(format!("aim-plot-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let png = dir.join("track.png");
        plot_track(&png, &fixes, &truth, &site).unwrap();
        let svg = std::fs::read_to_string(dir.join("track.svg")).unwrap();
        let texts: Vec<String> = svg
            .split("<text")
            .skip(1)
            .filter_map(|t| Some(t.split_once('>')?.1.split_once("</text>")?.0.trim().to_string()))
            .collect();
        for want in [
            "AIM track against the truth: plan view",
            "Height against time",
            "Position error against time",
            "x east (m)",
            "y north (m)",
            "time (s)",
            "height z (m)",
            "3-D error (m)",
            "truth",
            "track (LoS)",
            "track (NLoS)",
            "arrays",
            "obstacles",
            "track",
        ] {
            assert!(texts.iter().any(|t| t == want), "no text `{want}` in {texts:?}");
        }
        assert!(texts.iter().any(|t| t.starts_with("NLoS (tracker")), "{texts:?}");
        assert!(texts.iter().any(|t| t.starts_with("|track")), "{texts:?}");
        // Tick numbers: the plan spans 0–10 m, the time axes 0–10 s, the error axis 0–1.05 m.
        let numbers: Vec<f64> = texts.iter().filter_map(|t| t.parse().ok()).collect();
        assert!(numbers.len() >= 20, "{numbers:?}");
        assert!(numbers.iter().any(|&v| v >= 8.0) && numbers.iter().any(|&v| v > 0.0 && v < 0.5));
        // The PNG: its signature and the stated width and height in the IHDR chunk.
        let bytes = std::fs::read(&png).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        let be = |i: usize| u32::from_be_bytes(bytes[i..i + 4].try_into().unwrap());
        assert_eq!((be(16), be(20)), SIZE);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_bundled_font_registers() {
        register_font().expect("DejaVu Sans parses");
    }
}
