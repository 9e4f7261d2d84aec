//! CSV training logs read into [`Series`]: a header row of column names whose first is
//! `step`, then one row of numbers per logged step.

use std::path::Path;

use super::{write_png, CurveError, Series};

/// The `columns` of a CSV log as series against its first column, which must be `step`.
/// Line 1 is the header of column names; every other non-blank line has as many cells, each
/// a number or empty (an empty cell is a step where that column was not logged, skipped).
/// Errors name the 1-based line: a missing `step` or unknown column (line 1), a row with the
/// wrong number of cells, a cell that is not a number.
pub fn parse_csv(text: &str, columns: &[&str]) -> Result<Vec<Series>, CurveError> {
    let err = |line: usize, message: String| CurveError::Parse { line, message };
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l));
    let header: Vec<&str> = match lines.next() {
        Some((_, h)) => h.split(',').map(str::trim).collect(),
        None => return Err(err(1, "no header row".into())),
    };
    if header.first() != Some(&"step") {
        return Err(err(
            1,
            format!("first column is {:?}, not \"step\"", header[0]),
        ));
    }
    let index: Vec<usize> = columns
        .iter()
        .map(|c| header.iter().position(|h| h == c))
        .zip(columns)
        .map(|(i, c)| i.ok_or_else(|| err(1, format!("no column {c:?} in the header"))))
        .collect::<Result<_, _>>()?;
    let mut series: Vec<Series> = columns
        .iter()
        .map(|c| Series {
            name: c.to_string(),
            points: Vec::new(),
        })
        .collect();
    for (n, l) in lines.filter(|(_, l)| !l.trim().is_empty()) {
        let cells: Vec<&str> = l.split(',').map(str::trim).collect();
        if cells.len() != header.len() {
            let message = format!("{} cells, the header has {}", cells.len(), header.len());
            return Err(err(n, message));
        }
        let number = |k: usize| {
            cells[k]
                .parse::<f64>()
                .map_err(|_| err(n, format!("{}: {:?} is not a number", header[k], cells[k])))
        };
        let step = number(0)?;
        for (s, &k) in series.iter_mut().zip(&index) {
            if !cells[k].is_empty() {
                s.points.push((step, number(k)?));
            }
        }
    }
    Ok(series)
}

/// Reads the CSV log `csv`, draws its `columns` (see [`parse_csv`]) and writes the chart to
/// `png` (see [`write_png`]). Returns the series drawn.
pub fn plot_csv(
    csv: &Path,
    columns: &[&str],
    png: &Path,
    width: u32,
    height: u32,
) -> Result<Vec<Series>, CurveError> {
    let text = std::fs::read_to_string(csv).map_err(|source| CurveError::Io {
        path: csv.to_path_buf(),
        source,
    })?;
    let series = parse_csv(&text, columns)?;
    write_png(png, &series, width, height)?;
    Ok(series)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::curve::colour;

    fn series(name: &str, points: &[(f64, f64)]) -> Series {
        Series {
            name: name.into(),
            points: points.to_vec(),
        }
    }

    #[test]
    fn a_csv_log_parses_chosen_columns_and_skips_empty_cells() {
        let text = "step,loss,psnr,phase\n0,1.0,10,1\n10, 0.5 ,,1\n\n20,0.25,12.5,2\n";
        let got = parse_csv(text, &["psnr", "loss"]).unwrap();
        assert_eq!(got[0], series("psnr", &[(0.0, 10.0), (20.0, 12.5)]));
        assert_eq!(
            got[1],
            series("loss", &[(0.0, 1.0), (10.0, 0.5), (20.0, 0.25)])
        );
    }

    #[test]
    fn csv_errors_are_typed_with_their_line() {
        let line_of = |text: &str, columns: &[&str]| match parse_csv(text, columns) {
            Err(CurveError::Parse { line, .. }) => line,
            other => panic!("{other:?}"),
        };
        assert_eq!(line_of("", &["loss"]), 1);
        assert_eq!(line_of("epoch,loss\n0,1\n", &["loss"]), 1);
        assert_eq!(line_of("step,loss\n0,1\n", &["lr"]), 1);
        assert_eq!(line_of("step,loss\n0,1\n1,abc\n", &["loss"]), 3);
        assert_eq!(line_of("step,loss\n0,1\n\n2,1,3\n", &["loss"]), 4);
        assert_eq!(line_of("step,loss\nx,1\n", &["loss"]), 2);
        let e = parse_csv("step,loss\n0,1\n1,abc\n", &["loss"]).unwrap_err();
        assert_eq!(e.to_string(), "CSV line 3: loss: \"abc\" is not a number");
    }

    #[test]
    fn plot_csv_writes_a_png_of_the_requested_size_and_reports_io_errors() {
        let dir = std::env::temp_dir().join(format!("stereosplat-curve-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (csv, png) = (dir.join("log.csv"), dir.join("loss.png"));
        std::fs::write(&csv, "step,loss\n0,2\n1,1\n2,0.5\n").unwrap();
        let drawn = plot_csv(&csv, &["loss"], &png, 300, 150).unwrap();
        assert_eq!(drawn[0].points.len(), 3);
        let img = image::open(&png).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (300, 150));
        assert!(img.pixels().any(|&p| p == colour(0)));
        let missing = plot_csv(&dir.join("none.csv"), &["loss"], &png, 300, 150);
        assert!(matches!(missing, Err(CurveError::Io { .. })), "{missing:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
