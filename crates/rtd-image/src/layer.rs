//! The EXR layer vocabulary: every layer rtd writes or reads, with its channel names. Writers
//! (the film, the guide pass, the dataset, the benchmarks) and readers (the dataset loader,
//! `rtd denoise`) name layers through [`Layer`], never through strings.

/// How a layer's channels are named.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channels {
    /// Three colour channels `R,G,B`.
    Rgb,
    /// Three vector components `X,Y,Z` (normals).
    Xyz,
    /// One value per pixel, in the named channel (`Z` for depth, `Y` for scalars).
    Scalar(&'static str),
}

impl Channels {
    /// The three channel suffixes of an image layer (`R,G,B` or `X,Y,Z`); None for a scalar.
    pub fn triple(self) -> Option<[&'static str; 3]> {
        match self {
            Channels::Rgb => Some(["R", "G", "B"]),
            Channels::Xyz => Some(["X", "Y", "Z"]),
            Channels::Scalar(_) => None,
        }
    }
}

/// A layer of an rtd EXR file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layer {
    /// The image itself, in the unprefixed `R,G,B` channels every reader shows first.
    Beauty,
    /// The noisy render kept beside a denoised beauty (`noisy.R/G/B`).
    Noisy,
    /// A dataset view's noisy render at this many samples per pixel (`noisy8.R/G/B`).
    NoisyAt(u32),
    /// A dataset view's converged reference (`reference.R/G/B`).
    Reference,
    /// The guide RGB: material colour × ambient occlusion (`guide.R/G/B`).
    Guide,
    /// First-hit albedo (`albedo.R/G/B`).
    Albedo,
    /// First-hit world-space shading normal (`normal.X/Y/Z`).
    Normal,
    /// Camera distance to the first hit (`depth.Z`).
    Depth,
    /// Ambient occlusion (`ao.Y`).
    Ao,
    /// A reference's estimated remaining relMSE, stored in every pixel (`noise.Y`).
    NoiseEstimate,
    /// A reference's samples per pixel, stored in every pixel (`spp.Y`).
    SampleCount,
    /// The variance of each pixel's mean in the beauty beside it, per channel
    /// (`variance.R/G/B`): the noise the renderer measured, which the denoiser reads.
    Variance,
    /// The [`Layer::Variance`] of a dataset view's noisy render at this many samples per pixel
    /// (`variance8.R/G/B`).
    VarianceAt(u32),
}

impl Layer {
    /// The layer's prefix: the part of each channel name before the dot (empty for the beauty).
    pub fn prefix(self) -> String {
        match self {
            Layer::Beauty => String::new(),
            Layer::Noisy => "noisy".into(),
            Layer::NoisyAt(spp) => format!("noisy{spp}"),
            Layer::Reference => "reference".into(),
            Layer::Guide => "guide".into(),
            Layer::Albedo => "albedo".into(),
            Layer::Normal => "normal".into(),
            Layer::Depth => "depth".into(),
            Layer::Ao => "ao".into(),
            Layer::NoiseEstimate => "noise".into(),
            Layer::SampleCount => "spp".into(),
            Layer::Variance => "variance".into(),
            Layer::VarianceAt(spp) => format!("variance{spp}"),
        }
    }

    /// How the layer's channels are named.
    pub fn channels(self) -> Channels {
        match self {
            Layer::Normal => Channels::Xyz,
            Layer::Depth => Channels::Scalar("Z"),
            Layer::Ao | Layer::NoiseEstimate | Layer::SampleCount => Channels::Scalar("Y"),
            Layer::Beauty
            | Layer::Noisy
            | Layer::NoisyAt(_)
            | Layer::Reference
            | Layer::Guide
            | Layer::Albedo
            | Layer::Variance
            | Layer::VarianceAt(_) => Channels::Rgb,
        }
    }

    /// The full channel names, in order (`albedo.R`, `albedo.G`, `albedo.B`; `R`, `G`, `B`).
    pub fn channel_names(self) -> Vec<String> {
        let prefix = self.prefix();
        match self.channels() {
            Channels::Scalar(c) => vec![join(&prefix, c)],
            image => image.triple().into_iter().flatten().map(|s| join(&prefix, s)).collect(),
        }
    }
}

impl Layer {
    /// Names other software gives this layer's pass, matched without case against a prefix or
    /// its last dotted part ([`crate::Layers::find_channels`]): Blender's (`ViewLayer.Combined`,
    /// `ViewLayer.Denoising Albedo`), Nuke's (`rgba`) and Houdini's (`C`, `N`).
    pub fn studio_names(self) -> &'static [&'static str] {
        match self {
            Layer::Beauty => &["Combined", "rgba", "C", "beauty"],
            Layer::Albedo => &["Denoising Albedo", "albedo", "diffuse_albedo", "DiffCol"],
            Layer::Normal => &["Denoising Normal", "normal", "N", "normals"],
            Layer::Depth => &["Denoising Depth", "depth"],
            Layer::Noisy
            | Layer::NoisyAt(_)
            | Layer::Reference
            | Layer::Guide
            | Layer::Ao
            | Layer::NoiseEstimate
            | Layer::SampleCount
            | Layer::Variance
            | Layer::VarianceAt(_) => &[],
        }
    }
}

/// `prefix.channel`, or the bare channel for the empty prefix.
pub(crate) fn join(prefix: &str, channel: &str) -> String {
    if prefix.is_empty() {
        channel.to_string()
    } else {
        format!("{prefix}.{channel}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channel_names_follow_the_interoperable_convention() {
        assert_eq!(Layer::Beauty.channel_names(), ["R", "G", "B"]);
        assert_eq!(Layer::Albedo.channel_names(), ["albedo.R", "albedo.G", "albedo.B"]);
        assert_eq!(Layer::Normal.channel_names(), ["normal.X", "normal.Y", "normal.Z"]);
        assert_eq!(Layer::Depth.channel_names(), ["depth.Z"]);
        assert_eq!(Layer::Ao.channel_names(), ["ao.Y"]);
        assert_eq!(Layer::NoisyAt(8).channel_names(), ["noisy8.R", "noisy8.G", "noisy8.B"]);
        assert_eq!(Layer::NoiseEstimate.channel_names(), ["noise.Y"]);
        assert_eq!(Layer::SampleCount.channel_names(), ["spp.Y"]);
        assert_eq!(Layer::Variance.channel_names(), ["variance.R", "variance.G", "variance.B"]);
        assert_eq!(Layer::VarianceAt(8).channel_names(), ["variance8.R", "variance8.G", "variance8.B"]);
    }
}
