//! The denoising network: a U-Net of inception modules (the seed thesis's Model VI evaluated
//! fully convolutionally), plus its [`DenoiserConfig`], which is saved beside the weights.

use burn::config::Config;
use burn::module::{Module, ModuleMapper, Param, ParamId};
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::PaddingConfig2d;
use burn::tensor::activation::relu;
use burn::tensor::{Device, Tensor};

use crate::encode::Encoding;
use crate::extreme_pool::{extreme_pool, Window};
use crate::kernel_output::KernelOutput;
use crate::same_conv::same_conv;
use crate::tensor_ops::conv1x1;
use crate::upsample::upsample2;

/// Renumbers a module's parameters 1, 2, 3, … in traversal order. burn draws a random id for
/// every parameter, and the ids are written into every record: two identical training runs
/// would otherwise save model and checkpoint files whose tensors are equal but whose bytes are
/// not, and a reproduced model could not be checked by its hash.
struct NumberedParams(u64);

impl ModuleMapper for NumberedParams {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let (_, value, mapper) = param.consume();
        self.0 += 1;
        Param::from_mapped_value(ParamId::from(self.0), value, mapper)
    }
}

/// Network hyper-parameters; serialised as JSON beside the weights so a model file is
/// self-describing.
#[derive(Config, Debug, PartialEq)]
pub struct DenoiserConfig {
    /// Channels at each resolution level, full resolution first; each level below the first
    /// halves the resolution, so the image sides must be multiples of
    /// [`DenoiserConfig::alignment`].
    pub channels: Vec<usize>,
    /// Inception blocks after the encoder at the coarsest level (the bottleneck), with
    /// dilations 2, 4, 2, ...
    #[config(default = 2)]
    pub bottleneck_blocks: usize,
    /// Length k of the 1×k then k×1 branch.
    #[config(default = 5)]
    pub prong: usize,
    /// Input planes read, the first this many of the [`crate::planes::Plane`] layout:
    /// [`crate::INPUT_CHANNELS`], or [`crate::planes::LEGACY_INPUT_CHANNELS`] for models made
    /// before the variance planes (checked on load).
    #[config(default = 20)]
    pub input_channels: usize,
    /// Whether noisy colour and the network's output are divided by the albedo (plus
    /// [`crate::encode::DEMOD_EPS`]) when an albedo layer is given, so the network denoises
    /// lighting and the texture is multiplied back exactly. Absent (older model files) means
    /// no; read it through [`DenoiserConfig::demodulates`].
    pub demodulate: Option<bool>,
    /// The value auto-exposure maps the log-average luminance to before the log transfer
    /// ln(1 + x · exposure): a larger key gives dark regions more of the transfer's range (and
    /// of the training loss). Absent (older model files) means
    /// [`crate::encode::DEFAULT_KEY`]; read it through [`DenoiserConfig::exposure_key`].
    pub exposure_key: Option<f32>,
    /// Whether the output is kernel-predicting ([`crate::kernel_output`]) instead of the
    /// encoded colour itself. Absent (older model files) means no; read it through
    /// [`DenoiserConfig::predicts_kernels`].
    pub kernel_output: Option<bool>,
    /// Whether a kernel-predicting output blends each coarser level's correction in through
    /// bilinear upsampling instead of nearest (whose blocks show where the correction is
    /// large). Absent (older model files) means nearest; read it through
    /// [`DenoiserConfig::blends_bilinearly`].
    pub bilinear_blend: Option<bool>,
    /// The side of a kernel-predicting output's kernels at every level (odd, 3 to
    /// [`crate::kernel_output::MAX_KERNEL_SIZE`]). Absent (older model files) means
    /// [`crate::kernel_output::DEFAULT_KERNEL_SIZE`]; read it through
    /// [`DenoiserConfig::kernel_size`].
    pub kernel_size: Option<usize>,
}

