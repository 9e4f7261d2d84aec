//! The KITTI-360 calibration of the perspective stereo pair: reading and writing the three
//! files under `calibration/`, the rectified [`StereoRig`] they describe, and KITTI-360's
//! published values as a synthetic default.
//!
//! Conventions, as the official devkit uses them (`kitti360scripts/devkits/commons/
//! loadCalibration.py` reads the files; `helpers/project.py` and `viewer/
//! kitti360Viewer3DRaw.py` combine them):
//! - `perspective.txt` holds `key: numbers` lines; `P_rect_0x` is 3x4 row major and maps
//!   rectified camera-0 coordinates to image x pixels (so `P_rect_01[0][3] = -fx * baseline`),
//!   `R_rect_0x` (3x3 row major) rotates unrectified camera x into its rectified frame, and
//!   `S_rect_0x` is the rectified `width height`.
//! - `calib_cam_to_pose.txt` holds `image_0x:` 3x4 row-major unrectified-camera-to-pose
//!   (GPS/IMU frame: x forward, y right, z down) transforms for cameras 0 to 3.
//! - `calib_cam_to_velo.txt` is 12 bare numbers, 3x4 row major, unrectified camera 0 to
//!   velodyne (x forward, y left, z up).
//! - Rectified camera 0 to world is `pose * cam_to_pose_00 * inverse(R_rect_00)` (devkit
//!   `Camera.__init__`), and a velodyne point lands in rectified camera 0 at
//!   `R_rect_00 * inverse(cam_to_velo) * p` (devkit `projectVeloToImage`).

use std::path::{Path, PathBuf};

use glam::{DAffine3, DMat3, DVec3};
use renderer::Intrinsics;

use super::error::Kitti360Error;
use super::layout;
use super::text::{
    affine_from_rows, affine_rows, mat3_from_rows, mat3_rows, parse_all, read_text, sci_join,
    write_text, KeyedFile,
};
use crate::frame::StereoRig;

/// KITTI-360's published rectified width and height (`S_rect_00: 1.408000e+03 3.760000e+02`).
pub const KITTI360_SIZE: (u32, u32) = (1408, 376);
/// KITTI-360's `P_rect_00` focal length (both axes), pixels at [`KITTI360_SIZE`].
pub const KITTI360_FOCAL: f64 = 552.554261;
/// KITTI-360's `P_rect_00` principal point, pixels at [`KITTI360_SIZE`].
pub const KITTI360_PRINCIPAL: (f64, f64) = (682.049453, 238.769549);
/// KITTI-360's `P_rect_01[0][3]` (`-fx * baseline`), pixels times metres.
pub const KITTI360_P01_TX: f64 = -328.318735;

/// `calib_cam_to_pose.txt`'s `image_00` as KITTI-360 publishes it (3x4 row major).
const KITTI360_CAM0_TO_POSE: [f64; 12] = [
    0.0371783278,
    -0.0986182135,
    0.9944306009,
    1.5752681039, //
    0.9992675562,
    -0.0053553387,
    -0.0378902567,
    0.0043914093, //
    0.0090621821,
    0.9951109327,
    0.0983468786,
    -0.6500000000,
];

/// `calib_cam_to_velo.txt` as KITTI-360 publishes it (3x4 row major).
const KITTI360_CAM0_TO_VELO: [f64; 12] = [
    0.04307104361,
    -0.08829286498,
    0.995162929,
    0.8043914418, //
    -0.999004371,
    0.007784614041,
    0.04392796942,
    0.2993489574, //
    -0.01162548558,
    -0.9960641394,
    -0.08786966659,
    -0.1770225824,
];

/// The fisheye cameras `image_02` (looking left) and `image_03` (looking right) to pose.
/// This crate never reads them, but the devkit's `loadCalibrationCameraToPose` requires all
/// four lines, so the writer emits these plausible side-looking placeholders (not the
/// published values).
const FISHEYE_TO_POSE: [[f64; 12]; 2] = [
    [
        1.0, 0.0, 0.0, 0.5, 0.0, 0.0, -1.0, -0.9, 0.0, 1.0, 0.0, -0.95,
    ],
    [
        -1.0, 0.0, 0.0, 0.5, 0.0, 0.0, 1.0, 0.9, 0.0, 1.0, 0.0, -0.95,
    ],
];

/// Relative tolerance for "the two rectified cameras share intrinsics".
const RECTIFIED_TOL: f64 = 1e-6;

