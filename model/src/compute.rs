//! Where the candle networks run: the `device` setting every command takes
//! (`--set device=cuda`). The CPU is the default and the only choice of a build without the
//! `cuda` cargo feature; asking for CUDA there is a clear error, not a silent fallback.
//!
//! Device rule for the project's own ops (`crate::ops`): their hand-written kernels are CPU
//! kernels, and the bilinear sampler's also CUDA kernels. On another device `grid_sample`
//! runs as candle tensor ops (gathers and weights); off the CPU `transpose_last2` is
//! candle's strided copy, the convolution is candle's own, and the differentiable
//! rasterizer runs on the CPU (its input is copied to the CPU and its images back,
//! gradients likewise).

use candle_core::Device;
use serde::{Deserialize, Serialize};

/// A compute device by name: `cpu`, `cuda` (GPU 0) or `cuda:N`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum ComputeDevice {
    /// The CPU (candle's CPU backend, rayon threads).
    #[default]
    Cpu,
    /// The NVIDIA GPU of this ordinal (needs the `cuda` feature).
    Cuda(usize),
}

/// A device name [`ComputeDevice`] does not know.
#[derive(Debug, thiserror::Error)]
#[error("unknown device `{0}` (known: cpu, cuda, cuda:N)")]
pub struct UnknownDevice(pub String);

impl TryFrom<String> for ComputeDevice {
    type Error = UnknownDevice;

    fn try_from(name: String) -> Result<Self, UnknownDevice> {
        match name.as_str() {
            "cpu" => Ok(Self::Cpu),
            "cuda" => Ok(Self::Cuda(0)),
            other => other
                .strip_prefix("cuda:")
                .and_then(|n| n.parse().ok())
                .map(Self::Cuda)
                .ok_or(UnknownDevice(name)),
        }
    }
}

impl From<ComputeDevice> for String {
    fn from(device: ComputeDevice) -> String {
        match device {
            ComputeDevice::Cpu => "cpu".into(),
            ComputeDevice::Cuda(n) => format!("cuda:{n}"),
        }
    }
}

impl ComputeDevice {
    /// The candle device. CUDA in a build without the `cuda` feature, or with no such GPU,
    /// is candle's error saying so.
    pub fn open(self) -> candle_core::Result<Device> {
        match self {
            Self::Cpu => Ok(Device::Cpu),
            Self::Cuda(ordinal) => Device::new_cuda(ordinal),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_are_errors() {
        for (name, device) in [
            ("cpu", ComputeDevice::Cpu),
            ("cuda", ComputeDevice::Cuda(0)),
            ("cuda:3", ComputeDevice::Cuda(3)),
        ] {
            assert_eq!(ComputeDevice::try_from(name.to_string()).unwrap(), device);
        }
        assert_eq!(String::from(ComputeDevice::Cuda(0)), "cuda:0");
        for bad in ["gpu", "cuda:", "cuda:x", ""] {
            assert!(ComputeDevice::try_from(bad.to_string()).is_err(), "{bad}");
        }
    }

    #[cfg(not(feature = "cuda"))]
    #[test]
    fn cuda_without_the_feature_is_an_error_also_through_the_setting() {
        let err = ComputeDevice::Cuda(0).open().unwrap_err().to_string();
        assert!(err.to_lowercase().contains("cuda"), "{err}");
        let cfg = crate::net::Config::tiny()
            .with_settings(&["device=cuda"])
            .unwrap();
        assert_eq!(cfg.device, ComputeDevice::Cuda(0));
        let load =
            crate::net::LearnedReconstructor::load(&cfg, &crate::net::default_weights("tiny"));
        assert!(matches!(load, Err(crate::net::LoadError::Device(_))));
        let bad = crate::net::Config::tiny().with_settings(&["device=gpu"]);
        assert!(bad.unwrap_err().to_string().contains("unknown device"));
    }
}
