//! Loss curves as PNG line charts, so a training run can be watched without a plotting stack:
//! one or more named series of (step, value) points drawn on a white canvas inside an axes
//! box, the value on a log10 axis (losses fall over decades), with tick marks (a long one per
//! decade and per round step, short ones at 2..9 times a decade) and a legend of coloured
//! squares in series order. No text is drawn on loss curves; the legend's order is the
//! series' order. [`plot_csv`] draws chosen columns of a CSV log whose first column is
//! `step` ([`csv`]). [`scatter`] draws labelled trade-off charts (with a Pareto front) on
//! the same primitives, writing text with the bitmap font in [`glyphs`].

pub mod csv;
pub mod glyphs;
pub mod scatter;

use std::path::{Path, PathBuf};

use image::{Rgb, RgbImage};

pub use csv::{parse_csv, plot_csv};

/// One named line of a chart: (step, value) points. Points whose value is not a positive
/// finite number (or whose step is not finite) are skipped, since the y axis is log10.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// The series' name (a CSV column, for instance); the legend shows its colour only.
    pub name: String,
    /// (step, value) points in the order they are joined.
    pub points: Vec<(f64, f64)>,
}

/// Why a curve could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum CurveError {
    /// The CSV log could not be read.
    #[error("reading {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The PNG could not be encoded or written.
    #[error("writing {path}: {source}")]
    Image {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: image::ImageError,
    },
    /// The CSV log is malformed (line 1 is the header).
    #[error("CSV line {line}: {message}")]
    Parse {
        /// 1-based line number in the file.
        line: usize,
        /// What is wrong there.
        message: String,
    },
}

const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
const BLACK: Rgb<u8> = Rgb([0, 0, 0]);
/// Matplotlib's `tab10`: ten colours told apart easily, none white or black.
const PALETTE: [[u8; 3]; 10] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
];
/// Margins around the axes box, pixels: room for the ticks and, at the top, the legend.
const MARGIN_LEFT: i64 = 20;
const MARGIN_RIGHT: i64 = 12;
const MARGIN_TOP: i64 = 20;
const MARGIN_BOTTOM: i64 = 20;
/// Legend squares: side, distance between their left edges, top edge.
const LEGEND_SIDE: i64 = 8;
const LEGEND_PITCH: i64 = 14;
const LEGEND_TOP: i64 = 6;
/// Tick lengths, pixels, drawn outwards from the box.
const MAJOR_TICK: i64 = 6;
const MINOR_TICK: i64 = 3;
/// About this many round steps get a tick on the x axis.
const X_TICKS: f64 = 6.0;

/// The colour of the `index`-th series (in the lines and the legend); cycles after ten.
pub fn colour(index: usize) -> Rgb<u8> {
    Rgb(PALETTE[index % PALETTE.len()])
}

/// The points of `series` that can be drawn, as (step, log10 value).
fn visible(series: &Series) -> impl Iterator<Item = (f64, f64)> + '_ {
    series
        .points
        .iter()
        .filter(|(s, v)| s.is_finite() && v.is_finite() && *v > 0.0)
        .map(|&(s, v)| (s, v.log10()))
}

/// Smallest and largest of `values`, or `None` when there are none.
fn extent(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.fold(None, |r, v| match r {
        None => Some((v, v)),
        Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
    })
}

/// The axes box on the canvas and the data ranges it spans (here x in steps, y in log10
/// value; [`scatter`] fills it with its own ranges).
struct Axes {
    left: i64,
    right: i64,
    top: i64,
    bottom: i64,
    x: (f64, f64),
    y: (f64, f64),
}

impl Axes {
    /// Fits every visible point: x from the first to the last step, y over whole decades.
    /// Without any point the ranges are [0, 1] and one decade.
    fn fit(series: &[Series], width: u32, height: u32) -> Self {
        let points = || series.iter().flat_map(visible);
        let x = match extent(points().map(|p| p.0)) {
            Some((lo, hi)) if lo < hi => (lo, hi),
            Some((s, _)) => (s - 0.5, s + 0.5),
            None => (0.0, 1.0),
        };
        let y = match extent(points().map(|p| p.1)) {
            Some((lo, hi)) => (lo.floor(), hi.ceil().max(lo.floor() + 1.0)),
            None => (0.0, 1.0),
        };
        Self {
            left: MARGIN_LEFT,
            right: (width as i64 - 1 - MARGIN_RIGHT).max(MARGIN_LEFT + 1),
            top: MARGIN_TOP,
            bottom: (height as i64 - 1 - MARGIN_BOTTOM).max(MARGIN_TOP + 1),
            x,
            y,
        }
    }

