//! What the rectification tests share: calibrations like real ones (a KITTI-like wide
//! stereo camera, a VGA camera, a fisheye), rotations, a textured image, and PSNR.

use model::frame::Rgb8Image;

use crate::msg::sensor_msgs::CameraInfo;

/// A row-major rotation of `degrees` about `axis` (normalised first).
pub fn rotation(axis: [f64; 3], degrees: f64) -> [f64; 9] {
    let axis = glam::DVec3::from(axis).normalize();
    // glam is column major: its transpose's columns are the rows.
    glam::DMat3::from_axis_angle(axis, degrees.to_radians())
        .transpose()
        .to_cols_array()
}

/// Row-major `[fx 0 cx; 0 fy cy; 0 0 1]`.
pub fn k_matrix(fx: f64, fy: f64, cx: f64, cy: f64) -> [f64; 9] {
    [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
}

/// Row-major `[fx 0 cx tx; 0 fy cy 0; 0 0 1 0]`.
pub fn p_matrix(fx: f64, fy: f64, cx: f64, cy: f64, tx: f64) -> [f64; 12] {
    [fx, 0.0, cx, tx, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
}

/// A `CameraInfo` of the given parts (no binning, full image).
pub fn info(
    (width, height): (u32, u32),
    model: &str,
    d: &[f64],
    k: [f64; 9],
    r: [f64; 9],
    p: [f64; 12],
) -> CameraInfo {
    CameraInfo {
        width,
        height,
        distortion_model: model.to_owned(),
        d: d.to_vec(),
        k,
        r,
        p,
        ..CameraInfo::default()
    }
}

/// The identity rotation, row major.
pub const IDENTITY: [f64; 9] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

/// The three lens models at realistic strengths, each a left camera with a stereo
/// rectification rotation of 1.5 degrees: (name, `CameraInfo`).
pub fn cameras() -> Vec<(&'static str, CameraInfo)> {
    let r = rotation([0.3, -1.0, 0.2], 1.5);
    vec![
        (
            "plumb_bob",
            info(
                (1408, 376),
                "plumb_bob",
                &[-0.344, 0.152, 0.00067, -0.00033, -0.03],
                k_matrix(788.6, 786.4, 687.2, 186.0),
                r,
                p_matrix(600.0, 600.0, 700.0, 190.0, 0.0),
            ),
        ),
        (
            "rational_polynomial",
            info(
                (640, 480),
                "rational_polynomial",
                &[0.8, -0.2, 1e-4, -2e-4, 0.05, 1.1, -0.05, 0.1],
                k_matrix(500.0, 502.0, 321.0, 238.5),
                r,
                p_matrix(430.0, 430.0, 318.0, 242.0, 0.0),
            ),
        ),
        (
            "equidistant",
            info(
                (640, 480),
                "equidistant",
                &[-0.01, 0.05, -0.08, 0.04],
                k_matrix(300.0, 300.5, 319.5, 240.5),
                r,
                p_matrix(250.0, 250.0, 320.0, 240.0, 0.0),
            ),
        ),
    ]
}

/// A smooth texture (sinusoids of 17 to 41 px wavelength, each channel its own phases):
/// resampling it twice loses little, so round trips measure geometry, not blur.
pub fn textured(width: u32, height: u32) -> Rgb8Image {
    let tau = std::f64::consts::TAU;
    let mut data = Vec::with_capacity(3 * width as usize * height as usize);
    for y in 0..height {
        for x in 0..width {
            let (x, y) = (x as f64, y as f64);
            for c in 0..3 {
                let c = c as f64;
                let v = 128.0
                    + 55.0 * (tau * x / 41.0 + c).sin()
                    + 40.0 * (tau * (x + y) / 29.0 + 2.0 * c).sin()
                    + 25.0 * (tau * y / 17.0 + 3.0 * c).cos();
                data.push(v.round().clamp(0.0, 255.0) as u8);
            }
        }
    }
    Rgb8Image {
        width,
        height,
        data,
    }
}

/// PSNR (dB, peak 255) and the largest absolute difference of `a` and `b` over the pixels
/// `keep` says, and how many there were.
pub fn compare(a: &Rgb8Image, b: &Rgb8Image, keep: impl Fn(u32, u32) -> bool) -> (f64, u8, usize) {
    let (mut sq, mut max, mut n) = (0.0f64, 0u8, 0usize);
    for y in 0..a.height {
        for x in 0..a.width {
            if !keep(x, y) {
                continue;
            }
            let i = 3 * (y * a.width + x) as usize;
            for c in 0..3 {
                let d = a.data[i + c].abs_diff(b.data[i + c]);
                sq += (d as f64).powi(2);
                max = max.max(d);
            }
            n += 1;
        }
    }
    let mse = sq / (3 * n.max(1)) as f64;
    (10.0 * (255.0f64.powi(2) / mse).log10(), max, n)
}
