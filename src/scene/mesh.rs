//! Triangle meshes and the OBJ / glTF loaders.

use std::collections::HashMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat3, Mat4, Vec2, Vec3};

use super::texture::srgb_to_linear;
use super::{MapSampler, SceneError, Texture};

/// [`Mesh::vertex_textures`] of a vertex without a map.
pub const NO_MESH_TEXTURE: u32 = u32::MAX;

/// An indexed triangle mesh in object space.
///
/// Front faces are counter-clockwise seen from outside; `normals` has one
/// unit normal per position.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals, `normals.len() == positions.len()`.
    pub normals: Vec<Vec3>,
    /// Three indices into `positions` per triangle.
    pub indices: Vec<u32>,
    /// Texture coordinates, one per position, or empty when the file has
    /// none. (0, 0) is the image's top-left corner, v grows downwards (glTF's
    /// convention; OBJ's v is flipped at load).
    pub uvs: Vec<Vec2>,
    /// Base-colour images of the file's own materials (glTF
    /// `baseColorTexture` with `baseColorFactor` multiplied in, OBJ `map_Kd`),
    /// shown where the instance's material has no image or pattern.
    pub textures: Vec<Arc<Texture>>,
    /// How each of `textures` is sampled (glTF samplers), parallel to it, or
    /// empty when every map takes the default (repeat, trilinear).
    pub texture_samplers: Vec<MapSampler>,
    /// Per vertex: an index into `textures`, or [`NO_MESH_TEXTURE`]; empty
    /// when the mesh has no textures.
    pub vertex_textures: Vec<u32>,
    /// Where the mesh came from (a file path, or e.g. `"tessellated sphere"`).
    pub source: String,
}

