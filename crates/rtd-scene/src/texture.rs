use glam::{Vec2, Vec4};
use rayon::prelude::*;

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

/// A decoded texture read as linear float RGBA (sRGB colour textures are linearised), with a
/// box-filtered mip pyramid for footprint-filtered lookups ([`Texture::sample_footprint`]).
#[derive(Debug, Clone)]
pub struct Texture {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major texels, top row first (glTF's UV origin is the top-left).
    texels: Texels,
    /// Wrap mode along u.
    pub wrap_u: Wrap,
    /// Wrap mode along v.
    pub wrap_v: Wrap,
    /// Nearest-texel lookup instead of bilinear.
    pub nearest: bool,
    /// Mip levels 1, 2, …: each halves the one before (2×2 box), down to 1×1.
    mips: Vec<MipLevel>,
}

/// A texture's full-resolution texels as stored.
#[derive(Debug, Clone)]
enum Texels {
    /// Linear RGBA floats.
    Linear(Vec<Vec4>),
    /// 8-bit RGBA as an 8-bit image holds it, colour sRGB-encoded when `srgb`, decoded on each
    /// fetch ([`decode_rgba8`]): a quarter of the floats' memory, and the same values.
    Rgba8 { texels: Vec<[u8; 4]>, srgb: bool },
}

impl Texels {
    /// Texel `i`, as linear RGBA.
    #[inline]
    fn get(&self, i: usize) -> Vec4 {
        match self {
            Texels::Linear(t) => t[i],
            Texels::Rgba8 { texels, srgb } => decode_rgba8(texels[i], *srgb),
        }
    }

    /// Number of texels.
    fn len(&self) -> usize {
        match self {
            Texels::Linear(t) => t.len(),
            Texels::Rgba8 { texels, .. } => texels.len(),
        }
    }
}

/// An 8-bit RGBA texel as linear RGBA: colour through [`rtd_image::srgb8_to_linear`] when `srgb`
/// (else v / 255), alpha v / 255 (the values an 8-bit image's channels decode to at load).
#[inline(always)]
fn decode_rgba8(t: [u8; 4], srgb: bool) -> Vec4 {
    let c = |v: u8| if srgb { rtd_image::srgb8_to_linear(v) } else { v as f32 / 255.0 };
    Vec4::new(c(t[0]), c(t[1]), c(t[2]), t[3] as f32 / 255.0)
}

/// One reduced level of a texture's mip pyramid.
#[derive(Debug, Clone)]
struct MipLevel {
    width: u32,
    height: u32,
    texels: Vec<Vec4>,
}

/// How a footprint is filtered in one texture ([`Texture::footprint_filter`]): a plain lookup, or
/// `probes` bilinear lookups in mip `level`, spread along `major`. It depends only on the
/// footprint's UV steps, so lookups that share a footprint (samples within one pixel) compute it
/// once and move only its centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootprintFilter {
    level: usize,
    /// 0: a plain lookup.
    probes: usize,
    major: Vec2,
}

impl FootprintFilter {
    /// A plain (bilinear or nearest) lookup, as for a footprint no wider than a texel.
    pub const POINT: FootprintFilter = FootprintFilter { level: 0, probes: 0, major: Vec2::ZERO };
}

/// Most probes along the long axis of an anisotropic footprint.
const MAX_ANISOTROPY: usize = 2;

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
    // i mod m for m > 0; a mask when m is a power of two (two's complement makes that the
    // Euclidean remainder for negative i too), which spares a 64-bit division on tiled textures.
    let modulo = |m: i64| if m & (m - 1) == 0 { i & (m - 1) } else { i.rem_euclid(m) };
    (match wrap {
        Wrap::Repeat => modulo(n),
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Mirror => {
            let m = modulo(2 * n);
            if m < n {
                m
            } else {
                2 * n - 1 - m
            }
        }
    }) as usize
}

/// The wrapped index of `i + 1`, given `a`, the wrapped index of `i`: for `Repeat` one step
/// along the already-wrapped index (no second division), otherwise [`wrap_index`].
#[inline]
fn next_index(i: i64, a: usize, n: u32, wrap: Wrap) -> usize {
    match wrap {
        Wrap::Repeat if a + 1 == n as usize => 0,
        Wrap::Repeat => a + 1,
        _ => wrap_index(i.saturating_add(1), n, wrap),
    }
}

