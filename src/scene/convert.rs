//! Turns parsed file types into a [`Scene`]: resolves names, loads meshes,
//! applies defaults and validates.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::Mat4;

use super::file::{
    ron_options, ApertureFile, CameraFile, CsgFile, LightFile, MaterialFile, ModelFile,
    PatternFile, PlaneFile, SceneFile, ShapeFile, TextureFilterFile, TransformFile, VersionProbe,
    MAX_NESTING, SCENE_FORMAT_VERSION,
};
use super::{
    ApertureShape, BaseColorTexture, Camera, Csg, CsgLeaf, CsgNode, Instance, Light, Material,
    Mesh, Pattern, PlaneKind, Rim, Scene, SceneError, ShadingModel, Shape, Texture, TextureFilter,
    Toon, MAX_TEXTURES, MAX_TOON_BANDS,
};

/// Outline width of toon materials that do not give one.
const DEFAULT_TOON_OUTLINE_PX: f32 = 1.5;

/// Parses, converts and validates scene text.
///
/// `embedded` maps mesh paths, exactly as written in the file, to file
/// bytes used when the resolved path does not exist.
pub(crate) fn scene_from_str(
    src: &str,
    file_name: &str,
    base_dir: &Path,
    embedded: &[(&str, &[u8])],
) -> Result<Scene, SceneError> {
    let options = ron_options();
    let syntax_error = |e: ron::error::SpannedError| {
        let position = start_of_bad_name(src, &e);
        SceneError::Syntax {
            file: file_name.to_string(),
            line: position.line,
            col: position.col,
            message: match e.code {
                // ron's own text advises whoever builds celray.
                ron::Error::ExceededRecursionLimit => format!(
                    "nested too deeply: brackets and parentheses may nest at most \
                     {MAX_NESTING} levels in a scene file, and this file goes deeper here"
                ),
                code => code.to_string(),
            },
        }
    };

    // Check the version first, so that a newer file says so instead of
    // failing on its first new field.
    if let Ok(VersionProbe {
        version: Some(found),
    }) = options.from_str::<VersionProbe>(src)
    {
        if found != SCENE_FORMAT_VERSION {
            return Err(SceneError::UnsupportedVersion {
                file: file_name.to_string(),
                found,
                supported: SCENE_FORMAT_VERSION,
            });
        }
    }
    let file: SceneFile = options.from_str(src).map_err(syntax_error)?;
    if file.version != SCENE_FORMAT_VERSION {
        return Err(SceneError::UnsupportedVersion {
            file: file_name.to_string(),
            found: file.version,
            supported: SCENE_FORMAT_VERSION,
        });
    }

    let mut meshes = MeshLoader {
        base_dir,
        scene_file: file_name,
        embedded,
        cache: HashMap::new(),
        textures: Vec::new(),
    };
    let scene = convert(file, file_name, &mut meshes).map_err(|e| e.in_file(file_name))?;
    scene.validate().map_err(|e| e.in_file(file_name))?;
    log::info!(
        "loaded scene {file_name}: {} instances, {} shapes, {} materials, {} lights",
        scene.instances.len(),
        scene.shapes.len(),
        scene.materials.len(),
        scene.lights.len()
    );
    Ok(scene)
}

/// RON reports an unknown field or variant at the end of its name; move
/// the position back to where the name starts, which is where the user has
/// to look.
fn start_of_bad_name(src: &str, e: &ron::error::SpannedError) -> ron::error::Position {
    let position = e.position;
    let name = match &e.code {
        ron::Error::NoSuchStructField { found, .. }
        | ron::Error::NoSuchEnumVariant { found, .. } => found,
        _ => return position,
    };
    let Some(line) = src.lines().nth(position.line.saturating_sub(1)) else {
        return position;
    };
    let before: String = line.chars().take(position.col.saturating_sub(1)).collect();
    if before.ends_with(name.as_str()) {
        ron::error::Position {
            line: position.line,
            col: position.col - name.chars().count(),
        }
    } else {
        position
    }
}

