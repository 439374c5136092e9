use glam::Vec3;

/// Rec. 709 luminance of a linear RGB colour.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// A linear RGB float image, row-major, top row first.
#[derive(Debug, Clone, PartialEq)]
pub struct HdrImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` pixels, row-major from the top-left.
    pub pixels: Vec<Vec3>,
}

impl HdrImage {
    /// A black image of the given size.
    pub fn new(width: u32, height: u32) -> Self {
        HdrImage { width, height, pixels: vec![Vec3::ZERO; width as usize * height as usize] }
    }

    /// An image from pixels; `pixels.len()` must equal `width * height`.
    pub fn from_pixels(width: u32, height: u32, pixels: Vec<Vec3>) -> Self {
        assert_eq!(pixels.len(), width as usize * height as usize, "pixel count does not match size");
        HdrImage { width, height, pixels }
    }

    /// The pixel at column `x`, row `y`.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// Sets the pixel at column `x`, row `y`.
    #[inline]
    pub fn set(&mut self, x: u32, y: u32, v: Vec3) {
        let w = self.width as usize;
        self.pixels[y as usize * w + x as usize] = v;
    }

    /// One colour channel (0 = R, 1 = G, 2 = B) as a plane of floats.
    pub fn channel(&self, c: usize) -> Vec<f32> {
        self.pixels.iter().map(|p| p[c]).collect()
    }

    /// Builds an image from three planes of equal length `width * height`.
    pub fn from_planes(width: u32, height: u32, r: &[f32], g: &[f32], b: &[f32]) -> Self {
        let pixels = r.iter().zip(g).zip(b).map(|((&r, &g), &b)| Vec3::new(r, g, b)).collect();
        Self::from_pixels(width, height, pixels)
    }

    /// Mean of all pixels.
    pub fn mean(&self) -> Vec3 {
        let sum = self.pixels.iter().fold(glam::DVec3::ZERO, |a, p| a + p.as_dvec3());
        (sum / self.pixels.len().max(1) as f64).as_vec3()
    }

    /// True if every channel of every pixel is finite.
    pub fn is_finite(&self) -> bool {
        self.pixels.iter().all(|p| p.is_finite())
    }
}
