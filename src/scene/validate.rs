//! Range and consistency checks on a [`Scene`].

use glam::Vec3;

use super::material::check_color;
use super::{ApertureShape, Camera, Light, Scene, SceneError};

/// Largest accepted image width or height in pixels.
pub const MAX_IMAGE_SIZE: u32 = 16384;

/// Instance transforms with `|det| <` this are rejected as singular.
pub const MIN_TRANSFORM_DETERMINANT: f32 = 1e-8;

impl Scene {
    /// Checks every value against its documented range: camera, colours,
    /// lights, materials, shapes, and that each instance refers to an
    /// existing shape and material through a finite, affine, invertible
    /// transform.
    ///
    /// Loading already does this; call it again after editing a scene by
    /// hand.
    pub fn validate(&self) -> Result<(), SceneError> {
        self.camera
            .validate()
            .map_err(|m| SceneError::invalid("camera", m))?;
        check_color("ambient", self.ambient).map_err(|m| SceneError::invalid("scene", m))?;
        check_color("background", self.background).map_err(|m| SceneError::invalid("scene", m))?;
        for (i, light) in self.lights.iter().enumerate() {
            light
                .validate()
                .map_err(|m| SceneError::invalid(format!("light {i}"), m))?;
        }
        if self.material_names.len() != self.materials.len() {
            return Err(SceneError::invalid(
                "scene",
                "material_names and materials differ in length",
            ));
        }
        if self.shape_names.len() != self.shapes.len() {
            return Err(SceneError::invalid(
                "scene",
                "shape_names and shapes differ in length",
            ));
        }
        for (material, name) in self.materials.iter().zip(&self.material_names) {
            material
                .validate()
                .map_err(|m| SceneError::invalid(format!("material \"{name}\""), m))?;
        }
        for (shape, name) in self.shapes.iter().zip(&self.shape_names) {
            shape
                .validate()
                .map_err(|m| SceneError::invalid(format!("shape \"{name}\""), m))?;
            if let super::Shape::Csg(csg) = shape {
                csg.check_materials(self.materials.len())
                    .map_err(|m| SceneError::invalid(format!("shape \"{name}\""), m))?;
            }
        }
        for (i, instance) in self.instances.iter().enumerate() {
            let context = match self.shape_names.get(instance.shape) {
                Some(name) => format!("instance {i} (shape \"{name}\")"),
                None => format!("instance {i}"),
            };
            if instance.shape >= self.shapes.len() {
                return Err(SceneError::invalid(
                    context,
                    format!(
                        "shape id {} out of range ({} shapes)",
                        instance.shape,
                        self.shapes.len()
                    ),
                ));
            }
            if instance.material >= self.materials.len() {
                return Err(SceneError::invalid(
                    context,
                    format!(
                        "material id {} out of range ({} materials)",
                        instance.material,
                        self.materials.len()
                    ),
                ));
            }
            for m in
                std::iter::once(instance.world_from_object).chain(instance.world_from_object_end)
            {
                if !m.is_finite() {
                    return Err(SceneError::invalid(
                        context,
                        "transform has a non-finite entry (inf or NaN)",
                    ));
                }
                if m.row(3) != glam::Vec4::W {
                    return Err(SceneError::invalid(
                        context,
                        "transform is not affine: its last row must be (0, 0, 0, 1)",
                    ));
                }
                let det = m.determinant();
                if det.abs() < MIN_TRANSFORM_DETERMINANT || !m.inverse().is_finite() {
                    return Err(SceneError::invalid(
                    context,
                    format!(
                        "transform is singular (determinant {det:e}, |det| must be at least {MIN_TRANSFORM_DETERMINANT:e}); check for a zero scale"
                    ),
                ));
                }
            }
        }
        Ok(())
    }
}

/// Checks that a vector is finite and not (nearly) zero.
fn check_direction(what: &str, v: Vec3) -> Result<(), String> {
    if !v.is_finite() || v.length_squared() < 1e-12 {
        return Err(format!(
            "{what} must be a finite, non-zero vector, got ({}, {}, {})",
            v.x, v.y, v.z
        ));
    }
    Ok(())
}

fn check_finite(what: &str, v: Vec3) -> Result<(), String> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(format!(
            "{what} must be finite, got ({}, {}, {})",
            v.x, v.y, v.z
        ))
    }
}

impl Camera {
    /// Checks the ranges documented on the fields.
    pub fn validate(&self) -> Result<(), String> {
        for (what, size) in [("width", self.width), ("height", self.height)] {
            if !(1..=MAX_IMAGE_SIZE).contains(&size) {
                return Err(format!(
                    "image {what} must be in 1..={MAX_IMAGE_SIZE} pixels, got {size}"
                ));
            }
        }
        check_finite("eye", self.eye)?;
        check_finite("target", self.target)?;
        let view = self.target - self.eye;
        if view.length_squared() < 1e-12 {
            return Err(format!(
                "eye and target must differ, both are ({}, {}, {})",
                self.eye.x, self.eye.y, self.eye.z
            ));
        }
        check_direction("up", self.up)?;
        if view.normalize().cross(self.up.normalize()).length_squared() < 1e-12 {
            return Err("up must not be parallel to the view direction (target - eye)".into());
        }
        if !(self.fov_y_deg > 0.0 && self.fov_y_deg < 180.0) {
            return Err(format!(
                "fov_y_deg must be in (0, 180) degrees, got {}",
                self.fov_y_deg
            ));
        }
        if !(self.aperture_radius.is_finite() && self.aperture_radius >= 0.0) {
            return Err(format!(
                "aperture_radius must be >= 0 (0 = pinhole), got {}",
                self.aperture_radius
            ));
        }
        if let Some(d) = self.focus_distance {
            if !(d.is_finite() && d > 0.0) {
                return Err(format!("focus_distance must be positive, got {d}"));
            }
        }
        if let ApertureShape::Polygon {
            blades,
            rotation_deg,
        } = self.aperture
        {
            if blades < 3 {
                return Err(format!(
                    "a polygon aperture needs at least 3 blades, got {blades}"
                ));
            }
            if !rotation_deg.is_finite() {
                return Err(format!(
                    "aperture rotation_deg must be finite, got {rotation_deg}"
                ));
            }
        }
        if !(self.shutter_open_s.is_finite() && self.shutter_open_s >= 0.0) {
            return Err(format!(
                "shutter_open_s must be >= 0, got {}",
                self.shutter_open_s
            ));
        }
        if !(self.shutter_close_s.is_finite() && self.shutter_close_s >= self.shutter_open_s) {
            return Err(format!(
                "shutter_close_s must be >= shutter_open_s ({}), got {}",
                self.shutter_open_s, self.shutter_close_s
            ));
        }
        Ok(())
    }
}

impl Light {
    /// Checks that positions and directions are finite, directions
    /// non-zero, colours and intensities non-negative.
    pub fn validate(&self) -> Result<(), String> {
        let (color, intensity) = match self {
            Light::Directional {
                direction,
                color,
                intensity,
                ..
            } => {
                check_direction("direction", *direction)?;
                (*color, *intensity)
            }
            Light::Point {
                position,
                color,
                intensity,
                ..
            } => {
                check_finite("position", *position)?;
                (*color, *intensity)
            }
        };
        check_color("color", color)?;
        if !(intensity.is_finite() && intensity >= 0.0) {
            return Err(format!("intensity must be >= 0, got {intensity}"));
        }
        Ok(())
    }
}
