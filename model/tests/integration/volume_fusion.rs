//! `net::volume::ProjectionFusion`: the cost-volume Gaussians' features averaged into the
//! plane cells their centres fall in, against a direct per-cell reference; gradients with
//! respect to the features and the adapter against finite differences; centres outside the
//! volume, not finite, at depth near 0 or very far are dropped without NaN.

use crate::volume_support;

use candle_core::{DType, Device, Tensor, Var};
use candle_nn::{VarBuilder, VarMap};
use model::net::volume::{gaussian_rows, Plane, ProjectionFusion, VolumeConfig};
use rand::Rng;
use volume_support::{
    assert_finite, assert_finite_grads, check_gradients, rng, tiny_volume, uniform, values,
};

const K: usize = 3;

fn fusion(cfg: &VolumeConfig) -> (VarMap, ProjectionFusion) {
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F64, &Device::Cpu);
    let f = ProjectionFusion::new(vb.pp("fusion"), cfg, K).unwrap();
    (varmap, f)
}

fn var(varmap: &VarMap, name: &str) -> Var {
    varmap.data().lock().unwrap()[name].clone()
}

/// `n` centres: most inside the volume, some outside it, one NaN, one infinite, one at
/// depth 1e-7 (inside the first z cell), one at 1e6 m.
fn centres(n: usize, seed: u64) -> Vec<[f64; 3]> {
    let cfg = tiny_volume();
    let mut r = rng(seed);
    let mut out: Vec<[f64; 3]> = (0..n)
        .map(|_| {
            std::array::from_fn(|a| {
                let (lo, hi) = (cfg.range_min[a] as f64, cfg.range_max[a] as f64);
                r.random_range(lo - 0.3..hi + 0.3)
            })
        })
        .collect();
    out.extend([
        [f64::NAN, 0.5, 0.5],
        [0.5, f64::INFINITY, 0.5],
        [0.5, 0.5, 1e-7],
        [0.5, 0.5, 1e6],
        [-1e30, 1e30, 0.5],
    ]);
    out
}

fn means_tensor(c: &[[f64; 3]]) -> Tensor {
    Tensor::from_vec(c.concat(), (c.len(), 3), &Device::Cpu).unwrap()
}

/// The fusion written out: per plane cell, the mean of the features of the centres in it,
/// times the adapter's weight plus its bias; zero where no centre lands.
fn reference(cfg: &VolumeConfig, c: &[[f64; 3]], f: &[f64], w: &[f64], b: &[f64]) -> Vec<Vec<f64>> {
    let ch = cfg.channels;
    Plane::ALL
        .iter()
        .zip(cfg.plane_shapes())
        .map(|(plane, (rows, cols))| {
            let mut sum = vec![0.0; rows * cols * K];
            let mut count = vec![0usize; rows * cols];
            for (i, p) in c.iter().enumerate() {
                let Some(index) = cfg.cell_of(p.map(|v| v as f32)) else {
                    continue;
                };
                let (r, col) = plane.cell_of_voxel(index);
                let cell = r * cols + col;
                count[cell] += 1;
                for k in 0..K {
                    sum[cell * K + k] += f[i * K + k];
                }
            }
            let mut out = vec![0.0; ch * rows * cols];
            for cell in 0..rows * cols {
                if count[cell] == 0 {
                    continue;
                }
                for o in 0..ch {
                    let dot: f64 = (0..K)
                        .map(|k| w[o * K + k] * sum[cell * K + k] / count[cell] as f64)
                        .sum();
                    out[o * rows * cols + cell] = dot + b[o];
                }
            }
            out
        })
        .collect()
}

#[test]
fn cells_get_the_adapted_mean_of_the_gaussians_in_them() {
    let cfg = tiny_volume();
    let (varmap, fusion) = fusion(&cfg);
    let c = centres(40, 1);
    let features = uniform(&mut rng(2), &[c.len(), K], -1.0, 1.0);
    let planes = fusion.forward(&means_tensor(&c), &features).unwrap();
    let w = values(var(&varmap, "fusion.adapter.weight").as_tensor());
    let b = values(var(&varmap, "fusion.adapter.bias").as_tensor());
    let want = reference(&cfg, &c, &values(&features), &w, &b);
    for (p, (plane, (rows, cols))) in planes.iter().zip(cfg.plane_shapes()).enumerate() {
        assert_eq!(plane.dims(), [cfg.channels, rows, cols]);
        let got = values(plane);
        let err = got
            .iter()
            .zip(&want[p])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-12, "plane {p}: {err}");
        assert!(want[p].iter().any(|&v| v != 0.0));
    }
}

