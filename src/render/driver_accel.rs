//! The scene as the driver's acceleration structures, for the driver
//! variant of the ray-traced passes (wgpu ray queries,
//! `shaders/lib/trace_rq.wgsl`): the lecture's instancing done by the driver.
//!
//! - One bottom level (BLAS) per base shape that some instance uses: a
//!   mesh's triangles (in the order of celray's own triangle buffer, so the
//!   shader finds vertex normals at `rq_mesh_base[shape] + primitive`); one
//!   AABB for an analytic or CSG shape, whose candidate runs the exact
//!   intersection or the interval program in WGSL.
//! - One top-level (TLAS) instance per GPU instance: its world_from_object
//!   as the 3x4 transform, the GPU instance index as the custom index, mask
//!   [`MASK_MESH`] or [`MASK_OTHER`] (hybrid primary rays skip meshes).
//! - Motion blur: [`DriverAccel::encode_motion`] writes each instance's
//!   transform at the sample's shutter time and rebuilds the top level.
//! - Bindings: a driver-variant pass has the scene's group 0 and its own
//!   group 1 like the software variant, plus [`DRIVER_LAYOUT`] as group
//!   [`DRIVER_GROUP`] (`scene_tlas`, `rq_mesh_base` in trace_rq.wgsl).

use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

use crate::gpu::Gpu;
use crate::render::scene_buffers::SceneBuffers;
use crate::scene::{Scene, Shape};

/// Top-level mask of mesh instances (`RQ_MASK_MESH` in trace_rq.wgsl).
pub const MASK_MESH: u8 = 1;
/// Top-level mask of every other instance (`RQ_MASK_OTHER`).
pub const MASK_OTHER: u8 = 2;
/// The custom index of a top-level instance has 24 bits.
const MAX_CUSTOM_INDEX: usize = 1 << 24;

/// Sizes and times of a build, for the benchmark.
#[derive(Debug, Clone, Copy, Default)]
pub struct DriverAccelStats {
    /// Bottom levels built (one per used base shape).
    pub blas_count: usize,
    /// Top-level instances.
    pub instance_count: usize,
    /// Triangles and AABBs in the bottom levels.
    pub primitive_count: u64,
    /// Wall milliseconds from the start of the upload to the finished build
    /// (waited for), bottom and top levels together.
    pub build_ms: f64,
    /// Bytes of the build inputs celray uploads (vertex, AABB and
    /// per-shape buffers). wgpu 30 does not report the size the driver
    /// gives the structures themselves.
    pub input_bytes: u64,
}

pub struct DriverAccel {
    /// Kept alive for the top level, which refers to them.
    _blases: Vec<wgpu::Blas>,
    pub tlas: wgpu::Tlas,
    /// Per base shape: index of a mesh's first triangle in `triangles`.
    pub mesh_base: wgpu::Buffer,
    _vertices: Option<wgpu::Buffer>,
    _aabbs: Option<wgpu::Buffer>,
    /// Per top-level instance: the scene instance it is.
    instance_order: Vec<usize>,
    pub stats: DriverAccelStats,
}

/// A row-major 3x4 matrix (what a top-level instance takes) from `m`.
fn rows_3x4(m: Mat4) -> [f32; 12] {
    let t = m.transpose().to_cols_array();
    let mut out = [0.0; 12];
    out.copy_from_slice(&t[..12]);
    out
}

/// The range of `accel.triangles` a mesh's bottom-level BVH (rooted at
/// `root`) covers; its leaves hold one contiguous range.
fn mesh_triangle_range(nodes: &[crate::gpu::twins::BvhNode], root: u32) -> Option<(u32, u32)> {
    let mut stack = vec![root];
    let (mut lo, mut hi, mut total) = (u32::MAX, 0u32, 0u32);
    while let Some(i) = stack.pop() {
        let n = nodes.get(i as usize)?;
        if n.count > 0 {
            lo = lo.min(n.left_or_first);
            hi = hi.max(n.left_or_first + n.count);
            total += n.count;
        } else {
            stack.push(n.left_or_first);
            stack.push(n.left_or_first + 1);
        }
    }
    (total > 0 && hi - lo == total).then_some((lo, total))
}

/// The group of the driver's structures in a driver-variant pass.
pub const DRIVER_GROUP: u32 = 2;

