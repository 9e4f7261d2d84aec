//! Labelled scatter charts as PNG, side by side in panels, for trade-offs (latency against
//! quality in `bench pareto`, map size against quality in `eval-map`): every point a dot in
//! its own colour with its name beside it, the points on the Pareto front joined by a black
//! line in x order, the x axis linear or log10 (ticks at 1, 2 and 5 times a decade), the y
//! axis linear; tick values and axis titles written with [`super::glyphs`].

use std::path::Path;

use image::{Rgb, RgbImage};

use super::glyphs::{self, GLYPH};
use super::{colour, extent, line, round_step, save_png, square, Axes, CurveError, BLACK, WHITE};

/// One labelled point.
#[derive(Clone, Debug, PartialEq)]
pub struct ScatterPoint {
    /// The name written beside the dot.
    pub label: String,
    /// Horizontal value (must be positive on a log axis to be drawn).
    pub x: f64,
    /// Vertical value.
    pub y: f64,
    /// Joined to the other front points by the front line.
    pub on_front: bool,
}

/// One panel: its points and axis titles.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// Title of the x axis, written below it.
    pub x_title: String,
    /// Title of the y axis, written above the box.
    pub y_title: String,
    /// A log10 x axis.
    pub log_x: bool,
    /// The points; the `i`-th is drawn in [`colour`]`(i)`.
    pub points: Vec<ScatterPoint>,
}

const MARGIN_LEFT: i64 = 52;
const MARGIN_RIGHT: i64 = 14;
const MARGIN_TOP: i64 = 22;
const MARGIN_BOTTOM: i64 = 36;
const TICK: i64 = 5;
const DOT: i64 = 5;

/// A panel's axes box on the canvas and the data ranges it spans (the loss curve's [`Axes`],
/// x already log10 on a log axis), and whether x is on a log axis.
struct Frame {
    axes: Axes,
    log_x: bool,
}

impl Frame {
    fn fit(panel: &Panel, x0: i64, width: i64, height: i64) -> Self {
        let xs = || {
            panel
                .points
                .iter()
                .filter(|p| p.y.is_finite())
                .filter_map(|p| fx(panel.log_x, p.x))
        };
        let ys = || {
            panel
                .points
                .iter()
                .filter(|p| fx(panel.log_x, p.x).is_some())
                .map(|p| p.y)
                .filter(|y| y.is_finite())
        };
        let pad = |(lo, hi): (f64, f64), min_span: f64| {
            let span = (hi - lo).max(min_span);
            (lo - 0.08 * span, hi + 0.08 * span)
        };
        let x = extent(xs()).map_or((0.0, 1.0), |r| pad(r, if panel.log_x { 0.3 } else { 1.0 }));
        let y = extent(ys()).map_or((0.0, 1.0), |r| pad(r, 1e-3 + 0.05 * r.1.abs()));
        let axes = Axes {
            left: x0 + MARGIN_LEFT,
            right: (x0 + width - 1 - MARGIN_RIGHT).max(x0 + MARGIN_LEFT + 1),
            top: MARGIN_TOP,
            bottom: (height - 1 - MARGIN_BOTTOM).max(MARGIN_TOP + 1),
            x,
            y,
        };
        Self {
            axes,
            log_x: panel.log_x,
        }
    }
}

/// The drawable x of a value: itself, or its log10 on a log axis (positive values only).
fn fx(log_x: bool, x: f64) -> Option<f64> {
    match log_x {
        true => (x.is_finite() && x > 0.0).then(|| x.log10()),
        false => x.is_finite().then_some(x),
    }
}