#[test]
fn gradients_reach_features_and_adapter_exactly() {
    let cfg = tiny_volume();
    let (varmap, fusion) = fusion(&cfg);
    let c = centres(30, 3);
    let means = means_tensor(&c);
    let features = Var::from_tensor(&uniform(&mut rng(4), &[c.len(), K], -1.0, 1.0)).unwrap();
    let mut r = rng(5);
    let probes: Vec<Tensor> = cfg
        .plane_shapes()
        .iter()
        .map(|&(rows, cols)| uniform(&mut r, &[cfg.channels, rows, cols], -1.0, 1.0))
        .collect();
    let loss = || {
        let planes = fusion.forward(&means, features.as_tensor()).unwrap();
        planes
            .iter()
            .zip(&probes)
            .map(|(p, q)| (p * q).unwrap().sum_all().unwrap())
            .reduce(|a, b| (a + b).unwrap())
            .unwrap()
    };
    let weight = var(&varmap, "fusion.adapter.weight");
    let bias = var(&varmap, "fusion.adapter.bias");
    let worst = check_gradients(
        &[
            ("features", &features),
            ("weight", &weight),
            ("bias", &bias),
        ],
        64,
        &loss,
    );
    assert!(worst < 1e-6, "{worst}");
    // Rows of dropped centres (NaN, infinite, 1e6 m, 1e30) get exactly zero gradient.
    let grads = loss().backward().unwrap();
    let g = values(grads.get(features.as_tensor()).unwrap());
    let n = c.len();
    for row in [n - 5, n - 4, n - 2, n - 1] {
        assert!(
            g[row * K..(row + 1) * K].iter().all(|&v| v == 0.0),
            "row {row}"
        );
    }
    // The centre at depth 1e-7 lies in the first z cell and is kept.
    assert!(g[(n - 3) * K..(n - 2) * K].iter().any(|&v| v != 0.0));
}

#[test]
fn an_empty_volume_gives_zero_planes_and_finite_gradients() {
    let cfg = tiny_volume();
    let (varmap, fusion) = fusion(&cfg);
    // Every centre outside: behind, far, huge, not finite.
    let c = vec![
        [0.5, 0.5, -1.0],
        [0.5, 0.5, 1e6],
        [1e30, -1e30, 1e30],
        [f64::NAN, f64::NAN, f64::NAN],
    ];
    let features = Var::from_tensor(&uniform(&mut rng(6), &[4, K], -1e20, 1e20)).unwrap();
    let planes = fusion
        .forward(&means_tensor(&c), features.as_tensor())
        .unwrap();
    for (plane, (rows, cols)) in planes.iter().zip(cfg.plane_shapes()) {
        assert_eq!(plane.dims(), [cfg.channels, rows, cols]);
        assert!(values(plane).iter().all(|&v| v == 0.0));
    }
    let loss = planes
        .iter()
        .map(|p| p.sum_all().unwrap())
        .reduce(|a, b| (a + b).unwrap())
        .unwrap();
    let grads = loss.backward().unwrap();
    let weight = var(&varmap, "fusion.adapter.weight");
    assert_finite_grads(&grads, &[&features, &weight], "empty volume");
    // No centre at all works too.
    let none = fusion
        .forward(
            &Tensor::zeros((0, 3), DType::F64, &Device::Cpu).unwrap(),
            &Tensor::zeros((0, K), DType::F64, &Device::Cpu).unwrap(),
        )
        .unwrap();
    assert!(none.iter().all(|p| values(p).iter().all(|&v| v == 0.0)));
}

#[test]
fn huge_features_and_f32_stay_finite_and_shapes_are_checked() {
    let cfg = tiny_volume();
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
    let fusion = ProjectionFusion::new(vb, &cfg, K).unwrap();
    let c = centres(200, 7);
    let means = means_tensor(&c).to_dtype(DType::F32).unwrap();
    let features = Var::from_tensor(
        &uniform(&mut rng(8), &[c.len(), K], -1e20, 1e20)
            .to_dtype(DType::F32)
            .unwrap(),
    )
    .unwrap();
    let planes = fusion.forward(&means, features.as_tensor()).unwrap();
    let mut loss = None::<Tensor>;
    for p in &planes {
        assert_eq!(p.dtype(), DType::F32);
        assert_finite(p, "huge features");
        let s = p.sum_all().unwrap();
        loss = Some(match loss {
            None => s,
            Some(l) => (l + s).unwrap(),
        });
    }
    let grads = loss.unwrap().backward().unwrap();
    assert_finite_grads(&grads, &[&features], "huge features");
    // Wrong shapes are errors, not panics.
    assert!(fusion
        .forward(&means, &features.narrow(1, 0, 2).unwrap())
        .is_err());
    assert!(fusion
        .forward(&means.narrow(1, 0, 2).unwrap(), features.as_tensor())
        .is_err());
}

#[test]
fn prediction_features_become_rows_in_splat_order() {
    // (V = 2, k = 3, Hg = 2, Wg = 3): row v * 6 + y * 3 + x holds features[v, :, y, x].
    let data: Vec<f64> = (0..36).map(f64::from).collect();
    let features = Tensor::from_vec(data, (2, 3, 2, 3), &Device::Cpu).unwrap();
    let rows = gaussian_rows(&features).unwrap();
    assert_eq!(rows.dims(), [12, 3]);
    let r = values(&rows);
    let (v, y, x) = (1, 1, 2);
    let row = v * 6 + y * 3 + x;
    for k in 0..3 {
        assert_eq!(
            r[row * 3 + k],
            values(&features)[((v * 3 + k) * 2 + y) * 3 + x]
        );
    }
}