impl DenoiserConfig {
    /// The shipped architecture: three levels of 24, 48 and 64 channels.
    pub fn unet() -> Self {
        DenoiserConfig::new(vec![24, 48, 64])
    }

    /// Whether colour is demodulated by albedo (see the `demodulate` field).
    pub fn demodulates(&self) -> bool {
        self.demodulate.unwrap_or(false)
    }

    /// Whether the output is kernel-predicting (see the `kernel_output` field).
    pub fn predicts_kernels(&self) -> bool {
        self.kernel_output.unwrap_or(false)
    }

    /// Whether a kernel-predicting output blends bilinearly (see the `bilinear_blend` field).
    pub fn blends_bilinearly(&self) -> bool {
        self.bilinear_blend.unwrap_or(false)
    }

    /// The side of the predicted kernels (see the `kernel_size` field).
    pub fn kernel_size(&self) -> usize {
        self.kernel_size.unwrap_or(crate::kernel_output::DEFAULT_KERNEL_SIZE)
    }

    /// The exposure key (see the `exposure_key` field).
    pub fn exposure_key(&self) -> f32 {
        self.exposure_key.unwrap_or(crate::encode::DEFAULT_KEY)
    }

    /// How inputs are encoded for this network (every network reads the depth layer).
    pub fn encoding(&self) -> Encoding {
        Encoding { demodulate: self.demodulates(), key: self.exposure_key(), channels: self.input_channels }
    }

    /// Parses a model config, the `.json` saved beside the weights. Unknown fields are ignored.
    /// Files from before the architecture clean-up may carry `"depth"` and `"level_blocks"`,
    /// written for the removed `rtd train --no-depth` and `--grow`: they are accepted at the
    /// values that mean the option was not used (`null` or `true`; `null` or all zeros), and a
    /// model that used one is refused, since this rtd cannot compute what it does.
    pub fn from_json(text: &str) -> Result<Self, String> {
        let value: serde_json::Value = serde_json::from_str(text).map_err(|e| e.to_string())?;
        let no_depth = value.get("depth").is_some_and(|v| !v.is_null() && v.as_bool() != Some(true));
        if no_depth {
            return Err("made with `rtd train --no-depth`, which this rtd no longer supports".into());
        }
        let no_extra = |v: &serde_json::Value| v.as_array().is_some_and(|b| b.iter().all(|n| n.as_u64() == Some(0)));
        let grown = value.get("level_blocks").is_some_and(|v| !v.is_null() && !no_extra(v));
        if grown {
            return Err("made with `rtd train --grow`, which this rtd no longer supports".into());
        }
        serde_json::from_value(value).map_err(|e| e.to_string())
    }

    /// What makes this shape one no model file should have and no training run should build,
    /// if anything: no levels or more than [`MAX_LEVELS`], a level of no channels or more than
    /// [`MAX_LEVEL_CHANNELS`], an even prong or one wider than [`MAX_PRONG`] (an even one has no centre
    /// tap, so its branch would come out a pixel short of the others), or more than
    /// [`MAX_BOTTLENECK_BLOCKS`] bottleneck blocks, or a kernel side that is even (no centre
    /// tap) or outside 3 to [`crate::kernel_output::MAX_KERNEL_SIZE`]. One sentence.
    pub fn shape_problem(&self) -> Option<String> {
        let c = &self.channels;
        if c.is_empty() || c.len() > MAX_LEVELS || c.iter().any(|&n| n == 0 || n > MAX_LEVEL_CHANNELS) {
            return Some(format!(
                "implausible channel list {c:?} (1 to {MAX_LEVELS} levels of 1 to {MAX_LEVEL_CHANNELS} channels)"
            ));
        }
        if !(1..=MAX_PRONG).contains(&self.prong) || self.prong.is_multiple_of(2) {
            return Some(format!("implausible prong {} (an odd width from 1 to {MAX_PRONG})", self.prong));
        }
        if self.bottleneck_blocks > MAX_BOTTLENECK_BLOCKS {
            let blocks = self.bottleneck_blocks;
            return Some(format!("implausible bottleneck of {blocks} blocks (at most {MAX_BOTTLENECK_BLOCKS})"));
        }
        let (k, max_k) = (self.kernel_size(), crate::kernel_output::MAX_KERNEL_SIZE);
        if !(3..=max_k).contains(&k) || k.is_multiple_of(2) {
            return Some(format!("implausible kernel size {k} (an odd side from 3 to {max_k})"));
        }
        None
    }

