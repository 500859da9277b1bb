//! Scripted camera paths for tests and benchmarks: a RON file of keys,
//! `(version: 1, keys: [(frame: 0, eye: (x, y, z), target: (x, y, z)), ...])`,
//! eye, target and (optional) vertical field of view interpolated linearly
//! between keys; before the first key and after the last the camera holds.

use std::path::Path;

use glam::Vec3;
use serde::Deserialize;

use crate::scene::file::ron_options;
use crate::scene::{Camera, SceneError};

/// The camera-path file format version this build reads.
pub const CAMERA_PATH_VERSION: u32 = 1;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PathFile {
    version: u32,
    keys: Vec<KeyFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyFile {
    frame: u32,
    eye: (f32, f32, f32),
    target: (f32, f32, f32),
    #[serde(default)]
    fov_y_deg: Option<f32>,
}

/// One key of a camera path.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraKey {
    pub frame: u32,
    pub eye: Vec3,
    pub target: Vec3,
    /// Vertical field of view in degrees; None keeps the scene camera's.
    pub fov_y_deg: Option<f32>,
}

/// A validated camera path: at least one key, frames strictly increasing.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraPath {
    keys: Vec<CameraKey>,
}

impl CameraPath {
    /// Reads and validates a camera-path file. Never writes anything.
    pub fn load(path: &Path) -> Result<CameraPath, SceneError> {
        let src = std::fs::read_to_string(path).map_err(|e| SceneError::Io {
            path: path.to_path_buf(),
            reason: if path.is_dir() {
                "it is a folder; give the path of a .ron camera-path file".to_string()
            } else {
                e.to_string()
            },
        })?;
        CameraPath::from_ron_str(&src, &path.display().to_string())
    }

    /// Parses and validates camera-path text; `file_name` is used in messages.
    pub fn from_ron_str(src: &str, file_name: &str) -> Result<CameraPath, SceneError> {
        let file: PathFile = ron_options()
            .from_str(src)
            .map_err(|e| SceneError::Syntax {
                file: file_name.to_string(),
                line: e.position.line,
                col: e.position.col,
                message: e.code.to_string(),
            })?;
        if file.version != CAMERA_PATH_VERSION {
            return Err(SceneError::UnsupportedVersion {
                file: file_name.to_string(),
                found: file.version,
                supported: CAMERA_PATH_VERSION,
            });
        }
        let keys: Vec<CameraKey> = file
            .keys
            .into_iter()
            .map(|k| CameraKey {
                frame: k.frame,
                eye: Vec3::from(k.eye),
                target: Vec3::from(k.target),
                fov_y_deg: k.fov_y_deg,
            })
            .collect();
        CameraPath::new(keys).map_err(|e| e.in_file(file_name))
    }

    /// A path from keys, validated: at least one, frames strictly
    /// increasing, finite positions, eye and target apart, fov in (0, 180).
    pub fn new(keys: Vec<CameraKey>) -> Result<CameraPath, SceneError> {
        if keys.is_empty() {
            return Err(SceneError::invalid(
                "camera path",
                "no keys; give at least one (frame: 0, eye: (..), target: (..))",
            ));
        }
        for (i, k) in keys.iter().enumerate() {
            let context = format!("camera path key {i} (frame {})", k.frame);
            if i > 0 && k.frame <= keys[i - 1].frame {
                return Err(SceneError::invalid(
                    context,
                    format!(
                        "frames must increase from key to key (the previous key is frame {})",
                        keys[i - 1].frame
                    ),
                ));
            }
            if !k.eye.is_finite() || !k.target.is_finite() {
                return Err(SceneError::invalid(
                    context,
                    "eye and target must be finite",
                ));
            }
            if (k.target - k.eye).length() <= 1e-6 {
                return Err(SceneError::invalid(context, "eye and target coincide"));
            }
            if let Some(fov) = k.fov_y_deg {
                if !(fov > 0.0 && fov < 180.0) {
                    return Err(SceneError::invalid(
                        context,
                        format!("fov_y_deg {fov} is outside (0, 180)"),
                    ));
                }
            }
        }
        Ok(CameraPath { keys })
    }

    pub fn keys(&self) -> &[CameraKey] {
        &self.keys
    }

