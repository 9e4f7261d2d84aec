use renderer::*;
fn main() {
    let k = Intrinsics::from_hfov(544, 112, 90.0);
    let set = scene::pixel_aligned(0, &k, 2, 0.6);
    let cam = Camera::identity(k);
    let p = cam.params::<f32>();
    let v = set.view().unwrap();
    let s = RenderSettings::default();
    for _ in 0..3 {
        let _ = cpu::render(&v, &p, &s);
    }
    let mut t = vec![];
    let mut tb = vec![];
    for _ in 0..10 {
        let t0 = std::time::Instant::now();
        let f = cpu::render(&v, &p, &s);
        t.push(t0.elapsed().as_secs_f64() * 1e3);
        let g = vec![1.0f32; f.output.rgb.len()];
        let t0 = std::time::Instant::now();
        let _ = cpu::backward(
            &v,
            &p,
            &s,
            &f,
            &cpu::OutputGrads {
                rgb: Some(&g),
                ..Default::default()
            },
        );
        tb.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    t.sort_by(|a, b| a.partial_cmp(b).unwrap());
    tb.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let f = cpu::render(&v, &p, &s);
    let vis = f.projected.iter().flatten().count();
    println!(
        "n {} visible {} keys {} fwd med {:.2} min {:.2} bwd med {:.2}",
        set.len(),
        vis,
        f.bins.ids.len(),
        t[5],
        t[0],
        tb[5]
    );
    let mean_alpha: f32 = f.output.alpha.iter().sum::<f32>() / f.output.alpha.len() as f32;
    println!("mean alpha {mean_alpha}");
}