fn convert(file: SceneFile, file_name: &str, meshes: &mut MeshLoader) -> Result<Scene, SceneError> {
    let lights = file
        .lights
        .into_iter()
        .enumerate()
        .map(|(i, light)| {
            convert_light(light).map_err(|m| SceneError::invalid(format!("light {i}"), m))
        })
        .collect::<Result<Vec<_>, _>>()?;

    let mut materials = Vec::new();
    let mut material_names = Vec::new();
    for (name, mut material) in file.materials.0 {
        let filter = match material.texture_filter {
            TextureFilterFile::Linear => TextureFilter::Linear,
            TextureFilterFile::Nearest => TextureFilter::Nearest,
        };
        let texture = match material.base_color_texture.take() {
            Some(relative) => Some(BaseColorTexture {
                texture: meshes.texture(&relative, &name)?,
                filter,
            }),
            None => None,
        };
        let mut material = convert_material(material)
            .map_err(|m| SceneError::invalid(format!("material \"{name}\""), m))?;
        material.base_color_texture = texture;
        materials.push(material);
        material_names.push(name);
    }

    let mut shapes = Vec::new();
    let mut shape_names = Vec::new();
    for (name, shape) in file.shapes.0 {
        shapes.push(convert_shape(shape, &name, meshes, &material_names)?);
        shape_names.push(name);
    }
    // Meshes' own maps share the texture array with the materials' images.
    let mut images: Vec<Arc<Texture>> = meshes.textures.clone();
    for (shape, name) in shapes.iter().zip(&shape_names) {
        let Shape::Mesh(mesh) = shape else { continue };
        for t in &mesh.textures {
            if images.iter().any(|i| Arc::ptr_eq(i, t)) {
                continue;
            }
            if images.len() >= MAX_TEXTURES {
                return Err(SceneError::Texture {
                    path: t.path.clone(),
                    material: format!("{} (mesh of shape \"{name}\")", t.source),
                    reason: format!(
                        "too many textures: a scene may use at most {MAX_TEXTURES} images"
                    ),
                });
            }
            images.push(t.clone());
        }
    }

    let mut instances = Vec::new();
    for (i, instance) in file.instances.into_iter().enumerate() {
        let lookup = |kind: &'static str, names: &[String], name: &str| {
            names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| SceneError::UnknownName {
                    file: file_name.to_string(),
                    instance: i,
                    kind,
                    name: name.to_string(),
                    available: list_names(names),
                })
        };
        instances.push(Instance {
            shape: lookup("shape", &shape_names, &instance.shape)?,
            material: lookup("material", &material_names, &instance.material)?,
            world_from_object: transform_matrix(&instance.transform),
            world_from_object_end: instance.transform_end.as_ref().map(transform_matrix),
        });
    }

    Ok(Scene {
        camera: convert_camera(file.camera),
        ambient: file.ambient,
        background: file.background,
        lights,
        materials,
        material_names,
        shapes,
        shape_names,
        instances,
    })
}

