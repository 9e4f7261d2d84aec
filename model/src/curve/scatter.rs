//! Labelled scatter charts as PNG, side by side in panels, for trade-offs (latency against
//! quality in `bench pareto`, map size against quality in `eval-map`): each panel titled, with
//! titled axes (x linear or log10, y linear), every point a dot in its own colour with its name
//! beside it, and the points on the Pareto front ringed in black and joined by a black line in
//! x order.

use std::ops::Range;
use std::path::Path;

use image::{Rgb, RgbImage};
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

use super::{
    colour, extent, font, log_axis, log_tick, number, paint, rgb, save_png, widen, Area,
    CurveError, DECADES,
};

/// One labelled point.
#[derive(Clone, Debug, PartialEq)]
pub struct ScatterPoint {
    /// The name written beside the dot.
    pub label: String,
    /// Horizontal value (must be positive on a log axis to be drawn).
    pub x: f64,
    /// Vertical value.
    pub y: f64,
    /// On the Pareto front: ringed and joined to the other front points.
    pub on_front: bool,
}

/// One panel: its title, axis titles and points.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// Title written above the panel.
    pub title: String,
    /// Title of the x axis, written below it.
    pub x_title: String,
    /// Title of the y axis, written beside it.
    pub y_title: String,
    /// A log10 x axis.
    pub log_x: bool,
    /// The points; the `i`-th is drawn in [`colour`]`(i)`.
    pub points: Vec<ScatterPoint>,
}

/// Smallest panel, pixels: room for the title, tick labels and axis titles.
const MIN_PANEL: (u32, u32) = (200, 150);
/// Radius of a point's dot and of the black ring of a front point, pixels.
const DOT: i32 = 4;
const RING: i32 = 6;
/// Largest magnitude a drawn value may have, so every axis span stays finite.
const LIMIT: f64 = 1e300;

/// The drawable x of a value: itself, or its log10 on a log axis (positive values only).
fn fx(log_x: bool, x: f64) -> Option<f64> {
    let finite = x.is_finite() && x.abs() <= LIMIT;
    match log_x {
        true => (finite && x > 0.0)
            .then(|| x.log10())
            .filter(|d| (-DECADES..=DECADES).contains(d)),
        false => finite.then_some(x),
    }
}

/// A point's position in data units (x as log10 on a log axis), if it can be drawn.
fn position(log_x: bool, p: &ScatterPoint) -> Option<(f64, f64)> {
    let y_ok = p.y.is_finite() && p.y.abs() <= LIMIT;
    fx(log_x, p.x).filter(|_| y_ok).map(|x| (x, p.y))
}

/// A panel's data ranges: every drawable point with 8% to spare on each side; x in log10 on
/// a log axis (at least 0.3 decades, points within 1e-150..1e150), y at least 1e-3 plus 5% of its
/// size.
fn fit(panel: &Panel) -> ((f64, f64), (f64, f64)) {
    let at = || panel.points.iter().filter_map(|p| position(panel.log_x, p));
    let pad = |(lo, hi): (f64, f64)| {
        let span = hi - lo;
        (lo - 0.08 * span, hi + 0.08 * span)
    };
    let min_x = if panel.log_x { 0.3 } else { 1.0 };
    let mut x = extent(at().map(|p| p.0)).map_or((0.0, 1.0), |r| pad(widen(r, min_x)));
    if panel.log_x {
        // Plotters' log axis divides its ends: keep their ratio a finite f64.
        x = (x.0.max(-DECADES - 2.0), x.1.min(DECADES + 2.0));
    }
    let y = extent(at().map(|p| p.1)).map_or((0.0, 1.0), |r| {
        pad(widen(r, 1e-3 + 0.05 * r.0.abs().max(r.1.abs())))
    });
    (x, y)
}

/// Where a panel's plot area landed: its pixel ranges on the canvas.
#[derive(Clone, Debug, PartialEq)]
struct Frame {
    x_px: Range<i32>,
    y_px: Range<i32>,
}

/// Whether two rectangles (left, top, right, bottom) overlap.
fn overlaps(a: (i32, i32, i32, i32), b: (i32, i32, i32, i32)) -> bool {
    a.0 <= b.2 && b.0 <= a.2 && a.1 <= b.3 && b.1 <= a.3
}

/// A colour darkened for text, so light palette colours stay legible on white.
fn darker(c: Rgb<u8>) -> Rgb<u8> {
    Rgb(c.0.map(|v| (v as u16 * 3 / 4) as u8))
}

