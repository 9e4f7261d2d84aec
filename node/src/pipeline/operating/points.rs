//! The operating points of `bench pareto`, read from a TOML list (`launch/pareto.toml`):
//!
//! ```toml
//! [[point]]
//! name = "tiny-c16"          # unique, shown on the chart
//! method = "stereosplat"     # model::methods name (default stereosplat)
//! preset = "tiny"            # learned methods only (default tiny)
//! weights = "path.safetensors"  # default: the preset's shipped file
//! set = ["candidates=16"]    # model::net::Config::with_settings
//! scale = 0.5                # input resolution scale (renders stay at full size)
//! pairs = 1                  # input stereo pairs per bin
//! ```
//!
//! A file that does not parse or names a point twice is a typed error; a point whose weight
//! file is missing is not an error but [`Availability::Missing`], so a list can name
//! operating points whose weights are still training.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use model::methods::MethodSpec;
use serde::{Deserialize, Serialize};

/// One operating point: a reconstructor and the inference-time knobs it runs with.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "PointFields", into = "PointFields")]
pub struct OperatingPoint {
    /// Unique name, used as the label on the chart and the row in the table.
    pub name: String,
    /// The reconstructor: method, preset, weights (relative paths are taken from the working
    /// directory, as on the command line) and settings.
    pub method: MethodSpec,
    /// Input resolution scale in (0, 1]: the stereo pair and its cameras are downsized by
    /// it before the reconstructor (as the node does to `--working-pixels`); the map is
    /// still rendered and scored at the full size.
    pub scale: f64,
    /// Input stereo pairs per bin (the bin's first frames).
    pub pairs: usize,
}

/// An operating point as its files spell it (the module documentation's keys), every key
/// at the top level of its table and an unknown key an error.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PointFields {
    name: String,
    #[serde(default = "default_method")]
    method: String,
    #[serde(default)]
    preset: Option<String>,
    #[serde(default)]
    weights: Option<PathBuf>,
    #[serde(default)]
    set: Vec<String>,
    #[serde(default = "one")]
    scale: f64,
    #[serde(default = "one_pair")]
    pairs: usize,
}

impl From<PointFields> for OperatingPoint {
    fn from(f: PointFields) -> Self {
        Self {
            name: f.name,
            method: MethodSpec {
                method: f.method,
                preset: f.preset,
                weights: f.weights,
                settings: f.set,
            },
            scale: f.scale,
            pairs: f.pairs,
        }
    }
}

impl From<OperatingPoint> for PointFields {
    fn from(p: OperatingPoint) -> Self {
        Self {
            name: p.name,
            method: p.method.method,
            preset: p.method.preset,
            weights: p.method.weights,
            set: p.method.settings,
            scale: p.scale,
            pairs: p.pairs,
        }
    }
}

fn default_method() -> String {
    model::methods::DEFAULT.to_string()
}

fn one() -> f64 {
    1.0
}

fn one_pair() -> usize {
    1
}

/// The file's shape: a list of `[[point]]` tables.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PointsFile {
    point: Vec<OperatingPoint>,
}

/// Why a list of operating points could not be read.
#[derive(Debug, thiserror::Error)]
pub enum PointsError {
    /// The file could not be read.
    #[error("reading {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// Not TOML of the expected shape (unknown keys, wrong types, no `[[point]]`).
    #[error("operating points: {0}")]
    Syntax(#[from] toml::de::Error),
    /// The list is empty.
    #[error("operating points: the list is empty")]
    Empty,
    /// Two points share a name.
    #[error("operating points: `{0}` is named twice")]
    DuplicateName(String),
    /// A point's field is out of range.
    #[error("operating point `{name}`: {what}")]
    Invalid {
        /// The point.
        name: String,
        /// What is wrong.
        what: String,
    },
}

/// Whether a point can run here.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Availability {
    /// It can: the method needs no weights, or its weight file exists.
    Ready,
    /// Its weight file does not exist (skipped with this path in the report).
    Missing(PathBuf),
}

impl OperatingPoint {
    /// Whether this point's weights exist (methods without weights are always ready).
    pub fn availability(&self) -> Availability {
        match self.method.weights_file() {
            Some(path) if !model::assets::exists(&path) => Availability::Missing(path),
            _ => Availability::Ready,
        }
    }

