//! Small built-in scenes with closed-form answers, shared by the tests and
//! `celray experiment`: each is written once here. CPU only (imports scene).

use crate::scene::{Scene, SceneError};

/// A white `size_px` x `size_px` image crossed by the slanted edge of a
/// black card: a quad of half size (1, `half_length`) at x = -0.75, turned
/// to face the camera and rolled by `slant_deg`, so its right edge (object
/// x = 1) crosses the image at a slant. No lights, no ambient: every pixel
/// converges to its uncovered fraction. The camera looks down -z from
/// (0, 0, 4) with a 30 degree vertical field of view.
pub fn slanted_card(size_px: u32, half_length: f32, slant_deg: f32) -> Result<Scene, SceneError> {
    let ron = format!(
        r#"(version: 1,
            camera: (eye: (0.0, 0.0, 4.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 30.0, width: {size_px}, height: {size_px}),
            ambient: (0.0, 0.0, 0.0), background: (1.0, 1.0, 1.0), lights: [],
            materials: {{ "black": (base_color: (0.0, 0.0, 0.0), specular_color: (0.0, 0.0, 0.0), model: BlinnPhong) }},
            shapes: {{ "card": Plane(Quad(half_size: (1.0, {half_length:?}))) }},
            instances: [(shape: "card", material: "black", transform: (translate: (-0.75, 0.0, 0.0), rotate_deg: (90.0, 0.0, {slant_deg:?})))],
        )"#
    );
    Scene::from_ron_str(&ron, "slanted card", std::path::Path::new("."))
}