    /// The resolution factor the image size must be padded to: 2^(levels−1).
    pub fn alignment(&self) -> usize {
        1 << (self.channels.len() - 1)
    }

    /// Builds the network with random weights drawn from `seed`: the same seed gives the same
    /// weights whatever else the process does. burn's flex backend keeps one random generator
    /// for the whole process, so seeding it and drawing the weights happen under one lock,
    /// which every other draw of weights here ([`DenoiserConfig::init`]) takes too; threads
    /// seeding and drawing at once would otherwise interleave their draws (a test comparing
    /// two networks made from one seed failed this way once in CI).
    pub fn init_seeded(&self, device: &Device, seed: u64) -> DenoiserNet {
        let _held = backend_rng();
        device.seed(seed);
        self.build(device)
    }

    /// Builds the network with random weights from the backend's generator as it stands (see
    /// [`DenoiserConfig::init_seeded`] for reproducible ones): for a network whose weights are
    /// loaded over them. It draws under the same lock as [`DenoiserConfig::init_seeded`], so it
    /// never takes draws from a seeded one.
    pub fn init(&self, device: &Device) -> DenoiserNet {
        let _held = backend_rng();
        self.build(device)
    }

    /// The network with weights from the backend's generator; the caller holds [`backend_rng`].
    fn build(&self, device: &Device) -> DenoiserNet {
        let c = &self.channels;
        let levels = c.len();
        let stem = conv(self.input_channels, c[0], 3, 1, device);
        let mut encoders = vec![InceptionBlock::new(c[0], c[0], 1, self.prong, device)];
        for l in 1..levels {
            encoders.push(InceptionBlock::new(c[l - 1], c[l], 1, self.prong, device));
        }
        let last = c[levels - 1];
        let bottleneck = (0..self.bottleneck_blocks)
            .map(|i| InceptionBlock::new(last, last, block_dilation(i), self.prong, device))
            .collect();
        let decoders = (0..levels - 1)
            .map(|l| Decoder {
                fuse: conv(c[l + 1] + c[l], c[l], 1, 1, device),
                refine: conv(c[l], c[l], 3, 1, device),
            })
            .collect();
        let output = conv(c[0], 3, 1, 1, device);
        let kernel =
            self.predicts_kernels().then(|| KernelOutput::new(c, self.blends_bilinearly(), self.kernel_size(), device));
        let net = DenoiserNet { kernel, stem, encoders, bottleneck, decoders, output };
        net.map(&mut NumberedParams(0))
    }

    /// An upper bound on how far (in full-resolution pixels) an input pixel can influence an
    /// output pixel: half the receptive field. Tiles overlap by at least this much.
    pub fn receptive_radius(&self) -> usize {
        let levels = self.channels.len();
        let block = |dilation: usize, scale: usize| dilation.max(2).max((self.prong - 1) / 2) * scale;
        let mut r = 1; // stem 3×3
        r += block(1, 1);
        for l in 1..levels {
            let s = 1 << l;
            r += s / 2 + block(1, s); // 2× max-pool, then a block at scale s
        }
        // The deepest path also passes the bottleneck blocks, at the coarsest scale.
        r += (0..self.bottleneck_blocks).map(|i| block(block_dilation(i), 1 << (levels - 1))).sum::<usize>();
        for l in (0..levels - 1).rev() {
            r += (1 << l) * 2; // nearest upsample + 1×1 fuse + 3×3 conv at scale 2^l
        }
        if self.predicts_kernels() {
            r += KernelOutput::radius(levels, self.kernel_size());
        }
        r
    }

