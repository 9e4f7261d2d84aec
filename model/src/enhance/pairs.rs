//! The enhancer's training pairs on disk: per pair five PNGs (`<id>_render.png`,
//! `<id>_alpha.png`, `<id>_confidence.png`, `<id>_reference.png`, `<id>_target.png`; 8 bit,
//! the grey ones single-channel) and one row in `pairs.csv` naming where it came from. A
//! draw's rows are appended only after all its pictures are written, so the index never
//! names a missing file and a stopped `enhancer-data` resumes after its last whole draw.

use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};

use candle_core::{Device, Tensor};
use image::{GrayImage, RgbImage as Rgb8};

use super::EnhanceError;

/// The index's header.
pub const INDEX_COLUMNS: &str = "id,draw,sequence,first,target,side,input_pairs,weights";

/// One row of `pairs.csv`.
#[derive(Clone, Debug, PartialEq)]
pub struct PairRecord {
    /// The pair's number (file names `<id:06>_*.png`).
    pub id: usize,
    /// The draw (one bin, input pairs and weights) it came from.
    pub draw: usize,
    /// The sequence's name.
    pub sequence: String,
    /// The bin's first frame (its left image is the reference view).
    pub first: u32,
    /// The rendered frame.
    pub target: u32,
    /// `left` or `right`.
    pub side: String,
    /// Input stereo pairs the Gaussians came from.
    pub input_pairs: usize,
    /// Label of the weights that made the Gaussians.
    pub weights: String,
}

impl PairRecord {
    fn to_row(&self) -> String {
        format!(
            "{},{},{},{},{},{},{},{}",
            self.id,
            self.draw,
            self.sequence,
            self.first,
            self.target,
            self.side,
            self.input_pairs,
            self.weights
        )
    }

    fn parse(line: &str) -> Option<Self> {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 8 {
            return None;
        }
        Some(Self {
            id: f[0].parse().ok()?,
            draw: f[1].parse().ok()?,
            sequence: f[2].to_string(),
            first: f[3].parse().ok()?,
            target: f[4].parse().ok()?,
            side: f[5].to_string(),
            input_pairs: f[6].parse().ok()?,
            weights: f[7].to_string(),
        })
    }
}

/// A pair's pictures as `(C, H, W)` tensors in `[0, 1]`.
pub struct PairImages {
    /// RGB, alpha, confidence of the render, `(5, H, W)`.
    pub render: Tensor,
    /// The bin's first left image, `(3, H, W)`.
    pub reference: Tensor,
    /// The true image, `(3, H, W)`.
    pub target: Tensor,
}

/// The pictures of one pair before they are written: interleaved RGB and single-channel
/// planes, values in `[0, 1]`, all `width` x `height`.
pub struct PairPictures<'a> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The render's RGB.
    pub render: &'a [f32],
    /// Its accumulated opacity.
    pub alpha: &'a [f32],
    /// Its composited confidence.
    pub confidence: &'a [f32],
    /// The reference view's RGB.
    pub reference: &'a [f32],
    /// The true image's RGB.
    pub target: &'a [f32],
}

fn to_u8(v: &[f32]) -> Vec<u8> {
    v.iter()
        .map(|&x| renderer::picture::unit_to_u8(x))
        .collect()
}

/// The file of pair `id`'s picture `kind` under `dir`.
pub fn pair_file(dir: &Path, id: usize, kind: &str) -> PathBuf {
    dir.join(format!("{id:06}_{kind}.png"))
}

/// Writes pair `id`'s five pictures into `dir`.
pub fn write_pictures(dir: &Path, id: usize, p: &PairPictures) -> Result<(), EnhanceError> {
    let (w, h) = (p.width, p.height);
    let save_err = |path: PathBuf| move |source| EnhanceError::Image { path, source };
    for (kind, rgb) in [
        ("render", p.render),
        ("reference", p.reference),
        ("target", p.target),
    ] {
        let path = pair_file(dir, id, kind);
        let img = Rgb8::from_raw(w, h, to_u8(rgb)).ok_or_else(|| EnhanceError::size(&path))?;
        img.save(&path).map_err(save_err(path.clone()))?;
    }
    for (kind, grey) in [("alpha", p.alpha), ("confidence", p.confidence)] {
        let path = pair_file(dir, id, kind);
        let img =
            GrayImage::from_raw(w, h, to_u8(grey)).ok_or_else(|| EnhanceError::size(&path))?;
        img.save(&path).map_err(save_err(path.clone()))?;
    }
    Ok(())
}

