//! Procedural textures for the thesis's hard cases: stripes, faint lines, similar-colour edges,
//! colour edges, fine checkers and noise. Written as sRGB PNGs referenced by the glTF.

use glam::Vec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Which pattern a texture carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pattern {
    /// Alternating bands of two colours.
    Stripes,
    /// Thin lines only slightly darker than the background.
    FaintLines,
    /// Regions whose colours differ by a few percent.
    SimilarColourEdges,
    /// Regions of strongly different colours.
    ColourEdges,
    /// A checkerboard of small cells.
    FineCheckers,
    /// Value noise at several octaves.
    Noise,
}

impl Pattern {
    /// All patterns, in a fixed order.
    pub const ALL: [Pattern; 6] = [
        Pattern::Stripes,
        Pattern::FaintLines,
        Pattern::SimilarColourEdges,
        Pattern::ColourEdges,
        Pattern::FineCheckers,
        Pattern::Noise,
    ];
}

/// A random saturated-or-grey linear colour with components in [lo, hi].
pub fn random_colour(rng: &mut ChaCha8Rng, lo: f32, hi: f32) -> Vec3 {
    let grey = rng.random::<f32>() < 0.3;
    let base = Vec3::new(rng.random(), rng.random(), rng.random());
    let c = if grey { Vec3::splat(base.x) } else { base };
    Vec3::splat(lo) + c * (hi - lo)
}

/// Smooth value noise on an integer lattice hashed from `seed`, in [0, 1].
fn value_noise(x: f32, y: f32, period: u32, seed: u64) -> f32 {
    let h = |i: i64, j: i64| {
        let (i, j) = (i.rem_euclid(period as i64) as u64, j.rem_euclid(period as i64) as u64);
        let mut z = seed ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ j.wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        z = (z ^ (z >> 31)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 29)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 32)) >> 40) as f32 / (1u64 << 24) as f32
    };
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    // Smoothstep-weighted bilinear blend of the four lattice values.
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let (i, j) = (x0 as i64, y0 as i64);
    let a = h(i, j) + (h(i + 1, j) - h(i, j)) * sx;
    let b = h(i, j + 1) + (h(i + 1, j + 1) - h(i, j + 1)) * sx;
    a + (b - a) * sy
}

/// Renders `pattern` into a `size`² sRGB8 image (tileable).
pub fn make_texture(pattern: Pattern, size: u32, rng: &mut ChaCha8Rng) -> image::RgbImage {
    let a = random_colour(rng, 0.05, 0.9);
    let b = match pattern {
        Pattern::SimilarColourEdges | Pattern::FaintLines => a * (0.88 + 0.06 * rng.random::<f32>()),
        _ => random_colour(rng, 0.05, 0.9),
    };
    let c = random_colour(rng, 0.05, 0.9);
    let freq = [2u32, 4, 8, 16][rng.random_range(0..4)];
    let seed: u64 = rng.random();
    let angle_steps = rng.random_range(0..4);
    let s = size as f32;
    image::RgbImage::from_fn(size, size, |px, py| {
        let (u, v) = ((px as f32 + 0.5) / s, (py as f32 + 0.5) / s);
        // Rotate the pattern by multiples of 45° along lattice-compatible directions (tileable).
        let t = match angle_steps {
            0 => u,
            1 => v,
            2 => u + v,
            _ => u - v,
        };
        let col = match pattern {
            Pattern::Stripes => {
                if (t * freq as f32 * 2.0).rem_euclid(2.0) < 1.0 {
                    a
                } else {
                    b
                }
            }
            Pattern::FaintLines => {
                // Lines 6% of the period wide, but never thinner than one texel.
                let period_px = s / (freq as f32 * 4.0);
                let f = (t * freq as f32 * 4.0).rem_euclid(1.0);
                if f < 0.06f32.max(1.0 / period_px) {
                    b
                } else {
                    a
                }
            }
            Pattern::SimilarColourEdges | Pattern::ColourEdges => {
                // Blocky Voronoi-like regions: noise thresholded into three colours.
                let n = value_noise(u * freq as f32, v * freq as f32, freq, seed);
                if n < 0.4 {
                    a
                } else if n < 0.7 {
                    b
                } else if pattern == Pattern::ColourEdges {
                    c
                } else {
                    (a + b) * 0.5
                }
            }
            Pattern::FineCheckers => {
                let n = freq * 8;
                let (i, j) = ((u * n as f32) as u32, (v * n as f32) as u32);
                if (i + j) % 2 == 0 {
                    a
                } else {
                    b
                }
            }
            Pattern::Noise => {
                let mut n = 0.0;
                let mut amp = 0.5;
                let mut f = freq.max(4);
                for o in 0..4u64 {
                    n += amp * value_noise(u * f as f32, v * f as f32, f, seed.wrapping_add(o));
                    amp *= 0.5;
                    f *= 2;
                }
                a.lerp(b, (n / 0.9375).clamp(0.0, 1.0))
            }
        };
        let e = |x: f32| (rtd_image::linear_to_srgb(x.clamp(0.0, 1.0)) * 255.0).round() as u8;
        image::Rgb([e(col.x), e(col.y), e(col.z)])
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn patterns_are_deterministic_and_not_flat() {
        for p in Pattern::ALL {
            let t1 = make_texture(p, 64, &mut ChaCha8Rng::seed_from_u64(5));
            let t2 = make_texture(p, 64, &mut ChaCha8Rng::seed_from_u64(5));
            assert_eq!(t1, t2);
            let distinct: std::collections::HashSet<_> = t1.pixels().map(|p| p.0).collect();
            assert!(distinct.len() >= 2, "{p:?} is flat");
        }
    }
}