    /// Multiply-accumulates per full-resolution pixel of one forward pass.
    pub fn macs_per_pixel(&self) -> f64 {
        let c = &self.channels;
        let levels = c.len();
        let scale = |l: usize| 1.0 / (1u64 << (2 * l)) as f64;
        let mut m = (9 * self.input_channels * c[0]) as f64;
        m += InceptionBlock::macs(c[0], c[0], self.prong);
        for l in 1..levels {
            m += InceptionBlock::macs(c[l - 1], c[l], self.prong) * scale(l);
        }
        let last = levels - 1;
        m += self.bottleneck_blocks as f64 * InceptionBlock::macs(c[last], c[last], self.prong) * scale(last);
        for l in 0..levels - 1 {
            m += ((c[l + 1] + c[l]) * c[l] + 9 * c[l] * c[l]) as f64 * scale(l);
        }
        if self.predicts_kernels() {
            return m + KernelOutput::macs(c, self.kernel_size());
        }
        m + (c[0] * 3) as f64
    }
}

/// The lock on burn flex's process-wide random generator, held while a network's weights are
/// drawn (its parameters are made and initialised within [`DenoiserConfig::init`]).
fn backend_rng() -> std::sync::MutexGuard<'static, ()> {
    static BACKEND_RNG: std::sync::Mutex<()> = std::sync::Mutex::new(());
    BACKEND_RNG.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Keeps each parameter's id and forces its value, which burn draws lazily at first use.
#[cfg(test)]
struct DrawNow;

#[cfg(test)]
impl ModuleMapper for DrawNow {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let (id, value, mapper) = param.consume();
        Param::from_mapped_value(id, value, mapper)
    }
}

/// A test's layer with its weights drawn now, under [`backend_rng`], so they never interleave
/// with a seeded network's draws on another test thread.
#[cfg(test)]
pub(crate) fn drawn_now<M: Module>(make: impl FnOnce() -> M) -> M {
    let _held = backend_rng();
    make().map(&mut DrawNow)
}

/// The most resolution levels a network may have.
pub const MAX_LEVELS: usize = 5;
/// The most channels a level may have.
pub const MAX_LEVEL_CHANNELS: usize = 512;
/// The widest 1×k prong a block may have (k odd).
pub const MAX_PRONG: usize = 15;
/// The most inception blocks the bottleneck may have.
pub const MAX_BOTTLENECK_BLOCKS: usize = 64;

/// Dilation of the `i`th inception block at a level (after its encoder): 2, 4, 2, 4, ...
fn block_dilation(i: usize) -> usize {
    2 + i % 2 * 2
}

/// A stride-1 convolution with "same" padding.
fn conv(cin: usize, cout: usize, k: usize, dilation: usize, device: &Device) -> Conv2d {
    conv_rect(cin, cout, [k, k], dilation, device)
}

fn conv_rect(cin: usize, cout: usize, k: [usize; 2], dilation: usize, device: &Device) -> Conv2d {
    let (ph, pw) = ((k[0] - 1) / 2 * dilation, (k[1] - 1) / 2 * dilation);
    Conv2dConfig::new([cin, cout], k)
        .with_dilation([dilation, dilation])
        .with_padding(PaddingConfig2d::Explicit(ph, pw, ph, pw))
        .init(device)
}

