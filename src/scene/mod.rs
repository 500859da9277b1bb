//! Scene description: camera, lights, materials, shapes and instances,
//! loaded from RON scene files.
//!
//! This module is CPU only; it uses no GPU types.
//!
//! ```no_run
//! use celray::scene::{Scene, tessellate};
//! let scene = Scene::load(std::path::Path::new("assets/scenes/default.ron"))?;
//! for instance in &scene.instances {
//!     let mesh = tessellate(&scene.shapes[instance.shape]);
//!     println!("{} triangles", mesh.triangle_count());
//! }
//! # Ok::<(), celray::scene::SceneError>(())
//! ```
//!
//! # Scene file format, version 1
//!
//! ```ron
//! (
//!     version: 1,
//!     camera: (
//!         eye: (0.0, 1.5, 6.0), target: (0.0, 0.8, 0.0), up: (0.0, 1.0, 0.0),
//!         fov_y_deg: 40.0, width: 1280, height: 720,
//!         // Optional (pinhole defaults): aperture_radius: 0.0, focus_distance: None,
//!         // aperture: Disk | Square | Polygon(blades: 6, rotation_deg: 0.0),
//!         // shutter_open_s: 0.0, shutter_close_s: 0.0
//!     ),
//!     ambient: (0.08, 0.08, 0.1),        // optional, default (0.05, 0.05, 0.05)
//!     background: (0.6, 0.7, 0.85),      // optional, default (0.5, 0.5, 0.5)
//!     lights: [
//!         // color (default white), intensity (default 1) and
//!         // cast_shadows (default true) are optional.
//!         Directional(direction: (-0.5, -1.0, -0.6), color: (1.0, 1.0, 1.0), intensity: 1.0),
//!         Point(position: (3.0, 4.0, 2.0), color: (1.0, 0.9, 0.8), intensity: 0.6),
//!     ],
//!     materials: {
//!         // base_color and model are required. Optional: specular_color (1, 1, 1),
//!         // shininess 32, outline_color (0, 0, 0), outline_width_px (1.5 for toon,
//!         // 0 for Blinn-Phong), reflectivity 0, roughness 0.
//!         "red": (base_color: (0.8, 0.15, 0.1), model: Toon(bands: 4)),
//!         "plastic": (base_color: (0.2, 0.3, 0.8), model: BlinnPhong, shininess: 64.0),
//!         // Toon takes `bands` (even bands) or `thresholds`, not both; optional
//!         // specular_threshold (0.5) and rim (none).
//!         "skin": (base_color: (0.9, 0.7, 0.6), model: Toon(thresholds: [0.2, 0.5, 0.8],
//!                  rim: Some((color: (0.3, 0.3, 0.3), threshold: 0.6)))),
//!         // A PNG (relative to this file) replaces base_color; optional uv_scale
//!         // (1, 1) repeats it and texture_filter (Linear | Nearest) filters it.
//!         "spotted": (base_color: (1.0, 1.0, 1.0), model: Toon(bands: 4),
//!                     base_color_texture: "../models/spot/spot_texture.png", uv_scale: (2.0, 2.0)),
//!         // A checker in the shape's object space (cells `size` wide, one centred
//!         // on the origin); it takes precedence over a texture.
//!         "tiles": (base_color: (0.5, 0.5, 0.5), model: BlinnPhong,
//!                   base_color_pattern: Checker(a: (0.8, 0.8, 0.8), b: (0.2, 0.2, 0.2), size: 0.5)),
//!     },
//!     shapes: {
//!         "ball": Sphere(radius: 1.0),
//!         "crate": Box(half_extents: (0.5, 0.5, 0.5)),
//!         "can": Cylinder(radius: 0.5, height: 1.0),
//!         "cone": Cone(radius: 0.5, height: 1.0),
//!         "floor": Plane(Quad(half_size: (10.0, 10.0))),
//!         "disk": Plane(Disk(radius: 2.0)),
//!         // .obj, .gltf or .glb, relative to this file's directory
//!         "cow": Mesh(path: "../models/spot/spot_triangulated.obj"),
//!         // Constructive solid geometry: Union([..]), Intersection([..]) and
//!         // Difference(a, b), nested freely; leaves are Sphere, Box, Cylinder,
//!         // Cone or a closed Mesh(path: ..), each with an optional transform
//!         // (within the shape) and material (its surfaces' colour; default:
//!         // the instance's). Ray-traced only: raster mode draws nothing.
//!         "holed": Difference(
//!             Intersection([Box(half_extents: (0.8, 0.8, 0.8)), Sphere(radius: 1.05)]),
//!             Cylinder(radius: 0.4, height: 2.0, transform: (rotate_deg: (90.0, 0.0, 0.0)),
//!                      material: "plastic"),
//!         ),
//!     },
//!     instances: [
//!         // Every TRS field is optional; the matrix is T * Rz * Ry * Rx * S
//!         // (scale, then rotate about x, y, z in degrees, then translate).
//!         (shape: "ball", material: "red",
//!          transform: (translate: (0.0, 1.0, 0.0), rotate_deg: (0.0, 30.0, 0.0), scale: (1.0, 1.0, 1.0))),
//!         // Four rows, row-major as written on paper (translation in the last column).
//!         (shape: "crate", material: "plastic",
//!          transform: Matrix(((1, 0, 0, 2), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)))),
//!         (shape: "cow", material: "skin"),   // no transform: identity
//!     ],
//! )
//! ```
//!
//! Rules:
//! - Unknown fields are errors. Materials and shapes keep file order (their
//!   index is their id); a name defined twice is an error.
//! - Optional values may be written plainly (`focus_distance: 4.0`) or as
//!   `Some(4.0)` / `None` (RON's `implicit_some` is on).
//! - CSG: planes and disks have no inside and are refused as leaves; mesh
//!   leaves must be closed; a tree that a ray could split into more than
//!   [`CSG_MAX_INTERVALS`] intervals, or that needs more than [`CSG_STACK`]
//!   evaluation stack entries, is refused (see [`Csg`] for the counting).
//! - Instance transforms must be finite, affine and invertible
//!   (`|det| >= 1e-8`).
//! - All colours are linear RGB.
//! - Textures: images are PNG, sRGB-encoded; at most [`MAX_TEXTURES`]
//!   distinct images per scene (materials' and meshes' own together), each
//!   downscaled to at most [`MAX_TEXTURE_SIZE`] with a notice. A missing or
//!   undecodable image is an error naming the file and the material. Meshes
//!   bring their own maps (glTF `baseColorTexture` times `baseColorFactor`,
//!   OBJ `map_Kd`), used where the instance's material has no image or
//!   pattern. Texture coordinates of analytic shapes: a quad maps x from
//!   -half.x to +half.x to u in [0, 1] and z likewise to v; a disk its
//!   bounding square; a sphere u = atan2(z, x) / 2 pi + 1/2 (the seam at -x, growing
//!   from +x towards +z), v = 0 at the north pole (+y) to 1 at the south; cylinder and cone
//!   sides u = longitude, v = 0 at the top, caps like a disk; a box the whole
//!   image on each face, upright on the sides.

