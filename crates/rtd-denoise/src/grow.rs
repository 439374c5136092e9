//! Growing a trained network by one coarser level, without changing what it computes.
//!
//! [`add_level`] appends a level below the coarsest: 2× max-pool, a new encoder block and new
//! bottleneck blocks, and a decoder that fuses their upsampled output with the old coarsest
//! features. The old bottleneck stays where it was, as that level's blocks. The new decoder
//! starts as the identity on the old features (its 1×1 fuse passes the skip half through and
//! ignores the upsampled half, its 3×3 refine is a centred identity kernel), so the grown
//! network's output equals the old one's; training then brings in the coarser level, whose
//! weights get gradients once the fuse's weights on the upsampled half move off zero. This lets
//! a model gain receptive field and low-frequency capacity from where earlier training left it
//! instead of from random weights.

use burn::module::Param;
use burn::tensor::{Device, Tensor, TensorData};

use crate::model::{conv, Decoder, DenoiserConfig, DenoiserNet};

/// The config of `config` grown by a coarsest level of `channels` channels with `blocks`
/// bottleneck blocks; the old bottleneck becomes the old coarsest level's blocks.
pub fn grown_config(config: &DenoiserConfig, channels: usize, blocks: usize) -> DenoiserConfig {
    // Every old level's blocks, the old bottleneck (`blocks_at` of the coarsest) included.
    let level_blocks = (0..config.channels.len()).map(|l| config.blocks_at(l)).collect();
    let mut grown = config.clone();
    grown.channels.push(channels);
    grown.level_blocks = Some(level_blocks);
    grown.bottleneck_blocks = blocks;
    grown
}

/// `net` (built from `config`) with a coarser level of `channels` channels and `blocks`
/// bottleneck blocks added, computing the same function; returns it with its config. The new
/// encoder and bottleneck blocks are random (seeded by the device).
pub fn add_level(
    net: DenoiserNet,
    config: &DenoiserConfig,
    channels: usize,
    blocks: usize,
    device: &Device,
) -> (DenoiserNet, DenoiserConfig) {
    let grown = grown_config(config, channels, blocks);
    let fresh = grown.init(device);
    let old_coarse = *config.channels.last().expect("a config has at least one level");
    let mut encoders = net.encoders;
    encoders.push(fresh.encoders.into_iter().last().expect("the new level's encoder"));
    let mut level_blocks = net.level_blocks;
    level_blocks.resize_with(config.channels.len() - 1, Vec::new);
    level_blocks.push(net.bottleneck);
    let mut decoders = net.decoders;
    decoders.push(identity_decoder(channels, old_coarse, device));
    let net = DenoiserNet {
        stem: net.stem,
        encoders,
        level_blocks,
        bottleneck: fresh.bottleneck,
        decoders,
        output: net.output,
        downsample: net.downsample,
    };
    (net, grown)
}

/// A decoder from `coarse` upsampled channels and a `skip` of `c` channels to `c` channels that
/// returns the skip unchanged (for non-negative skips, as ReLU outputs are).
fn identity_decoder(coarse: usize, c: usize, device: &Device) -> Decoder {
    // fuse: [c, coarse + c, 1, 1], 1 from skip channel o (input coarse + o) to output o.
    let mut fuse = vec![0.0f32; c * (coarse + c)];
    for o in 0..c {
        fuse[o * (coarse + c) + coarse + o] = 1.0;
    }
    // refine: [c, c, 3, 3], 1 at the centre tap from channel o to channel o.
    let mut refine = vec![0.0f32; c * c * 9];
    for o in 0..c {
        refine[(o * c + o) * 9 + 4] = 1.0;
    }
    let mut d = Decoder { fuse: conv(coarse + c, c, 1, 1, device), refine: conv(c, c, 3, 1, device) };
    d.fuse.weight = Param::from_tensor(Tensor::from_data(TensorData::new(fuse, [c, coarse + c, 1, 1]), device));
    d.refine.weight = Param::from_tensor(Tensor::from_data(TensorData::new(refine, [c, c, 3, 3]), device));
    let zeros = || Some(Param::from_tensor(Tensor::from_data(TensorData::new(vec![0.0f32; c], [c]), device)));
    (d.fuse.bias, d.refine.bias) = (zeros(), zeros());
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::INPUT_CHANNELS;

    fn input(n: usize, h: usize, w: usize, device: &Device) -> Tensor<4> {
        let len = n * INPUT_CHANNELS * h * w;
        let v: Vec<f32> = (0..len).map(|i| ((i * 7919 + 13) % 1000) as f32 / 250.0 - 1.0).collect();
        Tensor::from_data(TensorData::new(v, [n, INPUT_CHANNELS, h, w]), device)
    }

    /// A small two-level network seeded by `seed`, its config, its device, an input and what
    /// the network computes on it.
    fn small_net(seed: u64, n: usize) -> (Device, DenoiserConfig, DenoiserNet, Tensor<4>, Vec<f32>) {
        let device = Device::flex();
        device.seed(seed);
        let config = DenoiserConfig::new(vec![8, 12]).with_bottleneck_blocks(1);
        let net = config.init(&device);
        let x = input(n, 16, 24, &device);
        let out = run(&net, &x);
        (device, config, net, x, out)
    }

    fn run(net: &DenoiserNet, x: &Tensor<4>) -> Vec<f32> {
        net.forward(x.clone()).into_data().try_to_vec().unwrap()
    }

    fn max_diff(a: &[f32], b: &[f32]) -> f32 {
        a.iter().zip(b).map(|(p, q)| (p - q).abs()).fold(0.0, f32::max)
    }

    /// Growing keeps the function (twice: the second growth moves a grown bottleneck too) while
    /// adding levels, blocks, receptive field and cost.
    #[test]
    fn a_grown_network_computes_the_same_function() {
        let (device, config, net, x, before) = small_net(5, 2);
        let (net, grown) = add_level(net, &config, 16, 2, &device);
        let (net, grown2) = add_level(net, &grown, 20, 1, &device);
        assert_eq!(grown2.channels, vec![8, 12, 16, 20]);
        assert_eq!(grown2.level_blocks, Some(vec![0, 1, 2]));
        assert_eq!(grown2.bottleneck_blocks, 1);
        assert!(grown2.receptive_radius() > grown.receptive_radius());
        assert!(grown.receptive_radius() > config.receptive_radius());
        assert!(grown2.macs_per_pixel() > config.macs_per_pixel());
        let after = run(&net, &x);
        let worst = max_diff(&before, &after);
        assert!(worst < 1e-5, "grown output differs by {worst}");
        // The grown net is the one its config describes: its record loads into a fresh build.
        use burn::module::Module;
        let reloaded = grown2.init(&device).load_record(net.clone().into_record());
        assert_eq!(after, run(&reloaded, &x));
    }

    /// The new level reaches the output once the fuse weighs it: the equality above comes from
    /// the identity decoder, not from a level that is cut off.
    #[test]
    fn the_identity_decoder_is_what_keeps_the_function() {
        let (device, config, net, x, before) = small_net(6, 1);
        let (mut net, _) = add_level(net, &config, 16, 1, &device);
        // Give the fuse a weight on the upsampled half: the output must now change.
        let d = net.decoders.last_mut().unwrap();
        d.fuse.weight = d.fuse.weight.clone().map(|w| w + 0.05);
        let worst = max_diff(&before, &run(&net, &x));
        assert!(worst > 1e-3, "the new level does not reach the output ({worst})");
    }
}