/// Draws `panel` on `area` with `x_axis` as its x coordinate (linear or log, over `x` in
/// values) and `y` as its y range; `x_of` turns a point's drawable x back into a value.
fn draw_panel<XC>(
    area: &Area,
    panel: &Panel,
    x_axis: XC,
    y: (f64, f64),
    x_of: impl Fn(f64) -> f64,
) -> Result<Frame, CurveError>
where
    XC: AsRangedCoord<Value = f64>,
    XC::CoordDescType: ValueFormatter<f64>,
{
    let log_x = panel.log_x;
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, font(16, BLACK))
        .margin(10)
        .x_label_area_size(42)
        .y_label_area_size(62)
        .build_cartesian_2d(x_axis, y.0..y.1)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_title.as_str())
        .y_desc(panel.y_title.as_str())
        .x_label_formatter(&|v| match log_x {
            true => log_tick(*v),
            false => number(*v),
        })
        .y_label_formatter(&|v| number(*v))
        .label_style(font(12, BLACK))
        .axis_desc_style(font(14, BLACK))
        .bold_line_style(RGBColor(215, 215, 215))
        .light_line_style(RGBColor(242, 242, 242))
        .draw()?;
    let at = |p: &ScatterPoint| position(panel.log_x, p).map(|(x, y)| (x_of(x), y));
    let mut front: Vec<(f64, f64)> = panel
        .points
        .iter()
        .filter(|p| p.on_front)
        .filter_map(at)
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart.draw_series(LineSeries::new(front, BLACK.stroke_width(2)))?;
    let mut placed = Vec::new();
    for (i, p) in panel.points.iter().enumerate() {
        let Some(v) = at(p) else { continue };
        if p.on_front {
            chart.draw_series([Circle::new(v, RING, BLACK.filled())])?;
        }
        chart.draw_series([Circle::new(v, DOT, rgb(colour(i)).filled())])?;
        let (x, y) = chart.backend_coord(&v);
        placed.push((x - RING, y - RING, x + RING, y + RING));
    }
    let (x_px, y_px) = chart.plotting_area().get_pixel_range();
    let dots: Vec<(usize, (i32, i32))> = panel
        .points
        .iter()
        .enumerate()
        .filter_map(|(i, p)| at(p).map(|v| (i, chart.backend_coord(&v))))
        .collect();
    drop(chart);
    let frame = Frame { x_px, y_px };
    let origin = area.get_base_pixel();
    for (i, (x, y)) in dots {
        let label = panel.points[i].label.as_str();
        let style = font(12, rgb(darker(colour(i))));
        let spot = place_label(area, &frame, &mut placed, label, &style, (x, y))?;
        area.draw(&Text::new(
            label,
            (spot.0 - origin.0, spot.1 - origin.1),
            style,
        ))?;
    }
    Ok(frame)
}

/// Where to write `label` (its top-left corner on the canvas) for the dot at `(x, y)`:
/// beside the dot first, then above or below it, then stepping away up and down on either
/// side, so crowded clusters still get every label apart; inside the plot area when it fits.
fn place_label(
    area: &Area,
    f: &Frame,
    placed: &mut Vec<(i32, i32, i32, i32)>,
    label: &str,
    style: &TextStyle,
    (x, y): (i32, i32),
) -> Result<(i32, i32), CurveError> {
    let (w, h) = area.estimate_text_size(label, style)?;
    let (w, h) = (w as i32, h as i32);
    let mut candidates = vec![
        (x + RING + 2, y - h / 2),
        (x - RING - 2 - w, y - h / 2),
        (x - w / 2, y - RING - 2 - h),
        (x - w / 2, y + RING + 2),
    ];
    for k in 1..=8 {
        for dy in [-k * (h + 2), k * (h + 2)] {
            candidates.push((x + RING + 2, y - h / 2 + dy));
            candidates.push((x - RING - 2 - w, y - h / 2 + dy));
        }
    }
    let inside = |&(lx, ly): &(i32, i32)| {
        lx > f.x_px.start && lx + w < f.x_px.end && ly > f.y_px.start && ly + h < f.y_px.end
    };
    let rect = |(lx, ly): (i32, i32)| (lx - 1, ly - 1, lx + w + 1, ly + h + 1);
    let spot = candidates
        .iter()
        .copied()
        .find(|c| inside(c) && !placed.iter().any(|r| overlaps(*r, rect(*c))))
        .or_else(|| candidates.iter().copied().find(inside))
        .unwrap_or(candidates[0]);
    placed.push(rect(spot));
    Ok(spot)
}

/// The panels side by side, each `panel_width` x `height` pixels (one blank panel when there
/// are none). Panels under 200 x 150 pixels are refused with [`CurveError::Canvas`].
pub fn render(panels: &[Panel], panel_width: u32, height: u32) -> Result<RgbImage, CurveError> {
    render_frames(panels, panel_width, height).map(|(img, _)| img)
}

/// [`render`], with where each panel's plot area landed.
fn render_frames(
    panels: &[Panel],
    panel_width: u32,
    height: u32,
) -> Result<(RgbImage, Vec<Frame>), CurveError> {
    if panel_width < MIN_PANEL.0 {
        return Err(CurveError::Canvas {
            width: panel_width,
            height,
            min_width: MIN_PANEL.0,
            min_height: MIN_PANEL.1,
        });
    }
    let width = panel_width.saturating_mul(panels.len().max(1) as u32);
    paint(width, height, (MIN_PANEL.0, MIN_PANEL.1), |root| {
        root.fill(&WHITE)?;
        let areas = root.split_evenly((1, panels.len().max(1)));
        let mut frames = Vec::new();
        for (panel, area) in panels.iter().zip(&areas) {
            let (x, y) = fit(panel);
            let frame = match panel.log_x {
                true => draw_panel(area, panel, log_axis(x), y, |v| 10f64.powf(v))?,
                false => draw_panel(area, panel, x.0..x.1, y, |v| v)?,
            };
            frames.push(frame);
        }
        Ok(frames)
    })
}

/// Writes [`render`]'s chart to `path` as PNG.
pub fn write_png(
    path: &Path,
    panels: &[Panel],
    panel_width: u32,
    height: u32,
) -> Result<(), CurveError> {
    save_png(&render(panels, panel_width, height)?, path)
}

#[cfg(test)]
mod tests;
