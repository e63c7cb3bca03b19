use candle_core::{D, DType, Device, Module, ModuleT, Tensor};
use candle_nn::{
    AdamW, BatchNorm, Conv2d, Conv2dConfig, Linear, Optimizer, ParamsAdamW, VarBuilder, VarMap,
    batch_norm, conv2d_no_bias, linear,
};

struct Block {
    c1: Conv2d,
    b1: BatchNorm,
    c2: Conv2d,
    b2: BatchNorm,
    skip: Conv2d,
}
impl Block {
    fn new(cin: usize, cout: usize, vb: VarBuilder) -> candle_core::Result<Self> {
        let s2 = Conv2dConfig {
            stride: 2,
            padding: 1,
            ..Default::default()
        };
        let s1 = Conv2dConfig {
            padding: 1,
            ..Default::default()
        };
        Ok(Self {
            c1: conv2d_no_bias(cin, cout, 3, s2, vb.pp("c1"))?,
            b1: batch_norm(cout, 1e-5, vb.pp("b1"))?,
            c2: conv2d_no_bias(cout, cout, 3, s1, vb.pp("c2"))?,
            b2: batch_norm(cout, 1e-5, vb.pp("b2"))?,
            skip: conv2d_no_bias(
                cin,
                cout,
                1,
                Conv2dConfig {
                    stride: 2,
                    ..Default::default()
                },
                vb.pp("skip"),
            )?,
        })
    }
    fn forward(&self, x: &Tensor, train: bool) -> candle_core::Result<Tensor> {
        let y = self.b1.forward_t(&self.c1.forward(x)?, train)?.relu()?;
        let y = self.b2.forward_t(&self.c2.forward(&y)?, train)?;
        (y + self.skip.forward(x)?)?.relu()
    }
}
struct Net {
    stem: Conv2d,
    bs: BatchNorm,
    blocks: Vec<Block>,
    head: Conv2d,
    out: Conv2d,
    cls: Linear,
}
impl Net {
    fn new(vb: VarBuilder) -> candle_core::Result<Self> {
        let s2 = Conv2dConfig {
            stride: 2,
            padding: 1,
            ..Default::default()
        };
        Ok(Self {
            stem: conv2d_no_bias(1, 16, 3, s2, vb.pp("stem"))?,
            bs: batch_norm(16, 1e-5, vb.pp("bs"))?,
            blocks: vec![
                Block::new(16, 32, vb.pp("l1"))?,
                Block::new(32, 64, vb.pp("l2"))?,
            ],
            head: candle_nn::conv2d(
                64,
                64,
                3,
                Conv2dConfig {
                    padding: 1,
                    ..Default::default()
                },
                vb.pp("head"),
            )?,
            out: candle_nn::conv2d(64, 7, 1, Default::default(), vb.pp("out"))?,
            cls: linear(64, 17, vb.pp("cls"))?,
        })
    }
    fn forward(&self, x: &Tensor, train: bool) -> candle_core::Result<(Tensor, Tensor)> {
        let mut y = self.bs.forward_t(&self.stem.forward(x)?, train)?.relu()?;
        for b in &self.blocks {
            y = b.forward(&y, train)?;
        }
        let pooled = y.mean(D::Minus1)?.mean(D::Minus1)?;
        let h = self.out.forward(&self.head.forward(&y)?.relu()?)?;
        Ok((h, self.cls.forward(&pooled)?))
    }
}
fn main() -> candle_core::Result<()> {
    let dev = Device::Cpu;
    let vm = VarMap::new();
    let net = Net::new(VarBuilder::from_varmap(&vm, DType::F32, &dev))?;
    let mut opt = AdamW::new(
        vm.all_vars(),
        ParamsAdamW {
            lr: 1e-3,
            ..Default::default()
        },
    )?;
    let (b, h, w) = (16, 128, 128);
    let x = Tensor::randn(0f32, 1., (b, 1, h, w), &dev)?;
    let target = Tensor::rand(0f32, 1., (b, 7, h / 8, w / 8), &dev)?;
    let labels = Tensor::zeros(b, DType::U32, &dev)?;
    let steps = 10;
    let mut times = vec![];
    for _ in 0..steps {
        let t = std::time::Instant::now();
        let (hm, logits) = net.forward(&x, true)?;
        let l1 = (candle_nn::ops::sigmoid(&hm)? - &target)?
            .sqr()?
            .mean_all()?;
        let l2 = candle_nn::loss::cross_entropy(&logits, &labels)?;
        let loss = (l1 + l2)?;
        opt.backward_step(&loss)?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let one = Tensor::randn(0f32, 1., (1, 1, 240, 320), &dev)?;
    let t = std::time::Instant::now();
    for _ in 0..10 {
        net.forward(&one, false)?;
    }
    times.sort_by(|a, b| a.partial_cmp(b).unwrap());
    println!(
        "train step b16 128x128 median {:.1} ms; infer 320x240 {:.1} ms",
        times[steps / 2],
        t.elapsed().as_secs_f64() * 100.0
    );
    Ok(())
}
