//! Loss-curve charts: where series land, what is skipped, and the extremes.

use super::*;

fn series(name: &str, points: &[(f64, f64)]) -> Series {
    Series {
        name: name.into(),
        points: points.to_vec(),
    }
}

/// The chart and where its plot area landed.
fn drawn(series: &[Series], width: u32, height: u32) -> (RgbImage, Frame) {
    paint(width, height, MIN_SIZE, |area| {
        draw_curves(area, series, None)
    })
    .unwrap()
}

/// The row of `f`'s plot area where log10 value `y` lies.
fn row_of(f: &Frame, y: f64) -> f64 {
    let t = (y - f.y.0) / (f.y.1 - f.y.0);
    f.y_px.end as f64 - t * (f.y_px.end - f.y_px.start) as f64
}

/// The row holding most pixels of colour `c` inside the plot area, and how many it holds.
fn busiest_row(img: &RgbImage, f: &Frame, c: Rgb<u8>) -> (u32, usize) {
    let mut counts = vec![0usize; img.height() as usize];
    for (x, y, p) in img.enumerate_pixels() {
        if *p == c && f.x_px.contains(&(x as i32)) && f.y_px.contains(&(y as i32)) {
            counts[y as usize] += 1;
        }
    }
    let (row, n) = counts.iter().enumerate().max_by_key(|r| r.1).unwrap();
    (row as u32, *n)
}

#[test]
fn flat_series_draw_in_their_colours_at_their_heights_on_a_log_axis() {
    let steps = |v: f64| (0..=100).map(|s| (s as f64, v)).collect::<Vec<_>>();
    let (img, f) = drawn(
        &[series("a", &steps(3.0)), series("b", &steps(0.3))],
        320,
        200,
    );
    assert_eq!(img.dimensions(), (320, 200));
    // Whole decades 0.1 to 10, steps 0 to 100.
    assert_eq!((f.x, f.y), ((0.0, 100.0), (-1.0, 1.0)));
    for (i, v) in [(0, 3f64), (1, 0.3)] {
        let (row, n) = busiest_row(&img, &f, colour(i));
        let want = row_of(&f, v.log10());
        assert!(
            (row as f64 - want).abs() <= 2.0,
            "series {i}: row {row}, want {want}"
        );
        // Most of the width: the legend box in the upper right covers part of a line.
        assert!(
            n as i32 >= (f.x_px.end - f.x_px.start) / 2,
            "series {i}: {n} px"
        );
    }
    // A decade apart on the log axis: half the plot's height.
    let gap = busiest_row(&img, &f, colour(1)).0 - busiest_row(&img, &f, colour(0)).0;
    let half = (f.y_px.end - f.y_px.start) as f64 / 2.0;
    assert!((gap as f64 - half).abs() <= 2.0, "{gap} against {half}");
    assert_eq!(*img.get_pixel(0, 0), Rgb([255, 255, 255]));
}

#[test]
fn the_legend_names_every_series_in_its_colour() {
    let empty = series("empty", &[]);
    let (img, f) = drawn(&[empty.clone(), series("lone", &[(5.0, 1e-3)])], 320, 200);
    // Legend markers sit in the plot's upper right; the empty series has its marker only.
    let in_legend = |c: Rgb<u8>| {
        img.enumerate_pixels()
            .filter(|p| *p.2 == c && p.1 < (f.y_px.start + 60) as u32 && p.0 > 160)
            .count()
    };
    assert!(in_legend(colour(0)) >= 100, "{}", in_legend(colour(0)));
    assert!(in_legend(colour(1)) >= 100, "{}", in_legend(colour(1)));
    // The names are written: renaming a series changes the picture.
    let renamed = render(
        &[
            series("a much longer name", &[]),
            series("lone", &[(5.0, 1e-3)]),
        ],
        320,
        200,
    );
    assert_ne!(renamed.unwrap(), img);
    // The lone point is a dot, so its colour appears beyond its legend marker.
    let all = |c: Rgb<u8>| img.pixels().filter(|&&p| p == c).count();
    assert!(all(colour(1)) > in_legend(colour(1)));
    assert_eq!(all(colour(0)), in_legend(colour(0)));
}

#[test]
fn points_that_cannot_sit_on_a_log_axis_are_skipped() {
    let bad = [
        (0.0, 0.0),
        (1.0, -2.0),
        (2.0, f64::NAN),
        (3.0, f64::INFINITY),
        (f64::NAN, 1.0),
        (f64::INFINITY, 1.0),
        (4.0, 1e-320),
        (5.0, 1e-151),
        (6.0, 1e151),
        (1e301, 1.0),
    ];
    let skipped = render(&[series("s", &bad)], 320, 200).unwrap();
    let empty = render(&[series("s", &[])], 320, 200).unwrap();
    assert_eq!(skipped, empty);
}

#[test]
fn extremes_give_a_png_or_a_typed_error_never_a_panic() {
    let wide_steps: Vec<(f64, f64)> = (0..=70)
        .map(|k| (10f64.powf(k as f64 / 10.0), 1.0 / (1.0 + k as f64)))
        .collect();
    let wide_values: Vec<(f64, f64)> = (0..=24).map(|k| (k as f64, 10f64.powi(k - 12))).collect();
    let cases: Vec<Vec<Series>> = vec![
        vec![],
        vec![series("empty", &[])],
        vec![series("one", &[(7.0, 0.5)])],
        vec![series("one", &[(1e15, 1e-5)])],
        vec![series("equal", &[(0.0, 2.0), (1.0, 2.0), (2.0, 2.0)])],
        vec![series("decade", &[(0.0, 10.0), (1.0, 10.0)])],
        vec![series("same step", &[(3.0, 1.0), (3.0, 2.0)])],
        vec![series("steps 1..1e7", &wide_steps)],
        vec![series("values 1e-12..1e12", &wide_values)],
        vec![series("limits", &[(-1e300, 1e-150), (1e300, 1e150)])],
        (0..12)
            .map(|i| series(&format!("s{i}"), &[(0.0, 1.0 + i as f64)]))
            .collect(),
    ];
    for s in &cases {
        let img = render(s, 400, 240).unwrap_or_else(|e| panic!("{s:?}: {e}"));
        assert_eq!(img.dimensions(), (400, 240));
        assert!(
            img.pixels().any(|p| p.0.iter().all(|&v| v < 80)),
            "{s:?}: no axes"
        );
    }
    for (w, h) in [(0, 0), (5, 5), (159, 480), (800, 119)] {
        let e = render(&cases[2], w, h).unwrap_err();
        assert!(matches!(e, CurveError::Canvas { width, height, .. } if (width, height) == (w, h)));
    }
}

#[test]
fn tick_values_are_written_short() {
    let cases = [
        (0.0, "0"),
        (-0.0, "0"),
        (2.5, "2.5"),
        (100.0, "100"),
        (0.1, "0.1"),
        (0.30000000000000004, "0.3"),
        (1234.6, "1235"),
        (1e7, "1e7"),
        (2.5e6, "2.5e6"),
        (1e-12, "1e-12"),
        (-4e-5, "-4e-5"),
    ];
    for (v, want) in cases {
        assert_eq!(number(v), want, "{v}");
    }
    // On log axes only 1, 2 and 5 times a decade are written.
    for (v, want) in [
        (1e-3, "0.001"),
        (20.0, "20"),
        (0.5, "0.5"),
        (30.0, ""),
        (9e6, ""),
    ] {
        assert_eq!(log_tick(v), want, "{v}");
    }
}
