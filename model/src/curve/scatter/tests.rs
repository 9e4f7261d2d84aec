//! Scatter panels: where dots land, the front, skipped points and the extremes.

use super::*;

fn point(label: &str, x: f64, y: f64, on_front: bool) -> ScatterPoint {
    ScatterPoint {
        label: label.into(),
        x,
        y,
        on_front,
    }
}

fn panel(log_x: bool, points: Vec<ScatterPoint>) -> Panel {
    Panel {
        title: "PSNR against latency".into(),
        x_title: "latency per bin, ms".into(),
        y_title: "PSNR, dB".into(),
        log_x,
        points,
    }
}

/// How many pixels of colour `c` lie in columns `cols`, and their mean column and row.
fn find(img: &RgbImage, c: Rgb<u8>, cols: Range<u32>) -> (usize, u32, u32) {
    let px: Vec<(u32, u32)> = img
        .enumerate_pixels()
        .filter(|p| *p.2 == c && cols.contains(&p.0))
        .map(|p| (p.0, p.1))
        .collect();
    let n = px.len().max(1) as u32;
    let sx: u32 = px.iter().map(|p| p.0).sum();
    let sy: u32 = px.iter().map(|p| p.1).sum();
    (px.len(), sx / n, sy / n)
}

#[test]
fn dots_sit_where_their_values_say_with_labels_and_the_front_line() {
    let p = panel(
        true,
        vec![
            point("fast", 10.0, 15.0, true),
            point("slow", 1000.0, 25.0, true),
            point("bad", 500.0, 14.0, false),
            point("nan", f64::NAN, 20.0, false),
        ],
    );
    let (img, frames) = render_frames(&[p.clone(), p.clone()], 400, 300).unwrap();
    assert_eq!(img.dimensions(), (800, 300));
    // Log x from 10 to 1000 padded by 8% of two decades: 10 sits 0.16/2.32 of the way in.
    let f = &frames[0];
    let along = |t: f64| f.x_px.start as f64 + t * (f.x_px.end - f.x_px.start) as f64;
    let (n0, x0, y0) = find(&img, colour(0), 0..400);
    let (n1, x1, y1) = find(&img, colour(1), 0..400);
    assert!(n0 > 20 && n1 > 20, "{n0} {n1}");
    assert!((x0 as f64 - along(0.16 / 2.32)).abs() <= 2.0, "{x0}");
    assert!((x1 as f64 - along(2.16 / 2.32)).abs() <= 2.0, "{x1}");
    assert!(y0 > y1, "higher PSNR higher up: {y0} {y1}");
    // The same dots again in panel 2, 400 px to the right.
    assert_eq!(frames[1].x_px.start, f.x_px.start + 400);
    assert_eq!(find(&img, colour(0), 400..800).1, x0 + 400);
    // The NaN point draws nothing, its label included; the others are labelled.
    assert_eq!(find(&img, colour(3), 0..800).0, 0);
    let relabelled = |i: usize, label: &str| {
        let mut q = p.clone();
        q.points[i].label = label.into();
        render(&[q], 400, 300).unwrap()
    };
    let one = render(std::slice::from_ref(&p), 400, 300).unwrap();
    assert_eq!(relabelled(3, ""), one);
    assert_ne!(relabelled(2, ""), one);
    // Front points are ringed in black and joined by a black line; others are not ringed.
    let black = |x: u32, y: u32| *img.get_pixel(x, y) == Rgb([0, 0, 0]);
    let ring = RING as u32 - 1;
    assert!(black(x0 + ring, y0), "ring right of the fast dot");
    let (_, x2, y2) = find(&img, colour(2), 0..400);
    assert!(
        !black(x2 + ring, y2),
        "no ring around the point off the front"
    );
    let mid = ((x0 + x1) / 2, (y0 + y1) / 2);
    let near_black = (mid.1 - 3..mid.1 + 4).any(|y| black(mid.0, y));
    assert!(near_black, "front line near {mid:?}");
}

#[test]
fn a_linear_x_axis_puts_dots_in_proportion() {
    let points = vec![
        point("a", 0.0, 1.0, false),
        point("b", 10.0, 1.0, false),
        point("c", 5.0, 1.0, false),
    ];
    let (img, frames) = render_frames(&[panel(false, points)], 400, 300).unwrap();
    let x = |i| find(&img, colour(i), 0..400).1;
    let (xa, xb, xc) = (x(0), x(1), x(2));
    assert!(
        ((xa + xb) as f64 / 2.0 - xc as f64).abs() <= 1.0,
        "{xa} {xc} {xb}"
    );
    let inside = |x: u32| frames[0].x_px.contains(&(x as i32));
    assert!(inside(xa) && inside(xb));
}

#[test]
fn extremes_give_a_png_or_a_typed_error_never_a_panic() {
    let many: Vec<ScatterPoint> = (0..30)
        .map(|i| {
            let y = 20.0 + (i % 3) as f64 * 0.01;
            point(&format!("setting {i}"), 100.0 + i as f64, y, i % 2 == 0)
        })
        .collect();
    let cases = [
        vec![],
        vec![point("one", 3.0, 3.0, true)],
        vec![
            point("zero", 0.0, 0.0, true),
            point("neg", -1.0, 1.0, false),
        ],
        vec![
            point("same", 5.0, 2.0, true),
            point("same too", 5.0, 2.0, true),
        ],
        vec![
            point("tiny", 1e-12, 1e-12, true),
            point("huge", 1e12, 1e12, true),
        ],
        vec![
            point("limit", 1e-150, -1e300, false),
            point("far", 1e150, 1e300, true),
        ],
        vec![
            point("beyond", 1e-300, 1.0, true),
            point("beyond too", 1e300, 2.0, true),
        ],
        vec![
            point("inf", f64::INFINITY, 1.0, true),
            point("nan y", 1.0, f64::NAN, true),
        ],
        many,
    ];
    for log_x in [false, true] {
        for points in &cases {
            let p = panel(log_x, points.clone());
            let img = render(&[p], 320, 240).unwrap_or_else(|e| panic!("{points:?}: {e}"));
            assert_eq!(img.dimensions(), (320, 240));
        }
    }
    assert_eq!(render(&[], 320, 240).unwrap().dimensions(), (320, 240));
    for (w, h) in [(0, 0), (10, 10), (199, 300), (300, 149)] {
        let e = render(&[panel(true, cases[1].clone())], w, h).unwrap_err();
        assert!(matches!(e, CurveError::Canvas { .. }), "{e}");
    }
}