/// One inception module: parallel 1×1, 3×3, dilated 3×3, 1×k→k×1, max-pool and min-pool
/// branches, concatenated and mixed by a 1×1 convolution, with a residual path when the widths
/// match.
#[derive(Module, Debug)]
pub struct InceptionBlock {
    pub(crate) one: Conv2d,
    pub(crate) three: Conv2d,
    pub(crate) dilated: Conv2d,
    pub(crate) prong_h: Conv2d,
    pub(crate) prong_v: Conv2d,
    pub(crate) max_proj: Conv2d,
    pub(crate) min_proj: Conv2d,
    pub(crate) mix: Conv2d,
    pub(crate) residual: bool,
}

impl InceptionBlock {
    /// Branch width for an output of `cout` channels.
    fn branch(cout: usize) -> usize {
        (cout / 4).max(4)
    }

    /// Width of each pooling branch's projection for an output of `cout` channels.
    fn half_branch(cout: usize) -> usize {
        (Self::branch(cout) / 2).max(2)
    }

    fn new(cin: usize, cout: usize, dilation: usize, prong: usize, device: &Device) -> Self {
        let (b, h) = (Self::branch(cout), Self::half_branch(cout));
        InceptionBlock {
            one: conv(cin, b, 1, 1, device),
            three: conv(cin, b, 3, 1, device),
            dilated: conv(cin, b, 3, dilation.max(2), device),
            prong_h: conv_rect(cin, b, [1, prong], 1, device),
            prong_v: conv_rect(b, b, [prong, 1], 1, device),
            max_proj: conv(cin, h, 1, 1, device),
            min_proj: conv(cin, h, 1, 1, device),
            mix: conv(4 * b + 2 * h, cout, 1, 1, device),
            residual: cin == cout,
        }
    }

    fn macs(cin: usize, cout: usize, prong: usize) -> f64 {
        let (b, h) = (Self::branch(cout), Self::half_branch(cout));
        (cin * b + 2 * 9 * cin * b + prong * cin * b + prong * b * b + 2 * cin * h + (4 * b + 2 * h) * cout) as f64
    }

    /// `x`: [N, cin, H, W] → [N, cout, H, W].
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let one = conv1x1(&self.one, x.clone()); // [N, b, H, W]
        let three = same_conv(&self.three, x.clone()); // [N, b, H, W]
        let dilated = same_conv(&self.dilated, x.clone()); // [N, b, H, W]
        let prong = same_conv(&self.prong_v, relu(same_conv(&self.prong_h, x.clone()))); // [N, b, H, W]
        let max = conv1x1(&self.max_proj, extreme_pool(x.clone(), Window::Three, true)); // [N, b/2, H, W]
        let min = conv1x1(&self.min_proj, extreme_pool(x.clone(), Window::Three, false)); // [N, b/2, H, W]
        let cat = relu(Tensor::cat(vec![one, three, dilated, prong, max, min], 1)); // [N, 4b + b, H, W]
        let y = relu(conv1x1(&self.mix, cat)); // [N, cout, H, W]
        if self.residual {
            y + x
        } else {
            y
        }
    }
}

/// The denoiser: stem conv, an encoder of inception blocks with 2× max-pool between levels,
/// inception bottleneck blocks, a decoder of nearest upsampling + skip concatenation + 1×1
/// fuse + 3×3 convs, and a 1×1 output conv predicting encoded colour.
#[derive(Module, Debug)]
pub struct DenoiserNet {
    pub(crate) stem: Conv2d,
    pub(crate) encoders: Vec<InceptionBlock>,
    pub(crate) bottleneck: Vec<InceptionBlock>,
    pub(crate) decoders: Vec<Decoder>,
    pub(crate) output: Conv2d,
    /// The kernel-predicting heads, which replace `output` when present.
    pub(crate) kernel: Option<KernelOutput>,
}

/// One decoder level: the upsampled coarse features and the skip are concatenated, fused by a
/// 1×1 convolution and refined by a 3×3 one.
#[derive(Module, Debug)]
pub struct Decoder {
    pub(crate) fuse: Conv2d,
    pub(crate) refine: Conv2d,
}