/// A tick value written short: no trailing zeros, at most 3 decimals.
fn tick_text(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

fn draw_frame(img: &mut RgbImage, f: &Frame, panel: &Panel) {
    f.axes.draw_box(img);
    let (l, r, t, b) = (f.axes.left, f.axes.right, f.axes.top, f.axes.bottom);
    // x ticks: 1, 2, 5 per decade on a log axis, round steps on a linear one.
    let ticks: Vec<f64> = match f.log_x {
        true => (f.axes.x.0.floor() as i64..=f.axes.x.1.ceil() as i64)
            .flat_map(|d| [1.0, 2.0, 5.0].map(|m| (m * 10f64.powi(d as i32)).log10()))
            .filter(|v| (f.axes.x.0..=f.axes.x.1).contains(v))
            .collect(),
        false => steps(f.axes.x),
    };
    for v in ticks {
        let x = f.axes.col(v);
        line(img, (x, b), (x, b + TICK), BLACK);
        let label = tick_text(if f.log_x { 10f64.powf(v) } else { v });
        glyphs::text(
            img,
            x - glyphs::width(&label) / 2,
            b + TICK + 2,
            &label,
            BLACK,
        );
    }
    for v in steps(f.axes.y) {
        let y = f.axes.row(v);
        line(img, (l - TICK, y), (l, y), BLACK);
        let label = tick_text(v);
        glyphs::text(
            img,
            l - TICK - 2 - glyphs::width(&label),
            y - GLYPH.1 / 2,
            &label,
            BLACK,
        );
    }
    let xt = &panel.x_title;
    glyphs::text(
        img,
        (l + r) / 2 - glyphs::width(xt) / 2,
        b + TICK + 14,
        xt,
        BLACK,
    );
    glyphs::text(img, l, t - GLYPH.1 - 6, &panel.y_title, BLACK);
}

/// Round-step tick values inside `range`.
fn steps(range: (f64, f64)) -> Vec<f64> {
    let step = round_step(range.1 - range.0);
    let (first, last) = (
        (range.0 / step).ceil() as i64,
        (range.1 / step).floor() as i64,
    );
    (first..=last).map(|k| k as f64 * step).collect()
}

/// Whether two rectangles (left, top, right, bottom) overlap.
fn overlaps(a: (i64, i64, i64, i64), b: (i64, i64, i64, i64)) -> bool {
    a.0 <= b.2 && b.0 <= a.2 && a.1 <= b.3 && b.1 <= a.3
}

fn draw_points(img: &mut RgbImage, f: &Frame, panel: &Panel) {
    let at = |p: &ScatterPoint| {
        let x = fx(f.log_x, p.x).filter(|_| p.y.is_finite())?;
        Some((f.axes.col(x), f.axes.row(p.y)))
    };
    let mut front: Vec<(i64, i64)> = panel
        .points
        .iter()
        .filter(|p| p.on_front)
        .filter_map(at)
        .collect();
    front.sort();
    for w in front.windows(2) {
        line(img, w[0], w[1], BLACK);
    }
    let mut placed: Vec<(i64, i64, i64, i64)> = Vec::new();
    for (i, p) in panel.points.iter().enumerate() {
        let Some((x, y)) = at(p) else { continue };
        if p.on_front {
            square(img, x - DOT / 2 - 1, y - DOT / 2 - 1, DOT + 2, BLACK);
        }
        square(img, x - DOT / 2, y - DOT / 2, DOT, colour(i));
        placed.push((x - DOT, y - DOT, x + DOT, y + DOT));
    }
    for (i, p) in panel.points.iter().enumerate() {
        let Some((x, y)) = at(p) else { continue };
        let w = glyphs::width(&p.label);
        let h = GLYPH.1;
        // Beside the dot first, then above or below it, then stepping away up and down on
        // either side, so crowded clusters still get every label apart.
        let mut candidates = vec![
            (x + DOT + 1, y - h / 2),
            (x - DOT - 1 - w, y - h / 2),
            (x - w / 2, y - DOT - 1 - h),
            (x - w / 2, y + DOT + 1),
        ];
        for k in 1..=8 {
            for dy in [-k * (h + 2), k * (h + 2)] {
                candidates.push((x + DOT + 1, y - h / 2 + dy));
                candidates.push((x - DOT - 1 - w, y - h / 2 + dy));
            }
        }
        let inside = |&(lx, ly): &(i64, i64)| {
            lx > f.axes.left && lx + w < f.axes.right && ly > f.axes.top && ly + h < f.axes.bottom
        };
        let rect = |(lx, ly): (i64, i64)| (lx - 1, ly - 1, lx + w + 1, ly + h + 1);
        let spot = candidates
            .iter()
            .copied()
            .find(|c| inside(c) && !placed.iter().any(|r| overlaps(*r, rect(*c))))
            .or_else(|| candidates.iter().copied().find(inside))
            .unwrap_or(candidates[0]);
        placed.push(rect(spot));
        glyphs::text(img, spot.0, spot.1, &p.label, darker(colour(i)));
    }
}

/// A colour darkened for text, so light palette colours stay legible on white.
fn darker(c: Rgb<u8>) -> Rgb<u8> {
    Rgb(c.0.map(|v| (v as u16 * 3 / 4) as u8))
}

/// The panels side by side, each `panel_width` x `height` pixels.
pub fn render(panels: &[Panel], panel_width: u32, height: u32) -> RgbImage {
    let width = panel_width * panels.len().max(1) as u32;
    let mut img = RgbImage::from_pixel(width, height, WHITE);
    for (k, panel) in panels.iter().enumerate() {
        let x0 = k as i64 * panel_width as i64;
        let f = Frame::fit(panel, x0, panel_width as i64, height as i64);
        draw_frame(&mut img, &f, panel);
        draw_points(&mut img, &f, panel);
    }
    img
}

/// Writes [`render`]'s chart to `path` as PNG.
pub fn write_png(
    path: &Path,
    panels: &[Panel],
    panel_width: u32,
    height: u32,
) -> Result<(), CurveError> {
    save_png(&render(panels, panel_width, height), path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(label: &str, x: f64, y: f64, on_front: bool) -> ScatterPoint {
        ScatterPoint {
            label: label.into(),
            x,
            y,
            on_front,
        }
    }

    #[test]
    fn points_sit_where_their_values_say_with_labels_and_the_front_line() {
        let panel = Panel {
            x_title: "LATENCY MS".into(),
            y_title: "PSNR DB".into(),
            log_x: true,
            points: vec![
                point("FAST", 10.0, 15.0, true),
                point("SLOW", 1000.0, 25.0, true),
                point("BAD", 500.0, 14.0, false),
                point("NAN", f64::NAN, 20.0, false),
            ],
        };
        let img = render(&[panel.clone(), panel], 400, 300);
        assert_eq!(img.dimensions(), (800, 300));
        let find = |c: Rgb<u8>, x_range: std::ops::Range<u32>| {
            let px: Vec<(u32, u32)> = img
                .enumerate_pixels()
                .filter(|p| *p.2 == c && x_range.contains(&p.0))
                .map(|p| (p.0, p.1))
                .collect();
            let n = px.len().max(1) as u32;
            let sx: u32 = px.iter().map(|p| p.0).sum();
            let sy: u32 = px.iter().map(|p| p.1).sum();
            (px.len(), sx / n, sy / n)
        };
        // Dots: the fast one left and low, the slow one right and high, both in panel 1.
        let (n0, x0, y0) = find(colour(0), 0..400);
        let (n1, x1, y1) = find(colour(1), 0..400);
        assert_eq!((n0, n1), (25, 25));
        assert!(x0 < 120 && x1 > 300 && y0 > y1, "{x0} {y0} {x1} {y1}");
        // The same dots again in panel 2, 400 px to the right.
        assert_eq!(find(colour(0), 400..800).1, x0 + 400);
        // The NaN point draws nothing.
        assert_eq!(find(colour(3), 0..800).0, 0);
        // Labels in a darker colour exist for drawn points.
        assert!(find(darker(colour(2)), 0..400).0 > 10);
        // The front line passes between the two front dots.
        let mid = ((x0 + x1) / 2, (y0 + y1) / 2);
        let near_black =
            (mid.1.saturating_sub(3)..mid.1 + 4).any(|y| *img.get_pixel(mid.0, y) == BLACK);
        assert!(near_black, "front line near {mid:?}");
    }

    #[test]
    fn empty_and_degenerate_panels_do_not_panic() {
        let empty = Panel {
            x_title: String::new(),
            y_title: String::new(),
            log_x: false,
            points: vec![point("ONE", 3.0, 3.0, true)],
        };
        assert_eq!(
            render(std::slice::from_ref(&empty), 100, 60).dimensions(),
            (100, 60)
        );
        assert_eq!(render(&[], 10, 10).dimensions(), (10, 10));
        assert_eq!(tick_text(2.500), "2.5");
        assert_eq!(tick_text(-0.0001), "0");
        assert_eq!(tick_text(100.0), "100");
    }
}