    /// Draws the box's four sides in black.
    fn draw_box(&self, img: &mut RgbImage) {
        let (l, r, t, b) = (self.left, self.right, self.top, self.bottom);
        for (p, q) in [
            ((l, t), (r, t)),
            ((r, t), (r, b)),
            ((r, b), (l, b)),
            ((l, b), (l, t)),
        ] {
            line(img, p, q, BLACK);
        }
    }

    /// Column of x value `s`.
    fn col(&self, s: f64) -> i64 {
        let t = (s - self.x.0) / (self.x.1 - self.x.0);
        self.left + (t * (self.right - self.left) as f64).round() as i64
    }

    /// Row of y value `y` (larger values higher up).
    fn row(&self, y: f64) -> i64 {
        let t = (y - self.y.0) / (self.y.1 - self.y.0);
        self.bottom - (t * (self.bottom - self.top) as f64).round() as i64
    }
}

/// Sets a pixel, ignoring any outside the canvas (small canvases clip, never panic).
fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if (0..img.width() as i64).contains(&x) && (0..img.height() as i64).contains(&y) {
        img.put_pixel(x as u32, y as u32, c);
    }
}

/// A one-pixel line from `a` to `b` (Bresenham).
fn line(img: &mut RgbImage, a: (i64, i64), b: (i64, i64), c: Rgb<u8>) {
    let (dx, dy) = ((b.0 - a.0).abs(), -(b.1 - a.1).abs());
    let (sx, sy) = ((b.0 - a.0).signum(), (b.1 - a.1).signum());
    let (mut x, mut y, mut err) = (a.0, a.1, dx + dy);
    loop {
        put(img, x, y, c);
        if (x, y) == b {
            return;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x += sx;
        }
        if e2 <= dx {
            err += dx;
            y += sy;
        }
    }
}

/// A filled square of side `side` with its top-left corner at `(x, y)`.
fn square(img: &mut RgbImage, x: i64, y: i64, side: i64, c: Rgb<u8>) {
    for j in y..y + side {
        line(img, (x, j), (x + side - 1, j), c);
    }
}

/// A round step (1, 2 or 5 times a power of ten) giving about [`X_TICKS`] ticks over `span`.
fn round_step(span: f64) -> f64 {
    let raw = span / X_TICKS;
    let decade = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|&s| s >= raw)
        .unwrap_or(10.0 * decade)
}

/// The axes box and its ticks: on the left a long tick per decade and short ones at 2..9
/// times it, below a long tick per round step.
fn draw_axes(img: &mut RgbImage, ax: &Axes) {
    ax.draw_box(img);
    let (l, b) = (ax.left, ax.bottom);
    let (lowest, highest) = (ax.y.0 as i64, ax.y.1 as i64);
    for decade in lowest..=highest {
        let y = ax.row(decade as f64);
        line(img, (l - MAJOR_TICK, y), (l, y), BLACK);
        for m in (2..=9).filter(|_| decade < highest) {
            let y = ax.row(decade as f64 + (m as f64).log10());
            line(img, (l - MINOR_TICK, y), (l, y), BLACK);
        }
    }
    let step = round_step(ax.x.1 - ax.x.0);
    let first = (ax.x.0 / step).ceil() as i64;
    let last = (ax.x.1 / step).floor() as i64;
    for k in first..=last {
        let x = ax.col(k as f64 * step);
        line(img, (x, b), (x, b + MAJOR_TICK), BLACK);
    }
}

/// One series: its visible points joined in order, a lone point as a 3x3 dot.
fn draw_series(img: &mut RgbImage, ax: &Axes, series: &Series, c: Rgb<u8>) {
    let pixels: Vec<(i64, i64)> = visible(series)
        .map(|(s, y)| (ax.col(s), ax.row(y)))
        .collect();
    match pixels.as_slice() {
        [] => {}
        [(x, y)] => square(img, x - 1, y - 1, 3, c),
        _ => pixels.windows(2).for_each(|w| line(img, w[0], w[1], c)),
    }
}

