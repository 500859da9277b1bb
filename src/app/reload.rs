//! Hot reload: watching the scene file, its images and the shader folder,
//! waiting for a burst of changes to settle, then reloading the scene (or
//! a dropped file) or rebuilding every view's renderer with the shaders on
//! disk. A failure keeps what was working and shows the error.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use winit::event_loop::EventLoopProxy;

use super::event_loop::{window_title, AppEvent};
use super::live::LiveApp;
use super::watch::{self, Changed};
use crate::gpu::shader::ShaderOverrides;
use crate::scene::Scene;

/// Wait this long after a file change before reloading (editors write in steps).
const RELOAD_DELAY: Duration = Duration::from_millis(120);

/// What changed on disk and is to be reloaded once changes settle.
#[derive(Debug, Clone, Copy)]
pub(super) struct PendingReload {
    pub at: Instant,
    pub scene: bool,
    pub shaders: bool,
}

/// The watcher and what it reported.
pub(super) struct HotReload {
    /// The shader folder, when watching.
    pub shader_dir: Option<PathBuf>,
    watcher: Option<watch::Watcher>,
    pending: Option<PendingReload>,
}

impl HotReload {
    /// Watches nothing yet (watching starts in `LiveApp::rewatch`); with
    /// `watch`, finds the shader folder to watch.
    pub fn new(watch: bool) -> HotReload {
        HotReload {
            shader_dir: if watch { watch::shader_dir() } else { None },
            watcher: None,
            pending: None,
        }
    }

    /// A file changed: reload after [`RELOAD_DELAY`] without another change.
    pub fn changed(&mut self, what: Changed) {
        let (scene, shaders) = self
            .pending
            .map_or((false, false), |p| (p.scene, p.shaders));
        self.pending = Some(PendingReload {
            at: Instant::now() + RELOAD_DELAY,
            scene: scene || what == Changed::Scene,
            shaders: shaders || what == Changed::Shaders,
        });
    }

    /// The reload due at `now`, if any (taken), else when the next one is due.
    pub fn due(&mut self, now: Instant) -> Result<Option<PendingReload>, Instant> {
        match self.pending {
            Some(p) if now >= p.at => Ok(self.pending.take()),
            Some(p) => Err(p.at),
            None => Ok(None),
        }
    }
}

impl LiveApp {
    /// Watches the scene file, its images and the shader folder again.
    pub(super) fn rewatch(&mut self, proxy: &EventLoopProxy<AppEvent>) {
        let proxy = proxy.clone();
        let images: Vec<PathBuf> = crate::render::textures::scene_images(&self.model.scene)
            .iter()
            .map(|t| t.path.clone())
            .collect();
        let result = watch::watch_with_images(
            self.model.scene_path.as_deref(),
            self.reload.shader_dir.as_deref(),
            &images,
            move |c| {
                let _ = proxy.send_event(AppEvent::FilesChanged(c));
            },
        );
        match result {
            Ok(w) => self.reload.watcher = Some(w),
            Err(e) => {
                self.reload.watcher = None;
                self.model.error = Some(format!("cannot watch files for changes: {e}"));
            }
        }
    }

    /// Does what `reload` says is due.
    pub(super) fn reload(&mut self, reload: PendingReload, proxy: &EventLoopProxy<AppEvent>) {
        if reload.scene {
            self.reload_scene(None, proxy);
        }
        if reload.shaders {
            self.reload_shaders();
        }
    }

    /// Loads `path` (a dropped file) or reloads the current scene file.
    /// A failure keeps the last good scene and shows the error.
    pub(super) fn reload_scene(&mut self, path: Option<PathBuf>, proxy: &EventLoopProxy<AppEvent>) {
        let dropped = path.is_some();
        let Some(path) = path.or_else(|| self.model.scene_path.clone()) else {
            return;
        };
        if dropped
            && !path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("ron"))
        {
            self.model.error = Some(format!(
                "{}: not a scene file (celray opens .ron scene files)",
                path.display()
            ));
            return;
        }
        match Scene::load(&path) {
            Ok(scene) => {
                self.model.replace_scene(scene, Some(path.clone()));
                self.model.error = None;
                self.model.status = Some(format!("loaded {}", path.display()));
                self.surface
                    .window
                    .set_title(&window_title(self.model.scene_path.as_deref()));
                // A new file, or new images to watch.
                if self.reload.watcher.is_some() {
                    self.rewatch(proxy);
                }
            }
            Err(e) => {
                self.model.error = Some(format!("{e}\n(keeping the last good scene)"));
            }
        }
    }

    /// Rebuilds every renderer with the shaders on disk; a shader that
    /// fails keeps the old renderers and shows the error.
    fn reload_shaders(&mut self) {
        let Some(dir) = self.reload.shader_dir.clone() else {
            return;
        };
        let overrides = match ShaderOverrides::read_dir(&dir) {
            Ok(o) => o,
            Err(e) => {
                self.model.error = Some(e.to_string());
                return;
            }
        };
        let previous = self.gpu.shader_overrides();
        self.gpu.set_shader_overrides(Some(overrides));
        match self.views.reload_renderers(&self.gpu) {
            Ok(()) => {
                self.model.error = None;
                self.model.status = Some(format!("shaders reloaded from {}", dir.display()));
            }
            Err(e) => {
                self.gpu
                    .set_shader_overrides(previous.map(|p| (*p).clone()));
                let _ = self.gpu.take_errors();
                self.model.error = Some(format!(
                    "shader reload failed, keeping the previous shaders:\n{e}"
                ));
            }
        }
    }
}
