//! The text side of the KITTI layout: reading whole files, numbers with line numbers for
//! errors, `key: v1 v2 ...` files, 3x4 row-major transforms, and the one fixed number format
//! the writer uses so its output is byte-deterministic.

use std::path::{Path, PathBuf};

use glam::{DAffine3, DMat3, DVec3};

use super::error::Kitti360Error;

/// The whole of a text file; a missing file is [`Kitti360Error::MissingFile`].
pub fn read_text(path: &Path) -> Result<String, Kitti360Error> {
    std::fs::read_to_string(path).map_err(|e| Kitti360Error::io(path, e))
}

/// Writes `text` to `path`, creating the parent directories, atomically
/// ([`renderer::atomic`]): a reader sees the old file or the whole new one, never part of it.
/// Sequences written into one root by parallel processes each check the shared calibration
/// files against their own (`SequenceWriter::create`), and a half-written file read that way
/// would fail one of them.
pub fn write_text(path: &Path, text: &str) -> Result<(), Kitti360Error> {
    create_parent(path)?;
    renderer::atomic::write_bytes_atomic(path, text.as_bytes())
        .map_err(|e| Kitti360Error::io(path, e))
}

/// Creates the directory that will hold `path`.
pub fn create_parent(path: &Path) -> Result<(), Kitti360Error> {
    match path.parent() {
        Some(dir) => std::fs::create_dir_all(dir).map_err(|e| Kitti360Error::io(dir, e)),
        None => Ok(()),
    }
}

/// One number of a text file; `nan` and `inf` parse (pose readers skip such frames).
pub fn parse_f64(path: &Path, line: usize, token: &str) -> Result<f64, Kitti360Error> {
    token
        .parse::<f64>()
        .map_err(|_| Kitti360Error::parse(path, line, format!("`{token}` is not a number")))
}

/// A frame index: a non-negative integer (`250`, or `250.0` as numpy's `savetxt` writes).
pub fn parse_index(path: &Path, line: usize, token: &str) -> Result<u32, Kitti360Error> {
    if let Ok(i) = token.parse::<u32>() {
        return Ok(i);
    }
    match token.parse::<f64>() {
        Ok(v) if v >= 0.0 && v <= u32::MAX as f64 && v.fract() == 0.0 => Ok(v as u32),
        _ => Err(Kitti360Error::parse(
            path,
            line,
            format!("`{token}` is not a frame index"),
        )),
    }
}

/// Every number of `tokens`, or the first bad one as an error at `line`.
pub fn parse_all(path: &Path, line: usize, tokens: &[&str]) -> Result<Vec<f64>, Kitti360Error> {
    tokens.iter().map(|t| parse_f64(path, line, t)).collect()
}

/// A file of `key: values` lines (`perspective.txt`, `calib_cam_to_pose.txt`). Values are
/// kept as text until asked for, since some keys hold non-numbers (`calib_time`).
#[derive(Debug)]
pub struct KeyedFile {
    path: PathBuf,
    entries: Vec<(String, usize, String)>,
}

impl KeyedFile {
    /// Reads and splits `path`; a non-blank line without `key:` is a parse error.
    pub fn read(path: &Path) -> Result<Self, Kitti360Error> {
        let text = read_text(path)?;
        let mut entries = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if line.is_empty() {
                continue;
            }
            let Some((key, rest)) = line.split_once(':') else {
                return Err(Kitti360Error::parse(path, i + 1, "expected `key: values`"));
            };
            let key = key.trim();
            if key.is_empty() || key.contains(char::is_whitespace) {
                return Err(Kitti360Error::parse(path, i + 1, "expected `key: values`"));
            }
            entries.push((key.to_string(), i + 1, rest.trim().to_string()));
        }
        Ok(Self {
            path: path.to_path_buf(),
            entries,
        })
    }

    /// Exactly `n` numbers under `key` (the first line with that key, as the devkit reads).
    pub fn numbers(&self, key: &str, n: usize) -> Result<Vec<f64>, Kitti360Error> {
        let Some((_, line, rest)) = self.entries.iter().find(|(k, _, _)| k == key) else {
            return Err(Kitti360Error::MissingKey {
                path: self.path.clone(),
                key: key.to_string(),
            });
        };
        let tokens: Vec<&str> = rest.split_whitespace().collect();
        if tokens.len() != n {
            return Err(Kitti360Error::parse(
                &self.path,
                *line,
                format!("`{key}` needs {n} numbers, found {}", tokens.len()),
            ));
        }
        let values = parse_all(&self.path, *line, &tokens)?;
        match values.iter().all(|v| v.is_finite()) {
            true => Ok(values),
            false => Err(Kitti360Error::parse(
                &self.path,
                *line,
                format!("`{key}` holds a non-finite number"),
            )),
        }
    }

    /// The 1-based line of `key`, for errors about its values.
    pub fn line_of(&self, key: &str) -> usize {
        self.entries
            .iter()
            .find(|(k, _, _)| k == key)
            .map_or(0, |(_, line, _)| *line)
    }
}