/// The calibration of KITTI-360's perspective stereo pair (cameras 0 and 1).
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// `P_rect_00`: rectified camera 0 coordinates to left image pixels, 3x4 row major.
    pub p_rect_00: [[f64; 4]; 3],
    /// `P_rect_01`: rectified camera 0 coordinates to right image pixels, 3x4 row major.
    pub p_rect_01: [[f64; 4]; 3],
    /// `R_rect_00`: unrectified to rectified camera 0 rotation.
    pub r_rect_00: DMat3,
    /// `R_rect_01`: unrectified to rectified camera 1 rotation.
    pub r_rect_01: DMat3,
    /// `S_rect_00`: rectified image width and height, pixels.
    pub image_size: (u32, u32),
    /// `image_00` and `image_01` of `calib_cam_to_pose.txt`: unrectified camera to pose.
    pub cam_to_pose: [DAffine3; 2],
    /// `calib_cam_to_velo.txt`: unrectified camera 0 to velodyne.
    pub cam_to_velo: DAffine3,
}

fn p_from_rows(v: &[f64]) -> [[f64; 4]; 3] {
    [
        [v[0], v[1], v[2], v[3]],
        [v[4], v[5], v[6], v[7]],
        [v[8], v[9], v[10], v[11]],
    ]
}

fn p_rows(p: &[[f64; 4]; 3]) -> Vec<f64> {
    p.iter().flatten().copied().collect()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= RECTIFIED_TOL * a.abs().max(b.abs()).max(1.0)
}

impl Calibration {
    /// Reads `calibration/{perspective,calib_cam_to_pose,calib_cam_to_velo}.txt` under
    /// `root`. Unknown keys (`calib_time`, `K_00`, `D_00`, fisheye lines) are ignored.
    pub fn read(root: &Path) -> Result<Self, Kitti360Error> {
        let persp_path = layout::perspective(root);
        let persp = KeyedFile::read(&persp_path)?;
        let size = persp.numbers("S_rect_00", 2)?;
        let dim = |v: f64| -> Result<u32, Kitti360Error> {
            match v >= 1.0 && v <= u32::MAX as f64 && v.fract() == 0.0 {
                true => Ok(v as u32),
                false => Err(Kitti360Error::parse(
                    &persp_path,
                    persp.line_of("S_rect_00"),
                    format!("`S_rect_00` size {v} is not a positive whole number"),
                )),
            }
        };
        let image_size = (dim(size[0])?, dim(size[1])?);
        let p_rect_00 = p_from_rows(&persp.numbers("P_rect_00", 12)?);
        let r_rect_00 = mat3_from_rows(&persp.numbers("R_rect_00", 9)?);
        let p_rect_01 = p_from_rows(&persp.numbers("P_rect_01", 12)?);
        let r_rect_01 = mat3_from_rows(&persp.numbers("R_rect_01", 9)?);

        let pose = KeyedFile::read(&layout::cam_to_pose(root))?;
        let cam_to_pose = [
            affine_from_rows(&pose.numbers("image_00", 12)?),
            affine_from_rows(&pose.numbers("image_01", 12)?),
        ];
        let cam_to_velo = affine_from_rows(&read_bare_numbers(&layout::cam_to_velo(root), 12)?);
        Ok(Self {
            p_rect_00,
            p_rect_01,
            r_rect_00,
            r_rect_01,
            image_size,
            cam_to_pose,
            cam_to_velo,
        })
    }

    /// Writes the three calibration files under `root/calibration` (overwriting them).
    pub fn write(&self, root: &Path) -> Result<(), Kitti360Error> {
        for (path, text) in self.files(root) {
            write_text(&path, &text)?;
        }
        Ok(())
    }

    /// The three calibration files and their exact contents, as [`Calibration::write`]
    /// writes them (the writer compares them with files already present).
    pub(super) fn files(&self, root: &Path) -> [(PathBuf, String); 3] {
        [
            (layout::perspective(root), self.perspective_text()),
            (layout::cam_to_pose(root), self.cam_to_pose_text()),
            (
                layout::cam_to_velo(root),
                format!("{}\n", sci_join(&affine_rows(&self.cam_to_velo))),
            ),
        ]
    }

