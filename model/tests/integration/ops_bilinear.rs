//! `model::ops::grid_sample` and `upsample_bilinear`: forward against a direct nested-loop
//! reference, gradients (through candle's `backward`) against central finite differences in
//! f64, zeros padding outside the image, and no NaN from extreme or NaN coordinates; and the
//! gather formulation other devices use (`grid_sample_by_gathers`) against the CPU kernel.

use candle_core::{DType, Device, Tensor, Var};
use model::ops::{grid_sample, grid_sample_by_gathers, upsample_bilinear};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const N: usize = 2;
const C: usize = 3;
const H: usize = 5;
const W: usize = 7;
const HO: usize = 4;
const WO: usize = 6;

fn random(rng: &mut ChaCha8Rng, n: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..n).map(|_| rng.random_range(lo..hi)).collect()
}

/// Grid points (x, y) over the image and up to 1.5 px beyond it; with `smooth`, every
/// coordinate's fractional part is in [0.1, 0.9] so the blend is differentiable there.
fn random_grid(rng: &mut ChaCha8Rng, smooth: bool) -> Vec<f64> {
    (0..N * HO * WO)
        .flat_map(|_| [W, H])
        .map(|size| {
            let v = rng.random_range(-1.5..size as f64 + 0.5);
            if smooth {
                v.floor() + 0.1 + 0.8 * rng.random_range(0.0..1.0)
            } else {
                v
            }
        })
        .collect()
}

/// The convention written out directly: the four neighbours of (x, y), each weighted by the
/// bilinear weight and read as zero outside the image.
fn reference(input: &[f64], grid: &[f64]) -> Vec<f64> {
    let pixel = |n: usize, c: usize, xi: f64, yi: f64| -> f64 {
        if xi < 0.0 || yi < 0.0 || xi > (W - 1) as f64 || yi > (H - 1) as f64 {
            0.0
        } else {
            input[((n * C + c) * H + yi as usize) * W + xi as usize]
        }
    };
    let mut out = Vec::new();
    for n in 0..N {
        for c in 0..C {
            for i in 0..HO {
                for j in 0..WO {
                    let g = 2 * ((n * HO + i) * WO + j);
                    let (x, y) = (grid[g], grid[g + 1]);
                    let (x0, y0) = (x.floor(), y.floor());
                    let (fx, fy) = (x - x0, y - y0);
                    out.push(
                        (1.0 - fx) * (1.0 - fy) * pixel(n, c, x0, y0)
                            + fx * (1.0 - fy) * pixel(n, c, x0 + 1.0, y0)
                            + (1.0 - fx) * fy * pixel(n, c, x0, y0 + 1.0)
                            + fx * fy * pixel(n, c, x0 + 1.0, y0 + 1.0),
                    );
                }
            }
        }
    }
    out
}

fn tensor(v: &[f64], shape: &[usize], dtype: DType) -> Tensor {
    Tensor::from_slice(v, shape, &Device::Cpu)
        .unwrap()
        .to_dtype(dtype)
        .unwrap()
}

fn values(t: &Tensor) -> Vec<f64> {
    t.to_dtype(DType::F64)
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn forward_matches_the_nested_loop_reference_in_f32_and_f64() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let input = random(&mut rng, N * C * H * W, -1.0, 1.0);
    let grid = random_grid(&mut rng, false);
    let want = reference(&input, &grid);
    assert!(
        want.iter().filter(|v| **v == 0.0).count() > 0,
        "some points outside"
    );
    for (dtype, tol) in [(DType::F64, 1e-14), (DType::F32, 2e-6)] {
        let out = grid_sample(
            &tensor(&input, &[N, C, H, W], dtype),
            &tensor(&grid, &[N, HO, WO, 2], dtype),
        )
        .unwrap();
        assert_eq!(out.dims(), &[N, C, HO, WO]);
        assert_eq!(out.dtype(), dtype);
        let err = max_abs_diff(&values(&out), &want);
        eprintln!("{dtype:?}: max |op - reference| = {err:.2e}");
        assert!(err <= tol, "{dtype:?}: {err}");
    }
}

#[test]
fn strided_inputs_sample_like_contiguous_ones() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let input = random(&mut rng, N * C * H * W, -1.0, 1.0);
    let grid = random_grid(&mut rng, false);
    // The same values held transposed, then transposed back: a non-contiguous view.
    let strided = tensor(&input, &[N, C, H, W], DType::F64)
        .transpose(2, 3)
        .unwrap()
        .contiguous()
        .unwrap()
        .transpose(2, 3)
        .unwrap();
    assert!(!strided.is_contiguous());
    let out = grid_sample(&strided, &tensor(&grid, &[N, HO, WO, 2], DType::F64)).unwrap();
    assert!(max_abs_diff(&values(&out), &reference(&input, &grid)) <= 1e-14);
}

