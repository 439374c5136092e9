use crate::{Camera, Projection, Scene};

/// A `--camera NAME|INDEX` choice that names no camera of the scene. The message lists what
/// exists; callers prefix the scene's path.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CameraError {
    /// The choice is a number past the end of [`Scene::cameras`].
    #[error("camera index {index} out of range (scene has {count} cameras)")]
    IndexOutOfRange {
        /// The index asked for.
        index: usize,
        /// How many cameras the scene has.
        count: usize,
    },
    /// No camera has the name asked for.
    #[error("no camera named '{name}' (cameras: {})", name_list(.available))]
    NoSuchName {
        /// The name asked for.
        name: String,
        /// The names of the scene's cameras, in file order.
        available: Vec<String>,
    },
}

/// `a, b, c`, or `none` for no names.
fn name_list(names: &[String]) -> String {
    if names.is_empty() {
        "none".to_string()
    } else {
        names.join(", ")
    }
}

impl Scene {
    /// The camera chosen by `--camera NAME|INDEX` (index in depth-first node order), else the first
    /// perspective camera, else the first camera, else an automatic one that frames the scene
    /// (returned with a warning). A choice that matches no camera is a [`CameraError`] naming the
    /// cameras that exist.
    pub fn select_camera(&self, choice: Option<&str>) -> Result<(Camera, Option<String>), CameraError> {
        match choice {
            Some(c) => self.camera_named(c).map(|cam| (cam, None)),
            None => match self
                .cameras
                .iter()
                .find(|c| matches!(c.projection, Projection::Perspective { .. }))
                .or(self.cameras.first())
            {
                Some(c) => Ok((c.clone(), None)),
                None => Ok((
                    Camera::framing(&self.bounds()),
                    Some("scene has no camera; using an automatic camera framing its bounds".into()),
                )),
            },
        }
    }

    /// The camera with index `choice` if it parses as a number, else the one named `choice`.
    fn camera_named(&self, choice: &str) -> Result<Camera, CameraError> {
        if let Ok(index) = choice.parse::<usize>() {
            return self
                .cameras
                .get(index)
                .cloned()
                .ok_or(CameraError::IndexOutOfRange { index, count: self.cameras.len() });
        }
        self.cameras.iter().find(|cam| cam.name == choice).cloned().ok_or_else(|| CameraError::NoSuchName {
            name: choice.to_string(),
            available: self.cameras.iter().map(|c| c.name.clone()).collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn scene_with(names: &[&str]) -> Scene {
        let cameras = names
            .iter()
            .map(|n| {
                let mut c = Camera::look_at(Vec3::Z, Vec3::ZERO, 40.0);
                c.name = n.to_string();
                c
            })
            .collect();
        Scene { cameras, ..Scene::default() }
    }

    #[test]
    fn a_choice_that_matches_no_camera_is_a_typed_error_with_the_old_text() {
        let s = scene_with(&["front", "top"]);
        assert_eq!(s.select_camera(Some("top")).unwrap().0.name, "top");
        assert_eq!(s.select_camera(Some("1")).unwrap().0.name, "top");
        let e = s.select_camera(Some("side")).unwrap_err();
        assert_eq!(e, CameraError::NoSuchName { name: "side".into(), available: vec!["front".into(), "top".into()] });
        assert_eq!(e.to_string(), "no camera named 'side' (cameras: front, top)");
        let e = s.select_camera(Some("2")).unwrap_err();
        assert_eq!(e, CameraError::IndexOutOfRange { index: 2, count: 2 });
        assert_eq!(e.to_string(), "camera index 2 out of range (scene has 2 cameras)");
        let e = scene_with(&[]).select_camera(Some("any")).unwrap_err();
        assert_eq!(e.to_string(), "no camera named 'any' (cameras: none)");
    }
}
