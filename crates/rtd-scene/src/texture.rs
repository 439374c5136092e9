use glam::{Vec2, Vec4};

/// How texture coordinates outside [0,1] are mapped back in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Wrap {
    /// Tile the texture.
    #[default]
    Repeat,
    /// Clamp to the edge texels.
    Clamp,
    /// Tile, mirroring every other copy.
    Mirror,
}

/// A decoded texture in linear float RGBA (sRGB colour textures are linearised at load).
#[derive(Debug, Clone)]
pub struct Texture {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major texels, top row first (glTF's UV origin is the top-left).
    pub texels: Vec<Vec4>,
    /// Wrap mode along u.
    pub wrap_u: Wrap,
    /// Wrap mode along v.
    pub wrap_v: Wrap,
    /// Nearest-texel lookup instead of bilinear.
    pub nearest: bool,
}

/// ⌊x⌋ as an integer (saturating), without a call into libm's `floor`.
#[inline]
fn floor(x: f64) -> i64 {
    let t = x as i64;
    // Truncation rounds negative non-integers up; step back one.
    t.saturating_sub(((t as f64) > x) as i64)
}

/// Maps an integer texel coordinate into [0, n) by the wrap mode.
#[inline]
fn wrap_index(i: i64, n: u32, wrap: Wrap) -> usize {
    let n = n as i64;
    // Inside the texture every mode is the identity (and this skips the division).
    if (0..n).contains(&i) {
        return i as usize;
    }
    (match wrap {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Mirror => {
            let m = i.rem_euclid(2 * n);
            if m < n {
                m
            } else {
                2 * n - 1 - m
            }
        }
    }) as usize
}

impl Texture {
    /// A 1×1 texture of one value.
    pub fn constant(v: Vec4) -> Self {
        Texture { width: 1, height: 1, texels: vec![v], wrap_u: Wrap::Repeat, wrap_v: Wrap::Repeat, nearest: true }
    }

    /// The texel at wrapped indices (`xi` < width, `yi` < height).
    #[inline]
    fn texel(&self, xi: usize, yi: usize) -> Vec4 {
        self.texels[yi * self.width as usize + xi]
    }

    /// Samples at texture coordinate `uv` with bilinear (or nearest) filtering.
    /// Non-finite coordinates sample texel (0,0).
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
        // Texel-centre convention: texel i covers [i, i+1) / n.
        let x = (uv.x as f64) * self.width as f64 - 0.5;
        let y = (uv.y as f64) * self.height as f64 - 0.5;
        let (wu, wv) = (|i| wrap_index(i, self.width, self.wrap_u), |i| wrap_index(i, self.height, self.wrap_v));
        if self.nearest {
            return self.texel(wu(floor(x + 0.5)), wv(floor(y + 0.5)));
        }
        let (x0, y0) = (floor(x), floor(y));
        // Fractional parts (0 beyond ±2⁶³, where floor saturated and every double is an integer).
        let frac = |v: f64, i: i64| Some((v - i as f64) as f32).filter(|f| (0.0..1.0).contains(f)).unwrap_or(0.0);
        let (fx, fy) = (frac(x, x0), frac(y, y0));
        let (xa, xb) = (wu(x0), wu(x0.saturating_add(1)));
        let (ya, yb) = (wv(y0), wv(y0.saturating_add(1)));
        let a = self.texel(xa, ya).lerp(self.texel(xb, ya), fx);
        let b = self.texel(xa, yb).lerp(self.texel(xb, yb), fx);
        a.lerp(b, fy)
    }

    /// Mean of all texels, used to estimate the power of textured emitters.
    pub fn mean(&self) -> Vec4 {
        let sum = self.texels.iter().fold(glam::DVec4::ZERO, |a, t| a + t.as_dvec4());
        (sum / self.texels.len().max(1) as f64).as_vec4()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker() -> Texture {
        Texture {
            width: 2,
            height: 2,
            texels: vec![Vec4::ONE, Vec4::ZERO, Vec4::ZERO, Vec4::ONE],
            wrap_u: Wrap::Repeat,
            wrap_v: Wrap::Repeat,
            nearest: false,
        }
    }

    #[test]
    fn bilinear_at_texel_centres_is_exact() {
        let t = checker();
        assert_eq!(t.sample(Vec2::new(0.25, 0.25)), Vec4::ONE);
        assert_eq!(t.sample(Vec2::new(0.75, 0.25)), Vec4::ZERO);
        // Halfway between texel centres, wrapping across the edge.
        assert_eq!(t.sample(Vec2::new(0.0, 0.25)), Vec4::splat(0.5));
        assert_eq!(t.sample(Vec2::new(1.25, -0.75)), Vec4::ONE);
        assert_eq!(t.sample(Vec2::new(f32::NAN, 0.0)), t.sample(Vec2::ZERO));
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(wrap_index(-1, 4, Wrap::Repeat), 3);
        assert_eq!(wrap_index(-1, 4, Wrap::Clamp), 0);
        assert_eq!(wrap_index(-1, 4, Wrap::Mirror), 0);
        assert_eq!(wrap_index(5, 4, Wrap::Mirror), 2);
        assert_eq!(wrap_index(9, 4, Wrap::Clamp), 3);
    }

    #[test]
    fn integer_floor_matches_f64_floor() {
        for x in [0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 2.999_999_999, -2.000_000_1, 1e15 + 0.5, -1e15 - 0.5, 4096.0 * 1e6] {
            assert_eq!(floor(x), x.floor() as i64, "{x}");
        }
        // Far outside the i64 range it saturates, and the neighbour index does not overflow.
        assert_eq!(floor(1e300), i64::MAX);
        assert_eq!(floor(-1e300), i64::MIN);
        let t = checker();
        assert!(t.sample(Vec2::new(3e38, -3e38)).is_finite());
    }
}
