//! Every custom op, LPIPS, the enhancer and the network on the GPU against the same
//! computation on the CPU. Built only with the `cuda` feature and run on a machine with an
//! NVIDIA GPU (`results/gpu/`): CI has neither, so this file
//! compiles to nothing there.
#![cfg(feature = "cuda")]

use candle_core::{DType, Device, Module, Tensor, Var};
use candle_nn::VarBuilder;
use model::ops::{grid_sample, render, transpose_last2, upsample_bilinear, Conv, SplatTensors};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use renderer::{scene, Camera, Intrinsics, RenderSettings};

fn gpu() -> Device {
    Device::new_cuda(0).expect("an NVIDIA GPU and the CUDA libraries")
}

fn random(seed: u64, shape: &[usize], lo: f32, hi: f32) -> Tensor {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = shape.iter().product();
    let v: Vec<f32> = (0..n).map(|_| rng.random_range(lo..hi)).collect();
    Tensor::from_vec(v, shape, &Device::Cpu).unwrap()
}

fn values(t: &Tensor) -> Vec<f32> {
    t.to_device(&Device::Cpu)
        .unwrap()
        .to_dtype(DType::F32)
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap()
}

/// Largest |a - b| relative to the larger of 1 and the largest |a|.
fn rel_diff(a: &Tensor, b: &Tensor) -> f32 {
    let (a, b) = (values(a), values(b));
    assert_eq!(a.len(), b.len());
    let scale = a.iter().fold(1f32, |m, v| m.max(v.abs()));
    a.iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
        / scale
}

/// `f` of variables made from `inputs` on `device`: the output and the gradient of a
/// fixed weighted sum of it with respect to each input.
fn with_grads(
    device: &Device,
    inputs: &[&Tensor],
    f: &dyn Fn(&[Tensor]) -> Tensor,
) -> (Tensor, Vec<Tensor>) {
    let vars: Vec<Var> = inputs
        .iter()
        .map(|t| Var::from_tensor(&t.to_device(device).unwrap()).unwrap())
        .collect();
    let out = f(&vars
        .iter()
        .map(|v| v.as_tensor().clone())
        .collect::<Vec<_>>());
    let weights = random(99, out.dims(), -1.0, 1.0)
        .to_dtype(out.dtype())
        .unwrap()
        .to_device(device)
        .unwrap();
    let grads = (&out * &weights)
        .unwrap()
        .sum_all()
        .unwrap()
        .backward()
        .unwrap();
    let grads = vars
        .iter()
        .map(|v| grads.get(v.as_tensor()).unwrap().clone())
        .collect();
    (out, grads)
}

/// Runs `f` on the CPU and the GPU and asserts the outputs and gradients agree to `tol`.
fn same_on_both(what: &str, inputs: &[&Tensor], tol: f32, f: &dyn Fn(&[Tensor]) -> Tensor) {
    let (cpu_out, cpu_grads) = with_grads(&Device::Cpu, inputs, f);
    let (gpu_out, gpu_grads) = with_grads(&gpu(), inputs, f);
    assert!(gpu_out.device().is_cuda(), "{what} left the GPU");
    let d = rel_diff(&cpu_out, &gpu_out);
    eprintln!("{what}: output rel diff {d:.2e}");
    assert!(d < tol, "{what}: output differs by {d}");
    for (i, (c, g)) in cpu_grads.iter().zip(&gpu_grads).enumerate() {
        let d = rel_diff(c, g);
        eprintln!("{what}: gradient {i} rel diff {d:.2e}");
        assert!(d < tol, "{what}: gradient {i} differs by {d}");
    }
}

#[test]
fn grid_sample_and_upsampling_agree_with_the_cpu_kernel() {
    let input = random(1, &[2, 8, 20, 30], -1.0, 1.0);
    let grid = random(2, &[2, 12, 16, 2], -2.0, 31.0);
    same_on_both("grid_sample", &[&input, &grid], 1e-5, &|t| {
        grid_sample(&t[0], &t[1]).unwrap()
    });
    same_on_both("upsample_bilinear", &[&input], 1e-5, &|t| {
        upsample_bilinear(&t[0], 40, 60).unwrap()
    });
}

/// The CUDA kernels in f64 on the points the convention singles out: NaN and infinite
/// coordinates, points at and beyond one pixel outside, on the image's edges and on integer
/// coordinates (the kink). Same samples and gradients as the CPU, all finite.
#[test]
fn the_sampler_kernels_agree_in_f64_off_and_on_the_edges() {
    let input = random(7, &[2, 3, 9, 11], -1.0, 1.0)
        .to_dtype(DType::F64)
        .unwrap();
    let (nan, inf) = (f64::NAN, f64::INFINITY);
    let points = [
        (nan, 2.0),
        (3.0, inf),
        (-inf, 1.0),
        (1e30, 1e30),
        (0.0, 0.0),
        (10.0, 8.0),
        (-1.0, 4.0),
        (11.0, 4.0),
        (-0.5, 3.5),
        (3.5, 8.5),
        (4.0, 5.0),
        (10.999, 0.25),
    ];
    let flat: Vec<f64> = points.iter().flat_map(|&(x, y)| [x, y]).collect();
    let grid = Tensor::from_vec([flat.clone(), flat].concat(), (2, 3, 4, 2), &Device::Cpu).unwrap();
    same_on_both("grid_sample f64", &[&input, &grid], 1e-12, &|t| {
        grid_sample(&t[0], &t[1]).unwrap()
    });
    let out = grid_sample(
        &input.to_device(&gpu()).unwrap(),
        &grid.to_device(&gpu()).unwrap(),
    )
    .unwrap();
    let v = values(&out);
    assert!(v.iter().all(|x| x.is_finite()));
    assert_eq!(v[0], 0.0, "a NaN point samples zero");
}