/// Nodes nested deeper than this in a glTF file are rejected (this also
/// stops cyclic node graphs).
const MAX_GLTF_DEPTH: usize = 64;

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Axis-aligned bounding box `(min, max)` of the positions;
    /// `(Vec3::ZERO, Vec3::ZERO)` for an empty mesh.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        if self.positions.is_empty() {
            return (Vec3::ZERO, Vec3::ZERO);
        }
        self.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    }

    /// Checks the invariants documented on the fields.
    pub fn validate(&self) -> Result<(), String> {
        if self.indices.is_empty() {
            return Err("mesh has no triangles".into());
        }
        if !self.indices.len().is_multiple_of(3) {
            return Err(format!(
                "mesh index count {} is not a multiple of 3",
                self.indices.len()
            ));
        }
        if self.normals.len() != self.positions.len() {
            return Err(format!(
                "mesh has {} normals for {} positions",
                self.normals.len(),
                self.positions.len()
            ));
        }
        if let Some(&bad) = self
            .indices
            .iter()
            .find(|&&i| i as usize >= self.positions.len())
        {
            return Err(format!(
                "mesh index {bad} is out of range ({} vertices)",
                self.positions.len()
            ));
        }
        if !self.uvs.is_empty() && self.uvs.len() != self.positions.len() {
            return Err(format!(
                "mesh has {} texture coordinates for {} positions",
                self.uvs.len(),
                self.positions.len()
            ));
        }
        if !self.vertex_textures.is_empty()
            && (self.vertex_textures.len() != self.positions.len()
                || self
                    .vertex_textures
                    .iter()
                    .any(|&t| t != NO_MESH_TEXTURE && t as usize >= self.textures.len()))
        {
            return Err("mesh has texture indices that do not match its vertices".into());
        }
        if !self.texture_samplers.is_empty() && self.texture_samplers.len() != self.textures.len() {
            return Err(format!(
                "mesh has {} texture samplers for {} textures",
                self.texture_samplers.len(),
                self.textures.len()
            ));
        }
        if !self.positions.iter().all(|p| p.is_finite()) {
            return Err("mesh has a non-finite position".into());
        }
        Ok(())
    }

    /// Loads a mesh file: Wavefront OBJ (`.obj`) or glTF 2.0
    /// (`.gltf` / `.glb`), chosen by extension.
    ///
    /// All objects / primitives of the file are merged into one mesh.
    /// Missing normals are computed with [`smooth_normals`].
    pub fn load(path: &Path) -> Result<Mesh, SceneError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("obj") => {
                let bytes = std::fs::read(path).map_err(|e| SceneError::MeshParse {
                    path: path.to_path_buf(),
                    reason: e.to_string(),
                })?;
                let mut mesh = Mesh::from_obj_bytes(&bytes, &path.display().to_string())?;
                obj_textures(&mut mesh, &bytes, path)?;
                Ok(mesh)
            }
            Some("gltf") | Some("glb") => Mesh::from_gltf_file(path),
            _ => Err(SceneError::MeshParse {
                path: path.to_path_buf(),
                reason: "unsupported mesh format; expected a .obj, .gltf or .glb file".into(),
            }),
        }
    }

    /// Parses Wavefront OBJ text. Faces are triangulated and all objects of
    /// the file are merged; material libraries are ignored. If any object
    /// has no normals, smooth normals are computed for the whole mesh.
    /// `source` is used in error messages and stored in [`Mesh::source`].
    pub fn from_obj_bytes(bytes: &[u8], source: &str) -> Result<Mesh, SceneError> {
        let parse_error = |reason: String| SceneError::MeshParse {
            path: source.into(),
            reason,
        };
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ..Default::default()
        };
        let (models, _materials) = tobj::load_obj_buf(&mut Cursor::new(bytes), &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| parse_error(format!("invalid OBJ: {e}")))?;

        let mut mesh = Mesh {
            source: source.to_string(),
            ..Default::default()
        };
        let mut all_have_normals = true;
        let mut uvs = Vec::new();
        let mut any_uvs = false;
        for model in &models {
            let m = &model.mesh;
            let base = u32::try_from(mesh.positions.len())
                .map_err(|_| parse_error("too many vertices".into()))?;
            let count = m.positions.len() / 3;
            mesh.positions.extend(
                m.positions
                    .chunks_exact(3)
                    .map(|p| Vec3::new(p[0], p[1], p[2])),
            );
            if m.texcoords.len() == count * 2 {
                any_uvs = true;
                uvs.extend(
                    m.texcoords
                        .chunks_exact(2)
                        .map(|t| Vec2::new(t[0], 1.0 - t[1])),
                );
            } else {
                uvs.extend(std::iter::repeat_n(Vec2::ZERO, count));
            }
            if m.normals.len() == m.positions.len() {
                mesh.normals.extend(
                    m.normals
                        .chunks_exact(3)
                        .map(|n| Vec3::new(n[0], n[1], n[2]).normalize_or(Vec3::Y)),
                );
            } else {
                all_have_normals = false;
                mesh.normals.extend(std::iter::repeat_n(Vec3::ZERO, count));
            }
            for &i in &m.indices {
                if i as usize >= count {
                    return Err(parse_error(format!(
                        "face index {} out of range in object \"{}\"",
                        i + 1,
                        model.name
                    )));
                }
                mesh.indices.push(base + i);
            }
        }
        if !all_have_normals {
            mesh.normals = smooth_normals(&mesh.positions, &mesh.indices);
        }
        if any_uvs {
            mesh.uvs = uvs;
        }
        finish(mesh)
    }

    /// Loads a glTF 2.0 file (`.gltf` with external or `data:` buffers, or
    /// `.glb`), with each material's base-colour image and its sampler
    /// (wrap and filter modes).
    ///
    /// The node tree of the default scene (or the first scene) is walked,
    /// node transforms are applied (normals with the inverse transpose) and
    /// all primitives with mode `Triangles` are merged into one mesh.
    pub fn from_gltf_file(path: &Path) -> Result<Mesh, SceneError> {
        let parse_error = |reason: String| SceneError::MeshParse {
            path: path.to_path_buf(),
            reason,
        };
        let gltf::Gltf { document, blob } =
            gltf::Gltf::open(path).map_err(|e| parse_error(format!("invalid glTF: {e}")))?;
        let base = path.parent().unwrap_or(Path::new("."));
        let buffers = gltf::import_buffers(&document, Some(base), blob).map_err(|e| {
            let files: Vec<String> = document
                .buffers()
                .filter_map(|b| match b.source() {
                    gltf::buffer::Source::Uri(uri) if !uri.starts_with("data:") => {
                        Some(base.join(uri).display().to_string())
                    }
                    _ => None,
                })
                .collect();
            if files.is_empty() {
                parse_error(format!("cannot read glTF buffers: {e}"))
            } else {
                parse_error(format!(
                    "cannot read glTF buffers (from {}): {e}",
                    files.join(", ")
                ))
            }
        })?;

        let scene = document
            .default_scene()
            .or_else(|| document.scenes().next())
            .ok_or_else(|| parse_error("the file has no scene".into()))?;

        let mut mesh = Mesh {
            source: path.display().to_string(),
            ..Default::default()
        };
        let mut maps = GltfMaps {
            path,
            base,
            buffers: &buffers,
            images: HashMap::new(),
            loaded: HashMap::new(),
        };
        let mut stack: Vec<(gltf::Node, Mat4, usize)> =
            scene.nodes().map(|n| (n, Mat4::IDENTITY, 0)).collect();
        while let Some((node, parent, depth)) = stack.pop() {
            if depth > MAX_GLTF_DEPTH {
                return Err(parse_error(format!(
                    "node hierarchy deeper than {MAX_GLTF_DEPTH} levels (cyclic?)"
                )));
            }
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            if let Some(gmesh) = node.mesh() {
                for primitive in gmesh.primitives() {
                    if primitive.mode() == gltf::mesh::Mode::Triangles {
                        let first = mesh.positions.len();
                        append_gltf_primitive(&mut mesh, &primitive, &buffers, world)
                            .map_err(&parse_error)?;
                        let map = maps.material_map(&mut mesh, &primitive.material())?;
                        if map != NO_MESH_TEXTURE || !mesh.vertex_textures.is_empty() {
                            mesh.vertex_textures.resize(first, NO_MESH_TEXTURE);
                            mesh.vertex_textures.resize(mesh.positions.len(), map);
                        }
                    }
                }
            }
            stack.extend(node.children().map(|c| (c, world, depth + 1)));
        }
        finish(mesh)
    }
}

