//! Function-preserving widening (Net2Net-style, Chen et al. 2016): a trained network embedded in
//! a wider one of the same depth, so that the wider network starts computing exactly what the
//! trained one did and training only has to teach its new channels something useful.
//!
//! Every convolution's old weights keep their place (within each concatenated segment of its
//! input, the old channels come first). The weights from a new input channel to an old output
//! channel are zero, so the new channels never reach the old ones; a new output channel keeps
//! the wider network's own random weights, so it computes something from the start and the
//! next layer's zero weights on it receive gradients.

use burn::module::{Module, Param};
use burn::nn::conv::Conv2d;
use burn::tensor::{Tensor, TensorData};

use crate::model::{DenoiserConfig, DenoiserNet, InceptionBlock, NumberedParams};

/// One side (output or input channels) of a convolution: the widths of the segments it is
/// concatenated from, before and after widening.
struct Side {
    old: Vec<usize>,
    new: Vec<usize>,
}

impl Side {
    fn single(old: usize, new: usize) -> Self {
        Side { old: vec![old], new: vec![new] }
    }

    /// For each new channel, the old channel it carries, if any (segment prefixes map in order).
    fn sources(&self) -> Vec<Option<usize>> {
        let mut map = Vec::with_capacity(self.new.iter().sum());
        let mut old_start = 0;
        for (&o, &n) in self.old.iter().zip(&self.new) {
            map.extend((0..n).map(|j| (j < o).then_some(old_start + j)));
            old_start += o;
        }
        map
    }
}

/// `fresh` (the wider network's convolution, random weights) with `old`'s weights embedded:
/// rows of old output channels copy the old weights and are zero on new input channels; rows of
/// new output channels stay as drawn.
fn embed(old: &Conv2d, fresh: Conv2d, out: Side, inp: Side) -> Conv2d {
    let old_w = floats(old.weight.val());
    let [_, old_cin, kh, kw] = old.weight.val().dims();
    let fresh_w = fresh.weight.val();
    let (fresh_b, fresh_conv) = (fresh.bias.clone(), fresh);
    let [cout, cin, _, _] = fresh_w.dims();
    let device = fresh_w.device();
    let mut w = floats(fresh_w);
    let (outs, ins) = (out.sources(), inp.sources());
    let taps = kh * kw;
    for (o_new, o_old) in outs.iter().enumerate() {
        let Some(o_old) = *o_old else { continue };
        for (i_new, i_old) in ins.iter().enumerate() {
            let dst = (o_new * cin + i_new) * taps;
            match i_old {
                Some(i_old) => {
                    let src = (o_old * old_cin + i_old) * taps;
                    w[dst..dst + taps].copy_from_slice(&old_w[src..src + taps]);
                }
                None => w[dst..dst + taps].fill(0.0),
            }
        }
    }
    let weight = Tensor::<4>::from_data(TensorData::new(w, [cout, cin, kh, kw]), &device);
    let bias = match (&old.bias, fresh_b) {
        (Some(old_b), Some(fresh_b)) => {
            let old_b = floats(old_b.val());
            let mut b = floats(fresh_b.val());
            for (o_new, o_old) in outs.iter().enumerate() {
                if let Some(o_old) = o_old {
                    b[o_new] = old_b[*o_old];
                }
            }
            Some(Param::from_tensor(Tensor::<1>::from_data(TensorData::new(b, [cout]), &device)))
        }
        (_, fresh_b) => fresh_b,
    };
    // `detach` makes each embedded weight a leaf, which autodiff needs to track it.
    let mut conv = fresh_conv;
    conv.weight = Param::from_tensor(weight.detach());
    conv.bias = bias;
    conv
}

/// A tensor's values as `f32`, in row-major order.
fn floats<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data().iter::<f32>().collect()
}