mod camera_path;
mod convert;
mod csg;
mod error;
mod file;
mod material;
mod mesh;
mod overrides;
mod shape;
mod tessellate;
mod texture;
mod validate;

use std::path::Path;

use glam::{Mat4, Vec3};

pub use camera_path::{CameraKey, CameraPath, CAMERA_PATH_VERSION};
pub use csg::{
    closed_mesh, Csg, CsgLeaf, CsgNode, CSG_MAX_INTERVALS, CSG_MESH_MAX_CROSSINGS, CSG_STACK,
};
pub use error::SceneError;
pub use file::{DEFAULT_AMBIENT, DEFAULT_BACKGROUND, MAX_NESTING, SCENE_FORMAT_VERSION};
pub use material::{
    parse_shading_model, Material, Rim, ShadingModel, Toon, DEFAULT_TOON_BANDS, MAX_TOON_BANDS,
};
pub use mesh::{smooth_normals, Mesh, NO_MESH_TEXTURE};
pub use overrides::OVERRIDE_KEYS;
pub use shape::{PlaneKind, Shape};
pub use tessellate::{
    sphere_inset, tessellate, tessellate_sphere, MAX_SILHOUETTE_ERROR_PX, ROUND_SEGMENTS,
    SPHERE_LEVELS, SPHERE_RINGS, SPHERE_SEGMENTS,
};
pub use texture::{
    srgb_to_linear, BaseColorTexture, MapSampler, Pattern, Texture, TextureFilter, Wrap,
    MAX_TEXTURES, MAX_TEXTURE_SIZE,
};
pub use validate::{MAX_IMAGE_SIZE, MIN_TRANSFORM_DETERMINANT};