/// Group [`DRIVER_GROUP`] of a driver-variant pass: the top level and the
/// per-shape mesh bases (`scene_tlas`, `rq_mesh_base` in trace_rq.wgsl).
pub const DRIVER_LAYOUT: [wgpu::BindGroupLayoutEntry; 2] = [
    wgpu::BindGroupLayoutEntry {
        binding: 0,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::AccelerationStructure {
            vertex_return: false,
        },
        count: None,
    },
    crate::gpu::layout::read_only_storage_entry(1, wgpu::ShaderStages::COMPUTE),
];

/// The layout of group [`DRIVER_GROUP`] ([`DRIVER_LAYOUT`]).
pub fn bind_group_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    gpu.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("driver accel layout"),
            entries: &DRIVER_LAYOUT,
        })
}

/// A driver-variant pass's pipeline: `module` (composed with
/// [`crate::gpu::shader::Traversal::Driver`]) over `own` (the scene's
/// layout and the pass's own, groups 0 and 1), then [`bind_group_layout`]
/// as group [`DRIVER_GROUP`], with override `constants`.
pub fn pipeline(
    gpu: &Gpu,
    label: &str,
    module: &wgpu::ShaderModule,
    own: &[&wgpu::BindGroupLayout],
    driver: &wgpu::BindGroupLayout,
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    let empty = gpu
        .device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("empty layout"),
            entries: &[],
        });
    let mut groups: Vec<Option<&wgpu::BindGroupLayout>> = own.iter().map(|l| Some(*l)).collect();
    while groups.len() < DRIVER_GROUP as usize {
        groups.push(Some(&empty));
    }
    groups.push(Some(driver));
    let layout = gpu
        .device
        .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &groups,
            immediate_size: 0,
        });
    gpu.device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(&layout),
            module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants,
                ..Default::default()
            },
            cache: None,
        })
}

