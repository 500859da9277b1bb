//! Serde types mirroring the scene file format (version 1, RON).
//!
//! These types only describe the text; `convert.rs` turns them into a
//! [`Scene`](super::Scene), resolving names and loading meshes.
//!
//! The format is documented on the [`scene`](super) module.

use std::collections::HashSet;
use std::fmt;
use std::marker::PhantomData;

use glam::{Vec2, Vec3};
use serde::de::{self, Deserializer, IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;

/// The scene format version this build reads.
pub const SCENE_FORMAT_VERSION: u32 = 1;

/// How deep brackets and parentheses may nest in a scene file (and a
/// `--set` value): a guard against running out of stack on a hostile file,
/// far above what any scene needs (a CSG tree level costs two).
pub const MAX_NESTING: usize = 128;

/// RON options used for scene files and `--set` values.
pub(crate) fn ron_options() -> ron::Options {
    ron::Options::default()
        .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
        .with_recursion_limit(MAX_NESTING)
}

/// Reads only `version`, ignoring everything else, so that a file of a
/// newer version reports its version rather than its first unknown field.
#[derive(Deserialize)]
pub(crate) struct VersionProbe {
    #[serde(default)]
    pub version: Option<u32>,
}

/// The whole file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "scene")]
pub(crate) struct SceneFile {
    /// Must be [`SCENE_FORMAT_VERSION`].
    pub version: u32,
    pub camera: CameraFile,
    #[serde(default = "default_ambient")]
    pub ambient: Vec3,
    #[serde(default = "default_background")]
    pub background: Vec3,
    #[serde(default)]
    pub lights: Vec<LightFile>,
    #[serde(default)]
    pub materials: NamedList<MaterialFile>,
    #[serde(default)]
    pub shapes: NamedList<ShapeFile>,
    #[serde(default)]
    pub instances: Vec<InstanceFile>,
}

/// Default ambient light (linear RGB).
pub const DEFAULT_AMBIENT: Vec3 = Vec3::splat(0.05);
/// Default background colour (linear RGB).
pub const DEFAULT_BACKGROUND: Vec3 = Vec3::splat(0.5);

fn default_ambient() -> Vec3 {
    DEFAULT_AMBIENT
}
fn default_background() -> Vec3 {
    DEFAULT_BACKGROUND
}
fn white() -> Vec3 {
    Vec3::ONE
}
fn one() -> f32 {
    1.0
}
fn yes() -> bool {
    true
}
fn half() -> f32 {
    0.5
}
fn default_shininess() -> f32 {
    32.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "camera")]
pub(crate) struct CameraFile {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    pub fov_y_deg: f32,
    pub width: u32,
    pub height: u32,
    #[serde(default)]
    pub aperture_radius: f32,
    #[serde(default)]
    pub focus_distance: Option<f32>,
    #[serde(default)]
    pub aperture: ApertureFile,
    #[serde(default)]
    pub shutter_open_s: f32,
    #[serde(default)]
    pub shutter_close_s: f32,
    #[serde(default)]
    pub f_number: Option<f32>,
    #[serde(default)]
    pub focal_length_mm: Option<f32>,
    #[serde(default)]
    pub eye_end: Option<Vec3>,
    #[serde(default)]
    pub target_end: Option<Vec3>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields, rename = "aperture")]
pub(crate) enum ApertureFile {
    #[default]
    Disk,
    Square,
    Polygon {
        blades: u32,
        #[serde(default)]
        rotation_deg: f32,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "light")]
pub(crate) enum LightFile {
    Directional {
        direction: Vec3,
        #[serde(default = "white")]
        color: Vec3,
        #[serde(default = "one")]
        intensity: f32,
        #[serde(default = "yes")]
        cast_shadows: bool,
    },
    Point {
        position: Vec3,
        #[serde(default = "white")]
        color: Vec3,
        #[serde(default = "one")]
        intensity: f32,
        #[serde(default = "yes")]
        cast_shadows: bool,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "material")]
pub(crate) struct MaterialFile {
    pub base_color: Vec3,
    pub model: ModelFile,
    #[serde(default = "white")]
    pub specular_color: Vec3,
    #[serde(default = "default_shininess")]
    pub shininess: f32,
    #[serde(default)]
    pub outline_color: Vec3,
    /// `None`: 1.5 for toon, 0 for Blinn-Phong.
    #[serde(default)]
    pub outline_width_px: Option<f32>,
    #[serde(default)]
    pub reflectivity: f32,
    #[serde(default)]
    pub roughness: f32,
    /// An image file (PNG), relative to the scene file's directory.
    #[serde(default)]
    pub base_color_texture: Option<String>,
    #[serde(default)]
    pub texture_filter: TextureFilterFile,
    #[serde(default = "unit_scale")]
    pub uv_scale: Vec2,
    #[serde(default)]
    pub base_color_pattern: Option<PatternFile>,
}

fn unit_scale() -> Vec2 {
    Vec2::ONE
}

#[derive(Deserialize, Default, Clone, Copy)]
#[serde(deny_unknown_fields, rename = "texture_filter")]
pub(crate) enum TextureFilterFile {
    #[default]
    Linear,
    Nearest,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "pattern")]
pub(crate) enum PatternFile {
    Checker { a: Vec3, b: Vec3, size: f32 },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "model")]
pub(crate) enum ModelFile {
    BlinnPhong,
    /// Exactly one of `bands` (even bands) and `thresholds` must be given.
    Toon {
        #[serde(default)]
        bands: Option<u32>,
        #[serde(default)]
        thresholds: Option<Vec<f32>>,
        #[serde(default = "half")]
        specular_threshold: f32,
        #[serde(default)]
        rim: Option<RimFile>,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "rim")]