/// The chart of `series` on a `width` x `height` canvas (see the module documentation).
/// Empty series, or series with no drawable point, still get their legend square.
pub fn render(series: &[Series], width: u32, height: u32) -> RgbImage {
    let mut img = RgbImage::from_pixel(width, height, WHITE);
    let ax = Axes::fit(series, width, height);
    draw_axes(&mut img, &ax);
    for (i, s) in series.iter().enumerate() {
        draw_series(&mut img, &ax, s, colour(i));
        let x = ax.left + i as i64 * LEGEND_PITCH;
        square(&mut img, x, LEGEND_TOP, LEGEND_SIDE, colour(i));
    }
    img
}

/// Writes the chart of `series` (see [`render`]) to `path` as PNG.
pub fn write_png(
    path: &Path,
    series: &[Series],
    width: u32,
    height: u32,
) -> Result<(), CurveError> {
    save_png(&render(series, width, height), path)
}

/// Saves a drawn chart as PNG, naming the file in the error (every chart of this module).
fn save_png(img: &RgbImage, path: &Path) -> Result<(), CurveError> {
    img.save_with_format(path, image::ImageFormat::Png)
        .map_err(|source| CurveError::Image {
            path: path.to_path_buf(),
            source,
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(name: &str, points: &[(f64, f64)]) -> Series {
        Series {
            name: name.into(),
            points: points.to_vec(),
        }
    }

    /// Rows where colour `c` appears.
    fn rows_of(img: &RgbImage, c: Rgb<u8>) -> Vec<u32> {
        let mut rows: Vec<u32> = img
            .enumerate_pixels()
            .filter(|p| *p.2 == c)
            .map(|p| p.1)
            .collect();
        rows.dedup();
        rows
    }

    #[test]
    fn a_chart_of_two_flat_series_draws_each_in_its_colour_at_its_height() {
        let steps = |v: f64| (0..=100).map(|s| (s as f64, v)).collect::<Vec<_>>();
        let img = render(
            &[series("a", &steps(3.0)), series("b", &steps(0.3))],
            320,
            200,
        );
        assert_eq!(img.dimensions(), (320, 200));
        for (x, y) in [(0, 0), (319, 199), (0, 199), (319, 0), (160, 190)] {
            assert_eq!(*img.get_pixel(x, y), WHITE, "({x}, {y})");
        }
        // Decades 0.1 to 10 over rows 20..=179: 3 is near row 62, 0.3 near row 141.
        let (a, b) = (rows_of(&img, colour(0)), rows_of(&img, colour(1)));
        let line_row = |rows: &[u32]| *rows.iter().max().unwrap();
        assert!((60..=64).contains(&line_row(&a)), "{a:?}");
        assert!((139..=143).contains(&line_row(&b)), "{b:?}");
        // The axes box is black.
        assert_eq!(*img.get_pixel(MARGIN_LEFT as u32, 100), BLACK);
        assert_eq!(*img.get_pixel(160, MARGIN_TOP as u32), BLACK);
    }

    #[test]
    fn legend_squares_follow_series_order_even_for_empty_series() {
        let empty = series("empty", &[]);
        let skipped = series("non-positive", &[(0.0, 0.0), (1.0, -2.0), (2.0, f64::NAN)]);
        let lone = series("lone", &[(5.0, 1e-3)]);
        let img = render(&[empty, skipped, lone], 200, 120);
        for i in 0..3 {
            let x = (MARGIN_LEFT + i * LEGEND_PITCH + LEGEND_SIDE / 2) as u32;
            let y = (LEGEND_TOP + LEGEND_SIDE / 2) as u32;
            assert_eq!(
                *img.get_pixel(x, y),
                colour(i as usize),
                "legend square {i}"
            );
        }
        // The lone point is a 3x3 dot (plus its legend square); the others draw nothing more.
        let count = |c| img.pixels().filter(|&&p| p == c).count() as i64;
        assert_eq!(count(colour(2)), 9 + LEGEND_SIDE * LEGEND_SIDE);
        assert_eq!(count(colour(0)), LEGEND_SIDE * LEGEND_SIDE);
        assert_eq!(count(colour(1)), LEGEND_SIDE * LEGEND_SIDE);
    }

    #[test]
    fn nothing_to_draw_and_tiny_canvases_do_not_panic() {
        assert_eq!(render(&[], 64, 48).dimensions(), (64, 48));
        assert_eq!(
            render(&[series("a", &[(0.0, 1.0), (1.0, 2.0)])], 5, 5).dimensions(),
            (5, 5)
        );
        assert_eq!(render(&[series("a", &[])], 0, 0).dimensions(), (0, 0));
    }
}
