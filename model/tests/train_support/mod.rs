//! What the resume tests of the two trainers (StereoSplat's and the enhancer's) share: the
//! exported weights compared name by name, the steps of a run's log.

use std::path::Path;

use candle_core::Device;

/// Asserts that two safetensors files hold the same names with values within `1e-5`.
pub fn assert_same_weights(a: &Path, b: &Path) {
    let read = |p: &Path| {
        let mut map: Vec<(String, Vec<f32>)> = candle_core::safetensors::load(p, &Device::Cpu)
            .unwrap()
            .into_iter()
            .map(|(k, v)| (k, v.flatten_all().unwrap().to_vec1().unwrap()))
            .collect();
        map.sort_by(|x, y| x.0.cmp(&y.0));
        map
    };
    let (a, b) = (read(a), read(b));
    assert_eq!(a.len(), b.len());
    for ((name, x), (other, y)) in a.iter().zip(&b) {
        assert_eq!(name, other);
        let diff = x
            .iter()
            .zip(y)
            .map(|(p, q)| (p - q).abs())
            .fold(0f32, f32::max);
        assert!(diff < 1e-5, "{name} differs by {diff}");
    }
}

/// The step column of a run's `log.csv`.
pub fn logged_steps(out: &Path) -> Vec<String> {
    let log = std::fs::read_to_string(out.join("log.csv")).unwrap();
    log.lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().to_string())
        .collect()
}