/// A complete scene, validated (see [`Scene::validate`]).
///
/// Materials, shapes and their names are in file order; an index into
/// `materials` is a material id, an index into `shapes` a shape id.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub camera: Camera,
    /// Linear RGB, added as `ambient * base_color`.
    pub ambient: Vec3,
    /// Linear RGB colour behind everything.
    pub background: Vec3,
    pub lights: Vec<Light>,
    pub materials: Vec<Material>,
    /// `material_names[i]` is the name of `materials[i]`.
    pub material_names: Vec<String>,
    pub shapes: Vec<Shape>,
    /// `shape_names[i]` is the name of `shapes[i]`.
    pub shape_names: Vec<String>,
    pub instances: Vec<Instance>,
}

/// A thin-lens perspective camera (a pinhole when `aperture_radius` is 0).
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    /// Up direction; need not be unit or orthogonal to the view direction,
    /// but must not be parallel to it.
    pub up: Vec3,
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_y_deg: f32,
    /// Image width in pixels, `1..=MAX_IMAGE_SIZE`.
    pub width: u32,
    /// Image height in pixels, `1..=MAX_IMAGE_SIZE`.
    pub height: u32,
    /// Lens radius in world units; 0 is a pinhole (no depth of field).
    pub aperture_radius: f32,
    /// Distance of the plane in focus; `None` means `|target - eye|`.
    pub focus_distance: Option<f32>,
    /// Shape of the lens opening (bokeh).
    pub aperture: ApertureShape,
    /// Shutter open time in seconds (motion blur); `open <= close`.
    pub shutter_open_s: f32,
    /// Shutter close time in seconds.
    pub shutter_close_s: f32,
    /// Where the eye is when the shutter closes (a moving camera), if it moves.
    pub eye_end: Option<Vec3>,
    /// Where the camera looks when the shutter closes, if that moves.
    pub target_end: Option<Vec3>,
}

impl Camera {
    /// The camera at shutter fraction `s` in [0, 1]: eye and target move
    /// linearly between their open and close positions.
    pub fn at(&self, s: f32) -> Camera {
        Camera {
            eye: self.eye.lerp(self.eye_end.unwrap_or(self.eye), s),
            target: self.target.lerp(self.target_end.unwrap_or(self.target), s),
            ..self.clone()
        }
    }

    /// Whether the eye or the target moves over the shutter.
    pub fn moves(&self) -> bool {
        self.eye_end.is_some_and(|e| e != self.eye)
            || self.target_end.is_some_and(|t| t != self.target)
    }
}

/// Shape of the camera aperture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ApertureShape {
    Disk,
    Square,
    /// Regular polygon with `blades >= 3` corners, rotated by
    /// `rotation_deg` (counter-clockwise).
    Polygon {
        blades: u32,
        rotation_deg: f32,
    },
}