impl DenoiserNet {
    /// The same network reading `channels` input planes instead of its stem's present count
    /// (more, not fewer): the stem gets zero weights for the added planes, so the network
    /// computes the same function until training teaches it to use them. This is how a model
    /// made before the variance planes seeds one that reads them.
    pub fn widen_input(mut self, channels: usize) -> Self {
        let weight = self.stem.weight.val(); // [c0, cin, 3, 3]
        let [c0, cin, kh, kw] = weight.dims();
        if channels > cin {
            let zeros = Tensor::<4>::zeros([c0, channels - cin, kh, kw], &weight.device());
            // `detach` makes the widened weight a leaf, which autodiff needs to track it.
            self.stem.weight = Param::from_tensor(Tensor::cat(vec![weight, zeros], 1).detach());
        }
        self.map(&mut NumberedParams(0))
    }

    /// The same network with kernel-predicting heads ([`crate::kernel_output`]) drawn from
    /// `seed` in place of its direct output (a network that has them keeps them): how a
    /// trained direct-prediction model seeds a kernel-predicting one.
    pub fn with_kernel_output(mut self, config: &DenoiserConfig, device: &Device, seed: u64) -> Self {
        // burn draws parameters lazily, so the lock is held until `map` has forced them.
        let _held = backend_rng();
        if self.kernel.is_none() {
            device.seed(seed);
            let (bilinear, size) = (config.blends_bilinearly(), config.kernel_size());
            self.kernel = Some(KernelOutput::new(&config.channels, bilinear, size, device));
        }
        self.map(&mut NumberedParams(0))
    }

