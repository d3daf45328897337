//! A PNG of the track against the truth: top view (x–y) above, height against time below.
//! Truth black, track red (LoS fixes) and orange (NLoS fixes), arrays green, obstacles grey.
//! Pixels only (no text), so no font is needed.

use std::path::Path;

use aim_tracker::tracker::Fix;
use anyhow::Context as _;
use plotters::prelude::*;

use crate::site::Site;
use crate::truth::Truth;

/// Width and height of the image, pixels.
const SIZE: (u32, u32) = (800, 1000);
const MARGIN: i32 = 20;

/// Draws the plot into `path` (PNG).
pub fn plot_track(path: &Path, fixes: &[Fix], truth: &Truth, site: &Site) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}")).context("drawing")?;
    let (top, bottom) = root.split_vertically(SIZE.0);
    // Top view: a square region holding the room (or the data) with a margin.
    let mut xs: Vec<f64> = truth
        .rows
        .iter()
        .flat_map(|r| [r.position[0]])
        .chain(fixes.iter().map(|f| f.position[0]))
        .collect();
    let mut ys: Vec<f64> = truth
        .rows
        .iter()
        .flat_map(|r| [r.position[1]])
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
    let (x0, x1) = bounds(&xs);
    let (y0, y1) = bounds(&ys);
    let span = (x1 - x0).max(y1 - y0).max(1.0);
    let px = (SIZE.0 as i32 - 2 * MARGIN) as f64 / span;
    let to_px = |x: f64, y: f64| {
        (MARGIN + ((x - x0) * px) as i32, SIZE.0 as i32 - MARGIN - ((y - y0) * px) as i32)
    };
    let err = |e: DrawingAreaErrorKind<_>| anyhow::anyhow!("{e}");
    // 1 m grid.
    let grey = RGBColor(230, 230, 230);
    for k in (x0.floor() as i64)..=(x0 + span).ceil() as i64 {
        top.draw(&PathElement::new(vec![to_px(k as f64, y0), to_px(k as f64, y0 + span)], grey))
            .map_err(err)?;
    }
    for k in (y0.floor() as i64)..=(y0 + span).ceil() as i64 {
        top.draw(&PathElement::new(vec![to_px(x0, k as f64), to_px(x0 + span, k as f64)], grey))
            .map_err(err)?;
    }
    for o in &site.obstacles {
        top.draw(&Rectangle::new(
            [to_px(o.min[0], o.max[1]), to_px(o.max[0], o.min[1])],
            RGBColor(170, 170, 170).filled(),
        ))
        .map_err(err)?;
    }
    let truth_path: Vec<(i32, i32)> =
        truth.rows.iter().map(|r| to_px(r.position[0], r.position[1])).collect();
    top.draw(&PathElement::new(truth_path, BLACK.stroke_width(2))).map_err(err)?;
    for w in fixes.windows(2) {
        let colour = if w[1].los { RED } else { RGBColor(255, 150, 0) };
        top.draw(&PathElement::new(
            vec![
                to_px(w[0].position[0], w[0].position[1]),
                to_px(w[1].position[0], w[1].position[1]),
            ],
            colour.stroke_width(2),
        ))
        .map_err(err)?;
    }
    for a in &site.arrays {
        let (cx, cy) = to_px(a.position[0], a.position[1]);
        top.draw(&Rectangle::new(
            [(cx - 6, cy - 6), (cx + 6, cy + 6)],
            RGBColor(0, 160, 0).filled(),
        ))
        .map_err(err)?;
    }
    // Height against time.
    let t0 = truth.rows.first().map_or(0.0, |r| r.t_s);
    let t1 = truth.rows.last().map_or(1.0, |r| r.t_s).max(t0 + 1.0);
    let zs: Vec<f64> = truth
        .rows
        .iter()
        .map(|r| r.position[2])
        .chain(fixes.iter().map(|f| f.position[2]))
        .collect();
    let (z0, z1) = bounds(&zs);
    let (w, h) = (SIZE.0 as i32 - 2 * MARGIN, (SIZE.1 - SIZE.0) as i32 - 2 * MARGIN);
    let to_tz = |t: f64, z: f64| {
        (
            MARGIN + ((t - t0) / (t1 - t0) * w as f64) as i32,
            MARGIN + h - ((z - z0) / (z1 - z0).max(0.5) * h as f64) as i32,
        )
    };
    for k in (z0.floor() as i64)..=z1.ceil() as i64 {
        bottom
            .draw(&PathElement::new(vec![to_tz(t0, k as f64), to_tz(t1, k as f64)], grey))
            .map_err(err)?;
    }
    bottom
        .draw(&PathElement::new(
            truth.rows.iter().map(|r| to_tz(r.t_s, r.position[2])).collect::<Vec<_>>(),
            BLACK.stroke_width(2),
        ))
        .map_err(err)?;
    bottom
        .draw(&PathElement::new(
            fixes.iter().map(|f| to_tz(f.t, f.position[2])).collect::<Vec<_>>(),
            RED.stroke_width(2),
        ))
        .map_err(err)?;
    root.present()
        .map_err(|e| anyhow::anyhow!("{e}"))
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Finite min and max with a margin of 0.5 m, or (0, 1).
fn bounds(v: &[f64]) -> (f64, f64) {
    let lo = v.iter().copied().filter(|x| x.is_finite()).fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().filter(|x| x.is_finite()).fold(f64::NEG_INFINITY, f64::max);
    if lo.is_finite() && hi.is_finite() {
        (lo - 0.5, hi + 0.5)
    } else {
        (0.0, 1.0)
    }
}
