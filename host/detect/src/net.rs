//! The network: a small ResNet backbone, CenterNet's heads at 1/8 of the image, and a
//! fabric classifier on the deepest features (the paper's extra classification branch).
//!
//! ```text
//! image 1×H×W → stem 3×3/2 → block /4 → block /8 ─┬→ heat (3), size (2), offset (2)
//!                                                  └→ block /16 → mean → fabric (17)
//! ```
//!
//! Each block is two 3 × 3 convolutions with batch norm and a 1 × 1 shortcut, the first
//! convolution halving the resolution.

use burn::module::{Module, Param};
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{BatchNorm, BatchNormConfig, Linear, LinearConfig, PaddingConfig2d};
use burn::tensor::{Device, Tensor, activation::relu};

use super::targets::KINDS;

/// The network's channel widths: stem, the /4 and /8 blocks, the classifier's /16 block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Widths(pub [usize; 4]);

impl Widths {
    /// The shipped model's widths.
    pub const SHIPPED: Widths = Widths([16, 32, 64, 96]);
}

/// A 3 × 3 convolution, halving the resolution or keeping it.
fn conv3(cin: usize, cout: usize, halve: bool, bias: bool, device: &Device) -> Conv2d {
    let stride = if halve { 2 } else { 1 };
    Conv2dConfig::new([cin, cout], [3, 3])
        .with_stride([stride, stride])
        .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
        .with_bias(bias)
        .init(device)
}

/// A residual block that halves the resolution.
#[derive(Module, Debug)]
pub struct Block {
    first: Conv2d,
    first_norm: BatchNorm,
    second: Conv2d,
    second_norm: BatchNorm,
    shortcut: Conv2d,
}

impl Block {
    fn new(cin: usize, cout: usize, device: &Device) -> Self {
        Self {
            first: conv3(cin, cout, true, false, device),
            first_norm: BatchNormConfig::new(cout).init(device),
            second: conv3(cout, cout, false, false, device),
            second_norm: BatchNormConfig::new(cout).init(device),
            shortcut: Conv2dConfig::new([cin, cout], [1, 1])
                .with_stride([2, 2])
                .with_bias(false)
                .init(device),
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let y = relu(self.first_norm.forward(self.first.forward(x.clone())));
        let y = self.second_norm.forward(self.second.forward(y));
        relu(y + self.shortcut.forward(x))
    }
}

/// A head: 3 × 3 convolution, ReLU, 1 × 1 convolution to `out` channels starting at `bias`.
#[derive(Module, Debug)]
pub struct Head {
    hidden: Conv2d,
    out: Conv2d,
}

impl Head {
    fn new(c: usize, out: usize, bias: f32, device: &Device) -> Self {
        let mut last = Conv2dConfig::new([c, out], [1, 1]).init(device);
        last.bias = Some(Param::from_tensor(Tensor::full([out], bias, device)));
        Self {
            hidden: conv3(c, c, false, true, device),
            out: last,
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        self.out.forward(relu(self.hidden.forward(x)))
    }
}

/// The network's raw outputs for a batch.
pub struct Raw {
    /// Heatmap logits, `(B, KINDS, H/8, W/8)`.
    pub heat: Tensor<4>,
    /// Box sizes in cells, `(B, 2, H/8, W/8)`.
    pub size: Tensor<4>,
    /// Centre offsets in the cell, `(B, 2, H/8, W/8)`.
    pub offset: Tensor<4>,
    /// Fabric logits, `(B, classes)`.
    pub fabric: Tensor<2>,
}

/// The detector network.
#[derive(Module, Debug)]
pub struct Net {
    stem: Conv2d,
    stem_norm: BatchNorm,
    quarter: Block,
    eighth: Block,
    sixteenth: Block,
    heat: Head,
    size: Head,
    offset: Head,
    fabric: Linear,
}

impl Net {
    /// A freshly initialized network on `device`.
    pub fn new(widths: Widths, classes: usize, device: &Device) -> Self {
        let [c0, c1, c2, c3] = widths.0;
        Self {
            stem: conv3(1, c0, true, false, device),
            stem_norm: BatchNormConfig::new(c0).init(device),
            quarter: Block::new(c0, c1, device),
            eighth: Block::new(c1, c2, device),
            sixteenth: Block::new(c2, c3, device),
            // CenterNet's prior: a heatmap that starts near 0.1 everywhere trains stably.
            heat: Head::new(c2, KINDS, -2.19, device),
            size: Head::new(c2, 2, 0.0, device),
            offset: Head::new(c2, 2, 0.0, device),
            fabric: LinearConfig::new(c3, classes).init(device),
        }
    }

    /// Runs a batch `(B, 1, H, W)` of normalized images. On an autodiff device batch norm
    /// uses the batch's statistics (training); elsewhere the running ones.
    pub fn forward(&self, x: Tensor<4>) -> Raw {
        let y = relu(self.stem_norm.forward(self.stem.forward(x)));
        let y = self.eighth.forward(self.quarter.forward(y));
        let deep = self.sixteenth.forward(y.clone());
        let pooled: Tensor<2> = deep.mean_dim(3).mean_dim(2).flatten(1, 3);
        Raw {
            heat: self.heat.forward(y.clone()),
            size: self.size.forward(y.clone()),
            offset: self.offset.forward(y),
            fabric: self.fabric.forward(pooled),
        }
    }
}