#[test]
fn the_convolution_and_the_transpose_agree_with_the_cpu() {
    let x = random(3, &[2, 16, 24, 40], -1.0, 1.0);
    let weight = random(4, &[32, 16, 3, 3], -0.2, 0.2);
    let bias = random(5, &[32], -0.1, 0.1);
    same_on_both("conv (training path)", &[&x, &weight, &bias], 1e-4, &|t| {
        let map = std::collections::HashMap::from([
            ("weight".to_string(), t[1].clone()),
            ("bias".to_string(), t[2].clone()),
        ]);
        let vb = VarBuilder::from_tensors(map, DType::F32, t[0].device());
        Conv::new(vb, (16, 32), 3, 2, 1, true)
            .unwrap()
            .forward(&t[0])
            .unwrap()
    });
    // Inference (no variables): the CPU's im2col kernel against candle's convolution.
    let run = |device: &Device| {
        let map = std::collections::HashMap::from([
            ("weight".to_string(), weight.to_device(device).unwrap()),
            ("bias".to_string(), bias.to_device(device).unwrap()),
        ]);
        let vb = VarBuilder::from_tensors(map, DType::F32, device);
        let conv = Conv::new(vb, (16, 32), 3, 1, 1, true).unwrap();
        conv.forward(&x.to_device(device).unwrap()).unwrap()
    };
    let d = rel_diff(&run(&Device::Cpu), &run(&gpu()));
    assert!(d < 1e-4, "conv (inference) differs by {d}");
    let y = random(6, &[3, 52, 777], -1.0, 1.0);
    same_on_both("transpose_last2", &[&y], 1e-7, &|t| {
        transpose_last2(&t[0]).unwrap()
    });
}

#[test]
fn the_differentiable_rasterizer_runs_for_gpu_tensors_with_the_cpu_result() {
    let k = Intrinsics::from_hfov(64, 48, 70.0);
    let set = scene::small_overlapping(7, 40, &k);
    let packed = SplatTensors::from_set(&set, DType::F32, &Device::Cpu)
        .unwrap()
        .pack()
        .unwrap();
    let cam = Camera::identity(k);
    let settings = RenderSettings::default();
    same_on_both("render", &[&packed], 1e-6, &|t| {
        render(&t[0], &cam, &settings).unwrap()
    });
}

#[test]
fn lpips_the_enhancer_and_the_network_agree_with_the_cpu() {
    let a = random(8, &[2, 3, 64, 96], 0.0, 1.0);
    let b = random(9, &[2, 3, 64, 96], 0.0, 1.0);
    let lpips = |device: &Device| {
        let net =
            model::lpips::Lpips::load(model::lpips::default_weights(), DType::F32, device).unwrap();
        net.forward(&a.to_device(device).unwrap(), &b.to_device(device).unwrap())
            .unwrap()
    };
    let d = rel_diff(&lpips(&Device::Cpu), &lpips(&gpu()));
    eprintln!("lpips: rel diff {d:.2e}");
    assert!(d < 1e-4, "lpips differs by {d}");

    let cfg = model::enhance::Config::tiny();
    let path = model::enhance::default_weights("tiny");
    let render = random(10, &[2, 5, 64, 96], 0.0, 1.0);
    let enhance = |device: &Device| {
        let net = model::enhance::load(&cfg, &path, device).unwrap();
        net.forward(
            &render.to_device(device).unwrap(),
            &a.to_device(device).unwrap(),
        )
        .unwrap()
    };
    let d = rel_diff(&enhance(&Device::Cpu), &enhance(&gpu()));
    eprintln!("enhancer: rel diff {d:.2e}");
    assert!(d < 1e-3, "enhancer differs by {d}");

    // The shipped tiny network, one pair: the same Gaussians on both devices.
    let net_cfg = model::net::Config::tiny();
    let images = random(11, &[2, 3, 112, 544], 0.0, 1.0);
    let k = Intrinsics::from_hfov(544, 112, 80.0);
    let left = Camera::identity(k);
    let right = Camera::from_camera_to_world(k, glam::Quat::IDENTITY, glam::Vec3::X * 0.6);
    let predict = |device: &Device| {
        let tensors =
            model::assets::load_tensors(&model::net::default_weights("tiny"), device).unwrap();
        let vb = VarBuilder::from_tensors(tensors, DType::F32, device);
        let net = model::net::StereoSplat::new(vb, &net_cfg).unwrap();
        let p = net
            .forward(&images.to_device(device).unwrap(), &[left, right])
            .unwrap();
        p.output().unwrap().pack().unwrap()
    };
    let d = rel_diff(&predict(&Device::Cpu), &predict(&gpu()));
    eprintln!("network: rel diff {d:.2e}");
    assert!(d < 1e-2, "network output differs by {d}");
}