/// Loss = sum(out * weights); gradients from candle against central differences of the op.
#[test]
fn gradients_match_central_finite_differences_in_f64() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let input = random(&mut rng, N * C * H * W, -1.0, 1.0);
    let grid = random_grid(&mut rng, true);
    let weights = tensor(
        &random(&mut rng, N * C * HO * WO, -1.0, 1.0),
        &[N, C, HO, WO],
        DType::F64,
    );
    let loss = |input: &[f64], grid: &[f64]| -> f64 {
        let out = grid_sample(
            &tensor(input, &[N, C, H, W], DType::F64),
            &tensor(grid, &[N, HO, WO, 2], DType::F64),
        )
        .unwrap();
        (out * &weights)
            .unwrap()
            .sum_all()
            .unwrap()
            .to_scalar()
            .unwrap()
    };
    let vi = Var::from_tensor(&tensor(&input, &[N, C, H, W], DType::F64)).unwrap();
    let vg = Var::from_tensor(&tensor(&grid, &[N, HO, WO, 2], DType::F64)).unwrap();
    let out = grid_sample(vi.as_tensor(), vg.as_tensor()).unwrap();
    let grads = (out * &weights)
        .unwrap()
        .sum_all()
        .unwrap()
        .backward()
        .unwrap();
    let d_input = values(grads.get(vi.as_tensor()).unwrap());
    let d_grid = values(grads.get(vg.as_tensor()).unwrap());

    let h = 1e-6;
    let numeric = |x: &[f64], f: &dyn Fn(&[f64]) -> f64| -> Vec<f64> {
        (0..x.len())
            .map(|i| {
                let (mut p, mut m) = (x.to_vec(), x.to_vec());
                p[i] += h;
                m[i] -= h;
                (f(&p) - f(&m)) / (2.0 * h)
            })
            .collect()
    };
    let n_input = numeric(&input, &|x| loss(x, &grid));
    let n_grid = numeric(&grid, &|g| loss(&input, g));
    for (what, a, n) in [("input", &d_input, &n_input), ("grid", &d_grid, &n_grid)] {
        let mut worst: f64 = 0.0;
        for (k, (a, n)) in a.iter().zip(n.iter()).enumerate() {
            let err = (a - n).abs();
            assert!(
                err <= 1e-8 + 1e-6 * a.abs().max(n.abs()),
                "{what}[{k}]: analytic {a:.9e} numeric {n:.9e}"
            );
            worst = worst.max(err);
        }
        let nonzero = a.iter().filter(|v| v.abs() > 1e-3).count();
        eprintln!(
            "{what}: {} gradients, {nonzero} non-zero, max |analytic - numeric| = {worst:.2e}",
            a.len()
        );
        assert!(nonzero > a.len() / 3, "{what}: too few non-zero gradients");
    }
}

/// A grid sampler: the CPU kernel or the gather formulation.
type Sampler = fn(&Tensor, &Tensor) -> candle_core::Result<Tensor>;

/// Both samplers, each test runs on.
const SAMPLERS: [Sampler; 2] = [grid_sample, grid_sample_by_gathers];

/// One point per case on a single 1x1-channel 3x4 image; returns the samples and the
/// gradients of their sum with respect to input and grid.
fn sample_points(
    sample: Sampler,
    points: &[[f64; 2]],
    dtype: DType,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let image: Vec<f64> = (1..=12).map(|v| v as f64).collect();
    let vi = Var::from_tensor(&tensor(&image, &[1, 1, 3, 4], dtype)).unwrap();
    let flat: Vec<f64> = points.iter().flatten().copied().collect();
    let vg = Var::from_tensor(&tensor(&flat, &[1, 1, points.len(), 2], dtype)).unwrap();
    let out = sample(vi.as_tensor(), vg.as_tensor()).unwrap();
    let grads = out.sum_all().unwrap().backward().unwrap();
    (
        values(&out),
        values(grads.get(vi.as_tensor()).unwrap()),
        values(grads.get(vg.as_tensor()).unwrap()),
    )
}

#[test]
fn points_a_pixel_or_more_outside_sample_zero_and_edges_blend_with_zero() {
    // Image 3 rows x 4 columns, values 1..12 row major: pixel (x, y) = 1 + x + 4 y.
    let outside = [
        [-1.0, 1.0],
        [4.0, 1.0],
        [1.0, -1.0],
        [1.0, 3.0],
        [-7.5, 0.5],
        [2.5, 40.0],
    ];
    for sample in SAMPLERS {
        let (out, d_input, d_grid) = sample_points(sample, &outside, DType::F64);
        assert_eq!(out, vec![0.0; outside.len()]);
        assert_eq!(d_input, vec![0.0; 12]);
        assert_eq!(d_grid, vec![0.0; 2 * outside.len()]);

        // Half a pixel outside blends the edge pixel with zero; a pixel centre reads it.
        let (out, _, _) = sample_points(
            sample,
            &[[-0.5, 0.0], [3.5, 2.0], [1.0, 2.5], [3.0, 2.0], [1.25, 0.5]],
            DType::F64,
        );
        let want = [0.5, 0.5 * 12.0, 0.5 * 10.0, 12.0, 0.5 * (2.25 + 6.25)];
        assert!(max_abs_diff(&out, &want) < 1e-12, "{out:?}");
    }
}

