//! A dataset rendered on many machines, a scene at a time: a render node renders every view of
//! one scene into a [`SceneShard`], and the machine that owns the dataset directory adds the
//! shard to it. Scenes and seeds derive from the dataset's options alone, so a shard holds the
//! same views, byte for byte, as the one-machine run renders for that scene.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{write_scene, DatasetOptions, DatasetScene, Manifest, RenderedView, ViewRender};
use crate::{Progress, TrainError};

/// Every view of one scene, rendered.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SceneShard {
    /// Scene index.
    pub scene: u64,
    /// The views, in camera order.
    pub views: Vec<RenderedView>,
}

/// Renders every view of scene `scene` of `options`, writing the scene's files into the
/// scratch folder `scene_dir`. Reports one step per view to `progress`; returns `None` when
/// `progress` was cancelled between views.
pub fn render_shard(
    scene_dir: &Path,
    options: &DatasetOptions,
    scene: u64,
    progress: &dyn Progress,
) -> Result<Option<SceneShard>, TrainError> {
    if scene >= options.scenes {
        return Err(TrainError::msg(scene_dir, format!("scene {scene} is not in a dataset of {}", options.scenes)));
    }
    let loaded = DatasetScene::write_and_load(scene_dir, options, scene)?;
    progress.start(options.views_per_scene as u64, "views");
    let mut views = Vec::with_capacity(options.views_per_scene);
    for view in 0..options.views_per_scene {
        if progress.cancelled() {
            return Ok(None);
        }
        views.push(loaded.render_view(options, view)?);
        progress.inc(1);
    }
    Ok(Some(SceneShard { scene, views }))
}

impl Manifest {
    /// Adds `shard` to the dataset in `dir`: writes the scene's files and every view the
    /// manifest lacks, saving the manifest after each. A shard that does not belong to this
    /// dataset (another scene count, view count or image size) is refused and nothing is
    /// written. Returns the number of views added (0 for a shard added before).
    pub fn add_shard(&mut self, dir: &Path, shard: &SceneShard, progress: &dyn Progress) -> Result<u64, TrainError> {
        self.check_shard(dir, shard)?;
        if shard.views.iter().all(|v| self.has_view(shard.scene, v.view)) {
            return Ok(0);
        }
        let options = self.options.clone();
        let layout = write_scene(&dir.join("scenes"), &options, shard.scene)?;
        let mut added = 0;
        for rendered in &shard.views {
            if self.record(dir, shard.scene, layout, rendered, progress)? {
                added += 1;
            }
        }
        Ok(added)
    }

    /// Refuses a shard whose scene, views or images cannot be this dataset's.
    fn check_shard(&self, dir: &Path, shard: &SceneShard) -> Result<(), TrainError> {
        let o = &self.options;
        let wrong = |why: String| Err(TrainError::msg(&dir.join("manifest.json"), why));
        if !o.scene_indices().any(|s| s == shard.scene) {
            return wrong(format!("a render node sent scene {}, which this dataset does not have", shard.scene));
        }
        let cameras: Vec<usize> = shard.views.iter().map(|v| v.view).collect();
        if cameras != (0..o.views_per_scene).collect::<Vec<_>>() {
            return wrong(format!(
                "a render node sent views {cameras:?} of scene {}, not 0..{}",
                shard.scene, o.views_per_scene
            ));
        }
        for v in &shard.views {
            if let ViewRender::Kept { exr, .. } = &v.render {
                let file = dir.join(super::view_file(shard.scene, v.view));
                let header = rtd_image::read_image_header(&file, exr)?;
                if header.format != rtd_image::ImageFormat::Exr || (header.width, header.height) != (o.size, o.size) {
                    return wrong(format!(
                        "a render node sent a {}x{} {:?} image for a view of {}x{} EXR",
                        header.width, header.height, header.format, o.size, o.size
                    ));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtd_image::Quiet;

    fn tiny() -> DatasetOptions {
        DatasetOptions::default().scenes(2).views_per_scene(1).size(16).reference_spp(4)
    }

    #[test]
    fn a_shard_is_added_once_and_a_foreign_one_not_at_all() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = tempfile::tempdir().unwrap();
        let shard = render_shard(scratch.path(), &tiny(), 1, &Quiet).unwrap().unwrap();
        let mut manifest = Manifest::open(dir.path(), &tiny()).unwrap();
        assert_eq!(manifest.scenes_to_render(), vec![0, 1]);
        assert_eq!(manifest.add_shard(dir.path(), &shard, &Quiet).unwrap(), 1);
        assert_eq!(manifest.add_shard(dir.path(), &shard, &Quiet).unwrap(), 0, "a second copy adds nothing");
        assert_eq!(manifest.scenes_to_render(), vec![0]);
        assert_eq!(Manifest::load(dir.path()).unwrap().views_done(), 1, "saved");

        let before = Manifest::load(dir.path()).unwrap().views_done();
        let mut other_scene = shard.clone();
        other_scene.scene = 7;
        let mut other_views = shard.clone();
        other_views.views[0].view = 3;
        let mut other_size = render_shard(scratch.path(), &tiny().size(20), 0, &Quiet).unwrap().unwrap();
        other_size.scene = 0;
        for (bad, says) in [(other_scene, "scene 7"), (other_views, "views [3]"), (other_size, "20x20")] {
            let e = manifest.add_shard(dir.path(), &bad, &Quiet).unwrap_err().to_string();
            assert!(e.contains(says) && e.contains("manifest.json"), "{e}");
        }
        assert_eq!(Manifest::load(dir.path()).unwrap().views_done(), before, "nothing added by a refused shard");
        assert!(!dir.path().join(crate::dataset::view_file(0, 0)).exists());
    }

    #[test]
    fn a_scene_outside_the_dataset_is_refused() {
        let scratch = tempfile::tempdir().unwrap();
        let e = render_shard(scratch.path(), &tiny(), 2, &Quiet).unwrap_err().to_string();
        assert!(e.contains("scene 2 is not in a dataset of 2"), "{e}");
    }
}
