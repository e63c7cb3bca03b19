use burn::module::Module;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::loss::CrossEntropyLossConfig;
use burn::nn::{BatchNorm, BatchNormConfig, Linear, LinearConfig, PaddingConfig2d};
use burn::optim::{AdamWConfig, GradientsParams, Optimizer};
use burn::tensor::{Device, Distribution, Int, Tensor, activation};

#[derive(Module, Debug)]
struct Block {
    c1: Conv2d,
    b1: BatchNorm,
    c2: Conv2d,
    b2: BatchNorm,
    skip: Conv2d,
}
impl Block {
    fn new(cin: usize, cout: usize, d: &Device) -> Self {
        Self {
            c1: Conv2dConfig::new([cin, cout], [3, 3])
                .with_stride([2, 2])
                .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                .with_bias(false)
                .init(d),
            b1: BatchNormConfig::new(cout).init(d),
            c2: Conv2dConfig::new([cout, cout], [3, 3])
                .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                .with_bias(false)
                .init(d),
            b2: BatchNormConfig::new(cout).init(d),
            skip: Conv2dConfig::new([cin, cout], [1, 1])
                .with_stride([2, 2])
                .with_bias(false)
                .init(d),
        }
    }
    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let y = activation::relu(self.b1.forward(self.c1.forward(x.clone())));
        let y = self.b2.forward(self.c2.forward(y));
        activation::relu(y + self.skip.forward(x))
    }
}
#[derive(Module, Debug)]
struct Net {
    stem: Conv2d,
    bs: BatchNorm,
    l1: Block,
    l2: Block,
    head: Conv2d,
    out: Conv2d,
    cls: Linear,
}
impl Net {
    fn new(d: &Device) -> Self {
        Self {
            stem: Conv2dConfig::new([1, 16], [3, 3])
                .with_stride([2, 2])
                .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                .with_bias(false)
                .init(d),
            bs: BatchNormConfig::new(16).init(d),
            l1: Block::new(16, 32, d),
            l2: Block::new(32, 64, d),
            head: Conv2dConfig::new([64, 64], [3, 3])
                .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                .init(d),
            out: Conv2dConfig::new([64, 7], [1, 1]).init(d),
            cls: LinearConfig::new(64, 17).init(d),
        }
    }
    fn forward(&self, x: Tensor<4>) -> (Tensor<4>, Tensor<2>) {
        let y = activation::relu(self.bs.forward(self.stem.forward(x)));
        let y = self.l2.forward(self.l1.forward(y));
        let pooled: Tensor<2> = y.clone().mean_dim(3).mean_dim(2).flatten(1, 3);
        let h = self.out.forward(activation::relu(self.head.forward(y)));
        (h, self.cls.forward(pooled))
    }
}
fn main() {
    let d = Device::flex().autodiff();
    let mut net: Net = Net::new(&d);
    let mut opt = AdamWConfig::new().init();
    let (b, h, w) = (16, 128, 128);
    let x = Tensor::<4>::random([b, 1, h, w], Distribution::Normal(0.0, 1.0), &d);
    let target = Tensor::<4>::random([b, 7, h / 8, w / 8], Distribution::Uniform(0.0, 1.0), &d);
    let labels = Tensor::<1, Int>::zeros([b], &d);
    let steps = 10;
    let mut times = vec![];
    for _ in 0..steps {
        let t = std::time::Instant::now();
        let (hm, logits) = net.forward(x.clone());
        let l1 = (activation::sigmoid(hm) - target.clone())
            .powf_scalar(2.0)
            .mean();
        let l2 = CrossEntropyLossConfig::new()
            .init(&d)
            .forward(logits, labels.clone());
        let loss = l1 + l2;
        let grads = GradientsParams::from_grads(loss.backward(), &net);
        net = opt.step(1e-3, net, grads);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let inf = net.valid();
    let one = Tensor::<4>::random(
        [1, 1, 240, 320],
        Distribution::Normal(0.0, 1.0),
        &Device::flex(),
    );
    let t = std::time::Instant::now();
    for _ in 0..10 {
        let _ = inf.forward(one.clone()).0.into_data();
    }
    times.sort_by(|a, b| a.partial_cmp(b).unwrap());
    println!(
        "train step b16 128x128 median {:.1} ms; infer 320x240 {:.1} ms",
        times[steps / 2],
        t.elapsed().as_secs_f64() * 100.0
    );
}
