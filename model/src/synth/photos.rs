//! The photo texture bank: 128x128 tiles cut from real photographs
//! (`model/textures/photo_bank.png`, made by `scripts/texture_bank.py` from the photographs in
//! the scikit-image wheel; licences in `model/textures/ATTRIBUTION.md`), mapped onto surfaces
//! by the domain randomisation so that the network sees the statistics of real images, not
//! only the generator's procedural ones (FlyingThings3D's recipe).
//!
//! Sampling is filtered for the pixel footprint: each tile keeps a box-filtered mip chain,
//! and a lookup blends the two levels around the footprint (trilinear), so a photographed
//! wall far away turns into its mean colour instead of aliasing.

use std::sync::OnceLock;

use glam::DVec3;

/// Side of one tile in texels.
pub const TILE: usize = 128;

/// The atlas, embedded so that generation never reads a file at run time.
const ATLAS_PNG: &[u8] = include_bytes!("../../textures/photo_bank.png");

/// One tile's mip chain: level 0 is `TILE` x `TILE`, each next level half the side.
struct Tile {
    levels: Vec<Vec<[f32; 3]>>,
}

impl Tile {
    fn from_atlas(atlas: &image::RgbImage, column: u32, row: u32) -> Self {
        let mut base = Vec::with_capacity(TILE * TILE);
        for y in 0..TILE as u32 {
            for x in 0..TILE as u32 {
                let p = atlas
                    .get_pixel(column * TILE as u32 + x, row * TILE as u32 + y)
                    .0;
                // The generator's albedos are display values, as the photo's bytes are.
                base.push(p.map(|c| c as f32 / 255.0));
            }
        }
        let mut levels = vec![base];
        let mut side = TILE;
        while side > 1 {
            let prev = levels.last().expect("level 0 exists");
            let half = side / 2;
            let mut next = Vec::with_capacity(half * half);
            for y in 0..half {
                for x in 0..half {
                    let mut sum = [0.0f32; 3];
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let p = prev[(2 * y + dy) * side + 2 * x + dx];
                        for c in 0..3 {
                            sum[c] += 0.25 * p[c];
                        }
                    }
                    next.push(sum);
                }
            }
            levels.push(next);
            side = half;
        }
        Self { levels }
    }

    /// Bilinear lookup with wrap-around at `level`, texture coordinates in tiles.
    fn bilinear(&self, level: usize, u: f64, v: f64) -> DVec3 {
        let data = &self.levels[level];
        let side = TILE >> level;
        let x = u.rem_euclid(1.0) * side as f64 - 0.5;
        let y = v.rem_euclid(1.0) * side as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |i: f64, j: f64| {
            let i = (i as i64).rem_euclid(side as i64) as usize;
            let j = (j as i64).rem_euclid(side as i64) as usize;
            let p = data[j * side + i];
            DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
        };
        let top = at(x0, y0).lerp(at(x0 + 1.0, y0), fx);
        let bottom = at(x0, y0 + 1.0).lerp(at(x0 + 1.0, y0 + 1.0), fx);
        top.lerp(bottom, fy)
    }
}

/// Every tile of the atlas, decoded once per process.
pub struct PhotoBank {
    tiles: Vec<Tile>,
}

impl PhotoBank {
    /// The shared bank (decoded on first use).
    pub fn get() -> &'static PhotoBank {
        static BANK: OnceLock<PhotoBank> = OnceLock::new();
        BANK.get_or_init(|| {
            let atlas = image::load_from_memory_with_format(ATLAS_PNG, image::ImageFormat::Png)
                .expect("the embedded photo bank is a valid PNG (scripts/texture_bank.py)")
                .to_rgb8();
            let (columns, rows) = (atlas.width() / TILE as u32, atlas.height() / TILE as u32);
            let tiles = (0..rows)
                .flat_map(|r| (0..columns).map(move |c| (c, r)))
                .map(|(c, r)| Tile::from_atlas(&atlas, c, r))
                .collect();
            PhotoBank { tiles }
        })
    }

    /// Number of tiles.
    pub fn len(&self) -> usize {
        self.tiles.len()
    }

    /// Whether the bank is empty (never, for the shipped atlas).
    pub fn is_empty(&self) -> bool {
        self.tiles.is_empty()
    }

    /// Albedo of tile `tile` (taken modulo the bank's size) at surface coordinates `(u, v)`
    /// metres, the tile repeating every `period` metres, for a footprint of `w` metres.
    pub fn sample(&self, tile: usize, u: f64, v: f64, period: f64, w: f64) -> DVec3 {
        let tile = &self.tiles[tile % self.tiles.len()];
        let period = period.max(1e-3);
        let texels = (w / period * TILE as f64).max(1.0);
        let level = texels.log2().clamp(0.0, (tile.levels.len() - 1) as f64);
        let lo = level.floor() as usize;
        let hi = (lo + 1).min(tile.levels.len() - 1);
        let (u, v) = (u / period, v / period);
        tile.bilinear(lo, u, v)
            .lerp(tile.bilinear(hi, u, v), level - lo as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bank_decodes_and_far_lookups_average_the_tile() {
        let bank = PhotoBank::get();
        assert_eq!(bank.len(), 48);
        let last = bank.tiles[0].levels.last().unwrap()[0];
        let mean = DVec3::new(last[0] as f64, last[1] as f64, last[2] as f64);
        // A footprint far larger than the tile returns the tile's mean, anywhere.
        for (u, v) in [(0.1, 0.2), (5.3, -7.9)] {
            let far = bank.sample(0, u, v, 1.0, 1000.0);
            assert!((far - mean).length() < 1e-6, "{far} vs {mean}");
        }
        // Near lookups vary and stay in [0, 1] with no NaN.
        let a = bank.sample(3, 0.1, 0.1, 1.0, 0.001);
        let b = bank.sample(3, 0.6, 0.4, 1.0, 0.001);
        assert!((a - b).length() > 1e-3);
        for p in [a, b, bank.sample(7, 1e9, -1e9, 1e-9, 0.0)] {
            assert!(p.is_finite() && p.min_element() >= 0.0 && p.max_element() <= 1.0);
        }
    }
}
