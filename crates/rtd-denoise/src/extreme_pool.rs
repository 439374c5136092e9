//! Training's pooling (the inception blocks' 3×3 stride-1 max and min branches, the 2×2
//! stride-2 max-pool between encoder levels) as one differentiable operation with its own
//! backward.
//!
//! Burn's flex backend computes a max-pool's indices with an allocation in its inner loop, and
//! the min branch as a max-pool of −x costs two negations and their backward as well. Here the
//! forward records, per output, the plane index of the input it took, and the backward adds each
//! output's gradient there: the gradient of an extreme is its argument's.
//!
//! Ties (equal inputs in one window) send the gradient to one of them, the first in the order
//! centre, up, down, then centre, left, right (for the 2×2 window: row-major); burn's module
//! breaks ties in its own order, so the tests compare on inputs without ties. The input of
//! every pool in the network is non-negative (a ReLU output, or one plus a residual ReLU
//! output), and its ties are mostly zeros, whose gradient the ReLUs' own backward discards.

use std::sync::Arc;

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

/// Which pooling window: 3×3 at stride 1 over the valid neighbours, or 2×2 at stride 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Window {
    /// 3×3, stride 1, output the input's size; neighbours outside the plane are left out.
    Three,
    /// 2×2, stride 2, output half the input's (even) size.
    Two,
}

/// The differentiable operation, routed by burn's dispatch to flex or to its autodiff wrapper.
#[backend_extension(Flex, Autodiff)]
pub trait ExtremePoolOps: Backend {
    /// The max (`max`) or min of each window of x [N, C, H, W], a 3×3 stride-1 one (`two` false)
    /// or a 2×2 stride-2 one (`two` true).
    fn extreme_pool(x: FloatTensor<Self>, two: bool, max: bool) -> FloatTensor<Self>;
}

/// Pooled values [N, C, h, w] and, per output, the index in its plane of the input it took.
struct Pooled {
    values: Vec<f32>,
    argument: Vec<u32>,
    dims: [usize; 4],
}

/// Pools every plane of x: the max or the min of each window, and its argument.
fn pool(x: &[f32], [n, c, h, w]: [usize; 4], window: Window, max: bool) -> Pooled {
    let (oh, ow) = match window {
        Window::Three => (h, w),
        Window::Two => (h / 2, w / 2),
    };
    let mut values = vec![0.0f32; n * c * oh * ow];
    let mut argument = vec![0u32; values.len()];
    if values.is_empty() {
        return Pooled { values, argument, dims: [n, c, oh, ow] };
    }
    values.par_chunks_mut(oh * ow).zip(argument.par_chunks_mut(oh * ow)).enumerate().for_each(|(p, (v, a))| {
        let plane = &x[p * h * w..][..h * w];
        match (window, max) {
            (Window::Three, true) => pool3_plane(plane, (w, h), v, a, |a, b| a > b),
            (Window::Three, false) => pool3_plane(plane, (w, h), v, a, |a, b| a < b),
            (Window::Two, true) => pool2_plane(plane, (w, h), v, a, |a, b| a > b),
            (Window::Two, false) => pool2_plane(plane, (w, h), v, a, |a, b| a < b),
        }
    });
    Pooled { values, argument, dims: [n, c, oh, ow] }
}

