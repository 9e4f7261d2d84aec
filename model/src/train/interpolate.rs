//! Weight-space interpolation of two trained end points of the same network: every tensor
//! becomes `(1 - t) * from + t * to`. Fine-tuning for a new domain (real rooms) moves the
//! weights away from what the old domain (the streets) wants; a point on the straight line
//! between the two runs often keeps most of both, and sometimes beats both (WiSE-FT,
//! Wortsman et al., "Robust fine-tuning of zero-shot models", CVPR 2022). The shipped
//! `tiny-3d` weights are such a blend (`scripts/train_tiny_3d.sh`, `results/tiny_3d/`).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use candle_core::{DType, Device, Tensor};
use thiserror::Error;

/// Why two weight files could not be interpolated.
#[derive(Debug, Error)]
pub enum InterpolateError {
    /// The factor is not a number in [0, 1] (outside it the line is extrapolated).
    #[error("interpolation factor {0} is not in [0, 1]")]
    Factor(f64),
    /// A weight file could not be read.
    #[error("cannot read weights {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// candle's reason.
        #[source]
        source: candle_core::Error,
    },
    /// A tensor is in one file but not the other: the files are of different networks.
    #[error("{name} is in one weight file but not the other (different networks?)")]
    Missing {
        /// The tensor's name.
        name: String,
    },
    /// A tensor has different shapes in the two files.
    #[error("{name} is {from:?} in the first weight file but {to:?} in the second")]
    Shape {
        /// The tensor's name.
        name: String,
        /// Its shape in the first file.
        from: Vec<usize>,
        /// Its shape in the second file.
        to: Vec<usize>,
    },
    /// A tensor is not floating point (an index or a count cannot be interpolated).
    #[error("{name} is {dtype:?}, not a floating-point tensor")]
    NotFloat {
        /// The tensor's name.
        name: String,
        /// Its type.
        dtype: DType,
    },
    /// A tensor holds NaN or infinity after interpolation (one of the inputs did).
    #[error("{name} is not finite after interpolation (NaN or Inf in an input)")]
    NonFinite {
        /// The tensor's name.
        name: String,
    },
    /// candle failed on a tensor.
    #[error("cannot interpolate {name}")]
    Compute {
        /// The tensor's name.
        name: String,
        /// candle's reason.
        #[source]
        source: candle_core::Error,
    },
    /// The result could not be written.
    #[error("cannot write weights {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// candle's reason.
        #[source]
        source: candle_core::Error,
    },
}

/// `(1 - t) * from + t * to` for every tensor of two weight maps with the same names and
/// shapes, computed in f64 and stored in each tensor's own type, so `t = 0` gives `from`
/// and `t = 1` gives `to` bit for bit.
pub fn interpolate(
    from: &HashMap<String, Tensor>,
    to: &HashMap<String, Tensor>,
    t: f64,
) -> Result<HashMap<String, Tensor>, InterpolateError> {
    if !(0.0..=1.0).contains(&t) {
        return Err(InterpolateError::Factor(t));
    }
    let in_both = |k: &&String| from.contains_key(*k) && to.contains_key(*k);
    if let Some(name) = from.keys().chain(to.keys()).find(|k| !in_both(k)) {
        return Err(InterpolateError::Missing { name: name.clone() });
    }
    from.iter()
        .map(|(name, a)| {
            let b = &to[name];
            if a.dims() != b.dims() {
                return Err(InterpolateError::Shape {
                    name: name.clone(),
                    from: a.dims().to_vec(),
                    to: b.dims().to_vec(),
                });
            }
            for dtype in [a.dtype(), b.dtype()] {
                if !dtype.is_float() {
                    let name = name.clone();
                    return Err(InterpolateError::NotFloat { name, dtype });
                }
            }
            Ok((name.clone(), mix(name, a, b, t)?))
        })
        .collect()
}

/// One tensor of [`interpolate`], checked finite.
fn mix(name: &str, a: &Tensor, b: &Tensor, t: f64) -> Result<Tensor, InterpolateError> {
    let compute = |source| InterpolateError::Compute {
        name: name.to_string(),
        source,
    };
    let a64 = a.to_dtype(DType::F64).map_err(compute)?;
    let b64 = b.to_dtype(DType::F64).map_err(compute)?;
    let mixed = ((a64 * (1.0 - t)).map_err(compute)? + (b64 * t).map_err(compute)?)
        .and_then(|m| m.to_dtype(a.dtype()))
        .map_err(compute)?;
    // Checked as stored: `to` may be a wider type whose values overflow `from`'s.
    let finite = mixed
        .to_dtype(DType::F64)
        .and_then(|m| m.flatten_all())
        .and_then(|m| m.to_vec1::<f64>())
        .map_err(compute)?
        .iter()
        .all(|v| v.is_finite());
    if !finite {
        return Err(InterpolateError::NonFinite {
            name: name.to_string(),
        });
    }
    Ok(mixed)
}

