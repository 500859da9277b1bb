//! `celray bench rays --export-rays FILE`: helmet_rays' work written out for
//! an outside ray tracer (tools/embree-compare), so that both time the same
//! rays against the same triangles on the same machine, and the outside
//! tracer can check that it finds the same hits.
//!
//! The file, all little-endian: the 8 bytes `CELRAYS1`; the triangle count
//! and the ray count (u32 each); per triangle its three world-space corners
//! (9 f32); per ray its origin and direction (6 f32, the direction as the
//! ray-batch kernel traces it); per ray celray's closest-hit distance t
//! (f32, +infinity on a miss).

use std::io::Write;
use std::path::Path;

use anyhow::Context;

use celray::gpu::twins::{GpuHit, GpuRay};
use celray::scene::{Scene, Shape};

/// Refuses a target that exists (no file is overwritten), a folder that
/// does not, and a suite without the helmet_rays case.
pub(super) fn check_target(path: &Path, suite: &str) -> anyhow::Result<()> {
    if !matches!(suite, "rays" | "all") {
        anyhow::bail!("--export-rays writes the helmet_rays case: use it with the suite `rays` or `all`, not `{suite}`");
    }
    if path.exists() {
        anyhow::bail!(
            "--export-rays: {} already exists; it is never overwritten",
            path.display()
        );
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        anyhow::bail!(
            "--export-rays: the folder {} does not exist",
            parent.display()
        );
    }
    Ok(())
}

/// Every triangle of the scene's mesh instances, in world space.
fn world_triangles(scene: &Scene) -> Vec<[f32; 9]> {
    let mut out = Vec::new();
    for inst in &scene.instances {
        let Shape::Mesh(mesh) = &scene.shapes[inst.shape] else {
            continue;
        };
        for tri in mesh.indices.chunks_exact(3) {
            let mut corners = [0.0; 9];
            for (k, &i) in tri.iter().enumerate() {
                let p = inst
                    .world_from_object
                    .transform_point3(mesh.positions[i as usize]);
                corners[3 * k..3 * k + 3].copy_from_slice(&p.to_array());
            }
            out.push(corners);
        }
    }
    out
}

pub(super) fn write_rays(
    path: &Path,
    scene: &Scene,
    rays: &[GpuRay],
    hits: &[GpuHit],
) -> anyhow::Result<()> {
    let triangles = world_triangles(scene);
    let mut bytes = Vec::with_capacity(16 + triangles.len() * 36 + rays.len() * 28);
    bytes.extend_from_slice(b"CELRAYS1");
    bytes.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&(rays.len() as u32).to_le_bytes());
    let mut put = |v: f32| bytes.extend_from_slice(&v.to_le_bytes());
    triangles.iter().flatten().for_each(|&v| put(v));
    for ray in rays {
        ray.origin[..3]
            .iter()
            .chain(&ray.dir[..3])
            .for_each(|&v| put(v));
    }
    for hit in hits {
        put(if hit.instance == u32::MAX {
            f32::INFINITY
        } else {
            hit.t
        });
    }
    // create_new: a file that appeared since the check is not overwritten.
    let mut file = std::fs::File::options()
        .write(true)
        .create_new(true)
        .open(path)
        .with_context(|| format!("--export-rays: cannot create {}", path.display()))?;
    file.write_all(&bytes)
        .with_context(|| format!("--export-rays: cannot write {}", path.display()))?;
    Ok(())
}