    /// `perspective.txt` in the line order of the published file. The unrectified entries
    /// (`S_0x`, `K_0x`, `D_0x`, `R_0x`, `T_0x`) are derived, since this struct does not hold
    /// them: no distortion, the rectified intrinsics, `R_01 = R_rect_01^T R_rect_00` and
    /// `T_01 = -baseline * R_rect_01^T x` (what makes the rectified pair exact).
    fn perspective_text(&self) -> String {
        let (w, h) = (self.image_size.0 as f64, self.image_size.1 as f64);
        let p0 = &self.p_rect_00;
        let k = [
            p0[0][0], 0.0, p0[0][2], 0.0, p0[1][1], p0[1][2], 0.0, 0.0, 1.0,
        ];
        let baseline = -self.p_rect_01[0][3] / p0[0][0];
        let r01 = self.r_rect_01.transpose() * self.r_rect_00;
        let t01 = self.r_rect_01.transpose() * DVec3::new(-baseline, 0.0, 0.0);
        let cams: [(DMat3, DVec3, DMat3, &[[f64; 4]; 3]); 2] = [
            (
                DMat3::IDENTITY,
                DVec3::ZERO,
                self.r_rect_00,
                &self.p_rect_00,
            ),
            (r01, t01, self.r_rect_01, &self.p_rect_01),
        ];
        let mut out = String::from("calib_time: 09-Jan-2012 13:57:47\n");
        out += &format!("corner_dist: {}\n", sci_join(&[9.95e-2]));
        for (i, (r, t, r_rect, p)) in cams.iter().enumerate() {
            out += &format!("S_0{i}: {}\n", sci_join(&[w, h]));
            out += &format!("K_0{i}: {}\n", sci_join(&k));
            out += &format!("D_0{i}: {}\n", sci_join(&[0.0; 5]));
            out += &format!("R_0{i}: {}\n", sci_join(&mat3_rows(r)));
            out += &format!("T_0{i}: {}\n", sci_join(&t.to_array()));
            out += &format!("S_rect_0{i}: {}\n", sci_join(&[w, h]));
            out += &format!("R_rect_0{i}: {}\n", sci_join(&mat3_rows(r_rect)));
            out += &format!("P_rect_0{i}: {}\n", sci_join(&p_rows(p)));
        }
        out
    }

    fn cam_to_pose_text(&self) -> String {
        let rows = [
            affine_rows(&self.cam_to_pose[0]),
            affine_rows(&self.cam_to_pose[1]),
            FISHEYE_TO_POSE[0],
            FISHEYE_TO_POSE[1],
        ];
        rows.iter()
            .enumerate()
            .map(|(i, r)| format!("image_0{i}: {}\n", sci_join(r)))
            .collect()
    }

