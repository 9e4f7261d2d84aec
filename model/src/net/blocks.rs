//! Convolution building blocks shared by the network's parts.

use candle_core::{Module, Result, Tensor};
use candle_nn::VarBuilder;

use crate::ops::Conv;

/// A `k` x `k` convolution with "same" padding and the given stride.
pub fn conv(vb: VarBuilder, cin: usize, cout: usize, k: usize, stride: usize) -> Result<Conv> {
    Conv::new(vb, (cin, cout), k, stride, k / 2, true)
}

/// A 3x3 convolution followed by ReLU.
#[derive(Clone, Debug)]
pub struct ConvRelu {
    conv: Conv,
}

impl ConvRelu {
    /// A 3x3 convolution `cin -> cout` with `stride`.
    pub fn new(vb: VarBuilder, cin: usize, cout: usize, stride: usize) -> Result<Self> {
        Ok(Self {
            conv: conv(vb, cin, cout, 3, stride)?,
        })
    }
}

impl Module for ConvRelu {
    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        self.conv.forward(x)?.relu()
    }
}

/// Two 3x3 convolutions with a skip connection (a ResNet basic block without norm).
#[derive(Clone, Debug)]
pub struct ResBlock {
    a: Conv,
    b: Conv,
}

impl ResBlock {
    /// A block on `channels` channels.
    pub fn new(vb: VarBuilder, channels: usize) -> Result<Self> {
        Ok(Self {
            a: conv(vb.pp("a"), channels, channels, 3, 1)?,
            b: conv(vb.pp("b"), channels, channels, 3, 1)?,
        })
    }
}

impl Module for ResBlock {
    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let y = self.b.forward(&self.a.forward(x)?.relu()?)?;
        (x + y)?.relu()
    }
}

/// `n` residual blocks in a row.
pub fn res_blocks(vb: VarBuilder, channels: usize, n: usize) -> Result<Vec<ResBlock>> {
    (0..n)
        .map(|i| ResBlock::new(vb.pp(i.to_string()), channels))
        .collect()
}

/// Applies `layers` in order.
pub fn chain<M: Module>(layers: &[M], x: &Tensor) -> Result<Tensor> {
    layers.iter().try_fold(x.clone(), |x, l| l.forward(&x))
}