/// A light source. Colours are linear RGB; `intensity` scales `color`
/// (how a point light falls off with distance is up to the renderer).
#[derive(Debug, Clone, PartialEq)]
pub enum Light {
    Directional {
        /// Unit direction the light travels in (normalised at load).
        direction: Vec3,
        color: Vec3,
        intensity: f32,
        cast_shadows: bool,
    },
    Point {
        position: Vec3,
        color: Vec3,
        intensity: f32,
        cast_shadows: bool,
    },
}

impl Light {
    /// Whether the light casts shadows.
    pub fn casts_shadows(&self) -> bool {
        match self {
            Light::Directional { cast_shadows, .. } | Light::Point { cast_shadows, .. } => {
                *cast_shadows
            }
        }
    }

    /// Its `cast_shadows` flag, to edit.
    pub fn cast_shadows_mut(&mut self) -> &mut bool {
        match self {
            Light::Directional { cast_shadows, .. } | Light::Point { cast_shadows, .. } => {
                cast_shadows
            }
        }
    }
}

/// One placed copy of a base shape.
#[derive(Debug, Clone, PartialEq)]
pub struct Instance {
    /// Index into [`Scene::shapes`].
    pub shape: usize,
    /// Index into [`Scene::materials`].
    pub material: usize,
    /// Object-to-world transform: affine and invertible. With motion, the
    /// transform when the shutter opens.
    pub world_from_object: Mat4,
    /// The transform when the shutter closes, for motion blur; between the
    /// two, scale and translation are interpolated linearly and rotation by
    /// slerp (a shear in a matrix transform is not interpolated).
    pub world_from_object_end: Option<Mat4>,
}

impl Instance {
    /// The transform at shutter fraction `s` in [0, 1].
    pub fn world_from_object_at(&self, s: f32) -> Mat4 {
        let Some(end) = self.world_from_object_end else {
            return self.world_from_object;
        };
        let (s0, r0, t0) = self.world_from_object.to_scale_rotation_translation();
        let (s1, r1, t1) = end.to_scale_rotation_translation();
        Mat4::from_scale_rotation_translation(s0.lerp(s1, s), r0.slerp(r1, s), t0.lerp(t1, s))
    }
}

impl Camera {
    /// Width divided by height.
    pub fn aspect(&self) -> f32 {
        self.width as f32 / self.height.max(1) as f32
    }

    /// The focus distance with `None` resolved to `|target - eye|`.
    pub fn resolved_focus_distance(&self) -> f32 {
        self.focus_distance
            .unwrap_or_else(|| self.eye.distance(self.target))
    }
}

impl Instance {
    /// Matrix for transforming normals: inverse transpose of the upper
    /// 3x3 of `world_from_object`.
    pub fn normal_matrix(&self) -> glam::Mat3 {
        glam::Mat3::from_mat4(self.world_from_object)
            .inverse()
            .transpose()
    }
}

/// File name used in messages about the built-in default scene.
const BUILTIN_FILE_NAME: &str = "<built-in default.ron>";

/// Meshes compiled into the binary so that the built-in scene loads from
/// any working directory: (path as written in `default.ron`, file bytes).
const EMBEDDED_MESHES: &[(&str, &[u8])] = &[(
    "../models/spot/spot_triangulated.obj",
    include_bytes!("../../assets/models/spot/spot_triangulated.obj"),
)];

impl Scene {
    /// The text of `assets/scenes/default.ron`, compiled in.
    pub const BUILTIN_DEFAULT_RON: &'static str = include_str!("../../assets/scenes/default.ron");

