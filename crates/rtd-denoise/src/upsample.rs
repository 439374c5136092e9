//! Training's nearest-neighbour 2× upsampling (the decoder's and the kernel blend's) as one
//! differentiable operation with its own backward.
//!
//! Through burn's tensor API the upsampling is a reshape, an `expand` and a reshape: flex copies
//! the expanded view element by element through a strided iterator, and the backward sums
//! over the expanded axes through general reductions. Here the forward copies each input row
//! twice, doubling each value along it, and the backward adds each output 2×2 block into its
//! input pixel. Measured in models/README.md ("Training's own speed").

use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::flex::FlexTensor;
use burn::backend::tensor::FloatTensor;
use burn::backend::{backend_extension, Autodiff, Backend, Dispatch, Flex};
use burn::tensor::{Tensor, TensorData};
use rayon::prelude::*;

use crate::tensor_ops::{dims4, flex_values};

/// The differentiable operation, routed by burn's dispatch to flex or to its autodiff wrapper.
#[backend_extension(Flex, Autodiff)]
pub trait UpsampleOps: Backend {
    /// Nearest-neighbour 2× upsampling: x [N, C, H, W] → [N, C, 2H, 2W].
    fn upsample2(x: FloatTensor<Self>) -> FloatTensor<Self>;
}

/// y[n][c][2y + i][2x + j] = x[n][c][y][x] for i, j in {0, 1}.
fn repeat(x: &[f32], [n, c, h, w]: [usize; 4]) -> FlexTensor {
    let mut y = vec![0.0f32; n * c * 4 * h * w];
    if !y.is_empty() {
        // One output row pair per input row.
        y.par_chunks_mut(4 * w).zip(x.par_chunks(w)).for_each(|(pair, row)| {
            let (top, bottom) = pair.split_at_mut(2 * w);
            for (out, &v) in top.chunks_exact_mut(2).zip(row) {
                out.fill(v);
            }
            bottom.copy_from_slice(top);
        });
    }
    FlexTensor::from_data(TensorData::new(y, [n, c, 2 * h, 2 * w]))
}

/// ∂x[n][c][y][x] = the sum of the output gradient over the 2×2 block x was copied to.
fn block_sums(g: &[f32], [n, c, h, w]: [usize; 4]) -> FlexTensor {
    let mut dx = vec![0.0f32; n * c * h * w];
    if !dx.is_empty() {
        dx.par_chunks_mut(w).zip(g.par_chunks(4 * w)).for_each(|(row, pair)| {
            let (top, bottom) = pair.split_at(2 * w);
            for (x, d) in row.iter_mut().enumerate() {
                *d = (top[2 * x] + top[2 * x + 1]) + (bottom[2 * x] + bottom[2 * x + 1]);
            }
        });
    }
    FlexTensor::from_data(TensorData::new(dx, [n, c, h, w]))
}

impl UpsampleOps for Flex {
    fn upsample2(x: FlexTensor) -> FlexTensor {
        repeat(&flex_values(&x), dims4(&x))
    }
}

/// The backward step: the output gradient's 2×2 block sums, for an input of the state's size.
#[derive(Debug)]
struct UpsampleBackward;

impl Backward<Flex, 1> for UpsampleBackward {
    type State = [usize; 4];

    fn backward(self, ops: Ops<Self::State, 1>, grads: &mut Gradients, _: &mut Checkpointer) {
        let [node_x] = ops.parents;
        let grad: FlexTensor = grads.consume::<Flex>(&ops.node);
        if let Some(node) = node_x {
            let [n, c, h, w] = ops.state;
            assert_eq!(dims4(&grad), [n, c, 2 * h, 2 * w], "upsample2: the gradient is not twice the input's size");
            grads.register::<Flex>(node.id, block_sums(&flex_values(&grad), ops.state));
        }
    }
}

impl<C: CheckpointStrategy> UpsampleOps for Autodiff<Flex, C> {
    fn upsample2(x: FloatTensor<Self>) -> FloatTensor<Self> {
        match UpsampleBackward.prepare::<C>([x.node()]).compute_bound().stateful() {
            OpsKind::Tracked(prep) => {
                let inner = x.into_primitive();
                prep.finish(dims4(&inner), Flex::upsample2(inner))
            }
            OpsKind::UnTracked(prep) => prep.finish(Flex::upsample2(x.into_primitive())),
        }
    }
}

/// Nearest-neighbour 2× upsampling: [N, C, H, W] → [N, C, 2H, 2W], as [`UpsampleOps::upsample2`].
pub(crate) fn upsample2(x: Tensor<4>) -> Tensor<4> {
    Tensor::from_dispatch(<Dispatch as UpsampleOps>::upsample2(x.into_dispatch()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;

    fn to_vec(t: Tensor<4>) -> Vec<f32> {
        t.into_data().try_to_vec().unwrap()
    }

    /// Burn's reshape–expand–reshape upsampling, the reference.
    fn by_expand(x: Tensor<4>) -> Tensor<4> {
        let [n, c, h, w] = x.dims();
        x.reshape([n, c, h, 1, w, 1]).expand([n, c, h, 2, w, 2]).reshape([n, c, 2 * h, 2 * w])
    }

    #[test]
    fn upsampling_repeats_each_pixel_in_a_2x2_block() {
        let x = Tensor::<4>::from_data(TensorData::new(vec![1.0f32, 2.0, 3.0, 4.0], [1, 1, 2, 2]), &Device::flex());
        let expected = [1., 1., 2., 2., 1., 1., 2., 2., 3., 3., 4., 4., 3., 3., 4., 4.];
        assert_eq!(to_vec(upsample2(x)), expected);
    }

    /// Values and the input gradient equal the expand form's, on odd sizes and several planes;
    /// an empty input gives an empty output.
    #[test]
    fn upsampling_equals_the_expand_form_forward_and_backward() {
        let device = Device::flex().autodiff();
        for dims in [[2, 3, 5, 7], [1, 1, 1, 1], [1, 2, 3, 1]] {
            let count: usize = dims.iter().product();
            let values: Vec<f32> = (0..count).map(|i| ((i * 37) % 23) as f32 * 0.1 - 1.0).collect();
            let x = Tensor::<4>::from_data(TensorData::new(values, dims), &device).require_grad();
            let run = |y: Tensor<4>| {
                let n: usize = y.dims().iter().product();
                let weights: Vec<f32> = (0..n).map(|i| ((i * 53) % 31) as f32 * 0.07 - 1.0).collect();
                let weights = Tensor::<4>::from_data(TensorData::new(weights, y.dims()), &device);
                let grads = (y.clone() * weights).sum().backward();
                (to_vec(y), to_vec(x.grad(&grads).expect("a gradient")))
            };
            let (a, b) = (run(upsample2(x.clone())), run(by_expand(x.clone())));
            assert_eq!(a.0, b.0, "{dims:?}");
            for (a, b) in a.1.iter().zip(&b.1) {
                assert!((a - b).abs() <= 1e-6, "{dims:?}: {a} vs {b}");
            }
        }
        let empty = Tensor::<4>::from_data(TensorData::new(Vec::<f32>::new(), [1, 2, 0, 3]), &Device::flex());
        assert_eq!(upsample2(empty).dims(), [1, 2, 0, 6]);
    }
}