/// The base-colour maps of a glTF file's materials, loaded once each.
struct GltfMaps<'a> {
    path: &'a Path,
    base: &'a Path,
    buffers: &'a [gltf::buffer::Data],
    /// (glTF image index, baseColorFactor bits) -> the decoded image:
    /// materials sharing an image and factor share the texture.
    images: HashMap<(usize, [u32; 3]), Arc<Texture>>,
    /// (image key, sampler) -> index into the mesh's textures.
    loaded: HashMap<((usize, [u32; 3]), MapSampler), u32>,
}

impl GltfMaps<'_> {
    /// The mesh texture of `material` (loading it the first time), or
    /// [`NO_MESH_TEXTURE`] when it has no base-colour texture.
    fn material_map(
        &mut self,
        mesh: &mut Mesh,
        material: &gltf::Material,
    ) -> Result<u32, SceneError> {
        let pbr = material.pbr_metallic_roughness();
        let Some(info) = pbr.base_color_texture() else {
            return Ok(NO_MESH_TEXTURE);
        };
        let factor = pbr.base_color_factor();
        let key = (
            info.texture().source().index(),
            [factor[0], factor[1], factor[2]].map(f32::to_bits),
        );
        let sampler = MapSampler::from_gltf(&info.texture().sampler());
        if let Some(&i) = self.loaded.get(&(key, sampler)) {
            return Ok(i);
        }
        if let Some(texture) = self.images.get(&key) {
            return Ok(self.add(mesh, key, texture.clone(), sampler));
        }
        let name = material
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("glTF material {}", material.index().unwrap_or(0)));
        let image = info.texture().source();
        let file_name = self.path.display().to_string();
        let (bytes, image_path, source): (Vec<u8>, PathBuf, String) = match image.source() {
            gltf::image::Source::View { view, .. } => {
                let data = self
                    .buffers
                    .get(view.buffer().index())
                    .map(|d| d.0.as_slice())
                    .unwrap_or(&[]);
                let bytes = data
                    .get(view.offset()..view.offset() + view.length())
                    .ok_or_else(|| SceneError::Texture {
                        path: self.path.to_path_buf(),
                        material: name.clone(),
                        reason: format!("image {} lies outside its buffer", image.index()),
                    })?;
                (
                    bytes.to_vec(),
                    self.path.to_path_buf(),
                    format!("{file_name} image {}", image.index()),
                )
            }
            gltf::image::Source::Uri { uri, .. } => {
                if let Some(data) = uri.strip_prefix("data:") {
                    let encoded = data.split_once(";base64,").map(|(_, b)| b).ok_or_else(|| {
                        SceneError::Texture {
                            path: self.path.to_path_buf(),
                            material: name.clone(),
                            reason: "a data: image URI that is not base64".into(),
                        }
                    })?;
                    use base64::Engine;
                    let bytes = base64::engine::general_purpose::STANDARD
                        .decode(encoded)
                        .map_err(|e| SceneError::Texture {
                            path: self.path.to_path_buf(),
                            material: name.clone(),
                            reason: format!("bad base64 in a data: image URI: {e}"),
                        })?;
                    (
                        bytes,
                        self.path.to_path_buf(),
                        format!("{file_name} image {}", image.index()),
                    )
                } else {
                    let file = self.base.join(uri);
                    let bytes = std::fs::read(&file).map_err(|e| SceneError::Texture {
                        path: file.clone(),
                        material: name.clone(),
                        reason: e.to_string(),
                    })?;
                    let source = file.display().to_string();
                    (bytes, file, source)
                }
            }
        };
        let mut texture = Texture::decode(&bytes, Path::new(&source), &name)?;
        texture.source = source;
        texture.path = image_path;
        if factor[..3] != [1.0, 1.0, 1.0] {
            multiply_linear(&mut texture, Vec3::new(factor[0], factor[1], factor[2]));
        }
        let texture = Arc::new(texture);
        self.images.insert(key, texture.clone());
        Ok(self.add(mesh, key, texture, sampler))
    }

    /// Adds `texture` sampled by `sampler` to the mesh's maps.
    fn add(
        &mut self,
        mesh: &mut Mesh,
        key: (usize, [u32; 3]),
        texture: Arc<Texture>,
        sampler: MapSampler,
    ) -> u32 {
        let index = mesh.textures.len() as u32;
        mesh.textures.push(texture);
        mesh.texture_samplers.push(sampler);
        self.loaded.insert((key, sampler), index);
        index
    }
}