/// `"a", "b"` or `(none)`.
fn list_names(names: &[String]) -> String {
    if names.is_empty() {
        "(none)".to_string()
    } else {
        names
            .iter()
            .map(|n| format!("\"{n}\""))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

fn convert_camera(c: CameraFile) -> Camera {
    Camera {
        eye: c.eye,
        target: c.target,
        up: c.up,
        fov_y_deg: c.fov_y_deg,
        width: c.width,
        height: c.height,
        // A lens of focal length f at f-number N has an aperture of diameter
        // f / N; scene units are metres.
        aperture_radius: match (c.f_number, c.focal_length_mm) {
            (Some(n), Some(f)) if n > 0.0 => f * 1e-3 / (2.0 * n),
            _ => c.aperture_radius,
        },
        focus_distance: c.focus_distance,
        aperture: match c.aperture {
            ApertureFile::Disk => ApertureShape::Disk,
            ApertureFile::Square => ApertureShape::Square,
            ApertureFile::Polygon {
                blades,
                rotation_deg,
            } => ApertureShape::Polygon {
                blades,
                rotation_deg,
            },
        },
        shutter_open_s: c.shutter_open_s,
        shutter_close_s: c.shutter_close_s,
        eye_end: c.eye_end,
        target_end: c.target_end,
    }
}

/// Normalises the direction of directional lights.
fn convert_light(light: LightFile) -> Result<Light, String> {
    Ok(match light {
        LightFile::Directional {
            direction,
            color,
            intensity,
            cast_shadows,
        } => {
            let unit = direction.try_normalize().ok_or_else(|| {
                format!(
                    "direction must be a finite, non-zero vector, got ({}, {}, {})",
                    direction.x, direction.y, direction.z
                )
            })?;
            Light::Directional {
                direction: unit,
                color,
                intensity,
                cast_shadows,
            }
        }
        LightFile::Point {
            position,
            color,
            intensity,
            cast_shadows,
        } => Light::Point {
            position,
            color,
            intensity,
            cast_shadows,
        },
    })
}

fn convert_material(m: MaterialFile) -> Result<Material, String> {
    let model = match m.model {
        ModelFile::BlinnPhong => ShadingModel::BlinnPhong,
        ModelFile::Toon {
            bands,
            thresholds,
            specular_threshold,
            rim,
        } => {
            let thresholds = match (bands, thresholds) {
                (Some(_), Some(_)) => {
                    return Err("Toon: give either `bands` or `thresholds`, not both".to_string())
                }
                (None, None) => {
                    return Err(
                        "Toon: give `bands: N` (even bands) or `thresholds: [..]`".to_string()
                    )
                }
                (Some(n), None) => {
                    if !(1..=MAX_TOON_BANDS).contains(&n) {
                        return Err(format!(
                            "toon bands must be in 1..={MAX_TOON_BANDS}, got {n}"
                        ));
                    }
                    Toon::even(n).thresholds
                }
                (None, Some(t)) => t,
            };
            ShadingModel::Toon(Toon {
                thresholds,
                specular_threshold,
                rim: rim.map(|r| Rim {
                    color: r.color,
                    threshold: r.threshold,
                }),
            })
        }
    };
    let default_outline = match model {
        ShadingModel::Toon(_) => DEFAULT_TOON_OUTLINE_PX,
        ShadingModel::BlinnPhong => 0.0,
    };
    Ok(Material {
        base_color: m.base_color,
        specular_color: m.specular_color,
        shininess: m.shininess,
        model,
        outline_color: m.outline_color,
        outline_width_px: m.outline_width_px.unwrap_or(default_outline),
        reflectivity: m.reflectivity,
        roughness: m.roughness,
        base_color_texture: None,
        uv_scale: m.uv_scale,
        base_color_pattern: m.base_color_pattern.map(|p| match p {
            PatternFile::Checker { a, b, size } => Pattern::Checker { a, b, size },
        }),
    })
}

fn convert_shape(
    shape: ShapeFile,
    name: &str,
    meshes: &mut MeshLoader,
    material_names: &[String],
) -> Result<Shape, SceneError> {
    let mut csg = |root: CsgFile| -> Result<Shape, SceneError> {
        Ok(Shape::Csg(Csg {
            root: Box::new(convert_csg(root, name, meshes, material_names)?),
        }))
    };
    Ok(match shape {
        ShapeFile::Sphere { radius } => Shape::Sphere { radius },
        ShapeFile::Box { half_extents } => Shape::Box { half_extents },
        ShapeFile::Cylinder { radius, height } => Shape::Cylinder { radius, height },
        ShapeFile::Cone { radius, height } => Shape::Cone { radius, height },
        ShapeFile::Plane(PlaneFile::Quad { half_size }) => {
            Shape::Plane(PlaneKind::Quad { half_size })
        }
        ShapeFile::Plane(PlaneFile::Disk { radius }) => Shape::Plane(PlaneKind::Disk { radius }),
        ShapeFile::Mesh { path } => Shape::Mesh(meshes.load(&path, name)?),
        ShapeFile::Union(children) => csg(CsgFile::Union(children))?,
        ShapeFile::Intersection(children) => csg(CsgFile::Intersection(children))?,
        ShapeFile::Difference(a, b) => csg(CsgFile::Difference(a, b))?,
    })
}

/// A CSG tree from its file form: resolves leaf material names and loads
/// mesh leaves (closedness and bounds are checked by validation).
fn convert_csg(
    node: CsgFile,
    shape_name: &str,
    meshes: &mut MeshLoader,
    material_names: &[String],
) -> Result<CsgNode, SceneError> {
    let children = |list: Vec<CsgFile>, meshes: &mut MeshLoader| {
        list.into_iter()
            .map(|c| convert_csg(c, shape_name, meshes, material_names))
            .collect::<Result<Vec<_>, _>>()
    };
    let (shape, transform, material) = match node {
        CsgFile::Union(list) => return Ok(CsgNode::Union(children(list, meshes)?)),
        CsgFile::Intersection(list) => return Ok(CsgNode::Intersection(children(list, meshes)?)),
        CsgFile::Difference(a, b) => {
            return Ok(CsgNode::Difference(
                Box::new(convert_csg(*a, shape_name, meshes, material_names)?),
                Box::new(convert_csg(*b, shape_name, meshes, material_names)?),
            ))
        }
        CsgFile::Sphere {
            radius,
            transform,
            material,
        } => (Shape::Sphere { radius }, transform, material),
        CsgFile::Box {
            half_extents,
            transform,
            material,
        } => (Shape::Box { half_extents }, transform, material),
        CsgFile::Cylinder {
            radius,
            height,
            transform,
            material,
        } => (Shape::Cylinder { radius, height }, transform, material),
        CsgFile::Cone {
            radius,
            height,
            transform,
            material,
        } => (Shape::Cone { radius, height }, transform, material),
        CsgFile::Mesh {
            path,
            transform,
            material,
        } => (
            Shape::Mesh(meshes.load(&path, shape_name)?),
            transform,
            material,
        ),
        CsgFile::Plane(_) => {
            return Err(SceneError::invalid(
                format!("shape \"{shape_name}\""),
                "a plane has no inside and cannot be a CSG leaf; use a thin Box",
            ))
        }
    };
    let material = match material {
        None => None,
        Some(m) => Some(material_names.iter().position(|n| *n == m).ok_or_else(|| {
            SceneError::invalid(
                format!("shape \"{shape_name}\""),
                format!(
                    "CSG leaf material \"{m}\" is not defined; available materials: {}",
                    list_names(material_names)
                ),
            )
        })?),
    };
    Ok(CsgNode::Leaf(CsgLeaf {
        shape,
        csg_from_leaf: transform_matrix(&transform),
        material,
    }))
}

/// `T * Rz * Ry * Rx * S` for the TRS form; the transpose of the rows for
/// the matrix form.
fn transform_matrix(t: &TransformFile) -> Mat4 {
    match t {
        TransformFile::Trs(trs) => {
            let r = trs.rotate_deg * (std::f32::consts::PI / 180.0);
            Mat4::from_translation(trs.translate)
                * Mat4::from_rotation_z(r.z)
                * Mat4::from_rotation_y(r.y)
                * Mat4::from_rotation_x(r.x)
                * Mat4::from_scale(trs.scale)
        }
        TransformFile::Matrix(rows) => Mat4::from_cols_array_2d(rows).transpose(),
    }
}

/// Loads mesh files relative to the scene's directory, once per path.
struct MeshLoader<'a> {
    base_dir: &'a Path,
    scene_file: &'a str,
    embedded: &'a [(&'a str, &'a [u8])],
    cache: HashMap<PathBuf, Mesh>,
    /// Images loaded so far (one per path), counted against MAX_TEXTURES.
    textures: Vec<Arc<Texture>>,
}

impl MeshLoader<'_> {
    /// Loads an image once per path; refuses more than MAX_TEXTURES.
    fn texture(&mut self, relative: &str, material: &str) -> Result<Arc<Texture>, SceneError> {
        let path = self.base_dir.join(relative);
        let texture = if let Some(t) = self.textures.iter().find(|t| t.path == path) {
            t.clone()
        } else {
            if self.textures.len() >= MAX_TEXTURES {
                return Err(SceneError::Texture {
                    path,
                    material: material.to_string(),
                    reason: format!(
                        "too many textures: a scene may use at most {MAX_TEXTURES} images"
                    ),
                });
            }
            let t = Arc::new(Texture::load(&path, material)?);
            self.textures.push(t.clone());
            t
        };
        Ok(texture)
    }

    fn load(&mut self, relative: &str, shape: &str) -> Result<Mesh, SceneError> {
        let path = self.base_dir.join(relative);
        if let Some(mesh) = self.cache.get(&path) {
            return Ok(mesh.clone());
        }
        let mesh = if path.is_file() {
            Mesh::load(&path)?
        } else if let Some((_, bytes)) = self.embedded.iter().find(|(p, _)| *p == relative) {
            log::debug!("{} not on disk; using the compiled-in copy", path.display());
            Mesh::from_obj_bytes(bytes, &format!("<built-in {relative}>"))?
        } else {
            return Err(SceneError::MeshNotFound {
                path,
                shape: shape.to_string(),
                scene: self.scene_file.to_string(),
            });
        };
        log::info!(
            "mesh \"{shape}\": {} ({} triangles)",
            mesh.source,
            mesh.triangle_count()
        );
        self.cache.insert(path, mesh.clone());
        Ok(mesh)
    }
}
