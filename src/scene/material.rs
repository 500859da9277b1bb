//! Materials and shading models.

use glam::{Vec2, Vec3};

use super::texture::{BaseColorTexture, Pattern};
use super::SceneError;

/// The largest number of toon bands a material may have.
pub const MAX_TOON_BANDS: u32 = 16;

/// The number of bands `"toon"` (without `:N`) means in [`parse_shading_model`].
pub const DEFAULT_TOON_BANDS: u32 = 4;

/// Surface appearance of an instance. All colours are linear RGB.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Diffuse colour; the ambient term is `scene.ambient * base_color`.
    pub base_color: Vec3,
    /// Colour of the specular highlight.
    pub specular_color: Vec3,
    /// Blinn-Phong exponent (> 0).
    pub shininess: f32,
    /// How the surface is lit.
    pub model: ShadingModel,
    /// Colour of the silhouette outline.
    pub outline_color: Vec3,
    /// Outline width in pixels; 0 draws no outline.
    pub outline_width_px: f32,
    /// Mirror reflection weight in [0, 1].
    pub reflectivity: f32,
    /// Blur of the reflection in [0, 1]; 0 is a perfect mirror.
    pub roughness: f32,
    /// An image that replaces `base_color` (sampled at the surface's UV
    /// times `uv_scale`); `None`: the mesh's own map if it has one, else
    /// `base_color`.
    pub base_color_texture: Option<BaseColorTexture>,
    /// Repeats of the texture across the UV square.
    pub uv_scale: Vec2,
    /// A procedural base colour; takes precedence over the texture.
    pub base_color_pattern: Option<Pattern>,
}

/// Lighting model of a material.
#[derive(Debug, Clone, PartialEq)]
pub enum ShadingModel {
    /// Smooth Blinn-Phong shading.
    BlinnPhong,
    /// Cel shading with quantised diffuse bands.
    Toon(Toon),
}

/// Parameters of the toon (cel) shading model.
///
/// The diffuse term `max(N.L, 0)` is quantised into bands: with thresholds
/// `t_1 < ... < t_{n-1}`, band `k` covers `[t_k, t_{k+1})` (with `t_0 = 0`,
/// `t_n = 1`).
#[derive(Debug, Clone, PartialEq)]
pub struct Toon {
    /// `bands() - 1` strictly increasing values in (0, 1).
    pub thresholds: Vec<f32>,
    /// The specular highlight is drawn (at full strength) where the
    /// Blinn-Phong specular term exceeds this value, in [0, 1].
    pub specular_threshold: f32,
    /// Optional rim light.
    pub rim: Option<Rim>,
}

/// Rim light of a toon material: `color` is added where
/// `1 - max(N.V, 0) > threshold`.
#[derive(Debug, Clone, PartialEq)]
pub struct Rim {
    /// Linear RGB colour added on the rim.
    pub color: Vec3,
    /// Threshold in [0, 1]; larger values give a thinner rim.
    pub threshold: f32,
}

impl Toon {
    /// Number of bands: `thresholds.len() + 1`.
    pub fn bands(&self) -> u32 {
        u32::try_from(self.thresholds.len())
            .unwrap_or(u32::MAX)
            .saturating_add(1)
    }

    /// `bands` evenly spaced bands: thresholds `i / bands` for
    /// `i = 1..bands`, specular threshold 0.5, no rim.
    /// `bands` is clamped to `1..=MAX_TOON_BANDS`.
    pub fn even(bands: u32) -> Toon {
        let bands = bands.clamp(1, MAX_TOON_BANDS);
        Toon {
            thresholds: (1..bands).map(|i| i as f32 / bands as f32).collect(),
            specular_threshold: 0.5,
            rim: None,
        }
    }

    /// Checks the invariants documented on the fields.
    pub fn validate(&self) -> Result<(), String> {
        let bands = self.bands();
        if !(1..=MAX_TOON_BANDS).contains(&bands) {
            return Err(format!(
                "toon bands must be in 1..={MAX_TOON_BANDS}, got {bands}"
            ));
        }
        check_thresholds(&self.thresholds)?;
        if !(0.0..=1.0).contains(&self.specular_threshold) {
            return Err(format!(
                "toon specular_threshold must be in [0, 1], got {}",
                self.specular_threshold
            ));
        }
        if let Some(rim) = &self.rim {
            check_color("rim color", rim.color)?;
            if !(0.0..=1.0).contains(&rim.threshold) {
                return Err(format!(
                    "rim threshold must be in [0, 1], got {}",
                    rim.threshold
                ));
            }
        }
        Ok(())
    }
}