/// 3×3 extreme of one plane, separably: the vertical extreme of rows y−1..=y+1 per column
/// (with its row), then the horizontal extreme of three such columns. A missing neighbour
/// outside the plane is replaced by the centre, which never wins a tie.
#[inline(always)]
fn pool3_plane(
    plane: &[f32],
    (w, h): (usize, usize),
    out: &mut [f32],
    arg: &mut [u32],
    beats: impl Fn(f32, f32) -> bool + Copy,
) {
    let (mut line, mut row_of) = (vec![0.0f32; w], vec![0u32; w]);
    for y in 0..h {
        let (up, down) = (y.saturating_sub(1), (y + 1).min(h - 1));
        let (m, u, d) = (&plane[y * w..][..w], &plane[up * w..][..w], &plane[down * w..][..w]);
        for x in 0..w {
            let (mut v, mut r) = (m[x], y);
            if beats(u[x], v) {
                (v, r) = (u[x], up);
            }
            if beats(d[x], v) {
                (v, r) = (d[x], down);
            }
            line[x] = v;
            row_of[x] = (r * w) as u32;
        }
        let (o, a) = (&mut out[y * w..][..w], &mut arg[y * w..][..w]);
        for x in 0..w {
            let (mut v, mut i) = (line[x], row_of[x] + x as u32);
            if x > 0 && beats(line[x - 1], v) {
                (v, i) = (line[x - 1], row_of[x - 1] + x as u32 - 1);
            }
            if x + 1 < w && beats(line[x + 1], v) {
                (v, i) = (line[x + 1], row_of[x + 1] + x as u32 + 1);
            }
            o[x] = v;
            a[x] = i;
        }
    }
}

/// 2×2 stride-2 extreme of one plane, row-major first on ties.
#[inline(always)]
fn pool2_plane(
    plane: &[f32],
    (w, h): (usize, usize),
    out: &mut [f32],
    arg: &mut [u32],
    beats: impl Fn(f32, f32) -> bool + Copy,
) {
    let ow = w / 2;
    for y in 0..h / 2 {
        for x in 0..ow {
            let i0 = 2 * y * w + 2 * x;
            let (mut v, mut i) = (plane[i0], i0);
            for j in [i0 + 1, i0 + w, i0 + w + 1] {
                if beats(plane[j], v) {
                    (v, i) = (plane[j], j);
                }
            }
            out[y * ow + x] = v;
            arg[y * ow + x] = i as u32;
        }
    }
}

/// ∂x: each output's gradient added at the input it took, plane by plane.
fn scatter(grad: &[f32], argument: &[u32], input: [usize; 4], output: [usize; 4]) -> Vec<f32> {
    let (n_in, n_out) = (input[2] * input[3], output[2] * output[3]);
    let mut dx = vec![0.0f32; input.iter().product()];
    if dx.is_empty() || n_out == 0 {
        return dx;
    }
    dx.par_chunks_mut(n_in).enumerate().for_each(|(p, plane)| {
        let (g, a) = (&grad[p * n_out..][..n_out], &argument[p * n_out..][..n_out]);
        for (g, &a) in g.iter().zip(a) {
            plane[a as usize] += g;
        }
    });
    dx
}

/// The window the operation's flag names.
fn window(two: bool) -> Window {
    if two {
        Window::Two
    } else {
        Window::Three
    }
}

impl ExtremePoolOps for Flex {
    fn extreme_pool(x: FlexTensor, two: bool, max: bool) -> FlexTensor {
        let pooled = pool(&flex_values(&x), dims4(&x), window(two), max);
        FlexTensor::from_data(TensorData::new(pooled.values, pooled.dims))
    }
}

/// The backward step's state: each output's argument, and the input's and output's sizes.
#[derive(Clone, Debug)]
struct PoolState {
    argument: Arc<Vec<u32>>,
    input: [usize; 4],
    output: [usize; 4],
}

/// The backward step: the output gradient scattered to the arguments.
#[derive(Debug)]
struct ExtremePoolBackward;

impl Backward<Flex, 1> for ExtremePoolBackward {
    type State = PoolState;

    fn backward(self, ops: Ops<Self::State, 1>, grads: &mut Gradients, _: &mut Checkpointer) {
        let [node_x] = ops.parents;
        let grad: FlexTensor = grads.consume::<Flex>(&ops.node);
        if let Some(node) = node_x {
            let state = ops.state;
            let dx = scatter(&flex_values(&grad), &state.argument, state.input, state.output);
            grads.register::<Flex>(node.id, FlexTensor::from_data(TensorData::new(dx, state.input)));
        }
    }
}