/// 2×2 box reduction of a `w`×`h` level whose texel `i` is `texel(i)` (an odd last row or column
/// is averaged with itself).
fn reduce(w: u32, h: u32, texel: impl Fn(usize) -> Vec4 + Sync) -> MipLevel {
    let (nw, nh) = (w.div_ceil(2).max(1), h.div_ceil(2).max(1));
    let at = |x: u32, y: u32| texel((y.min(h - 1) * w + x.min(w - 1)) as usize);
    // Rows in parallel, collected in order.
    let texels = (0..nh)
        .into_par_iter()
        .flat_map_iter(|y| (0..nw).map(move |x| (x, y)))
        .map(|(x, y)| {
            (at(2 * x, 2 * y) + at(2 * x + 1, 2 * y) + at(2 * x, 2 * y + 1) + at(2 * x + 1, 2 * y + 1)) * 0.25
        })
        .collect();
    MipLevel { width: nw, height: nh, texels }
}

impl Texture {
    /// Bytes held by the texels and their mip levels.
    pub fn heap_bytes(&self) -> usize {
        let level0 = match &self.texels {
            Texels::Linear(t) => std::mem::size_of_val(t.as_slice()),
            Texels::Rgba8 { texels, .. } => std::mem::size_of_val(texels.as_slice()),
        };
        level0 + self.mips.iter().map(|m| std::mem::size_of_val(m.texels.as_slice())).sum::<usize>()
    }

    /// A texture from row-major linear texels (top row first), with its mip pyramid built.
    /// `texels.len()` must be `width × height`.
    pub fn new(width: u32, height: u32, texels: Vec<Vec4>, wrap_u: Wrap, wrap_v: Wrap, nearest: bool) -> Self {
        Self::with_texels(width, height, Texels::Linear(texels), wrap_u, wrap_v, nearest)
    }

    /// A texture from row-major 8-bit RGBA texels (top row first), kept as they are and decoded on
    /// each lookup: colour channels as sRGB when `srgb` (else v / 255), alpha v / 255. It samples
    /// exactly as [`Texture::new`] of the decoded texels does, in a quarter of the memory.
    /// `texels.len()` must be `width × height`.
    pub fn from_rgba8(
        width: u32,
        height: u32,
        texels: Vec<[u8; 4]>,
        srgb: bool,
        wrap_u: Wrap,
        wrap_v: Wrap,
        nearest: bool,
    ) -> Self {
        Self::with_texels(width, height, Texels::Rgba8 { texels, srgb }, wrap_u, wrap_v, nearest)
    }

    /// A texture of `texels`, with its mip pyramid built.
    fn with_texels(width: u32, height: u32, texels: Texels, wrap_u: Wrap, wrap_v: Wrap, nearest: bool) -> Self {
        debug_assert_eq!(texels.len(), width as usize * height as usize);
        let mut mips: Vec<MipLevel> = Vec::new();
        let (mut w, mut h) = (width, height);
        while w > 1 || h > 1 {
            let next = match mips.last() {
                None => match &texels {
                    Texels::Linear(t) => reduce(w, h, |i| t[i]),
                    Texels::Rgba8 { texels, srgb } => reduce(w, h, |i| decode_rgba8(texels[i], *srgb)),
                },
                Some(m) => reduce(w, h, |i| m.texels[i]),
            };
            (w, h) = (next.width, next.height);
            mips.push(next);
        }
        Texture { width, height, texels, wrap_u, wrap_v, nearest, mips }
    }

    /// A 1×1 texture of one value.
    pub fn constant(v: Vec4) -> Self {
        Texture::new(1, 1, vec![v], Wrap::Repeat, Wrap::Repeat, true)
    }

