//! Procedural, band-limited texture building blocks: hashing, box-filtered stripes and
//! value noise whose octaves fade out once the pixel footprint exceeds their cell size, so
//! distant detail turns into its mean colour instead of aliasing.

/// A 64-bit mixing function (splitmix64 finaliser): the generator's deterministic hash for
/// per-segment seeds and noise lattices.
pub fn mix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// Hash of a seed and two lattice coordinates to [0, 1).
fn lattice(seed: u64, i: i64, j: i64) -> f64 {
    let h = mix64(seed ^ mix64(i as u64 ^ mix64(j as u64)));
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Antiderivative of a unit-period square wave that is 1 on [0, duty) and 0 elsewhere.
fn square_integral(x: f64, duty: f64) -> f64 {
    let f = x.floor();
    f * duty + (x - f).min(duty)
}

/// Fraction of a box filter of width `w` (in periods) centred at `x` (in periods) covered by
/// a periodic stripe of relative width `duty`: an exactly filtered square wave.
pub fn stripes(x: f64, duty: f64, w: f64) -> f64 {
    if w < 1e-6 {
        return if x - x.floor() < duty { 1.0 } else { 0.0 };
    }
    ((square_integral(x + 0.5 * w, duty) - square_integral(x - 0.5 * w, duty)) / w).clamp(0.0, 1.0)
}

/// Fraction of a box filter of width `w` centred at `x` that lies inside `[a, b]`.
pub fn band(x: f64, a: f64, b: f64, w: f64) -> f64 {
    let w = w.max(1e-6);
    let lo = (x - 0.5 * w).max(a);
    let hi = (x + 0.5 * w).min(b);
    ((hi - lo) / w).clamp(0.0, 1.0)
}

/// Smooth value noise in [0, 1) on a lattice of unit cells.
fn value_noise(seed: u64, x: f64, y: f64) -> f64 {
    let (xi, yi) = (x.floor(), y.floor());
    let (fx, fy) = (x - xi, y - yi);
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let (i, j) = (xi as i64, yi as i64);
    let a = lattice(seed, i, j);
    let b = lattice(seed, i + 1, j);
    let c = lattice(seed, i, j + 1);
    let d = lattice(seed, i + 1, j + 1);
    let top = a + (b - a) * sx;
    let bottom = c + (d - c) * sx;
    top + (bottom - top) * sy
}

/// How much of a detail with cell size `cell` survives a filter footprint `w` (same units):
/// 1 while the cell spans several footprints, 0 once a footprint covers a whole cell.
pub fn detail_weight(cell: f64, w: f64) -> f64 {
    (1.0 - (w / cell - 0.25) / 0.75).clamp(0.0, 1.0)
}

/// Fractal value noise centred on 0 (roughly [-0.5, 0.5]): `octaves` octaves starting at
/// cell size `cell`, each halving the cell, each faded by the footprint `w`.
pub fn fbm(seed: u64, x: f64, y: f64, cell: f64, octaves: u32, w: f64) -> f64 {
    let mut sum = 0.0;
    let mut amp = 0.5;
    let mut c = cell;
    for o in 0..octaves {
        let keep = detail_weight(c, w);
        if keep <= 0.0 {
            break;
        }
        let n = value_noise(seed.wrapping_add(o as u64), x / c, y / c) - 0.5;
        sum += amp * keep * n;
        amp *= 0.5;
        c *= 0.5;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filtered_stripes_average_to_duty() {
        assert!((stripes(0.3, 0.25, 4.0) - 0.25).abs() < 1e-12);
        assert_eq!(stripes(0.1, 0.25, 0.0), 1.0);
        assert!((band(0.0, -1.0, 1.0, 4.0) - 0.5).abs() < 1e-12);
    }
}
