//! PNG charts drawn with plotters (the field's maintained plotting crate, so axes, tick labels,
//! titles and legends come from it rather than from hand-set pixels), with text from the
//! DejaVu Sans font embedded in the binary: no system font is read and nothing is fetched.
//!
//! Loss curves ([`render`], [`write_png`]): one or more named series of (step, value) points
//! as lines, the step on a linear x axis titled `step`, the value on a log10 y axis (losses
//! fall over decades) titled with the series' name, and a legend of the series' names in their
//! colours. [`plot_csv`] draws chosen columns of a CSV log whose first column is `step`
//! ([`csv`]). [`scatter`] draws labelled trade-off charts with a Pareto front, in panels.

pub mod csv;
pub mod scatter;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use image::{Rgb, RgbImage};
use plotters::backend::{BitMapBackend, DrawingBackend};
use plotters::coord::Shift;
use plotters::prelude::*;

pub use csv::{parse_csv, plot_csv};

/// One named line of a chart: (step, value) points. Points that cannot sit on the log10 y
/// axis are skipped: a value that is not finite, not positive or outside [1e-150, 1e150], and
/// a step that is not finite or beyond ±1e300.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// The series' name (a CSV column, for instance), written in the legend.
    pub name: String,
    /// (step, value) points in the order they are joined.
    pub points: Vec<(f64, f64)>,
}

/// A plotters drawing error on the in-memory bitmap.
pub type DrawError = DrawingAreaErrorKind<<BitMapBackend<'static> as DrawingBackend>::ErrorType>;

/// Why a chart could not be read, drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum CurveError {
    /// The CSV log could not be read.
    #[error("reading {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The PNG could not be encoded or written.
    #[error("writing {path}: {source}")]
    Image {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
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
    /// The canvas has no room for the axes, their labels and the legend.
    #[error(
        "a {width}x{height} chart is too small: it needs at least {min_width}x{min_height} pixels"
    )]
    Canvas {
        /// Requested width, pixels (of one panel for scatter charts).
        width: u32,
        /// Requested height, pixels.
        height: u32,
        /// The smallest width drawn.
        min_width: u32,
        /// The smallest height drawn.
        min_height: u32,
    },
    /// The embedded font could not be parsed (a corrupt build).
    #[error("the embedded chart font could not be read")]
    Font,
    /// plotters failed while drawing.
    #[error("drawing the chart: {source}")]
    Draw {
        /// The underlying error.
        #[from]
        source: DrawError,
    },
}

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
/// DejaVu Sans 2.37 (licence beside it in `model/assets/fonts/`).
const FONT_TTF: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
/// The family name the embedded font is registered under with plotters.
const FONT: &str = "sans-serif";
/// Smallest loss-curve canvas, pixels: room for the tick labels, axis titles and legend.
const MIN_SIZE: (u32, u32) = (160, 120);
/// Largest magnitude a drawn step may have, so every axis span stays finite.
const LIMIT: f64 = 1e300;
/// Largest decade (and, negated, smallest) a value on a log axis may lie in: plotters' log
/// axis divides its ends, so their ratio must stay a finite f64 (below 1e308).
const DECADES: f64 = 150.0;

/// The colour of the `index`-th series (in the lines and the legend); cycles after ten.
pub fn colour(index: usize) -> Rgb<u8> {
    Rgb(PALETTE[index % PALETTE.len()])
}

/// [`colour`] as a plotters colour.
fn rgb(c: Rgb<u8>) -> RGBColor {
    RGBColor(c.0[0], c.0[1], c.0[2])
}

/// The embedded font at `size` pixels in colour `c`.
fn font(size: u32, c: RGBColor) -> TextStyle<'static> {
    (FONT, size).into_font().color(&c)
}

/// Registers the embedded font with plotters once per process.
fn register_font() -> Result<(), CurveError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| plotters::style::register_font(FONT, FontStyle::Normal, FONT_TTF).is_ok());
    ok.then_some(()).ok_or(CurveError::Font)
}

/// The in-memory canvas plotters draws on.
type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// A white `width` x `height` canvas handed to `draw`, returned as an image with what `draw`
/// returned. Refuses canvases under `min` pixels.
fn paint<T>(
    width: u32,
    height: u32,
    min: (u32, u32),
    draw: impl FnOnce(&Area) -> Result<T, CurveError>,
) -> Result<(RgbImage, T), CurveError> {
    if width < min.0 || height < min.1 {
        return Err(CurveError::Canvas {
            width,
            height,
            min_width: min.0,
            min_height: min.1,
        });
    }
    register_font()?;
    let mut buffer = vec![255u8; width as usize * height as usize * 3];
    let drawn = {
        let root = BitMapBackend::with_buffer(&mut buffer, (width, height)).into_drawing_area();
        let drawn = draw(&root)?;
        root.present()?;
        drawn
    };
    let img = RgbImage::from_raw(width, height, buffer).expect("buffer sized to the canvas");
    Ok((img, drawn))
}

/// A tick value written short: up to three significant digits, in scientific notation
/// outside [1e-3, 1e5), no trailing zeros.
fn number(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || !v.is_finite() {
        return if v.is_finite() {
            "0".into()
        } else {
            v.to_string()
        };
    }
    if !(1e-3..1e5).contains(&a) {
        let s = format!("{v:.2e}");
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
        return format!("{mantissa}e{exponent}");
    }
    let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        &s
    };
    match s {
        "-0" => "0".into(),
        s => s.into(),
    }
}

/// A tick value on a log axis: written (see [`number`]) at 1, 2 and 5 times a decade, left
/// blank at the other multiples so that the labels of a short range do not crowd.
fn log_tick(v: f64) -> String {
    let mantissa = v / 10f64.powf(v.abs().log10().floor());
    match [1.0, 2.0, 5.0].iter().any(|m| (mantissa - m).abs() < 1e-6) {
        true => number(v),
        false => String::new(),
    }
}