/// An inception block's convolutions embedded, from a block of `old` (cin, cout) widths into one
/// of `new` widths.
fn embed_block(old: &InceptionBlock, fresh: InceptionBlock, o: (usize, usize), n: (usize, usize)) -> InceptionBlock {
    let (ob, nb) = (InceptionBlock::branch(o.1), InceptionBlock::branch(n.1));
    let (oh, nh) = (InceptionBlock::half_branch(o.1), InceptionBlock::half_branch(n.1));
    let from_input = |out_old, out_new| (Side::single(out_old, out_new), Side::single(o.0, n.0));
    let branch = |c: &Conv2d, f: Conv2d| {
        let (out, inp) = from_input(ob, nb);
        embed(c, f, out, inp)
    };
    let half = |c: &Conv2d, f: Conv2d| {
        let (out, inp) = from_input(oh, nh);
        embed(c, f, out, inp)
    };
    // The mix reads the concatenation [one, three, dilated, prong, max, min].
    let cat = Side { old: vec![ob, ob, ob, ob, oh, oh], new: vec![nb, nb, nb, nb, nh, nh] };
    InceptionBlock {
        one: branch(&old.one, fresh.one),
        three: branch(&old.three, fresh.three),
        dilated: branch(&old.dilated, fresh.dilated),
        prong_h: branch(&old.prong_h, fresh.prong_h),
        prong_v: embed(&old.prong_v, fresh.prong_v, Side::single(ob, nb), Side::single(ob, nb)),
        max_proj: half(&old.max_proj, fresh.max_proj),
        min_proj: half(&old.min_proj, fresh.min_proj),
        mix: embed(&old.mix, fresh.mix, Side::single(o.1, n.1), cat),
        ..fresh
    }
}

