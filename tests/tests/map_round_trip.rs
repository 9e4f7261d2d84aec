//! A map's life across the renderer's parts: generated, written as a 3DGS PLY, read back,
//! and rendered by both rasterizers, which must agree with each other and with the render of
//! the map before it went through the file.

use renderer::gpu::GpuRasterizer;
use renderer::{cpu, ply, scene, Camera, Intrinsics, RenderSettings};

#[test]
fn a_map_survives_the_ply_file_and_renders_the_same_on_cpu_and_gpu() {
    let k = Intrinsics::from_hfov(160, 48, 90.0);
    let cam = Camera::identity(k);
    let set = scene::pixel_aligned(3, &k, 2, 0.6);
    let mut bytes = Vec::new();
    ply::write_ply(&set, &mut bytes).unwrap();
    let back = ply::read_ply(bytes.as_slice()).unwrap();
    assert_eq!(back.len(), set.len());

    let settings = RenderSettings {
        background: [0.1, 0.2, 0.3],
        ..Default::default()
    };
    let params = cam.params::<f32>();
    let before = cpu::render(&set.view().unwrap(), &params, &settings).output;
    let after = cpu::render(&back.view().unwrap(), &params, &settings).output;
    let max_diff = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()))
    };
    // The file stores opacity as a logit and colour as an SH coefficient: f32 round trips.
    assert!(max_diff(&before.rgb, &after.rgb) < 1e-4);

    let mut gpu = GpuRasterizer::new().expect("a wgpu adapter (lavapipe in CI)");
    let on_gpu = gpu.render(&back, &cam, &settings).unwrap();
    // Per channel within 2e-3, except pixels where the two disagree on the T < 1e-4 stop
    // (a one-ulp difference in transmittance there drops or keeps a whole Gaussian): those
    // must sit at the stop threshold and be under 0.1% of the image.
    let pixels = after.alpha.len();
    let mut flipped = 0;
    for p in 0..pixels {
        let rgb = (0..3).map(|k| (after.rgb[3 * p + k] - on_gpu.rgb[3 * p + k]).abs());
        let worst = rgb.fold((after.alpha[p] - on_gpu.alpha[p]).abs(), f32::max);
        if worst > 2e-3 {
            assert!(
                after.alpha[p] > 0.9997,
                "pixel {p} differs by {worst} away from the stop threshold"
            );
            flipped += 1;
        }
    }
    assert!(
        flipped * 1000 <= pixels,
        "{flipped} of {pixels} pixels differ"
    );
    let depth_rel = after
        .depth
        .iter()
        .zip(&on_gpu.depth)
        .fold(0.0f32, |m, (a, b)| m.max((a - b).abs() / a.max(1.0)));
    assert!(depth_rel <= 2e-3, "depth relative difference {depth_rel}");
}