    /// Samples at texture coordinate `uv` with bilinear (or nearest) filtering.
    /// Non-finite coordinates sample texel (0,0).
    #[inline]
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        let (w, h, nearest) = (self.width, self.height, self.nearest);
        // One lookup routine per storage, so the fetch inside it does not branch.
        match &self.texels {
            Texels::Linear(t) => self.sample_level(w, h, |i| t[i], uv, nearest),
            Texels::Rgba8 { texels, srgb: true } => {
                self.sample_level(w, h, |i| decode_rgba8(texels[i], true), uv, nearest)
            }
            Texels::Rgba8 { texels, srgb: false } => {
                self.sample_level(w, h, |i| decode_rgba8(texels[i], false), uv, nearest)
            }
        }
    }

    /// Bilinear (or nearest) lookup in one level of `w`×`h` texels, texel `i` being `fetch(i)`.
    #[inline(always)]
    fn sample_level(&self, w: u32, h: u32, fetch: impl Fn(usize) -> Vec4, uv: Vec2, nearest: bool) -> Vec4 {
        let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
        let texel = |xi: usize, yi: usize| fetch(yi * w as usize + xi);
        // Texel-centre convention: texel i covers [i, i+1) / n.
        let x = (uv.x as f64) * w as f64 - 0.5;
        let y = (uv.y as f64) * h as f64 - 0.5;
        let (wu, wv) = (|i| wrap_index(i, w, self.wrap_u), |i| wrap_index(i, h, self.wrap_v));
        if nearest {
            return texel(wu(floor(x + 0.5)), wv(floor(y + 0.5)));
        }
        let (x0, y0) = (floor(x), floor(y));
        // Fractional parts (0 beyond ±2⁶³, where floor saturated and every double is an integer).
        let frac = |v: f64, i: i64| Some((v - i as f64) as f32).filter(|f| (0.0..1.0).contains(f)).unwrap_or(0.0);
        let (fx, fy) = (frac(x, x0), frac(y, y0));
        let (xa, ya) = (wu(x0), wv(y0));
        let (xb, yb) = (next_index(x0, xa, w, self.wrap_u), next_index(y0, ya, h, self.wrap_v));
        let a = texel(xa, ya).lerp(texel(xb, ya), fx);
        let b = texel(xa, yb).lerp(texel(xb, yb), fx);
        a.lerp(b, fy)
    }

    /// Bilinear lookup in mip level `level` (0 = full resolution, as [`Texture::sample`]).
    #[inline]
    fn sample_mip(&self, level: usize, uv: Vec2) -> Vec4 {
        match level.checked_sub(1).and_then(|l| self.mips.get(l)) {
            Some(m) => self.sample_level(m.width, m.height, |i| m.texels[i], uv, false),
            None if level == 0 => self.sample(uv),
            None => self.mips.last().map_or(self.texels.get(0), |m| m.texels[0]),
        }
    }

    /// The texture averaged over a footprint: the parallelogram centred on `uv` spanned by `du`
    /// and `dv` (the UV steps across one footprint along two screen axes). Anisotropic filtering:
    /// up to [`MAX_ANISOTROPY`] bilinear probes spaced along the long axis, in the mip level
    /// nearest the short axis's width (or the long axis's over the probe count). A footprint no
    /// wider than a texel is a plain [`Texture::sample`].
    #[inline]
    pub fn sample_footprint(&self, uv: Vec2, du: Vec2, dv: Vec2) -> Vec4 {
        self.sample_filtered(&self.footprint_filter(du, dv), uv)
    }

    /// How [`Texture::sample_footprint`] filters the footprint spanned by `du` and `dv`.
    #[inline]
    pub fn footprint_filter(&self, du: Vec2, dv: Vec2) -> FootprintFilter {
        let size = Vec2::new(self.width as f32, self.height as f32);
        // Footprint axes in level-0 texels (squared lengths: one square root below, not two).
        let (a, b) = (du * size, dv * size);
        let (la, lb) = (a.length_squared(), b.length_squared());
        if !(la.max(lb) > 1.0) || !(la + lb).is_finite() {
            return FootprintFilter::POINT;
        }
        let (major, lmaj, lmin) = if la >= lb { (du, la, lb) } else { (dv, lb, la) };
        // Probes along the major axis; each covers √lmaj / probes texels.
        let probes = ((lmaj / lmin.max(1e-12)).sqrt().ceil() as usize).clamp(1, MAX_ANISOTROPY);
        let width2 = lmin.max(lmaj / (probes * probes) as f32);
        // The mip level nearest log2(width) = ½ log2(width²).
        let level = (0.5 * width2.max(1.0).log2()).round() as usize;
        FootprintFilter { level, probes, major }
    }

    /// The texture at `uv` through a filter from [`Texture::footprint_filter`]: the footprint's
    /// average, centred on `uv`.
    #[inline]
    pub fn sample_filtered(&self, filter: &FootprintFilter, uv: Vec2) -> Vec4 {
        let FootprintFilter { level, probes, major } = *filter;
        if probes == 0 {
            return self.sample(uv);
        }
        let mut sum = Vec4::ZERO;
        for k in 0..probes {
            sum += self.sample_mip(level, uv + major * ((k as f32 + 0.5) / probes as f32 - 0.5));
        }
        sum / probes as f32
    }

    /// Mean of all texels, used to estimate the power of textured emitters.
    pub fn mean(&self) -> Vec4 {
        let n = self.texels.len();
        let sum = (0..n).fold(glam::DVec4::ZERO, |a, i| a + self.texels.get(i).as_dvec4());
        (sum / n.max(1) as f64).as_vec4()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker() -> Texture {
        Texture::new(2, 2, vec![Vec4::ONE, Vec4::ZERO, Vec4::ZERO, Vec4::ONE], Wrap::Repeat, Wrap::Repeat, false)
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

    /// A `n`×`n` texture whose texel (x, y) is `f(x, y)` (grey).
    fn pattern(n: u32, f: impl Fn(u32, u32) -> f32) -> Texture {
        let texels = (0..n * n).map(|i| Vec4::splat(f(i % n, i / n))).collect();
        Texture::new(n, n, texels, Wrap::Repeat, Wrap::Repeat, false)
    }

    #[test]
    fn mip_levels_halve_down_to_one_texel_and_keep_the_mean() {
        let t = pattern(6, |x, y| ((x * 7 + y * 3) % 5) as f32);
        let sizes: Vec<(u32, u32)> = t.mips.iter().map(|m| (m.width, m.height)).collect();
        assert_eq!(sizes, [(3, 3), (2, 2), (1, 1)]);
        let even = pattern(8, |x, y| ((x * 7 + y * 3) % 5) as f32);
        assert!((even.mips.last().unwrap().texels[0].x - even.mean().x).abs() < 1e-5);
    }

    #[test]
    fn footprint_lookup_averages_detail_finer_than_the_footprint() {
        // A one-texel checker: point lookups give 0 or 1, an 8-texel footprint its mean.
        let t = pattern(64, |x, y| ((x + y) % 2) as f32);
        let step = 8.0 / 64.0;
        for uv in [Vec2::new(0.3, 0.7), Vec2::new(0.51, 0.12), Vec2::new(-2.2, 5.9)] {
            let v = t.sample_footprint(uv, Vec2::new(step, 0.0), Vec2::new(0.0, step)).x;
            assert!((v - 0.5).abs() < 0.02, "{uv}: {v}");
        }
        // A footprint under a texel is the plain bilinear lookup.
        let uv = Vec2::new(0.313, 0.77);
        assert_eq!(t.sample_footprint(uv, Vec2::new(0.5 / 64.0, 0.0), Vec2::new(0.0, 0.2 / 64.0)), t.sample(uv));
    }

    #[test]
    fn anisotropic_footprint_keeps_detail_across_its_short_axis() {
        // Vertical stripes 4 texels wide, and a footprint 1/2 texel across them and 6 along them
        // (a floor seen at a grazing angle): the stripe stays white. An isotropic filter sized by
        // the long axis would average a white and a black stripe.
        let t = pattern(64, |x, _| ((x / 4) % 2 == 0) as u32 as f32);
        let uv = Vec2::new(2.0 / 64.0, 0.4);
        let along = t.sample_footprint(uv, Vec2::new(0.5 / 64.0, 0.0), Vec2::new(0.0, 6.0 / 64.0)).x;
        assert!(along > 0.9, "{along}");
        // Turned 90°: the long axis crosses the stripes and takes in the black ones.
        let across = t.sample_footprint(uv, Vec2::new(6.0 / 64.0, 0.0), Vec2::new(0.0, 0.5 / 64.0)).x;
        assert!(across < 0.8, "{across}");
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(wrap_index(-1, 4, Wrap::Repeat), 3);
        assert_eq!(wrap_index(-1, 4, Wrap::Clamp), 0);
        assert_eq!(wrap_index(-1, 4, Wrap::Mirror), 0);
        assert_eq!(wrap_index(5, 4, Wrap::Mirror), 2);
        assert_eq!(wrap_index(9, 4, Wrap::Clamp), 3);
        // The neighbour index stepped from a wrapped index is the neighbour wrapped directly.
        for wrap in [Wrap::Repeat, Wrap::Clamp, Wrap::Mirror] {
            for n in [1, 2, 5] {
                for i in -12..12 {
                    let a = wrap_index(i, n, wrap);
                    assert_eq!(next_index(i, a, n, wrap), wrap_index(i + 1, n, wrap), "{wrap:?} n={n} i={i}");
                }
            }
        }
    }

    /// Power-of-two sizes wrap with a mask, the others with a division: both must give the
    /// modes' definitions, for negative and far-out indices too.
    #[test]
    fn wrap_index_matches_the_modes_definitions_at_every_size() {
        for n in 1..=17u32 {
            let m = n as i64;
            for i in (-70..70).chain([i64::MIN, i64::MIN + 1, -(1 << 40) - 3, (1 << 40) + 5, i64::MAX - 1, i64::MAX]) {
                let repeat = i.rem_euclid(m);
                let mirror = {
                    let r = i.rem_euclid(2 * m);
                    if r < m {
                        r
                    } else {
                        2 * m - 1 - r
                    }
                };
                assert_eq!(wrap_index(i, n, Wrap::Repeat), repeat as usize, "repeat n={n} i={i}");
                assert_eq!(wrap_index(i, n, Wrap::Mirror), mirror as usize, "mirror n={n} i={i}");
                assert_eq!(wrap_index(i, n, Wrap::Clamp), i.clamp(0, m - 1) as usize, "clamp n={n} i={i}");
            }
        }
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