/// A rigid (or any affine) transform from 12 numbers: a 3x4 matrix `[R | t]`, row major.
pub fn affine_from_rows(v: &[f64]) -> DAffine3 {
    let r = DMat3::from_cols(
        DVec3::new(v[0], v[4], v[8]),
        DVec3::new(v[1], v[5], v[9]),
        DVec3::new(v[2], v[6], v[10]),
    );
    DAffine3::from_mat3_translation(r, DVec3::new(v[3], v[7], v[11]))
}

/// The 12 numbers of `[R | t]`, row major.
pub fn affine_rows(a: &DAffine3) -> [f64; 12] {
    let (m, t) = (a.matrix3, a.translation);
    [
        m.x_axis.x, m.y_axis.x, m.z_axis.x, t.x, //
        m.x_axis.y, m.y_axis.y, m.z_axis.y, t.y, //
        m.x_axis.z, m.y_axis.z, m.z_axis.z, t.z,
    ]
}

/// A 3x3 matrix from 9 numbers, row major.
pub fn mat3_from_rows(v: &[f64]) -> DMat3 {
    DMat3::from_cols_array(&[v[0], v[3], v[6], v[1], v[4], v[7], v[2], v[5], v[8]])
}

/// The 9 numbers of a 3x3 matrix, row major.
pub fn mat3_rows(m: &DMat3) -> [f64; 9] {
    m.transpose().to_cols_array()
}

/// One number in the writer's fixed format: C's `%.15e` (`-7.051110000000000e-01`), the
/// shape of KITTI's `%e` columns with enough digits that f64 values survive to ~1e-16
/// relative (a pose 100 km from the origin to ~1e-11 m). Negative zero is written as zero.
pub fn sci(v: f64) -> String {
    let v = if v == 0.0 { 0.0 } else { v };
    let s = format!("{v:.15e}");
    match s.split_once('e') {
        Some((mantissa, exp)) => {
            let e: i32 = exp.parse().unwrap_or(0);
            let sign = if e < 0 { '-' } else { '+' };
            format!("{mantissa}e{sign}{:02}", e.abs())
        }
        None => s, // NaN and inf have no exponent
    }
}

/// Numbers joined by single spaces in the [`sci`] format.
pub fn sci_join(values: &[f64]) -> String {
    values.iter().map(|&v| sci(v)).collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sci_looks_like_c_printf() {
        assert_eq!(sci(552.554261), "5.525542610000000e+02");
        assert_eq!(sci(-0.0), "0.000000000000000e+00");
        assert_eq!(sci(-1.5e-7), "-1.500000000000000e-07");
        assert_eq!(sci(1e100), "1.000000000000000e+100");
    }

    #[test]
    fn rows_round_trip() {
        let v: Vec<f64> = (0..12).map(|i| i as f64 + 0.5).collect();
        assert_eq!(affine_rows(&affine_from_rows(&v)).to_vec(), v);
        let m: Vec<f64> = (0..9).map(|i| i as f64).collect();
        assert_eq!(mat3_rows(&mat3_from_rows(&m)).to_vec(), m);
    }
}
