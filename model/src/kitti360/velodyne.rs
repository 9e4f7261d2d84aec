//! Velodyne scans, `data_3d_raw/<seq>/velodyne_points/data/%010d.bin`: a flat array of
//! little-endian float32 `x y z reflectance`, 16 bytes a point, in the velodyne frame (x
//! forward, y left, z up), as the devkit's `loadVelodyneData` reads them
//! (`np.fromfile(..., dtype=np.float32).reshape(-1, 4)`). The scans are raw: the devkit
//! optionally "curls" them to undo the ego-motion during a sweep, this module does not.

use std::path::Path;

use super::error::Kitti360Error;
use super::text::create_parent;

/// Bytes per point: four float32.
const POINT_BYTES: usize = 16;

/// Reads one scan. An empty file is [`Kitti360Error::EmptyLidar`]; a length that is not a
/// multiple of 16 is [`Kitti360Error::BadLidarLength`].
pub fn read_scan(path: &Path) -> Result<Vec<[f32; 4]>, Kitti360Error> {
    let bytes = std::fs::read(path).map_err(|e| Kitti360Error::io(path, e))?;
    if bytes.is_empty() {
        return Err(Kitti360Error::EmptyLidar { path: path.into() });
    }
    if bytes.len() % POINT_BYTES != 0 {
        return Err(Kitti360Error::BadLidarLength {
            path: path.into(),
            len: bytes.len() as u64,
        });
    }
    Ok(bytes
        .chunks_exact(POINT_BYTES)
        .map(|p| {
            let f = |i: usize| f32::from_le_bytes([p[i], p[i + 1], p[i + 2], p[i + 3]]);
            [f(0), f(4), f(8), f(12)]
        })
        .collect())
}

/// Writes one scan (creating its directory). An empty scan is refused, since the reader
/// would refuse the file.
pub fn write_scan(path: &Path, points: &[[f32; 4]]) -> Result<(), Kitti360Error> {
    if points.is_empty() {
        return Err(Kitti360Error::EmptyLidar { path: path.into() });
    }
    let bytes: Vec<u8> = points
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    create_parent(path)?;
    std::fs::write(path, bytes).map_err(|e| Kitti360Error::io(path, e))
}
