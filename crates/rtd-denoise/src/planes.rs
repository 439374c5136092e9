//! The network's input-plane layout: which of the [`INPUT_CHANNELS`] planes holds what. The
//! encoder, the training batches and the guide-dropping augmentation all read it from here.

/// Input planes: noisy colour (3), guide RGB = albedo × AO (3), albedo (3), normal (3), AO (1),
/// depth (1), and two 0/1 flags saying whether albedo + normal and AO + depth are present.
pub const INPUT_CHANNELS: usize = 16;

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
}

/// The two optional input pairs, each of which a caller may leave out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OptionalPair {
    /// Albedo and normal.
    AlbedoNormal,
    /// Ambient occlusion and depth.
    AoDepth,
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
        }
    }

    /// The optional pair this plane belongs to (its data or its presence flag), if any.
    pub fn pair(self) -> Option<OptionalPair> {
        match self {
            Plane::Albedo(_) | Plane::Normal(_) | Plane::HasAlbedoNormal => Some(OptionalPair::AlbedoNormal),
            Plane::Ao | Plane::Depth | Plane::HasAoDepth => Some(OptionalPair::AoDepth),
            Plane::Color(_) | Plane::Guide(_) => None,
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
            |p: OptionalPair| (0..INPUT_CHANNELS).filter(|&i| Plane::of(i).pair() == Some(p)).collect::<Vec<_>>();
        assert_eq!(members(OptionalPair::AlbedoNormal), [6, 7, 8, 9, 10, 11, 14]);
        assert_eq!(members(OptionalPair::AoDepth), [12, 13, 15]);
    }
}