/// [`interpolate`] on two safetensors files, written to `out`; returns how many tensors it
/// wrote.
pub fn interpolate_files(
    from: &Path,
    to: &Path,
    t: f64,
    out: &Path,
) -> Result<usize, InterpolateError> {
    let read = |path: &Path| {
        candle_core::safetensors::load(path, &Device::Cpu).map_err(|source| {
            InterpolateError::Read {
                path: path.to_path_buf(),
                source,
            }
        })
    };
    let mixed = interpolate(&read(from)?, &read(to)?, t)?;
    candle_core::safetensors::save(&mixed, out).map_err(|source| InterpolateError::Write {
        path: out.to_path_buf(),
        source,
    })?;
    Ok(mixed.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(pairs: &[(&str, Tensor)]) -> HashMap<String, Tensor> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect()
    }

    fn values(m: &HashMap<String, Tensor>, name: &str) -> Vec<f32> {
        m[name].flatten_all().unwrap().to_vec1::<f32>().unwrap()
    }

    fn vec(v: &[f32]) -> Tensor {
        Tensor::new(v, &Device::Cpu).unwrap()
    }

    #[test]
    fn end_points_are_exact_and_a_quarter_is_a_quarter_of_the_way() {
        let from = map(&[("w", vec(&[0.1, -3.0, 1e-30, 7.25]))]);
        let to = map(&[("w", vec(&[0.3, 5.0, -1e-30, 7.25]))]);
        assert_eq!(
            values(&interpolate(&from, &to, 0.0).unwrap(), "w"),
            values(&from, "w")
        );
        assert_eq!(
            values(&interpolate(&from, &to, 1.0).unwrap(), "w"),
            values(&to, "w")
        );
        let q = values(&interpolate(&from, &to, 0.25).unwrap(), "w");
        assert!((q[0] - 0.15).abs() < 1e-7, "{q:?}");
        assert_eq!(q[1], -1.0);
        assert_eq!(q[3], 7.25);
    }

    #[test]
    fn extremes_stay_finite_and_keep_their_type() {
        // Near f32's largest value: an f32 sum would overflow, the f64 one does not.
        let big = f32::MAX * 0.9;
        let from = map(&[("w", vec(&[big, -big, f32::MIN_POSITIVE, 0.0]))]);
        let to = map(&[("w", vec(&[big, -big, 0.0, f32::MIN_POSITIVE]))]);
        let out = interpolate(&from, &to, 0.5).unwrap();
        assert_eq!(out["w"].dtype(), DType::F32);
        let v = values(&out, "w");
        assert!(v.iter().all(|x| x.is_finite()), "{v:?}");
        assert!((v[0] / big - 1.0).abs() < 1e-6);
    }

    #[test]
    fn mismatched_files_and_bad_factors_are_typed_errors() {
        let a = map(&[("w", vec(&[1.0, 2.0]))]);
        let other_name = map(&[("v", vec(&[1.0, 2.0]))]);
        let other_shape = map(&[("w", vec(&[1.0, 2.0, 3.0]))]);
        let not_finite = map(&[("w", vec(&[1.0, f32::NAN]))]);
        let ints = map(&[("w", Tensor::new(&[1u32, 2], &Device::Cpu).unwrap())]);
        let err = |e: InterpolateError| e.to_string();
        assert!(matches!(
            interpolate(&a, &other_name, 0.5),
            Err(InterpolateError::Missing { .. })
        ));
        assert!(matches!(
            interpolate(&other_name, &a, 0.5),
            Err(InterpolateError::Missing { .. })
        ));
        let shape = interpolate(&a, &other_shape, 0.5).map_err(err).unwrap_err();
        assert!(shape.contains("[2]") && shape.contains("[3]"), "{shape}");
        assert!(matches!(
            interpolate(&a, &not_finite, 0.5),
            Err(InterpolateError::NonFinite { .. })
        ));
        assert!(matches!(
            interpolate(&a, &ints, 0.5),
            Err(InterpolateError::NotFloat { .. })
        ));
        for t in [-0.1, 1.5, f64::NAN] {
            assert!(matches!(
                interpolate(&a, &a, t),
                Err(InterpolateError::Factor(_))
            ));
        }
    }

    #[test]
    fn files_round_trip_and_a_missing_file_names_itself() {
        let dir = std::env::temp_dir().join(format!("stereosplat-interp-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (from, to, out) = (dir.join("a.st"), dir.join("b.st"), dir.join("m.st"));
        candle_core::safetensors::save(&map(&[("w", vec(&[0.0, 4.0]))]), &from).unwrap();
        candle_core::safetensors::save(&map(&[("w", vec(&[2.0, 0.0]))]), &to).unwrap();
        assert_eq!(interpolate_files(&from, &to, 0.5, &out).unwrap(), 1);
        let back = candle_core::safetensors::load(&out, &Device::Cpu).unwrap();
        assert_eq!(values(&back, "w"), vec![1.0, 2.0]);
        let missing = dir.join("none.st");
        let e = interpolate_files(&missing, &to, 0.5, &out).unwrap_err();
        assert!(e.to_string().contains("none.st"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