impl DenoiserNet {
    /// This network (built for `from`) embedded in a network for `to`, which may have more
    /// channels at each level but the same levels, bottleneck blocks, prong and input planes:
    /// the result computes the same function (up to the rounding of sums over more, zero,
    /// terms) until training changes it. `to`'s new channels get the weights `seed` draws
    /// for it. Errors (one sentence) name what differs where `to` is not a widening of `from`.
    pub fn widen_to(&self, from: &DenoiserConfig, to: &DenoiserConfig, seed: u64) -> Result<DenoiserNet, String> {
        let same_shape = from.channels.len() == to.channels.len()
            && from.bottleneck_blocks == to.bottleneck_blocks
            && from.prong == to.prong
            && from.input_channels == to.input_channels;
        if !same_shape {
            return Err("only the channels of each level can widen; the levels, bottleneck blocks, prong and input planes must match".into());
        }
        if let Some((o, n)) = from.channels.iter().zip(&to.channels).find(|(o, n)| n < o) {
            return Err(format!("a level cannot narrow from {o} to {n} channels"));
        }
        let device = self.stem.weight.val().device();
        let fresh = to.init_seeded(&device, seed);
        let (oc, nc) = (&from.channels, &to.channels);
        let stem = embed(
            &self.stem,
            fresh.stem,
            Side::single(oc[0], nc[0]),
            Side::single(from.input_channels, to.input_channels),
        );
        let encoders = (self.encoders.iter().zip(fresh.encoders).enumerate())
            .map(|(l, (old, f))| {
                let below = l.saturating_sub(1);
                embed_block(old, f, (oc[below], oc[l]), (nc[below], nc[l]))
            })
            .collect();
        let (ol, nl) = (*oc.last().unwrap_or(&0), *nc.last().unwrap_or(&0));
        let bottleneck = (self.bottleneck.iter().zip(fresh.bottleneck))
            .map(|(old, f)| embed_block(old, f, (ol, ol), (nl, nl)))
            .collect();
        let decoders = (self.decoders.iter().zip(fresh.decoders).enumerate())
            .map(|(l, (old, f))| crate::model::Decoder {
                // The fuse reads the concatenation [upsampled level l + 1, skip of level l].
                fuse: embed(
                    &old.fuse,
                    f.fuse,
                    Side::single(oc[l], nc[l]),
                    Side { old: vec![oc[l + 1], oc[l]], new: vec![nc[l + 1], nc[l]] },
                ),
                refine: embed(&old.refine, f.refine, Side::single(oc[l], nc[l]), Side::single(oc[l], nc[l])),
            })
            .collect();
        let output = embed(&self.output, fresh.output, Side::single(3, 3), Side::single(oc[0], nc[0]));
        let net = DenoiserNet { stem, encoders, bottleneck, decoders, output, downsample: fresh.downsample };
        Ok(net.map(&mut NumberedParams(0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;

    fn input(c: usize, h: usize, w: usize) -> Tensor<4> {
        let values: Vec<f32> = (0..c * h * w).map(|i| ((i * 7919) % 211) as f32 / 105.0 - 1.0).collect();
        Tensor::<4>::from_data(TensorData::new(values, [1, c, h, w]), &Device::flex())
    }

    #[test]
    fn a_widened_network_computes_what_the_narrow_one_did() {
        let device = Device::flex();
        // Level 0 widens its blocks' branches too (4 → 6 wide, 2 → 3 for the pools), level 1
        // keeps its width but reads a wider level 0, level 2 widens its branches but not its pools.
        let narrow = DenoiserConfig::new(vec![16, 12, 16]);
        let wide = DenoiserConfig::new(vec![24, 12, 20]);
        let net = narrow.init_seeded(&device, 3);
        let x = input(narrow.input_channels, 16, 24);
        let before: Vec<f32> = net.forward(x.clone()).into_data().iter::<f32>().collect();
        let widened = net.widen_to(&narrow, &wide, 4).unwrap();
        assert_eq!(widened.stem.weight.val().dims()[0], 24);
        assert_eq!(widened.bottleneck[0].mix.weight.val().dims()[0], 20);
        let after: Vec<f32> = widened.forward(x.clone()).into_data().iter::<f32>().collect();
        let worst = before.iter().zip(&after).map(|(a, b)| (a - b).abs() / (1.0 + a.abs())).fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "widened output differs by {worst}");
        // The new channels are alive: a fresh network of the wide shape computes something else,
        // and the widened one's new stem channels are not all zero.
        let stem: Vec<f32> = widened.stem.weight.val().into_data().iter::<f32>().collect();
        let per_out = stem.len() / 24;
        assert!(stem[16 * per_out..].iter().any(|w| *w != 0.0));
        let other: Vec<f32> = wide.init_seeded(&device, 4).forward(x).into_data().iter::<f32>().collect();
        assert!(other.iter().zip(&after).any(|(a, b)| (a - b).abs() > 1e-3));
    }

    #[test]
    fn a_network_widened_for_training_keeps_every_parameter_trackable() {
        let device = Device::flex().autodiff();
        let narrow = DenoiserConfig::new(vec![8, 12]);
        let widened = narrow.init(&device).widen_to(&narrow, &DenoiserConfig::new(vec![12, 12]), 1).unwrap();
        let mix = &widened.encoders[0].mix;
        assert!(mix.weight.val().is_require_grad());
        assert!(mix.bias.as_ref().is_some_and(|b| b.val().is_require_grad()));
        assert!(widened.output.weight.val().is_require_grad());
    }

    #[test]
    fn only_channels_may_widen() {
        let device = Device::flex();
        let narrow = DenoiserConfig::new(vec![8, 12]);
        let net = narrow.init_seeded(&device, 3);
        let e = net.widen_to(&narrow, &DenoiserConfig::new(vec![8, 8]), 1).err().unwrap();
        assert!(e.contains("narrow from 12 to 8"), "{e}");
        let e = net.widen_to(&narrow, &DenoiserConfig::new(vec![8, 12, 16]), 1).err().unwrap();
        assert!(e.contains("levels"), "{e}");
        let e = net.widen_to(&narrow, &narrow.clone().with_bottleneck_blocks(3), 1).err().unwrap();
        assert!(e.contains("bottleneck"), "{e}");
    }
}