impl DriverAccel {
    /// Bind group 2 of a driver-variant pass, for this scene.
    pub fn bind_group(&self, gpu: &Gpu, layout: &wgpu::BindGroupLayout) -> wgpu::BindGroup {
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("driver accel bind group"),
            layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.tlas.as_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.mesh_base.as_entire_binding(),
                },
            ],
        })
    }

    /// Whether `gpu` can run the driver path at all.
    pub fn available(gpu: &Gpu) -> bool {
        gpu.has_ray_queries()
    }

    /// Builds both levels for `scene` (as uploaded in `buffers`) and waits
    /// for the build. `Err` says, in one line, why the driver path cannot
    /// serve this scene on this device (the caller falls back to software).
    pub fn build(gpu: &Gpu, scene: &Scene, buffers: &SceneBuffers) -> Result<DriverAccel, String> {
        if !Self::available(gpu) {
            return Err(format!(
                "adapter {} has no ray queries (wgpu Features::EXPERIMENTAL_RAY_QUERY)",
                gpu.summary.name
            ));
        }
        let start = std::time::Instant::now();
        let order = &buffers.instance_order;
        let limits = gpu.device.limits();
        if order.is_empty() {
            return Err("the scene has no instances".into());
        }
        if order.len() > MAX_CUSTOM_INDEX
            || order.len() as u64 > u64::from(limits.max_tlas_instance_count)
        {
            return Err(format!(
                "{} instances, over the driver's limit of {}",
                order.len(),
                limits.max_tlas_instance_count.min(MAX_CUSTOM_INDEX as u32)
            ));
        }
        let accel = &buffers.accel;
        let used: Vec<bool> = (0..scene.shapes.len())
            .map(|s| order.iter().any(|&i| scene.instances[i].shape == s))
            .collect();

        // Vertices of every used mesh's triangles, in celray's triangle
        // order; AABBs of every used analytic or CSG shape.
        let mut mesh_base = vec![0u32; scene.shapes.len().max(1)];
        let mut vertices: Vec<[f32; 3]> = Vec::new();
        let mut aabbs: Vec<[f32; 6]> = Vec::new();
        // Per shape: (first vertex or AABB, count), for used shapes.
        let mut geometry: Vec<Option<(bool, u32, u32)>> = vec![None; scene.shapes.len()];
        for (id, shape) in scene.shapes.iter().enumerate() {
            if !used[id] {
                continue;
            }
            let name = scene.shape_names.get(id).cloned().unwrap_or_default();
            if let Shape::Mesh(_) = shape {
                let (first, count) = mesh_triangle_range(&accel.nodes, accel.shapes[id].blas_root)
                    .ok_or_else(|| format!("mesh '{name}' has no triangles"))?;
                if u64::from(count) > u64::from(limits.max_blas_primitive_count) {
                    return Err(format!(
                        "mesh '{name}' has {count} triangles, over the driver's limit of {}",
                        limits.max_blas_primitive_count
                    ));
                }
                mesh_base[id] = first;
                let first_vertex = vertices.len() as u32;
                for t in &accel.triangles[first as usize..(first + count) as usize] {
                    for p in [t.p0, t.p1, t.p2] {
                        vertices.push([p[0], p[1], p[2]]);
                    }
                }
                geometry[id] = Some((true, first_vertex, count * 3));
            } else {
                // The same padded object bounds the software top level uses.
                let (lo, hi) = shape.bounds();
                let pad = Vec3::splat(1e-4 * (hi - lo).max_element().max(1e-3));
                let (lo, hi) = (lo - pad, hi + pad);
                geometry[id] = Some((false, aabbs.len() as u32, 1));
                aabbs.push([lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]);
            }
        }

        let input = wgpu::BufferUsages::BLAS_INPUT;
        let vertex_buffer = (!vertices.is_empty()).then(|| {
            gpu.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("driver accel vertices"),
                    contents: bytemuck::cast_slice(&vertices),
                    usage: input,
                })
        });
        let aabb_buffer = (!aabbs.is_empty()).then(|| {
            gpu.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("driver accel AABBs"),
                    contents: bytemuck::cast_slice(&aabbs),
                    usage: input,
                })
        });
        let mesh_base_buffer = gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("driver accel mesh bases"),
                contents: bytemuck::cast_slice(&mesh_base),
                usage: wgpu::BufferUsages::STORAGE,
            });

        // Size descriptors live as long as the build entries that borrow them.
        let flags = wgpu::AccelerationStructureGeometryFlags::OPAQUE;
        let tri_sizes: Vec<Option<wgpu::BlasTriangleGeometrySizeDescriptor>> = geometry
            .iter()
            .map(|g| match g {
                Some((true, _, n)) => Some(wgpu::BlasTriangleGeometrySizeDescriptor {
                    vertex_format: wgpu::VertexFormat::Float32x3,
                    vertex_count: *n,
                    index_format: None,
                    index_count: None,
                    flags,
                }),
                _ => None,
            })
            .collect();
        let aabb_size = wgpu::BlasAABBGeometrySizeDescriptor {
            primitive_count: 1,
            flags,
        };

        let built = gpu.scoped(|| {
            let mut blas_of: Vec<Option<usize>> = vec![None; scene.shapes.len()];
            let mut blases = Vec::new();
            for (id, g) in geometry.iter().enumerate() {
                let Some((is_mesh, _, _)) = g else { continue };
                let sizes = match &tri_sizes[id] {
                    Some(d) if *is_mesh => wgpu::BlasGeometrySizeDescriptors::Triangles {
                        descriptors: vec![d.clone()],
                    },
                    _ => wgpu::BlasGeometrySizeDescriptors::AABBs {
                        descriptors: vec![aabb_size.clone()],
                    },
                };
                blas_of[id] = Some(blases.len());
                blases.push(gpu.device.create_blas(
                    &wgpu::CreateBlasDescriptor {
                        label: Some("driver accel BLAS"),
                        flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
                        update_mode: wgpu::AccelerationStructureUpdateMode::Build,
                    },
                    sizes,
                ));
            }
            let mut entries = Vec::new();
            for (id, g) in geometry.iter().enumerate() {
                let (Some((is_mesh, first, _)), Some(b)) = (g, blas_of[id]) else {
                    continue;
                };
                let geometry = match (&tri_sizes[id], &vertex_buffer, &aabb_buffer) {
                    (Some(size), Some(vb), _) if *is_mesh => {
                        wgpu::BlasGeometries::TriangleGeometries(vec![wgpu::BlasTriangleGeometry {
                            size,
                            vertex_buffer: vb,
                            first_vertex: *first,
                            vertex_stride: 12,
                            index_buffer: None,
                            first_index: None,
                            transform_buffer: None,
                            transform_buffer_offset: None,
                        }])
                    }
                    (_, _, Some(ab)) => {
                        wgpu::BlasGeometries::AabbGeometries(vec![wgpu::BlasAabbGeometry {
                            size: &aabb_size,
                            stride: wgpu::AABB_GEOMETRY_MIN_STRIDE,
                            aabb_buffer: ab,
                            // In bytes.
                            primitive_offset: *first * wgpu::AABB_GEOMETRY_MIN_STRIDE as u32,
                        }])
                    }
                    _ => continue,
                };
                entries.push(wgpu::BlasBuildEntry {
                    blas: &blases[b],
                    geometry,
                });
            }
            let mut tlas = gpu.device.create_tlas(&wgpu::CreateTlasDescriptor {
                label: Some("driver accel TLAS"),
                max_instances: order.len() as u32,
                flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
                update_mode: wgpu::AccelerationStructureUpdateMode::Build,
            });
            for (gpu_index, &i) in order.iter().enumerate() {
                let inst = &scene.instances[i];
                let Some(b) = blas_of[inst.shape] else {
                    continue;
                };
                let mask = if matches!(scene.shapes[inst.shape], Shape::Mesh(_)) {
                    MASK_MESH
                } else {
                    MASK_OTHER
                };
                tlas[gpu_index] = Some(wgpu::TlasInstance::new(
                    &blases[b],
                    rows_3x4(inst.world_from_object),
                    gpu_index as u32,
                    mask,
                ));
            }
            let mut encoder = gpu
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("driver accel build"),
                });
            encoder.build_acceleration_structures(entries.iter(), [&tlas]);
            gpu.queue.submit([encoder.finish()]);
            (blases, tlas)
        });
        // One line: wgpu's validation messages span several.
        let one_line = |e: String| {
            let words: Vec<&str> = e.split_whitespace().collect();
            format!("building the structures failed: {}", words.join(" "))
        };
        let (blases, tlas) = built.map_err(|e| one_line(e.to_string()))?;
        gpu.wait_idle().map_err(|e| one_line(e.to_string()))?;
        gpu.take_errors().map_err(|e| one_line(e.to_string()))?;
        let primitive_count = geometry
            .iter()
            .flatten()
            .map(|&(m, _, n)| u64::from(if m { n / 3 } else { n }))
            .sum();
        let input_bytes = (vertices.len() * 12 + aabbs.len() * 24 + mesh_base.len() * 4) as u64;
        Ok(DriverAccel {
            stats: DriverAccelStats {
                blas_count: blases.len(),
                instance_count: order.len(),
                primitive_count,
                build_ms: start.elapsed().as_secs_f64() * 1e3,
                input_bytes,
            },
            _blases: blases,
            tlas,
            mesh_base: mesh_base_buffer,
            _vertices: vertex_buffer,
            _aabbs: aabb_buffer,
            instance_order: order.clone(),
        })
    }

    /// Records a rebuild of the top level with every instance at shutter
    /// fraction `s` (motion blur: the structure for sample k holds sample
    /// k's transforms).
    pub fn encode_motion(&mut self, encoder: &mut wgpu::CommandEncoder, scene: &Scene, s: f32) {
        for (gpu_index, &i) in self.instance_order.iter().enumerate() {
            let inst = &scene.instances[i];
            if inst.world_from_object_end.is_none() {
                continue;
            }
            if let Some(t) = self.tlas[gpu_index].as_mut() {
                t.transform = rows_3x4(inst.world_from_object_at(s));
            }
        }
        encoder.build_acceleration_structures(std::iter::empty(), [&self.tlas]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_the_matrix_rows() {
        let m = Mat4::from_cols_array_2d(&[
            [1.0, 2.0, 3.0, 0.0],
            [4.0, 5.0, 6.0, 0.0],
            [7.0, 8.0, 9.0, 0.0],
            [10.0, 11.0, 12.0, 1.0],
        ]);
        // Row 0 is the first component of each column; its last entry the
        // x translation.
        assert_eq!(
            rows_3x4(m),
            [1.0, 4.0, 7.0, 10.0, 2.0, 5.0, 8.0, 11.0, 3.0, 6.0, 9.0, 12.0]
        );
    }
}