    /// The rectified stereo rig: intrinsics from `P_rect_00` at `S_rect_00`, baseline
    /// `-P_rect_01[0][3] / fx`. An error when the two projections do not describe one
    /// rectified pair (different intrinsics, skew, a vertical or depth offset, a camera 0
    /// offset, a non-positive focal length or baseline, non-finite values).
    pub fn rig(&self) -> Result<StereoRig, Kitti360Error> {
        let bad = |reason: String| Kitti360Error::NonRectified {
            path: PathBuf::from("calibration/perspective.txt"),
            reason,
        };
        let (p0, p1) = (&self.p_rect_00, &self.p_rect_01);
        if !p0.iter().chain(p1).flatten().all(|v| v.is_finite()) {
            return Err(bad("a projection holds a non-finite number".into()));
        }
        let (fx, fy, cx, cy) = (p0[0][0], p0[1][1], p0[0][2], p0[1][2]);
        if fx <= 0.0 || fy <= 0.0 {
            return Err(bad(format!("focal lengths {fx}, {fy} must be positive")));
        }
        let shape = [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]];
        for (name, p) in [("P_rect_00", p0), ("P_rect_01", p1)] {
            for (r, row) in shape.iter().enumerate() {
                for (c, want) in row.iter().enumerate() {
                    if !close(p[r][c], *want) {
                        return Err(bad(format!(
                            "{name}[{r}][{c}] is {}, expected {want}",
                            p[r][c]
                        )));
                    }
                }
            }
        }
        for (name, p, r) in [
            ("P_rect_00", p0, 0),
            ("P_rect_00", p0, 1),
            ("P_rect_00", p0, 2),
            ("P_rect_01", p1, 1),
            ("P_rect_01", p1, 2),
        ] {
            if p[r][3].abs() > RECTIFIED_TOL * fx {
                return Err(bad(format!("{name}[{r}][3] is {}, expected 0", p[r][3])));
            }
        }
        let baseline = -p1[0][3] / fx;
        if baseline <= 0.0 {
            return Err(bad(format!("baseline {baseline} m must be positive")));
        }
        Ok(StereoRig {
            intrinsics: Intrinsics {
                fx: fx as f32,
                fy: fy as f32,
                cx: cx as f32,
                cy: cy as f32,
                width: self.image_size.0,
                height: self.image_size.1,
            },
            baseline,
        })
    }

    /// [`Calibration::rig`] for the calibration stored under `root`: a
    /// [`Kitti360Error::NonRectified`] then names that root's `perspective.txt`.
    pub(super) fn rig_under(&self, root: &Path) -> Result<StereoRig, Kitti360Error> {
        self.rig().map_err(|e| match e {
            Kitti360Error::NonRectified { reason, .. } => Kitti360Error::NonRectified {
                path: layout::perspective(root),
                reason,
            },
            other => other,
        })
    }

    /// KITTI-360's published calibration (sequence-independent) with the intrinsics scaled
    /// to `width` x `height` as [`Intrinsics::scaled`] does (pixel centres at integers) and
    /// `R_rect` = identity, so data made with it are exactly rectified. The baseline stays
    /// 328.318735 / 552.554261 = 0.594 m; `image_01` to pose is `image_00` to pose moved by
    /// the baseline along camera x (the published one carries a small rotation that its
    /// `R_rect_01` undoes). Zero sizes are raised to 1.
    pub fn synthetic(width: u32, height: u32) -> Self {
        let (width, height) = (width.max(1), height.max(1));
        let sx = width as f64 / KITTI360_SIZE.0 as f64;
        let sy = height as f64 / KITTI360_SIZE.1 as f64;
        let fx = KITTI360_FOCAL * sx;
        let fy = KITTI360_FOCAL * sy;
        let cx = (KITTI360_PRINCIPAL.0 + 0.5) * sx - 0.5;
        let cy = (KITTI360_PRINCIPAL.1 + 0.5) * sy - 0.5;
        let baseline = -KITTI360_P01_TX / KITTI360_FOCAL;
        let p = |tx: f64| [[fx, 0.0, cx, tx], [0.0, fy, cy, 0.0], [0.0, 0.0, 1.0, 0.0]];
        let cam0_to_pose = affine_from_rows(&KITTI360_CAM0_TO_POSE);
        Self {
            p_rect_00: p(0.0),
            p_rect_01: p(-fx * baseline),
            r_rect_00: DMat3::IDENTITY,
            r_rect_01: DMat3::IDENTITY,
            image_size: (width, height),
            cam_to_pose: [
                cam0_to_pose,
                cam0_to_pose * DAffine3::from_translation(DVec3::new(baseline, 0.0, 0.0)),
            ],
            cam_to_velo: affine_from_rows(&KITTI360_CAM0_TO_VELO),
        }
    }

    /// A rig of another camera on KITTI-360's mounting: `size` pixels, focal length
    /// `focal_px` (square pixels, principal point at the image centre) and `baseline_m`
    /// metres between the cameras, as the domain randomisation draws them.
    pub fn synthetic_rig(size: (u32, u32), focal_px: f64, baseline_m: f64) -> Self {
        let (width, height) = (size.0.max(1), size.1.max(1));
        let (cx, cy) = (0.5 * width as f64 - 0.5, 0.5 * height as f64 - 0.5);
        let f = focal_px;
        let p = |tx: f64| [[f, 0.0, cx, tx], [0.0, f, cy, 0.0], [0.0, 0.0, 1.0, 0.0]];
        let base = Self::synthetic(width, height);
        let cam0_to_pose = base.cam_to_pose[0];
        Self {
            p_rect_00: p(0.0),
            p_rect_01: p(-f * baseline_m),
            cam_to_pose: [
                cam0_to_pose,
                cam0_to_pose * DAffine3::from_translation(DVec3::new(baseline_m, 0.0, 0.0)),
            ],
            ..base
        }
    }

    /// Rectified camera 0 to the GPS/IMU pose frame: `cam_to_pose_00 * inverse(R_rect_00)`,
    /// so that `cam0_to_world = pose * rect_to_pose()`.
    pub fn rect_to_pose(&self) -> DAffine3 {
        self.cam_to_pose[0] * DAffine3::from_mat3(self.r_rect_00).inverse()
    }

    /// Velodyne to rectified camera 0: `R_rect_00 * inverse(cam_to_velo)`.
    pub fn velo_to_rect(&self) -> DAffine3 {
        DAffine3::from_mat3(self.r_rect_00) * self.cam_to_velo.inverse()
    }
}

/// Exactly `n` whitespace-separated numbers spread over the lines of a file without keys
/// (the devkit reads `calib_cam_to_velo.txt` with `np.loadtxt(...).reshape(3,4)`).
fn read_bare_numbers(path: &Path, n: usize) -> Result<Vec<f64>, Kitti360Error> {
    let text = read_text(path)?;
    let mut values = Vec::with_capacity(n);
    let mut last_line = 1;
    for (i, line) in text.lines().enumerate() {
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.is_empty() {
            continue;
        }
        last_line = i + 1;
        let parsed = parse_all(path, i + 1, &tokens)?;
        if parsed.iter().any(|v| !v.is_finite()) {
            return Err(Kitti360Error::parse(path, i + 1, "non-finite number"));
        }
        values.extend(parsed);
    }
    match values.len() == n {
        true => Ok(values),
        false => Err(Kitti360Error::parse(
            path,
            last_line,
            format!("expected {n} numbers, found {}", values.len()),
        )),
    }
}