impl<C: CheckpointStrategy> ExtremePoolOps for Autodiff<Flex, C> {
    fn extreme_pool(x: FloatTensor<Self>, two: bool, max: bool) -> FloatTensor<Self> {
        match ExtremePoolBackward.prepare::<C>([x.node()]).compute_bound().stateful() {
            OpsKind::Tracked(prep) => {
                let inner = x.into_primitive();
                let input = dims4(&inner);
                let pooled = pool(&flex_values(&inner), input, window(two), max);
                let state = PoolState { argument: Arc::new(pooled.argument), input, output: pooled.dims };
                prep.finish(state, FlexTensor::from_data(TensorData::new(pooled.values, pooled.dims)))
            }
            OpsKind::UnTracked(prep) => prep.finish(Flex::extreme_pool(x.into_primitive(), two, max)),
        }
    }
}

/// The max (`max`) or min of each `window` of x [N, C, H, W], as [`ExtremePoolOps::extreme_pool`]:
/// what burn's `MaxPool2d` computes with a 3×3 window, stride 1 and padding 1 (or a 2×2 window
/// at stride 2), and −maxpool(−x) for the min.
pub(crate) fn extreme_pool(x: Tensor<4>, window: Window, max: bool) -> Tensor<4> {
    let out = <Dispatch as ExtremePoolOps>::extreme_pool(x.into_dispatch(), window == Window::Two, max);
    Tensor::from_dispatch(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::pool::{MaxPool2d, MaxPool2dConfig};
    use burn::nn::PaddingConfig2d;
    use burn::tensor::Device;

    fn to_vec(t: Tensor<4>) -> Vec<f32> {
        t.into_data().try_to_vec().unwrap()
    }

    /// The network's pools as burn modules: 3×3 stride 1 padding 1, and 2×2 stride 2.
    fn modules() -> (MaxPool2d, MaxPool2d) {
        let three =
            MaxPool2dConfig::new([3, 3]).with_strides([1, 1]).with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1));
        (three.init(), MaxPool2dConfig::new([2, 2]).init())
    }

    /// Distinct values (a permutation of 0..n, scaled): no window has a tie.
    fn distinct(dims: [usize; 4], device: &Device) -> Tensor<4> {
        let n: usize = dims.iter().product();
        let v: Vec<f32> = (0..n).map(|i| ((i * 7919) % n) as f32 * 0.01 - 1.0).collect();
        Tensor::from_data(TensorData::new(v, dims), device)
    }

    /// Values and input gradients equal burn's max-pool modules' (and −maxpool(−x) for the min),
    /// for both windows, on odd and even sizes.
    #[test]
    fn extreme_pools_equal_burns_modules_forward_and_backward() {
        let device = Device::flex().autodiff();
        let (three, two) = modules();
        for (dims, window) in
            [([2, 3, 7, 5], Window::Three), ([1, 2, 1, 4], Window::Three), ([2, 3, 6, 8], Window::Two)]
        {
            for max in [true, false] {
                let x = distinct(dims, &device).require_grad();
                let reference = |x: Tensor<4>| {
                    let pool = |x| if window == Window::Two { two.forward(x) } else { three.forward(x) };
                    if max {
                        pool(x)
                    } else {
                        -pool(-x)
                    }
                };
                let run = |y: Tensor<4>| {
                    let weights = distinct(y.dims(), &device);
                    let grads = (y.clone() * weights).sum().backward();
                    (to_vec(y), to_vec(x.grad(&grads).expect("a gradient")))
                };
                let (a, b) = (run(extreme_pool(x.clone(), window, max)), run(reference(x.clone())));
                assert_eq!(a, b, "{dims:?} {window:?} max {max}");
            }
        }
    }

    /// Ties go where the module's documentation says: for the 3×3 window the centre, then up,
    /// down, then the centre column, left, right; for the 2×2 window row-major first.
    #[test]
    fn ties_go_in_the_documented_order() {
        let device = Device::flex().autodiff();
        // A 3×3 plane, max 5 at (0, 0), (0, 2) and (2, 1); the centre output's window holds all.
        let plane = [5.0f32, 1.0, 5.0, 0.0, 2.0, 0.0, 1.0, 5.0, 1.0];
        let x = Tensor::<4>::from_data(TensorData::new(plane.to_vec(), [1, 1, 3, 3]), &device).require_grad();
        let y = extreme_pool(x.clone(), Window::Three, true);
        // The centre output's gradient alone. Each column's vertical max comes first (the centre
        // column's is 5 at (2, 1)); a side column replaces it only when strictly larger.
        let mask =
            Tensor::<4>::from_data(TensorData::new(vec![0., 0., 0., 0., 1., 0., 0., 0., 0.], [1, 1, 3, 3]), &device);
        let grads = (y * mask).sum().backward();
        assert_eq!(to_vec(x.grad(&grads).unwrap()), [0., 0., 0., 0., 0., 0., 0., 1., 0.]);
        // The min over the same window: 0 at (1, 0) and (1, 2), in the side columns; left first.
        let y = extreme_pool(x.clone(), Window::Three, false);
        let mask =
            Tensor::<4>::from_data(TensorData::new(vec![0., 0., 0., 0., 1., 0., 0., 0., 0.], [1, 1, 3, 3]), &device);
        let grads = (y * mask).sum().backward();
        assert_eq!(to_vec(x.grad(&grads).unwrap()), [0., 0., 0., 1., 0., 0., 0., 0., 0.]);
        // 2×2: all equal, row-major first.
        let x = Tensor::<4>::from_data(TensorData::new(vec![3.0f32; 4], [1, 1, 2, 2]), &device).require_grad();
        let grads = extreme_pool(x.clone(), Window::Two, false).sum().backward();
        assert_eq!(to_vec(x.grad(&grads).unwrap()), [1., 0., 0., 0.]);
    }

    /// A one-pixel-wide plane, odd sizes for the 2×2 window (the last row and column left out,
    /// as burn's module does) and an empty output all work.
    #[test]
    fn edge_sizes_match_the_module() {
        let device = Device::flex().autodiff();
        let (three, two) = modules();
        let x = distinct([1, 2, 5, 1], &device);
        assert_eq!(to_vec(extreme_pool(x.clone(), Window::Three, true)), to_vec(three.forward(x)));
        let x = distinct([2, 1, 5, 7], &device);
        assert_eq!(to_vec(extreme_pool(x.clone(), Window::Two, true)), to_vec(two.forward(x)));
        let x = distinct([1, 1, 1, 4], &device).require_grad();
        let y = extreme_pool(x.clone(), Window::Two, true);
        assert_eq!(y.dims(), [1, 1, 0, 2]);
        let grads = (y.sum() + x.clone().sum()).backward();
        assert_eq!(to_vec(x.grad(&grads).unwrap()), [1.0; 4]);
    }

    /// With ties (a constant plane), each output's gradient still lands once, on an input that
    /// holds the extreme, so the gradient's sum is kept.
    #[test]
    fn ties_keep_the_gradients_sum() {
        let device = Device::flex().autodiff();
        let x = Tensor::<4>::from_data(TensorData::new(vec![2.0f32; 2 * 5 * 6], [1, 2, 5, 6]), &device).require_grad();
        let y = extreme_pool(x.clone(), Window::Three, true);
        assert!(to_vec(y.clone()).iter().all(|&v| v == 2.0));
        let grads = (y * 3.0).sum().backward();
        let dx = to_vec(x.grad(&grads).unwrap());
        assert_eq!(dx.iter().sum::<f32>(), 3.0 * 60.0);
    }

    /// Without autodiff (inference tensors) the operation runs the forward alone.
    #[test]
    fn extreme_pool_runs_on_plain_flex_tensors() {
        let device = Device::flex();
        let x = distinct([1, 2, 4, 6], &device);
        let (_, pool) = modules();
        assert_eq!(to_vec(extreme_pool(x.clone(), Window::Two, true)), to_vec(pool.forward(x)));
    }
}
