//! Speckle filtering, as OpenCV's `filterSpeckles`: valid pixels are grouped into regions of
//! 4-connected neighbours whose disparities differ by at most `max_step`, and regions smaller
//! than `min_region` pixels are rejected. Wrong matches come in small islands that disagree
//! with their surroundings; real surfaces form large smooth regions.

/// Sets to NaN every valid pixel of `disparity` (`width` wide, NaN = invalid) whose region
/// holds fewer than `min_region` pixels; returns how many were rejected. Memory: one label
/// per pixel and a stack, `O(W x H)`.
pub fn filter(disparity: &mut [f32], width: usize, min_region: usize, max_step: f32) -> usize {
    if width == 0 || min_region <= 1 {
        return 0;
    }
    let n = disparity.len();
    let height = n / width;
    let mut seen = vec![false; n];
    let mut stack = Vec::new();
    let mut region = Vec::new();
    let mut rejected = 0;
    for start in 0..n {
        if seen[start] || disparity[start].is_nan() {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        region.clear();
        while let Some(i) = stack.pop() {
            region.push(i);
            let (x, y) = (i % width, i / width);
            let d = disparity[i];
            let neighbours = [
                (x > 0).then(|| i - 1),
                (x + 1 < width).then(|| i + 1),
                (y > 0).then(|| i - width),
                (y + 1 < height).then(|| i + width),
            ];
            for j in neighbours.into_iter().flatten() {
                if !seen[j] && (disparity[j] - d).abs() <= max_step {
                    seen[j] = true;
                    stack.push(j);
                }
            }
        }
        if region.len() < min_region {
            rejected += region.len();
            region.iter().for_each(|&i| disparity[i] = f32::NAN);
        }
    }
    rejected
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_island_goes_and_a_large_smooth_region_stays() {
        let (w, h) = (20usize, 10usize);
        // A smooth ramp over the image with a 2x2 island 30 px off it.
        let mut d: Vec<f32> = (0..w * h).map(|i| 10.0 + 0.1 * (i % w) as f32).collect();
        for (x, y) in [(5, 5), (6, 5), (5, 6), (6, 6)] {
            d[y * w + x] = 40.0;
        }
        let rejected = filter(&mut d, w, 10, 1.0);
        assert_eq!(rejected, 4);
        assert!(d[5 * w + 5].is_nan() && !d[0].is_nan() && !d[w * h - 1].is_nan());
        assert_eq!(d.iter().filter(|v| v.is_nan()).count(), 4);
    }

    #[test]
    fn invalid_pixels_split_regions() {
        let w = 9;
        let mut d = vec![5.0f32; w];
        d[4] = f32::NAN;
        assert_eq!(filter(&mut d, w, 5, 1.0), 8);
        assert!(d.iter().all(|v| v.is_nan()));
    }
}
