//! Finding a layer in a file from any renderer: rtd's own channel names, the names Blender,
//! Nuke and Houdini give the same pass ([`Layer::studio_names`]), or a prefix the user names
//! (`--layer-color`). The three channels may be `R,G,B`, `X,Y,Z`, their lower-case forms or
//! Nuke's `red,green,blue`.

use crate::layer::{join, Layer};
use crate::{HdrImage, Layers};

/// The channel suffixes an image layer's three channels may have, in the order tried.
const SUFFIXES: [[&str; 3]; 5] =
    [["R", "G", "B"], ["X", "Y", "Z"], ["r", "g", "b"], ["x", "y", "z"], ["red", "green", "blue"]];

impl Layers {
    /// The three channel names holding `layer`: under `prefix` when the user names one (the
    /// whole prefix, or its last dotted part, compared without case), else rtd's own names, then
    /// the other renderers' names for the pass under any prefix (Blender's
    /// `ViewLayer.Denoising Albedo.R`, Houdini's `N.x`, Nuke's `rgba.red`).
    pub fn find_channels(&self, layer: Layer, prefix: Option<&str>) -> Option<[String; 3]> {
        if let Some(wanted) = prefix {
            let exact = self.prefixes().into_iter().find(|p| p == wanted);
            let candidates = exact.into_iter().chain(self.prefixes_named(&[wanted]));
            return candidates.into_iter().find_map(|p| self.triple_under(&p));
        }
        let own = layer.channels().triple().map(|t| t.map(|c| join(&layer.prefix(), c)));
        if let Some(names) = own.filter(|n| n.iter().all(|c| self.get(c).is_some())) {
            return Some(names);
        }
        if !layer.prefix().is_empty() {
            if let Some(names) = self.triple_under(&layer.prefix()) {
                return Some(names);
            }
        }
        self.prefixes_named(layer.studio_names()).into_iter().find_map(|p| self.triple_under(&p))
    }

    /// The image of `layer` ([`Layers::find_channels`] without a named prefix).
    pub fn find_image(&self, layer: Layer) -> Option<HdrImage> {
        self.find_channels(layer, None).map(|names| self.image_in(&names))
    }

    /// The image in the three channels `names`, which must exist.
    pub fn image_in(&self, names: &[String; 3]) -> HdrImage {
        let [r, g, b] = [0, 1, 2].map(|c| self.get(&names[c]).unwrap_or_default());
        HdrImage::from_planes(self.width, self.height, r, g, b)
    }

    /// The distinct layer prefixes present (the part of each channel name before its last dot;
    /// empty for bare channels), in file order: what an error lists when a layer is missing.
    pub fn prefixes(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for (name, _) in &self.channels {
            let prefix = name.rsplit_once('.').map_or("", |(p, _)| p).to_string();
            if !out.contains(&prefix) {
                out.push(prefix);
            }
        }
        out
    }

    /// The prefixes whose whole name, or last dotted part, is one of `names` (without case), in
    /// the order of `names`, then of the file.
    fn prefixes_named(&self, names: &[&str]) -> Vec<String> {
        let prefixes = self.prefixes();
        let last = |p: &str| p.rsplit_once('.').map_or(p, |(_, l)| l).to_string();
        let mut out = Vec::new();
        for name in names {
            for p in &prefixes {
                let hit = p.eq_ignore_ascii_case(name) || last(p).eq_ignore_ascii_case(name);
                if hit && !out.contains(p) {
                    out.push(p.clone());
                }
            }
        }
        out
    }

    /// The three channels under `prefix` with the first suffix naming all of whose channels exist.
    fn triple_under(&self, prefix: &str) -> Option<[String; 3]> {
        SUFFIXES.iter().map(|s| s.map(|c| join(prefix, c))).find(|names| names.iter().all(|n| self.get(n).is_some()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layers(names: &[&str]) -> Layers {
        let mut l = Layers::new(1, 1);
        for (i, n) in names.iter().enumerate() {
            l.push(*n, vec![i as f32]);
        }
        l
    }

    fn found(l: &Layers, layer: Layer, prefix: Option<&str>) -> Option<Vec<String>> {
        l.find_channels(layer, prefix).map(|n| n.to_vec())
    }

    #[test]
    fn other_renderers_names_are_found() {
        let blender = layers(&[
            "ViewLayer.Combined.R",
            "ViewLayer.Combined.G",
            "ViewLayer.Combined.B",
            "ViewLayer.Combined.A",
            "ViewLayer.Denoising Normal.X",
            "ViewLayer.Denoising Normal.Y",
            "ViewLayer.Denoising Normal.Z",
        ]);
        assert_eq!(found(&blender, Layer::Beauty, None).unwrap()[0], "ViewLayer.Combined.R");
        assert_eq!(found(&blender, Layer::Normal, None).unwrap()[2], "ViewLayer.Denoising Normal.Z");
        assert_eq!(found(&blender, Layer::Albedo, None), None);
        let houdini = layers(&["C.r", "C.g", "C.b", "albedo.r", "albedo.g", "albedo.b", "N.x", "N.y", "N.z"]);
        assert_eq!(found(&houdini, Layer::Beauty, None).unwrap(), ["C.r", "C.g", "C.b"]);
        assert_eq!(found(&houdini, Layer::Albedo, None).unwrap(), ["albedo.r", "albedo.g", "albedo.b"]);
        assert_eq!(found(&houdini, Layer::Normal, None).unwrap(), ["N.x", "N.y", "N.z"]);
        let nuke = layers(&[
            "rgba.red",
            "rgba.green",
            "rgba.blue",
            "rgba.alpha",
            "diffuse.red",
            "diffuse.green",
            "diffuse.blue",
        ]);
        assert_eq!(found(&nuke, Layer::Beauty, None).unwrap(), ["rgba.red", "rgba.green", "rgba.blue"]);
        assert_eq!(found(&nuke, Layer::Albedo, None), None);
        // A named prefix: the whole name or its last part, without case; nothing else.
        assert_eq!(found(&nuke, Layer::Albedo, Some("DIFFUSE")).unwrap()[1], "diffuse.green");
        assert_eq!(found(&blender, Layer::Beauty, Some("ViewLayer.Combined")).unwrap()[0], "ViewLayer.Combined.R");
        assert_eq!(found(&blender, Layer::Beauty, Some("Noisy")), None);
    }

    #[test]
    fn rtds_own_names_come_first() {
        let l = layers(&[
            "R",
            "G",
            "B",
            "x.Combined.R",
            "x.Combined.G",
            "x.Combined.B",
            "normal.R",
            "normal.G",
            "normal.B",
        ]);
        assert_eq!(found(&l, Layer::Beauty, None).unwrap(), ["R", "G", "B"]);
        assert_eq!(found(&l, Layer::Normal, None).unwrap(), ["normal.R", "normal.G", "normal.B"]);
    }
}