    /// Reads and validates a scene file. Mesh paths are relative to the
    /// file's directory. Never writes anything.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let src = std::fs::read_to_string(path).map_err(|e| SceneError::Io {
            path: path.to_path_buf(),
            reason: if path.is_dir() {
                "it is a folder; give the path of a .ron scene file".to_string()
            } else {
                e.to_string()
            },
        })?;
        let base_dir = match path.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir,
            _ => Path::new("."),
        };
        Scene::from_ron_str(&src, &path.display().to_string(), base_dir)
    }

    /// Parses and validates scene text. `file_name` is used in messages;
    /// mesh paths are resolved against `base_dir`.
    pub fn from_ron_str(src: &str, file_name: &str, base_dir: &Path) -> Result<Scene, SceneError> {
        convert::scene_from_str(src, file_name, base_dir, &[])
    }

    /// The built-in default scene ([`Scene::BUILTIN_DEFAULT_RON`]).
    ///
    /// Its cow mesh is read from the source tree's `assets/` when that
    /// exists, otherwise from a copy compiled into the binary, so this
    /// works from any working directory.
    pub fn builtin_default() -> Scene {
        let base_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
        match convert::scene_from_str(
            Self::BUILTIN_DEFAULT_RON,
            BUILTIN_FILE_NAME,
            &base_dir,
            EMBEDDED_MESHES,
        ) {
            Ok(scene) => scene,
            // The text and mesh are compiled in and covered by tests.
            Err(e) => panic!("the built-in default scene is broken: {e}"),
        }
    }

    /// Gives every material the shading model `model` (for example from
    /// `--shading toon:3`). Outline settings are left as they are.
    pub fn override_shading(&mut self, model: &ShadingModel) {
        for material in &mut self.materials {
            material.model = model.clone();
        }
    }

    /// World-space axis-aligned bounding box `(min, max)` over all
    /// instances; `(Vec3::ZERO, Vec3::ZERO)` when there are none.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for instance in &self.instances {
            let Some(shape) = self.shapes.get(instance.shape) else {
                continue;
            };
            let (a, b) = shape.bounds();
            for i in 0..8 {
                let corner = Vec3::new(
                    if i & 1 == 0 { a.x } else { b.x },
                    if i & 2 == 0 { a.y } else { b.y },
                    if i & 4 == 0 { a.z } else { b.z },
                );
                let p = instance.world_from_object.transform_point3(corner);
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        if lo.x > hi.x {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            (lo, hi)
        }
    }

    /// Index of the material called `name`.
    pub fn material_id(&self, name: &str) -> Option<usize> {
        self.material_names.iter().position(|n| n == name)
    }

    /// Index of the shape called `name`.
    pub fn shape_id(&self, name: &str) -> Option<usize> {
        self.shape_names.iter().position(|n| n == name)
    }

    /// Per shape of [`Scene::shapes`], whether some instance shows it.
    pub fn shapes_shown(&self) -> Vec<bool> {
        let mut shown = vec![false; self.shapes.len()];
        for instance in &self.instances {
            shown[instance.shape] = true;
        }
        shown
    }

    /// The shapes some instance shows, each once, in the order of
    /// [`Scene::shapes`]: what a pipeline must be able to draw. A shape
    /// the scene defines but no instance uses is left out.
    /// Yields each with its index.
    pub fn used_shapes(&self) -> impl Iterator<Item = (usize, &Shape)> {
        let shapes = self.shapes.iter().enumerate().zip(self.shapes_shown());
        shapes.filter_map(|(s, shown)| shown.then_some(s))
    }

    /// Per material of [`Scene::materials`], whether some visible surface
    /// can show it: the instances' own and those the leaves of their CSG
    /// shapes name.
    pub fn materials_shown(&self) -> Vec<bool> {
        let mut shown = vec![false; self.materials.len()];
        for instance in &self.instances {
            shown[instance.material] = true;
            if let Shape::Csg(csg) = &self.shapes[instance.shape] {
                for leaf in csg.root.leaves() {
                    if let Some(m) = leaf.material {
                        shown[m] = true;
                    }
                }
            }
        }
        shown
    }

    /// The materials some visible surface can show
    /// ([`Scene::materials_shown`]), each once, in the order of
    /// [`Scene::materials`]. A material no surface shows is left out.
    pub fn used_materials(&self) -> impl Iterator<Item = &Material> {
        (self.materials.iter().zip(self.materials_shown()))
            .filter_map(|(m, shown)| shown.then_some(m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Only what an instance shows counts as used: the instances' shapes
    /// and materials and the materials their CSG leaves name; a CSG shape
    /// no instance shows does not bring in its leaves' materials. Each is
    /// given once, in the scene's order: "drilled" is shown before "ball"
    /// and "plain" before "bore" (a leaf's), but each is defined after.
    #[test]
    fn used_shapes_and_materials_are_what_instances_show() {
        let ron = r#"(version: 1,
            camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 8, height: 8),
            lights: [],
            materials: { "bore": (base_color: (0.0, 0.0, 1.0), model: Toon(bands: 3)),
                         "plain": (base_color: (1.0, 1.0, 1.0), model: BlinnPhong),
                         "cut": (base_color: (1.0, 0.0, 0.0), model: BlinnPhong),
                         "mirror": (base_color: (1.0, 1.0, 1.0), model: BlinnPhong, reflectivity: 0.9) },
            shapes: { "ball": Sphere(radius: 1.0),
                      "crate": Box(half_extents: (1.0, 1.0, 1.0)),
                      "drilled": Difference(Sphere(radius: 1.0), Cylinder(radius: 0.3, height: 3.0, material: "bore")),
                      "notched": Difference(Box(half_extents: (1.0, 1.0, 1.0)), Sphere(radius: 0.5, material: "cut")) },
            instances: [(shape: "drilled", material: "plain"), (shape: "ball", material: "plain"),
                        (shape: "ball", material: "plain", transform: (translate: (3.0, 0.0, 0.0)))],
        )"#;
        let scene = Scene::from_ron_str(ron, "test", Path::new(".")).unwrap();
        let shapes: Vec<usize> = scene.used_shapes().map(|(id, _)| id).collect();
        let expect = ["ball", "drilled"].map(|n| scene.shape_id(n).unwrap());
        let mut expect = expect.to_vec();
        expect.sort();
        assert_eq!(shapes, expect, "each shown shape once, in order");
        let shown = |mask: Vec<bool>| -> Vec<usize> {
            (mask.iter().enumerate())
                .filter_map(|(i, s)| s.then_some(i))
                .collect()
        };
        assert_eq!(shown(scene.shapes_shown()), expect);
        let mut expect = ["plain", "bore"].map(|n| scene.material_id(n).unwrap());
        expect.sort();
        assert_eq!(shown(scene.materials_shown()), expect);
        let materials: Vec<&Material> = scene.used_materials().collect();
        let at: Vec<&Material> = expect.iter().map(|&i| &scene.materials[i]).collect();
        assert_eq!(materials, at, "the shown materials, in order");
    }

    /// The built-in scene still finds its cow when the assets directory is
    /// not there (binary run from elsewhere).
    #[test]
    fn builtin_default_falls_back_to_embedded_mesh() {
        let nowhere = Path::new("/nonexistent/celray/assets/scenes");
        let scene = convert::scene_from_str(
            Scene::BUILTIN_DEFAULT_RON,
            BUILTIN_FILE_NAME,
            nowhere,
            EMBEDDED_MESHES,
        )
        .unwrap();
        let on_disk = Scene::builtin_default();
        assert_eq!(scene.instances, on_disk.instances);
        let meshes: Vec<&Mesh> = scene
            .shapes
            .iter()
            .filter_map(|s| match s {
                Shape::Mesh(m) => Some(m),
                _ => None,
            })
            .collect();
        assert_eq!(meshes.len(), 1);
        assert_eq!(meshes[0].triangle_count(), 5856);
        assert!(meshes[0].source.contains("built-in"));

        // Without the embedded copy the same text fails with a clear error.
        let err = convert::scene_from_str(Scene::BUILTIN_DEFAULT_RON, "x.ron", nowhere, &[])
            .unwrap_err()
            .to_string();
        assert!(err.contains("spot_triangulated.obj") && err.contains("not found"));
    }
}