/// Appends `records` to `dir/pairs.csv` (writing the header first if the file is new).
pub fn append_records(dir: &Path, records: &[PairRecord]) -> Result<(), EnhanceError> {
    let path = dir.join("pairs.csv");
    let new = !path.exists();
    let mut file = OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .map_err(EnhanceError::io(&path))?;
    let mut text = String::new();
    if new {
        text.push_str(INDEX_COLUMNS);
        text.push('\n');
    }
    for r in records {
        text.push_str(&r.to_row());
        text.push('\n');
    }
    file.write_all(text.as_bytes())
        .map_err(EnhanceError::io(&path))
}

/// The pairs of a folder written by `enhancer-data`.
pub struct PairSet {
    dir: PathBuf,
    records: Vec<PairRecord>,
}

impl PairSet {
    /// Reads `dir/pairs.csv` (no file: no pairs). A malformed row is an error.
    pub fn open(dir: &Path) -> Result<Self, EnhanceError> {
        let path = dir.join("pairs.csv");
        let records = match std::fs::read_to_string(&path) {
            Ok(text) => text
                .lines()
                .skip(1)
                .filter(|l| !l.trim().is_empty())
                .map(|l| {
                    PairRecord::parse(l).ok_or_else(|| EnhanceError::Index {
                        path: path.clone(),
                        line: l.to_string(),
                    })
                })
                .collect::<Result<_, _>>()?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
            Err(e) => return Err(EnhanceError::io(&path)(e)),
        };
        Ok(Self {
            dir: dir.to_path_buf(),
            records,
        })
    }

    /// The index's rows.
    pub fn records(&self) -> &[PairRecord] {
        &self.records
    }

    /// How many pairs there are.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Reads pair `i` (of [`Self::len`]).
    pub fn load(&self, i: usize, device: &Device) -> Result<PairImages, EnhanceError> {
        let id = self.records[i].id;
        let read = |kind: &str, rgb: bool| -> Result<Tensor, EnhanceError> {
            let path = pair_file(&self.dir, id, kind);
            let img = image::open(&path).map_err(|source| EnhanceError::Image {
                path: path.clone(),
                source,
            })?;
            let (w, h) = (img.width() as usize, img.height() as usize);
            let (bytes, c) = match rgb {
                true => (img.to_rgb8().into_raw(), 3),
                false => (img.to_luma8().into_raw(), 1),
            };
            let data: Vec<f32> = bytes.iter().map(|&b| b as f32 / 255.0).collect();
            Ok(Tensor::from_vec(data, (h, w, c), device)?
                .permute((2, 0, 1))?
                .contiguous()?)
        };
        let render = Tensor::cat(
            &[
                read("render", true)?,
                read("alpha", false)?,
                read("confidence", false)?,
            ],
            0,
        )?;
        Ok(PairImages {
            render,
            reference: read("reference", true)?,
            target: read("target", true)?,
        })
    }

    /// Pairs `indices` as a batch `(B, C, H, W)` of each part; with `flip`, every image of
    /// the batch mirrored left to right (render, reference and target alike).
    pub fn batch(
        &self,
        indices: &[usize],
        flip: bool,
        device: &Device,
    ) -> Result<PairImages, EnhanceError> {
        let pairs = indices
            .iter()
            .map(|&i| self.load(i, device))
            .collect::<Result<Vec<_>, _>>()?;
        let stack = |f: &dyn Fn(&PairImages) -> &Tensor| -> Result<Tensor, EnhanceError> {
            let t = Tensor::stack(&pairs.iter().map(f).collect::<Vec<_>>(), 0)?;
            Ok(match flip {
                true => t.flip(&[3])?,
                false => t,
            })
        };
        Ok(PairImages {
            render: stack(&|p| &p.render)?,
            reference: stack(&|p| &p.reference)?,
            target: stack(&|p| &p.target)?,
        })
    }
}