/// Checks that toon thresholds are strictly increasing and inside (0, 1).
fn check_thresholds(thresholds: &[f32]) -> Result<(), String> {
    for (i, &t) in thresholds.iter().enumerate() {
        if !(t > 0.0 && t < 1.0) {
            return Err(format!(
                "toon thresholds must lie strictly between 0 and 1, but thresholds[{i}] = {t}"
            ));
        }
        if i > 0 && t <= thresholds[i - 1] {
            return Err(format!(
                "toon thresholds must be strictly increasing, but thresholds[{}] = {} is followed by {t}",
                i - 1,
                thresholds[i - 1]
            ));
        }
    }
    Ok(())
}

/// Checks that a colour is finite and has no negative component.
pub(crate) fn check_color(what: &str, c: Vec3) -> Result<(), String> {
    if !c.is_finite() || c.min_element() < 0.0 {
        return Err(format!(
            "{what} must have finite, non-negative components, got ({}, {}, {})",
            c.x, c.y, c.z
        ));
    }
    Ok(())
}

impl Material {
    /// Checks that every field is in its documented range.
    pub fn validate(&self) -> Result<(), String> {
        check_color("base_color", self.base_color)?;
        check_color("specular_color", self.specular_color)?;
        check_color("outline_color", self.outline_color)?;
        if !(self.shininess.is_finite() && self.shininess > 0.0) {
            return Err(format!(
                "shininess must be positive, got {}",
                self.shininess
            ));
        }
        if !(self.outline_width_px.is_finite() && self.outline_width_px >= 0.0) {
            return Err(format!(
                "outline_width_px must be >= 0, got {}",
                self.outline_width_px
            ));
        }
        if !(0.0..=1.0).contains(&self.reflectivity) {
            return Err(format!(
                "reflectivity must be in [0, 1], got {}",
                self.reflectivity
            ));
        }
        if !(0.0..=1.0).contains(&self.roughness) {
            return Err(format!(
                "roughness must be in [0, 1], got {}",
                self.roughness
            ));
        }
        if let ShadingModel::Toon(toon) = &self.model {
            toon.validate()?;
        }
        if !(self.uv_scale.is_finite() && self.uv_scale.min_element() > 0.0) {
            return Err(format!(
                "uv_scale must be positive, got ({}, {})",
                self.uv_scale.x, self.uv_scale.y
            ));
        }
        if let Some(Pattern::Checker { a, b, size }) = self.base_color_pattern {
            check_color("checker colour a", a)?;
            check_color("checker colour b", b)?;
            if !(size.is_finite() && size > 0.0) {
                return Err(format!("checker size must be positive, got {size}"));
            }
        }
        Ok(())
    }
}

/// Parses a shading model given on the command line:
/// `"blinn-phong"`, `"toon"` (= [`DEFAULT_TOON_BANDS`] even bands) or
/// `"toon:N"` (N even bands, `1 <= N <= MAX_TOON_BANDS`).
/// Surrounding white space and letter case are ignored.
pub fn parse_shading_model(s: &str) -> Result<ShadingModel, SceneError> {
    let bad = || SceneError::BadShadingModel {
        text: s.to_string(),
        max: MAX_TOON_BANDS,
    };
    let text = s.trim().to_ascii_lowercase();
    match text.as_str() {
        "blinn-phong" => Ok(ShadingModel::BlinnPhong),
        "toon" => Ok(ShadingModel::Toon(Toon::even(DEFAULT_TOON_BANDS))),
        _ => {
            let n = text
                .strip_prefix("toon:")
                .and_then(|n| n.trim().parse::<u32>().ok())
                .ok_or_else(bad)?;
            if (1..=MAX_TOON_BANDS).contains(&n) {
                Ok(ShadingModel::Toon(Toon::even(n)))
            } else {
                Err(bad())
            }
        }
    }
}
