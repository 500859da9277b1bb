//! Every scene shipped in assets/scenes parses and renders on lavapipe.

mod common;

use celray::render::RenderSettings;
use celray::scene::Scene;

#[test]
fn every_shipped_scene_renders() {
    let gpu = common::gpu();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let mut rendered = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("ron") {
            continue;
        }
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let settings = RenderSettings {
            width: 160,
            height: 90,
            spp: 2,
            ..RenderSettings::default()
        };
        let (img, ids) = common::render(&gpu, scene, settings);
        let covered = ids.iter().filter(|&&id| id != 0).count();
        assert!(
            covered > 160 * 90 / 20,
            "{}: only {covered} pixels show geometry",
            path.display()
        );
        let distinct: std::collections::BTreeSet<&[u8]> = img.chunks(4).collect();
        assert!(
            distinct.len() > 8,
            "{}: only {} colours",
            path.display(),
            distinct.len()
        );
        rendered += 1;
    }
    assert!(
        rendered >= 2,
        "expected the default and the comparison scene"
    );
}