#[test]
fn nan_and_extreme_coordinates_sample_zero_with_finite_gradients() {
    let extreme = [
        [f64::NAN, 1.0],
        [1.0, f64::NAN],
        [f64::INFINITY, 1.0],
        [f64::NEG_INFINITY, 1.0],
        [1e30, -1e30],
        [f32::MAX as f64, 1.0],
        [-(f32::MAX as f64), 1.0],
        [1.5, 1.5], // an ordinary point beside them still samples
    ];
    for (dtype, sample) in [DType::F32, DType::F64]
        .into_iter()
        .flat_map(|d| SAMPLERS.map(|s| (d, s)))
    {
        let (out, d_input, d_grid) = sample_points(sample, &extreme, dtype);
        assert!(
            out.iter()
                .chain(&d_input)
                .chain(&d_grid)
                .all(|v| v.is_finite()),
            "{dtype:?}: {out:?} {d_grid:?}"
        );
        assert_eq!(&out[..7], &[0.0; 7]);
        assert_eq!(&d_grid[..14], &[0.0; 14]);
        assert!((out[7] - 0.25 * (6.0 + 7.0 + 10.0 + 11.0)).abs() < 1e-5);
        // Only the last point's four neighbours receive gradient, a quarter each.
        assert!((d_input.iter().sum::<f64>() - 1.0).abs() < 1e-6);
    }
}

#[test]
fn upsampling_matches_the_half_pixel_formula_and_has_a_backward() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (h, w, oh, ow) = (3, 4, 7, 10);
    let x = random(&mut rng, 2 * h * w, -1.0, 1.0);
    let src = |i: usize, from: usize, to: usize| {
        ((i as f64 + 0.5) * from as f64 / to as f64 - 0.5).clamp(0.0, from as f64 - 1.0)
    };
    let mut want = Vec::new();
    for c in 0..2 {
        for i in 0..oh {
            for j in 0..ow {
                let (sy, sx) = (src(i, h, oh), src(j, w, ow));
                let (y0, x0) = (sy.floor() as usize, sx.floor() as usize);
                let (y1, x1) = ((y0 + 1).min(h - 1), (x0 + 1).min(w - 1));
                let (fy, fx) = (sy - y0 as f64, sx - x0 as f64);
                let p = |row: usize, col: usize| x[(c * h + row) * w + col];
                want.push(
                    (1.0 - fy) * ((1.0 - fx) * p(y0, x0) + fx * p(y0, x1))
                        + fy * ((1.0 - fx) * p(y1, x0) + fx * p(y1, x1)),
                );
            }
        }
    }
    let v = Var::from_tensor(&tensor(&x, &[1, 2, h, w], DType::F64)).unwrap();
    let up = upsample_bilinear(v.as_tensor(), oh, ow).unwrap();
    assert_eq!(up.dims(), &[1, 2, oh, ow]);
    assert!(max_abs_diff(&values(&up), &want) < 1e-14);

    // The sum of an upsampled image is linear in the input: its gradient is how much each
    // input pixel contributes, and those contributions add up to the output pixel count.
    let g = values(
        up.sum_all()
            .unwrap()
            .backward()
            .unwrap()
            .get(v.as_tensor())
            .unwrap(),
    );
    assert!((g.iter().sum::<f64>() - (2 * oh * ow) as f64).abs() < 1e-9);
    assert!(g.iter().all(|&v| v > 0.0));

    // Same size is the identity.
    let same = upsample_bilinear(&tensor(&x, &[1, 2, h, w], DType::F32), h, w).unwrap();
    assert!(max_abs_diff(&values(&same), &x) < 1e-7);
}

#[test]
fn the_gather_formulation_matches_the_cpu_kernel_in_value_and_both_gradients() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let input = random(&mut rng, N * C * H * W, -1.0, 1.0);
    // Not smoothed: integer coordinates take the same one-sided derivative in both.
    let mut grid = random_grid(&mut rng, false);
    grid[0] = 2.0;
    grid[1] = 3.0;
    let weights = random(&mut rng, N * C * HO * WO, -1.0, 1.0);
    let run = |sample: Sampler| {
        let vi = Var::from_tensor(&tensor(&input, &[N, C, H, W], DType::F64)).unwrap();
        let vg = Var::from_tensor(&tensor(&grid, &[N, HO, WO, 2], DType::F64)).unwrap();
        let out = sample(vi.as_tensor(), vg.as_tensor()).unwrap();
        let loss = (&out * tensor(&weights, &[N, C, HO, WO], DType::F64))
            .unwrap()
            .sum_all()
            .unwrap();
        let grads = loss.backward().unwrap();
        [
            values(&out),
            values(grads.get(vi.as_tensor()).unwrap()),
            values(grads.get(vg.as_tensor()).unwrap()),
        ]
    };
    let (kernel, gathers) = (run(grid_sample), run(grid_sample_by_gathers));
    for (what, (a, b)) in ["value", "input gradient", "grid gradient"]
        .iter()
        .zip(kernel.iter().zip(&gathers))
    {
        assert!(max_abs_diff(a, b) < 1e-12, "{what}: {}", max_abs_diff(a, b));
    }
    assert!(
        kernel[2].iter().any(|g| g.abs() > 0.1),
        "the grid gradient is not trivial"
    );
}
