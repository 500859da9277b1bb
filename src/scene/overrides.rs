//! `--set key=value` edits of a loaded scene.

use serde::de::DeserializeOwned;

use super::file::ron_options;
use super::{parse_shading_model, Light, Scene, SceneError};

/// The keys [`Scene::apply_override`] accepts; `NAME` is a material name,
/// `I` a light index (from 0).
pub const OVERRIDE_KEYS: &[&str] = &[
    "camera.eye",
    "camera.target",
    "camera.up",
    "camera.fov_y_deg",
    "camera.width",
    "camera.height",
    "camera.aperture_radius",
    "camera.focus_distance",
    "camera.shutter_open_s",
    "camera.shutter_close_s",
    "ambient",
    "background",
    "materials.NAME.base_color",
    "materials.NAME.specular_color",
    "materials.NAME.shininess",
    "materials.NAME.outline_color",
    "materials.NAME.outline_width_px",
    "materials.NAME.reflectivity",
    "materials.NAME.roughness",
    "materials.NAME.model",
    "lights.I.intensity",
    "lights.I.color",
];

const VEC3: &str = "a RON tuple of 3 numbers like (0.0, 1.0, 2.0)";
const NUMBER: &str = "a number";
const PIXELS: &str = "a whole number of pixels";

impl Scene {
    /// Changes one setting, as given on the command line with
    /// `--set key=value`, then validates the scene again.
    ///
    /// Values are RON: numbers (`40`, `0.5`), tuples (`(0, 1, 2)`);
    /// `camera.focus_distance` also takes `None`; `materials.NAME.model`
    /// takes the [`parse_shading_model`] syntax. See [`OVERRIDE_KEYS`].
    ///
    /// On error the scene is left unchanged: an unknown key lists the valid
    /// keys, a value of the wrong type names the key and the expected type,
    /// and a value out of range gives the validation message.
    pub fn apply_override(&mut self, key: &str, value: &str) -> Result<(), SceneError> {
        let before = (
            self.camera.clone(),
            self.ambient,
            self.background,
            self.lights.clone(),
            self.materials.clone(),
        );
        let result = self
            .set(key.trim(), value.trim())
            .and_then(|()| self.validate())
            .map_err(|e| e.in_file(&format!("--set {key}={value}")));
        if result.is_err() {
            (
                self.camera,
                self.ambient,
                self.background,
                self.lights,
                self.materials,
            ) = before;
        }
        result
    }

    fn set(&mut self, key: &str, value: &str) -> Result<(), SceneError> {
        let v = Value { key, value };
        let c = &mut self.camera;
        match key {
            "camera.eye" => c.eye = v.parse(VEC3)?,
            "camera.target" => c.target = v.parse(VEC3)?,
            "camera.up" => c.up = v.parse(VEC3)?,
            "camera.fov_y_deg" => c.fov_y_deg = v.parse(NUMBER)?,
            "camera.width" => c.width = v.parse(PIXELS)?,
            "camera.height" => c.height = v.parse(PIXELS)?,
            "camera.aperture_radius" => c.aperture_radius = v.parse(NUMBER)?,
            "camera.focus_distance" => {
                c.focus_distance = v.parse("a number, or None for |target - eye|")?
            }
            "camera.shutter_open_s" => c.shutter_open_s = v.parse(NUMBER)?,
            "camera.shutter_close_s" => c.shutter_close_s = v.parse(NUMBER)?,
            "ambient" => self.ambient = v.parse(VEC3)?,
            "background" => self.background = v.parse(VEC3)?,
            _ => {
                if let Some(rest) = key.strip_prefix("materials.") {
                    return self.set_material(rest, &v);
                }
                if let Some(rest) = key.strip_prefix("lights.") {
                    return self.set_light(rest, &v);
                }
                return Err(self.unknown_key(key));
            }
        }
        Ok(())
    }

    /// `rest` is `NAME.FIELD`; names may contain dots.
    fn set_material(&mut self, rest: &str, v: &Value) -> Result<(), SceneError> {
        let Some((name, field)) = rest.rsplit_once('.') else {
            return Err(self.unknown_key(v.key));
        };
        let Some(id) = self.material_id(name) else {
            return Err(self.unknown_key(v.key));
        };
        let m = &mut self.materials[id];
        match field {
            "base_color" => m.base_color = v.parse(VEC3)?,
            "specular_color" => m.specular_color = v.parse(VEC3)?,
            "outline_color" => m.outline_color = v.parse(VEC3)?,
            "shininess" => m.shininess = v.parse(NUMBER)?,
            "outline_width_px" => m.outline_width_px = v.parse(NUMBER)?,
            "reflectivity" => m.reflectivity = v.parse(NUMBER)?,
            "roughness" => m.roughness = v.parse(NUMBER)?,
            "model" => {
                m.model = parse_shading_model(v.value).map_err(|e| SceneError::BadValue {
                    key: v.key.to_string(),
                    value: v.value.to_string(),
                    expected: "blinn-phong, toon or toon:N".to_string(),
                    reason: e.to_string(),
                })?
            }
            _ => return Err(self.unknown_key(v.key)),
        }
        Ok(())
    }

    /// `rest` is `I.FIELD`.
    fn set_light(&mut self, rest: &str, v: &Value) -> Result<(), SceneError> {
        let light = rest
            .split_once('.')
            .and_then(|(index, field)| Some((index.parse::<usize>().ok()?, field)))
            .filter(|(index, _)| *index < self.lights.len());
        let Some((index, field)) = light else {
            return Err(self.unknown_key(v.key));
        };
        let (Light::Directional {
            color, intensity, ..
        }
        | Light::Point {
            color, intensity, ..
        }) = &mut self.lights[index];
        match field {
            "intensity" => *intensity = v.parse(NUMBER)?,
            "color" => *color = v.parse(VEC3)?,
            _ => return Err(self.unknown_key(v.key)),
        }
        Ok(())
    }

    /// The error for an unknown key, listing the keys valid for this scene.
    fn unknown_key(&self, key: &str) -> SceneError {
        let mut valid: Vec<String> = OVERRIDE_KEYS
            .iter()
            .filter(|k| !k.starts_with("materials.") && !k.starts_with("lights."))
            .map(|k| k.to_string())
            .collect();
        valid.push(format!(
            "materials.NAME.{{base_color|specular_color|shininess|outline_color|outline_width_px|reflectivity|roughness|model}} with NAME one of: {}",
            if self.material_names.is_empty() {
                "(no materials)".to_string()
            } else {
                self.material_names.join(", ")
            }
        ));
        valid.push(if self.lights.is_empty() {
            "lights.I.{intensity|color} (this scene has no lights)".to_string()
        } else {
            format!(
                "lights.I.{{intensity|color}} with I in 0..={}",
                self.lights.len() - 1
            )
        });
        SceneError::UnknownKey {
            key: key.to_string(),
            valid: valid.join(", "),
        }
    }
}

/// A `--set` value and the key it is for.
struct Value<'a> {
    key: &'a str,
    value: &'a str,
}

impl Value<'_> {
    /// Parses the value as RON.
    fn parse<T: DeserializeOwned>(&self, expected: &str) -> Result<T, SceneError> {
        ron_options()
            .from_str(self.value)
            .map_err(|e| SceneError::BadValue {
                key: self.key.to_string(),
                value: self.value.to_string(),
                expected: expected.to_string(),
                reason: e.code.to_string(),
            })
    }
}