/// Multiplies every texel by `factor` in linear light (sRGB re-encoded).
fn multiply_linear(texture: &mut Texture, factor: Vec3) {
    for px in texture.rgba8.chunks_exact_mut(4) {
        for c in 0..3 {
            let v = (srgb_to_linear(px[c]) * factor[c]).clamp(0.0, 1.0);
            let s = if v <= 0.003_130_8 {
                v * 12.92
            } else {
                1.055 * v.powf(1.0 / 2.4) - 0.055
            };
            px[c] = (s * 255.0 + 0.5) as u8;
        }
    }
}

/// Reads the `map_Kd` images of an OBJ file's material library (`mtllib`,
/// relative to the OBJ) and assigns them to the vertices of the objects
/// that use them. A missing library or image is an error naming the file
/// and the material.
fn obj_textures(mesh: &mut Mesh, bytes: &[u8], path: &Path) -> Result<(), SceneError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let library_error = std::cell::RefCell::new(None);
    let (models, materials) = tobj::load_obj_buf(&mut Cursor::new(bytes), &options, |lib| {
        let file = dir.join(lib);
        let loaded = tobj::load_mtl(&file);
        if let Err(e) = &loaded {
            *library_error.borrow_mut() = Some((file, e.to_string()));
        }
        loaded
    })
    .map_err(|e| SceneError::MeshParse {
        path: path.to_path_buf(),
        reason: format!("invalid OBJ: {e}"),
    })?;
    if let Some((file, reason)) = library_error.into_inner() {
        return Err(SceneError::MeshParse {
            path: path.to_path_buf(),
            reason: format!(
                "cannot read its material library {}: {reason}",
                file.display()
            ),
        });
    }
    let materials = materials.map_err(|e| SceneError::MeshParse {
        path: path.to_path_buf(),
        reason: format!("invalid material library: {e}"),
    })?;
    let mut loaded: HashMap<usize, u32> = HashMap::new();
    let mut vertex_textures = Vec::with_capacity(mesh.positions.len());
    for model in &models {
        let count = model.mesh.positions.len() / 3;
        let mut map = NO_MESH_TEXTURE;
        if let Some(id) = model.mesh.material_id {
            if let Some(&i) = loaded.get(&id) {
                map = i;
            } else if let Some(material) = materials.get(id) {
                if let Some(file) = &material.diffuse_texture {
                    let file = dir.join(file.trim());
                    let texture = Texture::load(&file, &material.name)?;
                    map = mesh.textures.len() as u32;
                    mesh.textures.push(Arc::new(texture));
                }
                loaded.insert(id, map);
            }
        }
        vertex_textures.extend(std::iter::repeat_n(map, count));
    }
    if !mesh.textures.is_empty() && vertex_textures.len() == mesh.positions.len() {
        mesh.vertex_textures = vertex_textures;
    }
    Ok(())
}