    /// The frame of the last key: from it on, the camera holds still.
    pub fn last_frame(&self) -> u32 {
        self.keys.last().map_or(0, |k| k.frame)
    }

    /// `base` (the scene camera: up, lens, shutter, image size) moved to
    /// this path's eye, target and field of view at `frame`.
    pub fn camera_at(&self, base: &Camera, frame: u32) -> Camera {
        let fov = |k: &CameraKey| k.fov_y_deg.unwrap_or(base.fov_y_deg);
        let next = self.keys.iter().position(|k| k.frame > frame);
        let (eye, target, fov_y_deg) = match next {
            Some(0) => (self.keys[0].eye, self.keys[0].target, fov(&self.keys[0])),
            Some(j) => {
                let (a, b) = (&self.keys[j - 1], &self.keys[j]);
                let t = (frame - a.frame) as f32 / (b.frame - a.frame) as f32;
                (
                    a.eye.lerp(b.eye, t),
                    a.target.lerp(b.target, t),
                    fov(a) + (fov(b) - fov(a)) * t,
                )
            }
            None => {
                let k = &self.keys[self.keys.len() - 1];
                (k.eye, k.target, fov(k))
            }
        };
        Camera {
            eye,
            target,
            fov_y_deg,
            eye_end: None,
            target_end: None,
            ..base.clone()
        }
    }

    /// Checks that every key can look along its direction with `base`'s up
    /// vector (not parallel to it).
    pub fn check_up(&self, base: &Camera) -> Result<(), SceneError> {
        for (i, k) in self.keys.iter().enumerate() {
            let forward = (k.target - k.eye).normalize();
            if forward.cross(base.up.normalize_or_zero()).length() < 1e-4 {
                return Err(SceneError::invalid(
                    format!("camera path key {i} (frame {})", k.frame),
                    "the view direction is parallel to the camera's up vector",
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn base() -> Camera {
        crate::scene::Scene::builtin_default().camera
    }

    #[test]
    fn interpolates_linearly_and_holds_outside_the_keys() {
        let path = CameraPath::from_ron_str(
            "(version: 1, keys: [(frame: 2, eye: (0.0, 1.0, 4.0), target: (0.0, 0.0, 0.0)), \
             (frame: 6, eye: (4.0, 1.0, 0.0), target: (0.0, 2.0, 0.0), fov_y_deg: 30.0)])",
            "p.ron",
        )
        .unwrap();
        let b = base();
        let at = |f| path.camera_at(&b, f);
        assert_eq!(at(0).eye, Vec3::new(0.0, 1.0, 4.0));
        assert_eq!(at(2).eye, Vec3::new(0.0, 1.0, 4.0));
        // Frame 3 is a quarter of the way from key 0 to key 1.
        assert!((at(3).eye - Vec3::new(1.0, 1.0, 3.0)).length() < 1e-6);
        assert!((at(3).target - Vec3::new(0.0, 0.5, 0.0)).length() < 1e-6);
        assert!((at(3).fov_y_deg - (b.fov_y_deg + (30.0 - b.fov_y_deg) * 0.25)).abs() < 1e-4);
        assert_eq!(at(6).eye, Vec3::new(4.0, 1.0, 0.0));
        assert_eq!(at(100).fov_y_deg, 30.0);
        assert_eq!(at(100).width, b.width);
        assert_eq!(path.last_frame(), 6);
    }

    #[test]
    fn bad_paths_are_refused_with_a_reason() {
        let err = |src: &str| {
            CameraPath::from_ron_str(src, "p.ron")
                .unwrap_err()
                .to_string()
        };
        assert!(err("(version: 1, keys: [])").contains("no keys"));
        assert!(err("(version: 2, keys: [])").contains("version 2"));
        assert!(err(
            "(version: 1, keys: [(frame: 3, eye: (0.0, 0.0, 1.0), target: (0.0, 0.0, 0.0)), \
             (frame: 3, eye: (0.0, 0.0, 2.0), target: (0.0, 0.0, 0.0))])"
        )
        .contains("frames must increase"));
        assert!(err(
            "(version: 1, keys: [(frame: 0, eye: (1.0, 0.0, 0.0), target: (1.0, 0.0, 0.0))])"
        )
        .contains("coincide"));
        let typo = err("(version: 1, keyz: [])");
        assert!(typo.starts_with("p.ron:1:"), "{typo}");
    }
}