    /// `x`: [N, C, H, W] encoded inputs (C the config's input planes), H and W multiples of the config's alignment
    /// → [N, 3, H, W] encoded colour.
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let mut skips = Vec::with_capacity(self.encoders.len());
        // Kernel heads read the noisy colour and every level's decoder output.
        let mut kernel_inputs = self.kernel.as_ref().map(|_| (x.clone().narrow(1, 0, 3), vec![])); // [N, 3, H, W]
        let mut y = relu(same_conv(&self.stem, x)); // [N, c0, H, W]
        for (l, enc) in self.encoders.iter().enumerate() {
            if l > 0 {
                y = extreme_pool(y, Window::Two, true); // [N, c(l−1), H/2^l, W/2^l]
            }
            y = enc.forward(y); // [N, c(l), H/2^l, W/2^l]
            skips.push(y.clone());
        }
        for b in &self.bottleneck {
            y = b.forward(y); // [N, c(last), H/2^(L−1), W/2^(L−1)]
        }
        skips.pop();
        for dec in self.decoders.iter().rev() {
            if let Some((_, levels)) = &mut kernel_inputs {
                levels.push(y.clone()); // coarsest first
            }
            let skip = skips.pop().expect("one skip per decoder level"); // [N, c(l), H/2^l, W/2^l]
            let up = upsample2(y); // [N, c(l+1), H/2^l, W/2^l]
            let fused = relu(conv1x1(&dec.fuse, Tensor::cat(vec![up, skip], 1))); // [N, c(l), H/2^l, W/2^l]
            y = relu(same_conv(&dec.refine, fused)); // [N, c(l), H/2^l, W/2^l]
        }
        match (&self.kernel, kernel_inputs) {
            (Some(kernel), Some((noisy, mut levels))) => {
                levels.push(y);
                levels.reverse();
                kernel.forward(noisy, &levels) // [N, 3, H, W]
            }
            _ => conv1x1(&self.output, y), // [N, 3, H, W]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planes::INPUT_CHANNELS;
    use burn::tensor::TensorData;

    #[test]
    fn shapes_are_preserved_and_costs_follow_the_config() {
        let device = Device::flex();
        for config in [DenoiserConfig::new(vec![8, 12, 16]), DenoiserConfig::new(vec![8])] {
            let a = config.alignment();
            let net = config.init(&device);
            let (h, w) = (3 * a * 2, 5 * a * 2);
            let x = Tensor::<4>::from_data(
                TensorData::new(vec![0.5f32; 2 * INPUT_CHANNELS * h * w], [2, INPUT_CHANNELS, h, w]),
                &device,
            );
            assert_eq!(net.forward(x).dims(), [2, 3, h, w]);
        }
        // The shipped U-Net's figures, as models/README.md and the tile margin have them.
        let u = DenoiserConfig::unet().with_input_channels(crate::planes::LEGACY_INPUT_CHANNELS);
        assert_eq!((u.alignment(), u.receptive_radius()), (4, 48));
        assert_eq!(u.macs_per_pixel(), 29768.0);
        // The variance planes add four stem inputs: 4 × 9 × 24 multiply-adds per pixel.
        assert_eq!(DenoiserConfig::unet().macs_per_pixel(), 29768.0 + 864.0);
        // Each bottleneck block adds cost and reach.
        let deeper = DenoiserConfig::unet().with_bottleneck_blocks(3);
        assert!(deeper.macs_per_pixel() > u.macs_per_pixel() && deeper.receptive_radius() > u.receptive_radius());
    }

    /// Threads that seed and draw networks at once still get each seed's own weights.
    #[test]
    fn a_seed_gives_the_same_weights_while_other_threads_draw() {
        let config = DenoiserConfig::new(vec![8, 12]);
        let weights = |seed: u64| -> Vec<f32> {
            let net = config.init_seeded(&Device::flex(), seed);
            let mut all: Vec<f32> = net.stem.weight.val().into_data().try_to_vec().unwrap();
            all.extend(net.output.weight.val().into_data().try_to_vec::<f32>().unwrap());
            all
        };
        let expected = weights(5);
        let drawn: Vec<Vec<f32>> = std::thread::scope(|s| {
            // Unseeded draws (a network whose weights will be loaded over them) alongside.
            s.spawn(|| (0..40).for_each(|_| drop(config.init(&Device::flex()))));
            let threads: Vec<_> = (0..8u64)
                .map(|t| s.spawn(move || (0..40).map(|i| weights(5 + (i + t) % 2)).collect::<Vec<_>>()))
                .collect();
            threads.into_iter().flat_map(|t| t.join().unwrap()).collect()
        });
        let fives = drawn.iter().filter(|w| **w == expected).count();
        assert_eq!(fives, 160, "of 320 draws, 160 were from seed 5; {fives} gave its weights");
    }

    #[test]
    fn a_widened_network_ignores_its_new_planes_until_trained() {
        let device = Device::flex();
        let narrow = DenoiserConfig::new(vec![8, 12]).with_input_channels(crate::planes::LEGACY_INPUT_CHANNELS);
        let net = narrow.init_seeded(&device, 7);
        let (h, w, c) = (8, 12, INPUT_CHANNELS);
        let values: Vec<f32> = (0..c * h * w).map(|i| (i * 37 % 101) as f32 / 50.0 - 1.0).collect();
        let full = Tensor::<4>::from_data(TensorData::new(values, [1, c, h, w]), &device);
        let first = full.clone().narrow(1, 0, crate::planes::LEGACY_INPUT_CHANNELS);
        let before: Vec<f32> = net.forward(first).into_data().try_to_vec().unwrap();
        let wide = net.widen_input(c);
        assert_eq!(wide.stem.weight.val().dims()[1], c);
        let after: Vec<f32> = wide.forward(full).into_data().try_to_vec().unwrap();
        assert_eq!(before, after);
        // Training widens on the autodiff device, whose parameters must stay trackable leaves.
        let trained = narrow.init(&Device::flex().autodiff()).widen_input(c);
        assert!(trained.stem.weight.val().is_require_grad());
    }

    /// A kernel-predicting network keeps a flat noisy colour flat whatever its weights, a
    /// trained direct network gains such heads from a seed, and the heads add their cost and
    /// reach to the config's figures.
    #[test]
    fn kernel_heads_keep_flat_colour_and_attach_to_a_direct_network() {
        let device = Device::flex();
        let direct = DenoiserConfig::new(vec![8, 12]);
        let kp = direct.clone().with_kernel_output(Some(true));
        assert!(kp.macs_per_pixel() > direct.macs_per_pixel());
        // Wider kernels cost more and reach further; an even or oversized side is refused.
        let wide = kp.clone().with_kernel_size(Some(7));
        assert!(wide.macs_per_pixel() > kp.macs_per_pixel() && wide.receptive_radius() > kp.receptive_radius());
        assert!(kp.shape_problem().is_none() && wide.shape_problem().is_none());
        for bad in [1, 4, 11] {
            assert!(kp.clone().with_kernel_size(Some(bad)).shape_problem().is_some(), "kernel size {bad}");
        }
        assert!(kp.receptive_radius() > direct.receptive_radius());
        let (h, w, c) = (8, 12, INPUT_CHANNELS);
        let mut values: Vec<f32> = (0..c * h * w).map(|i| (i * 37 % 101) as f32 / 50.0).collect();
        values[..3 * h * w].fill(0.75);
        let x = Tensor::<4>::from_data(TensorData::new(values, [1, c, h, w]), &device);
        let heads = |seed| direct.init_seeded(&device, 3).with_kernel_output(&kp, &device, seed);
        let out: Vec<f32> = heads(4).forward(x.clone()).into_data().try_to_vec().unwrap();
        assert!(out.iter().all(|v| (v - 0.75).abs() < 1e-5), "{:?}", &out[..4]);
        let weights = |n: DenoiserNet| -> Vec<f32> {
            n.kernel.unwrap().kernels[0].weight.val().into_data().try_to_vec().unwrap()
        };
        assert_eq!(weights(heads(4)), weights(heads(4)));
        assert_ne!(weights(heads(4)), weights(heads(5)));
        assert_eq!(kp.init(&device).forward(x).dims(), [1, 3, h, w]);
    }

    #[test]
    fn model_configs_of_removed_training_options_are_refused_and_the_shipped_one_loads() {
        use serde_json::json;
        let shipped = DenoiserConfig::from_json(include_str!("../../../models/rtd-denoiser.json")).unwrap();
        assert_eq!((&shipped.channels, shipped.bottleneck_blocks, shipped.prong), (&vec![24, 48, 64], 2, 5));
        assert!(shipped.demodulates() && (shipped.exposure_key() - 2.88).abs() < 1e-6);
        assert!(shipped.predicts_kernels() && shipped.blends_bilinearly() && shipped.kernel_size() == 7);
        assert_eq!(
            shipped.encoding(),
            Encoding { demodulate: true, key: shipped.exposure_key(), channels: INPUT_CHANNELS }
        );
        // A small config's JSON with one field set as older rtd versions wrote it.
        let with = |field: &str, v: serde_json::Value| {
            let mut json = serde_json::to_value(DenoiserConfig::new(vec![8, 8])).unwrap();
            json[field] = v;
            DenoiserConfig::from_json(&json.to_string())
        };
        for (field, unused) in [("depth", json!(null)), ("depth", json!(true)), ("level_blocks", json!([0]))] {
            assert_eq!(with(field, unused.clone()), Ok(DenoiserConfig::new(vec![8, 8])), "{field}: {unused}");
        }
        assert_eq!(with("level_blocks", json!(null)), Ok(DenoiserConfig::new(vec![8, 8])));
        let e = with("depth", json!(false)).unwrap_err();
        assert!(e.contains("--no-depth"), "{e}");
        let e = with("level_blocks", json!([0, 1])).unwrap_err();
        assert!(e.contains("--grow"), "{e}");
        assert!(DenoiserConfig::from_json("{").is_err());
    }
}
