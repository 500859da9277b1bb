//! What the user sees and edits, apart from any GPU object: the scene (with
//! its camera), the render settings, the views and how they are laid out.
//! The window turns changes of the model into renderer calls.

use std::path::PathBuf;

use glam::Vec3;

use super::controller::{self, AxisView, MoveKeys, NavMode};
use super::layout::Layout;
use crate::render::RenderSettings;
use crate::scene::{Scene, ShadingModel, Toon};
use crate::view::ViewSpec;

/// One-shot requests from the panel or the keyboard, served by the window.
#[derive(Debug, Default, Clone, Copy)]
pub struct Requests {
    pub screenshot: bool,
    pub save_views: bool,
    pub frame_all: bool,
    pub axis_view: Option<AxisView>,
}

pub struct Model {
    /// The scene being shown; its camera is the camera all views share.
    pub scene: Scene,
    /// Counts edits of materials, lights, ambient and background (not the
    /// camera): views compare it with what they were given.
    pub scene_rev: u64,
    /// The last scene that passed validation.
    last_good: Scene,
    /// The camera the scene file had when loaded: a reload keeps the
    /// user's camera unless the file's camera changed.
    file_camera: crate::scene::Camera,
    pub world_up: Vec3,
    /// Shared by all views; width and height are set per view.
    pub settings: RenderSettings,
    /// Four slots; the layout shows the first `layout.view_count()`.
    pub views: Vec<ViewSpec>,
    pub layout: Layout,
    /// Wipe line position, as a fraction of the view width.
    pub wipe: f32,
    pub nav: NavMode,
    pub fly_speed: f32,
    pub move_keys: MoveKeys,
    pub vsync: bool,
    pub samples_per_frame: u32,
    pub scene_path: Option<PathBuf>,
    /// The last error (reload, edit, GPU), shown until dismissed.
    pub error: Option<String>,
    /// The last thing done (screenshot saved, scene reloaded).
    pub status: Option<String>,
    pub requests: Requests,
    /// Width / height of the first view, for framing.
    pub view_aspect: f32,
}

/// The default four view slots.
pub fn default_views() -> Vec<ViewSpec> {
    vec![
        ViewSpec::SCENE,
        ViewSpec::with_model(ShadingModel::BlinnPhong),
        ViewSpec::with_model(ShadingModel::Toon(Toon::even(4))),
        ViewSpec::with_model(ShadingModel::Toon(Toon::even(2))),
    ]
}

impl Model {
    pub fn new(
        scene: Scene,
        scene_path: Option<PathBuf>,
        given_views: &[ViewSpec],
        layout: Layout,
        settings: RenderSettings,
    ) -> Model {
        let mut views = default_views();
        for (slot, v) in views.iter_mut().zip(given_views) {
            *slot = v.clone();
        }
        let world_up = scene.camera.up.try_normalize().unwrap_or(Vec3::Y);
        Model {
            fly_speed: controller::default_fly_speed(scene.bounds()),
            view_aspect: scene.camera.aspect(),
            file_camera: scene.camera.clone(),
            last_good: scene.clone(),
            scene,
            scene_rev: 0,
            world_up,
            settings,
            views,
            layout,
            wipe: 0.5,
            nav: NavMode::Orbit,
            move_keys: MoveKeys::default(),
            vsync: true,
            samples_per_frame: 1,
            scene_path,
            error: None,
            status: None,
            requests: Requests::default(),
        }
    }

    /// The views the layout shows.
    pub fn active_views(&self) -> &[ViewSpec] {
        &self.views[..self.layout.view_count()]
    }