/// Adds one glTF primitive, transformed by `world`, to `mesh`.
fn append_gltf_primitive(
    mesh: &mut Mesh,
    primitive: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    world: Mat4,
) -> Result<(), String> {
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| d.0.as_slice()));
    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or("a triangle primitive has no POSITION attribute")?
        .map(|p| world.transform_point3(Vec3::from(p)))
        .collect();
    let count = u32::try_from(positions.len()).map_err(|_| "too many vertices")?;
    let mut indices: Vec<u32> = match reader.read_indices() {
        Some(ix) => ix.into_u32().collect(),
        None => (0..count).collect(),
    };
    indices.truncate(indices.len() / 3 * 3);
    if let Some(&bad) = indices.iter().find(|&&i| i >= count) {
        return Err(format!(
            "index {bad} out of range in a primitive with {count} vertices"
        ));
    }
    // A mirroring transform flips the winding; swap two corners to keep
    // front faces counter-clockwise.
    if world.determinant() < 0.0 {
        for tri in indices.chunks_exact_mut(3) {
            tri.swap(1, 2);
        }
    }
    let normals: Vec<Vec3> = match reader.read_normals() {
        Some(ns) => {
            let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
            ns.map(|n| (normal_matrix * Vec3::from(n)).normalize_or(Vec3::Y))
                .collect()
        }
        None => smooth_normals(&positions, &indices),
    };
    if normals.len() != positions.len() {
        return Err("NORMAL and POSITION attributes have different lengths".into());
    }
    let base = u32::try_from(mesh.positions.len()).map_err(|_| "too many vertices")?;
    let tex_coord = primitive
        .material()
        .pbr_metallic_roughness()
        .base_color_texture()
        .map_or(0, |t| t.tex_coord());
    let uvs: Vec<Vec2> = match reader.read_tex_coords(tex_coord) {
        Some(tc) => tc.into_f32().map(Vec2::from).collect(),
        None => Vec::new(),
    };
    if !uvs.is_empty() && uvs.len() != positions.len() {
        return Err("TEXCOORD and POSITION attributes have different lengths".into());
    }
    // Keep `uvs` parallel to `positions` across primitives with and without.
    if !uvs.is_empty() && mesh.uvs.len() < mesh.positions.len() {
        mesh.uvs.resize(mesh.positions.len(), Vec2::ZERO);
    }
    if !mesh.uvs.is_empty() || !uvs.is_empty() {
        let n = positions.len();
        mesh.uvs.extend(uvs);
        mesh.uvs.resize(mesh.positions.len() + n, Vec2::ZERO);
    }
    mesh.positions.extend(positions);
    mesh.normals.extend(normals);
    mesh.indices.extend(indices.iter().map(|i| base + i));
    Ok(())
}

/// Final checks shared by the loaders.
fn finish(mesh: Mesh) -> Result<Mesh, SceneError> {
    match mesh.validate() {
        Ok(()) => {
            log::debug!(
                "loaded mesh {}: {} vertices, {} triangles",
                mesh.source,
                mesh.positions.len(),
                mesh.triangle_count()
            );
            Ok(mesh)
        }
        Err(reason) => Err(SceneError::MeshParse {
            path: mesh.source.clone().into(),
            reason,
        }),
    }
}

/// Smooth, area-weighted vertex normals for a counter-clockwise triangle
/// list.
///
/// Vertices at the same position share their normal (so seams where a file
/// splits vertices, e.g. for texture coordinates, stay smooth). A vertex
/// that touches no non-degenerate triangle gets +y.
pub fn smooth_normals(positions: &[Vec3], indices: &[u32]) -> Vec<Vec3> {
    // Weld vertices by exact position.
    let mut slot_of_position: HashMap<[u32; 3], usize> = HashMap::new();
    let slots: Vec<usize> = positions
        .iter()
        .map(|p| {
            let next = slot_of_position.len();
            *slot_of_position
                .entry(p.to_array().map(f32::to_bits))
                .or_insert(next)
        })
        .collect();

    // The cross product's length is twice the triangle area: summing
    // unnormalised face normals weights them by area.
    let mut sums = vec![Vec3::ZERO; slot_of_position.len()];
    for tri in indices.chunks_exact(3) {
        let [a, b, c] = [tri[0], tri[1], tri[2]].map(|i| i as usize);
        if a >= positions.len() || b >= positions.len() || c >= positions.len() {
            continue;
        }
        let n = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        for v in [a, b, c] {
            sums[slots[v]] += n;
        }
    }
    slots
        .iter()
        .map(|&s| sums[s].normalize_or(Vec3::Y))
        .collect()
}