pub(crate) struct RimFile {
    pub color: Vec3,
    pub threshold: f32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "shape")]
pub(crate) enum ShapeFile {
    Sphere {
        radius: f32,
    },
    Box {
        half_extents: Vec3,
    },
    Cylinder {
        radius: f32,
        height: f32,
    },
    Cone {
        radius: f32,
        height: f32,
    },
    Plane(PlaneFile),
    /// Path relative to the scene file's directory.
    Mesh {
        path: String,
    },
    /// CSG: `Union([..])`, `Intersection([..])`, `Difference(a, b)` of
    /// [`CsgFile`] solids.
    Union(Vec<CsgFile>),
    Intersection(Vec<CsgFile>),
    Difference(Box<CsgFile>, Box<CsgFile>),
}

/// A node of a CSG tree: an operation or a solid with an optional
/// transform (within the CSG shape) and an optional material name.
#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "csg")]
pub(crate) enum CsgFile {
    Union(Vec<CsgFile>),
    Intersection(Vec<CsgFile>),
    Difference(Box<CsgFile>, Box<CsgFile>),
    Sphere {
        radius: f32,
        #[serde(default)]
        transform: TransformFile,
        #[serde(default)]
        material: Option<String>,
    },
    Box {
        half_extents: Vec3,
        #[serde(default)]
        transform: TransformFile,
        #[serde(default)]
        material: Option<String>,
    },
    Cylinder {
        radius: f32,
        height: f32,
        #[serde(default)]
        transform: TransformFile,
        #[serde(default)]
        material: Option<String>,
    },
    Cone {
        radius: f32,
        height: f32,
        #[serde(default)]
        transform: TransformFile,
        #[serde(default)]
        material: Option<String>,
    },
    /// A closed mesh, path relative to the scene file's directory.
    Mesh {
        path: String,
        #[serde(default)]
        transform: TransformFile,
        #[serde(default)]
        material: Option<String>,
    },
    /// Parsed only to be refused with a clear message (no inside).
    Plane(IgnoredAny),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "Plane")]
pub(crate) enum PlaneFile {
    Quad { half_size: Vec2 },
    Disk { radius: f32 },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "instance")]
pub(crate) struct InstanceFile {
    pub shape: String,
    pub material: String,
    #[serde(default)]
    pub transform: TransformFile,
    #[serde(default)]
    pub transform_end: Option<TransformFile>,
}

/// An instance transform, written either as
/// `(translate: (x, y, z), rotate_deg: (x, y, z), scale: (x, y, z))`
/// (every field optional) or as
/// `Matrix(((m00, m01, m02, m03), (m10, ...), (m20, ...), (m30, ...)))`:
/// four rows, row-major as written on paper (translation in the last
/// column).
///
/// The TRS form builds `T * Rz * Ry * Rx * S`: scale first, then rotate
/// about x, then y, then z (degrees), then translate.
pub(crate) enum TransformFile {
    Trs(TrsFile),
    /// Rows of the matrix.
    Matrix([[f32; 4]; 4]),
}

impl Default for TransformFile {
    fn default() -> Self {
        TransformFile::Trs(TrsFile::default())
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, rename = "transform")]
pub(crate) struct TrsFile {
    #[serde(default)]
    pub translate: Vec3,
    #[serde(default)]
    pub rotate_deg: Vec3,
    #[serde(default = "white")]
    pub scale: Vec3,
}

impl Default for TrsFile {
    fn default() -> Self {
        TrsFile {
            translate: Vec3::ZERO,
            rotate_deg: Vec3::ZERO,
            scale: Vec3::ONE,
        }
    }
}

impl<'de> Deserialize<'de> for TransformFile {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        // RON hands a struct with named fields to `visit_map` and
        // `Matrix((...))` to `visit_seq`; the identifier itself is not
        // passed on by RON's `deserialize_any`.
        deserializer.deserialize_any(TransformVisitor)
    }
}

struct TransformVisitor;

impl<'de> Visitor<'de> for TransformVisitor {
    type Value = TransformFile;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(
            "a transform: (translate: (x, y, z), rotate_deg: (x, y, z), scale: (x, y, z)) \
             or Matrix(((..4 numbers..), (..), (..), (..)))",
        )
    }

    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<Self::Value, A::Error> {
        TrsFile::deserialize(de::value::MapAccessDeserializer::new(map)).map(TransformFile::Trs)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let rows: [[f32; 4]; 4] = seq
            .next_element()?
            .ok_or_else(|| de::Error::invalid_length(0, &self))?;
        if seq.next_element::<IgnoredAny>()?.is_some() {
            return Err(de::Error::invalid_length(2, &self));
        }
        Ok(TransformFile::Matrix(rows))
    }
}

/// A RON map `{ "name": value, ... }` kept in file order; a name given
/// twice is an error.
pub(crate) struct NamedList<T>(pub Vec<(String, T)>);

impl<T> Default for NamedList<T> {
    fn default() -> Self {
        NamedList(Vec::new())
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for NamedList<T> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_map(NamedListVisitor(PhantomData))
    }
}

struct NamedListVisitor<T>(PhantomData<T>);

impl<'de, T: Deserialize<'de>> Visitor<'de> for NamedListVisitor<T> {
    type Value = NamedList<T>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a map from names to definitions, like { \"name\": ... }")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
        let mut seen = HashSet::new();
        let mut entries = Vec::new();
        while let Some(name) = map.next_key::<String>()? {
            if !seen.insert(name.clone()) {
                return Err(de::Error::custom(format!(
                    "the name \"{name}\" is defined twice"
                )));
            }
            let value = map.next_value()?;
            entries.push((name, value));
        }
        Ok(NamedList(entries))
    }
}
