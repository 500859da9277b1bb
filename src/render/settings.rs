//! User-facing render settings, and their GPU twins filled in `to_gpu`.

use crate::gpu::twins::{ResolveUniforms, TONE_MAP_CLAMP, TONE_MAP_REINHARD};
use crate::sampling::PixelPattern;

/// How linear radiance becomes a displayable value in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ToneMap {
    /// Clamp to [0, 1]: shading values are shown as computed (what the
    /// tests compare against closed forms).
    #[default]
    Clamp,
    /// c / (1 + c): keeps highlights from clipping.
    Reinhard,
}

impl ToneMap {
    pub fn parse(text: &str) -> Option<ToneMap> {
        match text {
            "clamp" => Some(ToneMap::Clamp),
            "reinhard" => Some(ToneMap::Reinhard),
            _ => None,
        }
    }
}

/// Everything about how a scene is rendered that is not the scene itself.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSettings {
    /// Image size in pixels (defaults to the scene camera's size).
    pub width: u32,
    pub height: u32,
    /// Samples per pixel the accumulation converges to.
    pub spp: u32,
    /// Seed of every random choice: same seed, same image.
    pub seed: u32,
    /// Sub-pixel positions of the samples.
    pub pattern: PixelPattern,
    pub tone_map: ToneMap,
    /// Linear scale applied before tone mapping.
    pub exposure: f32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 1280,
            height: 720,
            spp: 16,
            seed: 0,
            pattern: PixelPattern::Jittered,
            tone_map: ToneMap::Clamp,
            exposure: 1.0,
        }
    }
}

impl RenderSettings {
    /// Settings at the scene camera's image size.
    pub fn for_camera(camera: &crate::scene::Camera) -> RenderSettings {
        RenderSettings {
            width: camera.width,
            height: camera.height,
            ..RenderSettings::default()
        }
    }

    /// The resolve pass's uniforms for a target of this width.
    pub fn to_gpu(&self, target_is_srgb: bool) -> ResolveUniforms {
        ResolveUniforms {
            width: self.width,
            tone_map: match self.tone_map {
                ToneMap::Clamp => TONE_MAP_CLAMP,
                ToneMap::Reinhard => TONE_MAP_REINHARD,
            },
            encode_srgb: u32::from(!target_is_srgb),
            exposure: self.exposure,
        }
    }
}
