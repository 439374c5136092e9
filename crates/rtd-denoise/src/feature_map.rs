//! Planar (C×H×W) feature maps and the pool that recycles their buffers between layers and
//! tiles: the data both inference kernels ([`crate::fast`] and [`crate::direct`]) work on.

/// A C×H×W feature map: one plane per channel.
#[derive(Clone, Debug)]
pub struct Map {
    /// Width in pixels.
    pub w: usize,
    /// Height in pixels.
    pub h: usize,
    /// Number of channels (planes).
    pub c: usize,
    /// Values, index (channel·h + y)·w + x.
    pub data: Vec<f32>,
}

/// Feature buffers recycled between layers and tiles, so a forward pass maps fresh memory
/// (and takes its page faults) only for its first few layers.
#[derive(Default)]
pub struct Scratch {
    free: Vec<Vec<f32>>,
}

impl Scratch {
    /// A w×h×c map whose contents are unspecified: every caller overwrites all of it.
    pub fn map(&mut self, w: usize, h: usize, c: usize) -> Map {
        let len = w * h * c;
        // The smallest free buffer that fits, else the largest (it will grow).
        let pick = (0..self.free.len())
            .filter(|&i| self.free[i].capacity() >= len)
            .min_by_key(|&i| self.free[i].capacity())
            .or_else(|| (0..self.free.len()).max_by_key(|&i| self.free[i].capacity()));
        let mut data = pick.map(|i| self.free.swap_remove(i)).unwrap_or_default();
        data.resize(len, 0.0);
        Map { w, h, c, data }
    }

    /// Returns a map's buffer to the pool.
    pub fn recycle(&mut self, m: Map) {
        self.free.push(m.data);
    }
}

/// Which output rows a convolution computes and where they go: rows `of_x` of its input's grid
/// (each read from the input rows around it), stored from row `at` of the destination.
#[derive(Clone, Debug)]
pub struct Rows {
    /// Output rows, in the input's row numbers.
    pub of_x: std::ops::Range<usize>,
    /// The destination row of the first.
    pub at: usize,
}
