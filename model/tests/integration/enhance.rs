//! The one-step enhancer (`model::enhance`): exactly the identity at initialisation (the
//! residual's last layer starts at 0), finite outputs in [0, 1] and finite gradients on a
//! black, a saturated and an all-transparent render (with that layer drawn at random, so the
//! whole network acts),
//! the reference view reaching the output, and the joint attention's gradients against
//! central finite differences in f64.

use candle_core::{DType, Device, Tensor, Var};
use candle_nn::{VarBuilder, VarMap};
use model::enhance::joint_attention::{mix, JointAttention};
use model::enhance::loss::{losses, LossWeights};
use model::enhance::{Config, Enhancer};
use model::lpips::Lpips;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const H: usize = 40;
const W: usize = 96;

fn network() -> (VarMap, Enhancer) {
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
    let net = Enhancer::new(vb, &Config::tiny()).unwrap();
    (varmap, net)
}

fn random(rng: &mut ChaCha8Rng, shape: &[usize]) -> Tensor {
    let n: usize = shape.iter().product();
    let data: Vec<f32> = (0..n).map(|_| rng.random_range(0.0..1.0)).collect();
    Tensor::from_vec(data, shape, &Device::Cpu).unwrap()
}

fn values(t: &Tensor) -> Vec<f32> {
    t.flatten_all().unwrap().to_vec1().unwrap()
}

#[test]
fn the_untrained_enhancer_returns_the_render_exactly() {
    let (varmap, net) = network();
    let params: usize = varmap.all_vars().iter().map(|v| v.elem_count()).sum();
    // The suggested size: about 0.6 M weights.
    assert!((300_000..900_000).contains(&params), "{params} weights");
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let render = random(&mut rng, &[2, 5, H, W]);
    let reference = random(&mut rng, &[2, 3, H, W]);
    let out = net.forward(&render, &reference).unwrap();
    assert_eq!(out.dims(), &[2, 3, H, W]);
    assert_eq!(values(&out), values(&render.narrow(1, 0, 3).unwrap()));
}

#[test]
fn black_saturated_and_transparent_renders_give_finite_outputs_and_gradients() {
    let (varmap, net) = network();
    // Draw the residual's last layer (zero at init, when the output is the render itself).
    let head = varmap.data().lock().unwrap()["decoder.zero_head.weight"].clone();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let drawn: Vec<f32> = (0..head.elem_count())
        .map(|_| rng.random_range(-0.2..0.2))
        .collect();
    head.set(&Tensor::from_vec(drawn, head.shape(), &Device::Cpu).unwrap())
        .unwrap();
    let lpips = Lpips::load_default().unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let target = random(&mut rng, &[1, 3, H, W]);
    let reference = random(&mut rng, &[1, 3, H, W]);
    let full = |v: f32| Tensor::full(v, (1, 1, H, W), &Device::Cpu).unwrap();
    let cases = [
        // black, opaque and confident
        (
            "black",
            Tensor::cat(&[full(0.0), full(0.0), full(0.0), full(1.0), full(1.0)], 1),
        ),
        // saturated white
        (
            "saturated",
            Tensor::cat(&[full(1.0), full(1.0), full(1.0), full(1.0), full(1.0)], 1),
        ),
        // nothing drawn: alpha and confidence 0, the background (black) showing
        (
            "transparent",
            Tensor::cat(&[full(0.0), full(0.0), full(0.0), full(0.0), full(0.0)], 1),
        ),
    ];
    for (name, render) in cases {
        let render = render.unwrap();
        let out = net.forward(&render, &reference).unwrap();
        let v = values(&out);
        assert!(
            v.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)),
            "{name}: output outside [0, 1] or not finite"
        );
        let l = losses(&out, &target, &lpips, &LossWeights::default()).unwrap();
        assert!(l.total.to_scalar::<f32>().unwrap().is_finite(), "{name}");
        let grads = l.total.backward().unwrap();
        let mut reached = 0;
        for var in varmap.all_vars() {
            if let Some(g) = grads.get(var.as_tensor()) {
                assert!(values(g).iter().all(|x| x.is_finite()), "{name}: gradient");
                reached += 1;
            }
        }
        assert_eq!(
            reached,
            varmap.all_vars().len(),
            "{name}: every weight gets a gradient"
        );
    }
}

/// Central finite differences of `f` at `x` against the analytic gradient `g`, f64.
fn check(f: &dyn Fn(&[f64]) -> f64, x: &[f64], g: &[f64], what: &str) {
    let eps = 1e-6;
    for i in 0..x.len() {
        let (mut up, mut down) = (x.to_vec(), x.to_vec());
        up[i] += eps;
        down[i] -= eps;
        let numeric = (f(&up) - f(&down)) / (2.0 * eps);
        assert!(
            (numeric - g[i]).abs() <= 1e-6 + 1e-5 * numeric.abs(),
            "{what}[{i}]: numeric {numeric} vs analytic {}",
            g[i]
        );
    }
}

#[test]
fn joint_attention_gradients_match_finite_differences_and_reach_the_reference() {
    let (n, c, h, w) = (1, 8, 2, 3);
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F64, &Device::Cpu);
    let layer = JointAttention::new(vb, c, 2).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut draw = |k: usize| -> Vec<f64> { (0..k).map(|_| rng.random_range(-1.0..1.0)).collect() };
    let size = n * c * h * w;
    let (render0, reference0, weights) = (draw(size), draw(size), draw(size));
    let dev = Device::Cpu;
    let t = |v: &[f64]| Tensor::from_vec(v.to_vec(), (n, c, h, w), &dev).unwrap();
    let objective = |render: &Tensor, reference: &Tensor| -> Tensor {
        let out = mix(std::slice::from_ref(&layer), render, reference).unwrap();
        (out * t(&weights)).unwrap().sum_all().unwrap()
    };
    let (render, reference) = (
        Var::from_tensor(&t(&render0)).unwrap(),
        Var::from_tensor(&t(&reference0)).unwrap(),
    );
    let grads = objective(render.as_tensor(), reference.as_tensor())
        .backward()
        .unwrap();
    let g = |v: &Var| -> Vec<f64> {
        grads
            .get(v.as_tensor())
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap()
    };
    let value = |a: &[f64], b: &[f64]| objective(&t(a), &t(b)).to_scalar::<f64>().unwrap();
    check(&|x| value(x, &reference0), &render0, &g(&render), "render");
    let g_ref = g(&reference);
    check(&|x| value(&render0, x), &reference0, &g_ref, "reference");
    assert!(
        g_ref.iter().any(|v| v.abs() > 1e-3),
        "the reference reaches the render's tokens"
    );
    // And the layer's own weights: the query projection's.
    let q = varmap.data().lock().unwrap()["attn.q.weight"].clone();
    let q0: Vec<f64> = q.flatten_all().unwrap().to_vec1().unwrap();
    let gq = g(&q);
    let shape = q.shape().clone();
    check(
        &|x| {
            q.set(&Tensor::from_vec(x.to_vec(), &shape, &dev).unwrap())
                .unwrap();
            let v = value(&render0, &reference0);
            q.set(&Tensor::from_vec(q0.clone(), &shape, &dev).unwrap())
                .unwrap();
            v
        },
        &q0,
        &gq,
        "attn.q.weight",
    );
}
