//! Hot reload: watches the scene file, its image files and the `shaders/`
//! folder (notify) and says which of them changed.

use std::path::{Path, PathBuf};

use notify::Watcher as _;

/// What changed on disk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Changed {
    Scene,
    Shaders,
}

/// Keeps the watches alive; dropping it stops them.
pub struct Watcher {
    _inner: notify::RecommendedWatcher,
}

/// The `shaders/` folder to read for hot reload: `./shaders` when it holds
/// the pass files, else the one in the source tree celray was built from,
/// else none (the embedded shaders stay).
pub fn shader_dir() -> Option<PathBuf> {
    let candidates = [
        std::env::current_dir().ok().map(|d| d.join("shaders")),
        Some(Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders")),
    ];
    candidates
        .into_iter()
        .flatten()
        .find(|d| d.join("raster.wgsl").is_file())
        .and_then(|d| d.canonicalize().ok())
}

/// Watches `scene` (through its folder, so that editors that save by
/// renaming are seen) and every `.wgsl` file under `shaders`, calling
/// `on_change` from the watcher's thread.
pub fn watch(
    scene: Option<&Path>,
    shaders: Option<&Path>,
    on_change: impl Fn(Changed) + Send + 'static,
) -> notify::Result<Watcher> {
    watch_with_images(scene, shaders, &[], on_change)
}

/// [`watch`], and also the scene's image files: a changed image reports
/// [`Changed::Scene`] (reloading the scene reads it again).
pub fn watch_with_images(
    scene: Option<&Path>,
    shaders: Option<&Path>,
    images: &[PathBuf],
    on_change: impl Fn(Changed) + Send + 'static,
) -> notify::Result<Watcher> {
    let images: Vec<PathBuf> = images
        .iter()
        .map(|p| p.canonicalize().unwrap_or_else(|_| p.to_path_buf()))
        .collect();
    let image_dirs: Vec<PathBuf> = images
        .iter()
        .filter_map(|p| p.parent().map(Path::to_path_buf))
        .collect();
    let scene = scene.map(|p| p.canonicalize().unwrap_or_else(|_| p.to_path_buf()));
    let scene_name = scene
        .as_ref()
        .and_then(|p| p.file_name().map(|n| n.to_owned()));
    let shader_root = shaders.map(Path::to_path_buf);
    let mut inner = notify::recommended_watcher(move |event: notify::Result<notify::Event>| {
        let Ok(event) = event else { return };
        if matches!(event.kind, notify::EventKind::Access(_)) {
            return;
        }
        let mut scene_hit = false;
        let mut shader_hit = false;
        for path in &event.paths {
            if scene_name.is_some() && path.file_name() == scene_name.as_deref() {
                scene_hit = true;
            }
            if images.iter().any(|i| i == path) {
                scene_hit = true;
            }
            if let Some(root) = &shader_root {
                if path.starts_with(root) && path.extension().is_some_and(|e| e == "wgsl") {
                    shader_hit = true;
                }
            }
        }
        if scene_hit {
            on_change(Changed::Scene);
        }
        if shader_hit {
            on_change(Changed::Shaders);
        }
    })?;
    if let Some(dir) = scene.as_ref().and_then(|p| p.parent()) {
        inner.watch(dir, notify::RecursiveMode::NonRecursive)?;
    }
    if let Some(dir) = shaders {
        inner.watch(dir, notify::RecursiveMode::Recursive)?;
    }
    let scene_dir = scene.as_ref().and_then(|p| p.parent());
    let mut watched: Vec<&Path> = Vec::new();
    for dir in &image_dirs {
        if Some(dir.as_path()) != scene_dir && !watched.contains(&dir.as_path()) {
            inner.watch(dir, notify::RecursiveMode::NonRecursive)?;
            watched.push(dir);
        }
    }
    Ok(Watcher { _inner: inner })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc;
    use std::time::Duration;

    #[test]
    fn reports_scene_and_shader_changes() {
        let root = std::env::temp_dir().join(format!("celray-watch-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(root.join("shaders/lib")).unwrap();
        let scene = root.join("scene.ron");
        std::fs::write(&scene, "()").unwrap();
        std::fs::write(root.join("other.txt"), "x").unwrap();
        let (tx, rx) = mpsc::channel();
        let shaders = root.join("shaders").canonicalize().unwrap();
        let _w = watch(Some(&scene), Some(&shaders), move |c| {
            let _ = tx.send(c);
        })
        .unwrap();
        let wait_for = |want: Changed| {
            let deadline = std::time::Instant::now() + Duration::from_secs(10);
            while std::time::Instant::now() < deadline {
                if rx.recv_timeout(Duration::from_millis(200)) == Ok(want) {
                    return true;
                }
            }
            false
        };
        std::fs::write(&scene, "(version: 1)").unwrap();
        assert!(wait_for(Changed::Scene));
        std::fs::write(root.join("shaders/lib/x.wgsl"), "// x").unwrap();
        assert!(wait_for(Changed::Shaders));
        std::fs::remove_dir_all(&root).unwrap();
    }
}