/// Smallest and largest of `values`, or `None` when there are none.
fn extent(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.fold(None, |r, v| match r {
        None => Some((v, v)),
        Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
    })
}

/// `(lo, hi)` widened to at least `min_span` (and a relative 1e-9, so the span survives
/// rounding at any magnitude), centred on the data.
fn widen((lo, hi): (f64, f64), min_span: f64) -> (f64, f64) {
    let span = (hi - lo).max(min_span).max(1e-9 * lo.abs().max(hi.abs()));
    let mid = lo / 2.0 + hi / 2.0;
    match hi - lo >= span {
        true => (lo, hi),
        false => (mid - span / 2.0, mid + span / 2.0),
    }
}

/// The points of `series` that can be drawn (see [`Series`]).
fn visible(series: &Series) -> impl Iterator<Item = (f64, f64)> + '_ {
    series.points.iter().copied().filter(|&(s, v)| {
        let decade = v.log10();
        s.is_finite() && s.abs() <= LIMIT && (-DECADES..=DECADES).contains(&decade)
    })
}

/// Where a loss curve's plot area landed: its pixel ranges and the data ranges it spans
/// (steps; log10 values, whole decades). Read by the tests, which check where lines land.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(not(test), allow(dead_code))]
struct Frame {
    x_px: std::ops::Range<i32>,
    y_px: std::ops::Range<i32>,
    x: (f64, f64),
    y: (f64, f64),
}

/// The data ranges of a loss curve: x from the first to the last step (a unit around a lone
/// step), y over the whole decades the values cover (one decade without any).
fn fit(series: &[Series]) -> ((f64, f64), (f64, f64)) {
    let points = || series.iter().flat_map(visible);
    let x = extent(points().map(|p| p.0)).map_or((0.0, 1.0), |r| widen(r, 1.0));
    let y = match extent(points().map(|p| p.1.log10())) {
        Some((lo, hi)) => (lo.floor(), hi.ceil().max(lo.floor() + 1.0)),
        None => (0.0, 1.0),
    };
    (x, y)
}

/// A log axis from 10^`lo` to 10^`hi`, its ends nudged outwards by a millionth so that
/// rounding in plotters' tick search cannot drop the tick of a decade at an end.
fn log_axis((lo, hi): (f64, f64)) -> LogCoord<f64> {
    (10f64.powf(lo) * (1.0 - 1e-6)..10f64.powf(hi) * (1.0 + 1e-6))
        .log_scale()
        .into()
}

/// Draws the loss curve of `series` on `area` (see the module documentation).
fn draw_curves(
    area: &Area,
    series: &[Series],
    titles: Option<(&str, &str)>,
) -> Result<Frame, CurveError> {
    area.fill(&WHITE)?;
    let (x, y) = fit(series);
    let (x_title, y_title) = match (titles, series) {
        (Some((x, y)), _) => (x.to_string(), y.to_string()),
        (None, [one]) => ("step".into(), format!("{} (log scale)", one.name)),
        (None, _) => ("step".into(), "value (log scale)".into()),
    };
    let mut chart = ChartBuilder::on(area)
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d(x.0..x.1, log_axis(y))?;
    chart
        .configure_mesh()
        .x_desc(x_title)
        .y_desc(y_title)
        .x_label_formatter(&|v| number(*v))
        .y_label_formatter(&|v| log_tick(*v))
        .label_style(font(13, BLACK))
        .axis_desc_style(font(15, BLACK))
        .bold_line_style(RGBColor(215, 215, 215))
        .light_line_style(RGBColor(240, 240, 240))
        .draw()?;
    for (i, s) in series.iter().enumerate() {
        let c = rgb(colour(i));
        let points: Vec<(f64, f64)> = visible(s).collect();
        let lone = match points.as_slice() {
            [p] => Some(*p),
            _ => None,
        };
        chart
            .draw_series(LineSeries::new(points, c.stroke_width(2)))?
            .label(s.name.as_str())
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], c.filled()));
        chart.draw_series(lone.map(|p| Circle::new(p, 3, c.filled())))?;
    }
    if !series.is_empty() {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font(font(13, BLACK))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
    }
    let (x_px, y_px) = chart.plotting_area().get_pixel_range();
    Ok(Frame { x_px, y_px, x, y })
}

/// The chart of `series` on a `width` x `height` canvas (see the module documentation).
/// Series with no drawable point still get their legend entry. Canvases under 160 x 120
/// pixels are refused with [`CurveError::Canvas`].
pub fn render(series: &[Series], width: u32, height: u32) -> Result<RgbImage, CurveError> {
    paint(width, height, MIN_SIZE, |area| {
        draw_curves(area, series, None)
    })
    .map(|(img, _)| img)
}

/// Writes the chart of `series` (see [`render`]) to `path` as PNG with the axis titles
/// `(x, y)` instead of `step` and the series' name (the y axis is log10 either way).
pub fn write_png_titled(
    path: &Path,
    series: &[Series],
    titles: (&str, &str),
    width: u32,
    height: u32,
) -> Result<(), CurveError> {
    let img = paint(width, height, MIN_SIZE, |area| {
        draw_curves(area, series, Some(titles))
    })?;
    save_png(&img.0, path)
}

/// Writes the chart of `series` (see [`render`]) to `path` as PNG.
pub fn write_png(
    path: &Path,
    series: &[Series],
    width: u32,
    height: u32,
) -> Result<(), CurveError> {
    save_png(&render(series, width, height)?, path)
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
mod tests;