    /// Validates what the panel changed this frame. A valid edit of the
    /// scene's look bumps [`Model::scene_rev`]; an invalid one is undone and
    /// reported. Returns true when the scene's look changed.
    pub fn commit_edits(&mut self) -> bool {
        let s = &self.scene;
        let g = &self.last_good;
        let look_changed = s.ambient != g.ambient
            || s.background != g.background
            || s.lights != g.lights
            || s.materials != g.materials;
        let camera_changed = s.camera != g.camera;
        if !look_changed && !camera_changed {
            return false;
        }
        match self.scene.validate() {
            Ok(()) => {
                self.last_good.camera = self.scene.camera.clone();
                if look_changed {
                    self.last_good.ambient = self.scene.ambient;
                    self.last_good.background = self.scene.background;
                    self.last_good.lights = self.scene.lights.clone();
                    self.last_good.materials = self.scene.materials.clone();
                    self.scene_rev += 1;
                }
                look_changed
            }
            Err(e) => {
                self.error = Some(format!("edit not applied: {e}"));
                self.scene.camera = self.last_good.camera.clone();
                self.scene.ambient = self.last_good.ambient;
                self.scene.background = self.last_good.background;
                self.scene.lights = self.last_good.lights.clone();
                self.scene.materials = self.last_good.materials.clone();
                false
            }
        }
    }

    /// Shows `scene` from now on (a reload or a dropped file). A reload of
    /// the same file keeps the user's camera unless the file's camera
    /// changed; another file brings its own camera.
    pub fn replace_scene(&mut self, mut scene: Scene, path: Option<PathBuf>) {
        let same_file = path == self.scene_path;
        let file_camera = scene.camera.clone();
        if same_file && file_camera == self.file_camera {
            scene.camera = self.scene.camera.clone();
        } else {
            self.world_up = file_camera.up.try_normalize().unwrap_or(Vec3::Y);
            self.fly_speed = controller::default_fly_speed(scene.bounds());
        }
        self.file_camera = file_camera;
        self.last_good = scene.clone();
        self.scene = scene;
        self.scene_path = path;
        self.scene_rev += 1;
    }

    /// Serves the camera requests (frame all, numpad views).
    pub fn apply_camera_requests(&mut self) {
        let bounds = self.scene.bounds();
        let cam = &self.scene.camera;
        if std::mem::take(&mut self.requests.frame_all) {
            self.scene.camera =
                controller::frame_bounds(cam, self.world_up, bounds, self.view_aspect);
        } else if let Some(view) = self.requests.axis_view.take() {
            self.scene.camera = controller::axis_view(cam, view, bounds, self.view_aspect);
            self.world_up = Vec3::Y;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> Model {
        let scene = Scene::builtin_default();
        Model::new(scene, None, &[], Layout::Single, RenderSettings::default())
    }

    #[test]
    fn valid_edits_bump_the_revision_and_invalid_ones_are_undone() {
        let mut m = model();
        assert!(!m.commit_edits());
        m.scene.materials[0].shininess = 10.0;
        assert!(m.commit_edits());
        assert_eq!(m.scene_rev, 1);
        // A camera move is not a scene edit.
        m.scene.camera.eye.x += 1.0;
        assert!(!m.commit_edits());
        assert_eq!(m.scene_rev, 1);
        // Invalid: negative intensity. Undone, reported, revision kept.
        let before = m.scene.lights.clone();
        if let crate::scene::Light::Directional { intensity, .. } = &mut m.scene.lights[0] {
            *intensity = -1.0;
        }
        assert!(!m.commit_edits());
        assert_eq!(m.scene.lights, before);
        assert_eq!(m.scene_rev, 1);
        assert!(m.error.as_deref().unwrap().contains("intensity"));
    }

    #[test]
    fn reload_keeps_the_users_camera_unless_the_file_camera_changed() {
        let mut m = model();
        m.scene.camera.eye = Vec3::new(5.0, 5.0, 5.0);
        m.commit_edits();
        let user_eye = m.scene.camera.eye;
        let mut reloaded = Scene::builtin_default();
        reloaded.materials[0].shininess = 99.0;
        m.replace_scene(reloaded.clone(), None);
        assert_eq!(m.scene.camera.eye, user_eye);
        assert_eq!(m.scene.materials[0].shininess, 99.0);
        reloaded.camera.fov_y_deg = 30.0;
        m.replace_scene(reloaded, None);
        assert_eq!(m.scene.camera.fov_y_deg, 30.0);
        assert_ne!(m.scene.camera.eye, user_eye);
    }
}
