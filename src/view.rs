//! What one view of a comparison or of the window's side-by-side slots
//! shows ([`ViewSpec`]: the scene's materials, or every material switched
//! to one shading model), how a list of them is parsed from `--views`, and
//! the labels views and their settings carry on screen and in reports.

use crate::render::RenderSettings;
use crate::scene::{parse_shading_model, Scene, SceneError, ShadingModel};

/// The most views one comparison renders.
pub const MAX_VIEWS: usize = 16;

/// A `--views` list that does not parse.
#[derive(Debug, thiserror::Error)]
#[error("--views {text:?}: {reason}")]
pub struct ViewListError {
    pub text: String,
    pub reason: String,
}

/// One view of a comparison: the scene's own materials, or every material
/// switched to one shading model.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewSpec {
    /// `None`: materials as the scene file says.
    pub shading: Option<ShadingModel>,
}

impl ViewSpec {
    /// The scene's materials as authored.
    pub const SCENE: ViewSpec = ViewSpec { shading: None };

    /// Every material switched to `model`.
    pub fn with_model(model: ShadingModel) -> ViewSpec {
        ViewSpec {
            shading: Some(model),
        }
    }

    /// `scene` (materials as authored), `blinn-phong`, `toon` or `toon:N`.
    pub fn parse(text: &str) -> Result<ViewSpec, SceneError> {
        let t = text.trim().to_ascii_lowercase();
        if t == "scene" {
            return Ok(ViewSpec::SCENE);
        }
        parse_shading_model(&t).map(ViewSpec::with_model)
    }

    /// A comma-separated list such as `"blinn-phong,toon:4,toon:7"`.
    pub fn parse_list(text: &str) -> Result<Vec<ViewSpec>, ViewListError> {
        let bad = |reason: String| ViewListError {
            text: text.to_string(),
            reason,
        };
        if text.trim().is_empty() {
            return Err(bad(
                "no views; give a comma-separated list such as \"blinn-phong,toon:4\"".into(),
            ));
        }
        let views = text
            .split(',')
            .enumerate()
            .map(|(i, part)| {
                ViewSpec::parse(part).map_err(|e| {
                    bad(format!(
                        "view {} ({:?}): {e}; \"scene\" keeps the scene's own materials",
                        i + 1,
                        part.trim()
                    ))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        if views.len() > MAX_VIEWS {
            return Err(bad(format!("{} views; at most {MAX_VIEWS}", views.len())));
        }
        Ok(views)
    }

    /// The text that parses back to this view (`scene`, `blinn-phong`,
    /// `toon:4`), or a description for toon models with uneven thresholds.
    pub fn label(&self) -> String {
        match &self.shading {
            None => "scene".to_string(),
            Some(model) => model_label(model),
        }
    }

    /// `scene` with this view's shading applied.
    pub fn apply(&self, scene: &Scene) -> Scene {
        let mut scene = scene.clone();
        if let Some(model) = &self.shading {
            scene.override_shading(model);
        }
        scene
    }
}

/// `blinn-phong`, `toon:N` for evenly spaced bands, else
/// `toon (N bands: t1, t2, ...)`.
pub fn model_label(model: &ShadingModel) -> String {
    match model {
        ShadingModel::BlinnPhong => "blinn-phong".to_string(),
        ShadingModel::Toon(toon) => {
            let even = crate::scene::Toon::even(toon.bands());
            if toon.thresholds == even.thresholds {
                format!("toon:{}", toon.bands())
            } else {
                let t: Vec<String> = toon.thresholds.iter().map(|t| format!("{t:.2}")).collect();
                format!("toon ({} bands: {})", toon.bands(), t.join(", "))
            }
        }
    }
}

/// A short description of the settings that change a view's look:
/// `16 spp, jittered, clamp`.
pub fn settings_label(settings: &RenderSettings) -> String {
    let pattern = settings.pattern.name();
    let tone = settings.tone_map.name();
    let mut s = format!("{} spp, {pattern}, {tone}", settings.spp);
    if (settings.exposure - 1.0).abs() > 1e-6 {
        s.push_str(&format!(", exposure {:.2}", settings.exposure));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_view_lists() {
        let v = ViewSpec::parse_list("blinn-phong, toon:4 ,TOON:7,scene").unwrap();
        let labels: Vec<String> = v.iter().map(ViewSpec::label).collect();
        assert_eq!(labels, ["blinn-phong", "toon:4", "toon:7", "scene"]);
        assert_eq!(ViewSpec::parse("toon").unwrap().label(), "toon:4");
        let err = ViewSpec::parse_list("toon:4,phong")
            .unwrap_err()
            .to_string();
        assert!(err.contains("view 2") && err.contains("phong"), "{err}");
        assert!(ViewSpec::parse_list("").is_err());
        assert!(ViewSpec::parse_list("toon:99").is_err());
        let many = vec!["toon"; MAX_VIEWS + 1].join(",");
        assert!(ViewSpec::parse_list(&many).is_err());
    }

    #[test]
    fn labels_of_uneven_toon_models_list_thresholds() {
        let model = ShadingModel::Toon(crate::scene::Toon {
            thresholds: vec![0.15, 0.5, 0.85],
            specular_threshold: 0.5,
            rim: None,
        });
        assert_eq!(model_label(&model), "toon (4 bands: 0.15, 0.50, 0.85)");
    }
}