    /// Whether the point's fields are in range: a name, a known method, a scale in (0, 1]
    /// and at least one pair.
    pub(crate) fn check(&self) -> Result<(), PointsError> {
        let invalid = |what: String| {
            Err(PointsError::Invalid {
                name: self.name.clone(),
                what,
            })
        };
        if self.name.trim().is_empty() {
            return invalid("the name is empty".into());
        }
        if !model::methods::NAMES.contains(&self.method.method.as_str()) {
            return invalid(format!(
                "unknown method `{}` (known: {})",
                self.method.method,
                model::methods::NAMES.join(", ")
            ));
        }
        if !(self.scale.is_finite() && self.scale > 0.0 && self.scale <= 1.0) {
            return invalid(format!("scale {} is not in (0, 1]", self.scale));
        }
        if self.pairs == 0 {
            return invalid("pairs must be at least 1".into());
        }
        Ok(())
    }
}

/// The points of a TOML text, checked (see the module documentation).
pub fn parse_points(text: &str) -> Result<Vec<OperatingPoint>, PointsError> {
    let file: PointsFile = toml::from_str(text)?;
    if file.point.is_empty() {
        return Err(PointsError::Empty);
    }
    let mut names = HashSet::new();
    for p in &file.point {
        p.check()?;
        if !names.insert(p.name.as_str()) {
            return Err(PointsError::DuplicateName(p.name.clone()));
        }
    }
    Ok(file.point)
}

/// The points of the TOML file at `path`.
pub fn load_points(path: &Path) -> Result<Vec<OperatingPoint>, PointsError> {
    let text = std::fs::read_to_string(path).map_err(|source| PointsError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_points(&text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_list_parses_with_defaults_filled_in() {
        let points = parse_points(
            r#"
            [[point]]
            name = "sgm"
            method = "sgm"

            [[point]]
            name = "tiny-half"
            set = ["candidates=16"]
            scale = 0.5
            pairs = 2
            "#,
        )
        .unwrap();
        assert_eq!(points.len(), 2);
        assert_eq!(points[0].method, MethodSpec::from("sgm"));
        assert_eq!((points[0].scale, points[0].pairs), (1.0, 1));
        assert_eq!(points[1].method.method, "stereosplat");
        assert_eq!(points[1].method.settings, vec!["candidates=16".to_string()]);
        assert_eq!((points[1].scale, points[1].pairs), (0.5, 2));
        assert_eq!(points[0].availability(), Availability::Ready);
    }

    #[test]
    fn bad_files_are_typed_errors() {
        let err = |t: &str| parse_points(t).unwrap_err();
        assert!(matches!(err("point = 3"), PointsError::Syntax(_)));
        assert!(matches!(
            err("[[point]]\nnam = \"x\""),
            PointsError::Syntax(_)
        ));
        assert!(matches!(
            err("[[point]]\nname = \"x\"\ncolour = 1"),
            PointsError::Syntax(_)
        ));
        assert!(matches!(err("point = []"), PointsError::Empty));
        assert!(matches!(
            err("[[point]]\nname = \"a\"\n[[point]]\nname = \"a\""),
            PointsError::DuplicateName(n) if n == "a"
        ));
        for bad in [
            "scale = 0.0",
            "scale = 1.5",
            "scale = nan",
            "pairs = 0",
            "method = \"magic\"",
        ] {
            assert!(
                matches!(
                    err(&format!("[[point]]\nname = \"p\"\n{bad}")),
                    PointsError::Invalid { name, .. } if name == "p"
                ),
                "{bad}"
            );
        }
        assert!(matches!(
            err("[[point]]\nname = \" \""),
            PointsError::Invalid { .. }
        ));
        assert!(matches!(
            load_points(Path::new("/nonexistent/pareto.toml")).unwrap_err(),
            PointsError::Io { .. }
        ));
    }

    #[test]
    fn the_shipped_points_file_parses_and_its_weight_files_are_in_the_repository() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let points = load_points(&root.join("launch/pareto.toml")).unwrap();
        assert!(points.len() >= 20, "{}", points.len());
        for p in &points {
            if let Some(w) = &p.method.weights {
                assert!(root.join(w).is_file(), "{}: {}", p.name, w.display());
            }
        }
    }

    #[test]
    fn a_missing_weight_file_is_reported_not_fatal() {
        let p = &parse_points(
            "[[point]]\nname = \"small\"\npreset = \"small\"\nweights = \"/nonexistent/w.safetensors\"",
        )
        .unwrap()[0];
        assert_eq!(
            p.availability(),
            Availability::Missing(PathBuf::from("/nonexistent/w.safetensors"))
        );
    }
}
