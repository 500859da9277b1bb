//! Base-colour images and procedural patterns of materials.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::Vec3;

use super::SceneError;

/// The most distinct images one scene may use (they share one texture
/// array on the GPU: the CPU driver has no binding arrays).
pub const MAX_TEXTURES: usize = 16;

/// Largest width or height of a texture on the GPU; larger images are
/// downscaled at load with a notice. All textures of a scene are resampled
/// to one square layer size (the largest image's, at most this), so a scene
/// holds at most `MAX_TEXTURES * MAX_TEXTURE_SIZE^2 * 4 * 4/3` bytes
/// (358 MiB) of texture.
pub const MAX_TEXTURE_SIZE: u32 = 2048;

/// A decoded image: sRGB-encoded RGBA, 8 bits per channel, top row first.
/// (`Eq` lets `Arc<Texture>` comparisons short-cut on pointer equality.)
#[derive(Clone, PartialEq, Eq)]
pub struct Texture {
    /// Where it came from, for messages and the panel: a file path.
    pub source: String,
    /// The file it was read from (watched for hot reload).
    pub path: PathBuf,
    pub width: u32,
    pub height: u32,
    /// `width * height * 4` bytes.
    pub rgba8: Vec<u8>,
}

impl std::fmt::Debug for Texture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Texture({}, {}x{})",
            self.source, self.width, self.height
        )
    }
}

impl Texture {
    /// Reads and decodes an image file (PNG). `material` is named in the
    /// error. Images wider or taller than [`MAX_TEXTURE_SIZE`] are
    /// downscaled (a notice is logged).
    pub fn load(path: &Path, material: &str) -> Result<Texture, SceneError> {
        let bad = |reason: String| SceneError::Texture {
            path: path.to_path_buf(),
            material: material.to_string(),
            reason,
        };
        let bytes = std::fs::read(path).map_err(|e| bad(e.to_string()))?;
        Texture::decode(&bytes, path, material)
    }

    /// Decodes image bytes (PNG); `path` is what messages name.
    pub fn decode(bytes: &[u8], path: &Path, material: &str) -> Result<Texture, SceneError> {
        let bad = |reason: String| SceneError::Texture {
            path: path.to_path_buf(),
            material: material.to_string(),
            reason,
        };
        let image = image::load_from_memory(bytes)
            .map_err(|e| bad(format!("cannot decode the image: {e}")))?;
        let mut rgba = image.to_rgba8();
        let (w, h) = rgba.dimensions();
        if w == 0 || h == 0 {
            return Err(bad("the image is empty".into()));
        }
        if w.max(h) > MAX_TEXTURE_SIZE {
            let scale = MAX_TEXTURE_SIZE as f32 / w.max(h) as f32;
            let (nw, nh) = (
                ((w as f32 * scale).round() as u32).max(1),
                ((h as f32 * scale).round() as u32).max(1),
            );
            log::warn!(
                "texture {} of material \"{material}\" is {w}x{h}, over the limit of {MAX_TEXTURE_SIZE}: downscaled to {nw}x{nh}",
                path.display()
            );
            rgba = image::imageops::resize(&rgba, nw, nh, image::imageops::FilterType::Triangle);
        }
        let (width, height) = rgba.dimensions();
        Ok(Texture {
            source: path.display().to_string(),
            path: path.to_path_buf(),
            width,
            height,
            rgba8: rgba.into_raw(),
        })
    }

    /// The file name without its folder, for the panel.
    pub fn name(&self) -> String {
        self.path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| self.source.clone())
    }

    /// Mean of the texels in linear RGB (sRGB decoded).
    pub fn mean_linear(&self) -> Vec3 {
        let mut sum = Vec3::ZERO;
        for px in self.rgba8.chunks_exact(4) {
            sum += Vec3::new(
                srgb_to_linear(px[0]),
                srgb_to_linear(px[1]),
                srgb_to_linear(px[2]),
            );
        }
        sum / (self.rgba8.len() / 4).max(1) as f32
    }
}

/// sRGB-encoded byte to linear value (the IEC 61966-2-1 curve).
pub fn srgb_to_linear(c: u8) -> f32 {
    let c = f32::from(c) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// How a material's base-colour image is filtered when magnified.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TextureFilter {
    /// Bilinear within a mip level, trilinear between levels.
    #[default]
    Linear,
    /// The nearest texel of the nearest mip level (pixel art, tests).
    Nearest,
}

/// How texture coordinates outside [0, 1] map onto the image along one
/// axis (glTF sampler `wrapS` / `wrapT`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum Wrap {
    /// The image tiles: u and u + 1 show the same texel.
    #[default]
    Repeat,
    /// The edge texels extend outwards.
    ClampToEdge,
    /// The image tiles reflected every other period.
    MirroredRepeat,
}

/// How a mesh's own map is sampled (a glTF sampler): wrap per axis, the
/// filter when magnified and when minified, and how mip levels are used.
/// The default (repeat, linear, linear between mip levels) is what a glTF
/// texture without a sampler gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct MapSampler {
    pub wrap_s: Wrap,
    pub wrap_t: Wrap,
    /// Nearest texel when magnified (glTF magFilter NEAREST).
    pub mag_nearest: bool,
    /// Nearest texel within a level when minified.
    pub min_nearest: bool,
    /// Minification uses the nearest mip level rather than blending two.
    pub mip_nearest: bool,
    /// Minification reads level 0 only (glTF minFilter NEAREST or LINEAR).
    pub no_mips: bool,
}

impl MapSampler {
    /// The sampler of a glTF texture (its defaults where a field is absent).
    pub fn from_gltf(sampler: &gltf::texture::Sampler) -> MapSampler {
        use gltf::texture::{MagFilter, MinFilter, WrappingMode};
        let wrap = |w: WrappingMode| match w {
            WrappingMode::Repeat => Wrap::Repeat,
            WrappingMode::ClampToEdge => Wrap::ClampToEdge,
            WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        };
        let (min_nearest, mip_nearest, no_mips) = match sampler.min_filter() {
            None | Some(MinFilter::LinearMipmapLinear) => (false, false, false),
            Some(MinFilter::Nearest) => (true, false, true),
            Some(MinFilter::Linear) => (false, false, true),
            Some(MinFilter::NearestMipmapNearest) => (true, true, false),
            Some(MinFilter::LinearMipmapNearest) => (false, true, false),
            Some(MinFilter::NearestMipmapLinear) => (true, false, false),
        };
        MapSampler {
            wrap_s: wrap(sampler.wrap_s()),
            wrap_t: wrap(sampler.wrap_t()),
            mag_nearest: sampler.mag_filter() == Some(MagFilter::Nearest),
            min_nearest,
            mip_nearest,
            no_mips,
        }
    }
}

/// A material's base-colour image and how it is mapped.
#[derive(Debug, Clone, PartialEq)]
pub struct BaseColorTexture {
    pub texture: Arc<Texture>,
    pub filter: TextureFilter,
}

/// A procedural base colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pattern {
    /// A 3D checkerboard in the shape's object space: cells `size` units
    /// wide, one centred on the origin, colour `a` where
    /// `floor(x/size + 1/2) + floor(y/size + 1/2) + floor(z/size + 1/2)` is
    /// even, `b` where it is odd (linear RGB). Edges are exact at any
    /// distance: every sample evaluates the pattern at its own point.
    Checker { a: Vec3, b: Vec3, size: f32 },
}
