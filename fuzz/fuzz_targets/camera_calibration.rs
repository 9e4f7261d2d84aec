//! ROS `camera_calibration` YAML files of a stereo pair (joined by a NUL), as
//! `stereosplat reconstruct --camera-info` reads them. Needs the `runtime` feature.
//! The body is `node::untrusted_input::live::camera_calibration`, which the test suite's seeded
//! mutations call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::live::camera_calibration(data));
