//! The network's input-plane layout: which of the [`INPUT_CHANNELS`] planes holds what. The
//! encoder, the training batches and the guide-dropping augmentation all read it from here.

/// Input planes: noisy colour (3), guide RGB = albedo × AO (3), albedo (3), normal (3), AO (1),
/// depth (1), two 0/1 flags saying whether albedo + normal and AO + depth are present, then the
/// standard deviation of the colour's estimate (3) and a flag saying whether it is present.
pub const INPUT_CHANNELS: usize = 20;

/// The planes models made before the variance planes read: the first 16 of the layout, which
/// are unchanged. Such a model is given those and nothing else.
pub const LEGACY_INPUT_CHANNELS: usize = 16;

/// The input widths a model may have: [`LEGACY_INPUT_CHANNELS`] or [`INPUT_CHANNELS`].
pub fn is_supported_width(channels: usize) -> bool {
    channels == LEGACY_INPUT_CHANNELS || channels == INPUT_CHANNELS
}

/// What one input plane holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plane {
    /// Encoded noisy colour, channel 0–2.
    Color(usize),
    /// Guide RGB (material colour × AO), channel 0–2.
    Guide(usize),
    /// Albedo, channel 0–2.
    Albedo(usize),
    /// World-space normal, component 0–2.
    Normal(usize),
    /// Ambient occlusion.
    Ao,
    /// Depth relative to the mean hit distance.
    Depth,
    /// 1 where the albedo + normal pair is given, else 0.
    HasAlbedoNormal,
    /// 1 where the AO + depth pair is given, else 0.
    HasAoDepth,
    /// Encoded standard deviation of the noisy colour's estimate (the renderer's per-pixel
    /// variance), channel 0–2.
    Deviation(usize),
    /// 1 where the variance is given, else 0.
    HasVariance,
}

/// The optional inputs, each of which a caller may leave out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OptionalInput {
    /// Albedo and normal.
    AlbedoNormal,
    /// Ambient occlusion and depth.
    AoDepth,
    /// The per-pixel variance of the colour (rtd's own renders have it; other software's files
    /// do not).
    Variance,
}

impl Plane {
    /// The plane at `index` (0..[`INPUT_CHANNELS`]).
    pub fn of(index: usize) -> Plane {
        match index {
            0..=2 => Plane::Color(index),
            3..=5 => Plane::Guide(index - 3),
            6..=8 => Plane::Albedo(index - 6),
            9..=11 => Plane::Normal(index - 9),
            12 => Plane::Ao,
            13 => Plane::Depth,
            14 => Plane::HasAlbedoNormal,
            15 => Plane::HasAoDepth,
            16..=18 => Plane::Deviation(index - 16),
            19 => Plane::HasVariance,
            _ => panic!("input plane {index} is outside 0..{INPUT_CHANNELS}"),
        }
    }

    /// This plane's index.
    pub fn index(self) -> usize {
        match self {
            Plane::Color(k) => k,
            Plane::Guide(k) => 3 + k,
            Plane::Albedo(k) => 6 + k,
            Plane::Normal(k) => 9 + k,
            Plane::Ao => 12,
            Plane::Depth => 13,
            Plane::HasAlbedoNormal => 14,
            Plane::HasAoDepth => 15,
            Plane::Deviation(k) => 16 + k,
            Plane::HasVariance => 19,
        }
    }

    /// The optional input this plane belongs to (its data or its presence flag), if any.
    pub fn optional(self) -> Option<OptionalInput> {
        match self {
            Plane::Albedo(_) | Plane::Normal(_) | Plane::HasAlbedoNormal => Some(OptionalInput::AlbedoNormal),
            Plane::Ao | Plane::Depth | Plane::HasAoDepth => Some(OptionalInput::AoDepth),
            Plane::Deviation(_) | Plane::HasVariance => Some(OptionalInput::Variance),
            Plane::Color(_) | Plane::Guide(_) => None,
        }
    }

    /// The colour channel this plane carries, if it carries one: such planes share one
    /// channel permutation in training's augmentation.
    pub fn colour_channel(self) -> Option<usize> {
        match self {
            Plane::Color(k) | Plane::Guide(k) | Plane::Albedo(k) | Plane::Deviation(k) => Some(k),
            _ => None,
        }
    }

    /// This plane with its colour channel replaced by `k` (other planes unchanged).
    pub fn with_colour_channel(self, k: usize) -> Plane {
        match self {
            Plane::Color(_) => Plane::Color(k),
            Plane::Guide(_) => Plane::Guide(k),
            Plane::Albedo(_) => Plane::Albedo(k),
            Plane::Deviation(_) => Plane::Deviation(k),
            other => other,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_index_round_trips_and_the_pairs_hold_their_flags() {
        for i in 0..INPUT_CHANNELS {
            assert_eq!(Plane::of(i).index(), i);
        }
        let members =
            |p: OptionalInput| (0..INPUT_CHANNELS).filter(|&i| Plane::of(i).optional() == Some(p)).collect::<Vec<_>>();
        assert_eq!(members(OptionalInput::AlbedoNormal), [6, 7, 8, 9, 10, 11, 14]);
        assert_eq!(members(OptionalInput::AoDepth), [12, 13, 15]);
        assert_eq!(members(OptionalInput::Variance), [16, 17, 18, 19]);
        // Models made before the variance planes read the first 16, which hold none of them.
        assert!((0..LEGACY_INPUT_CHANNELS).all(|i| Plane::of(i).optional() != Some(OptionalInput::Variance)));
        for i in 0..INPUT_CHANNELS {
            let p = Plane::of(i);
            match p.colour_channel() {
                Some(k) => assert_eq!(p.with_colour_channel(k), p),
                None => assert_eq!(p.with_colour_channel(2), p),
            }
        }
        assert_eq!(Plane::Deviation(0).with_colour_channel(2), Plane::Deviation(2));
    }
}
