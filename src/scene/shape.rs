//! Base shapes that instances refer to.

use glam::{Vec2, Vec3};

use super::{Csg, Mesh};

/// A base shape in object space. Analytic shapes can be ray-traced or
/// turned into triangles with [`tessellate`](super::tessellate).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Sphere centred at the origin.
    Sphere { radius: f32 },
    /// Axis-aligned box centred at the origin.
    Box { half_extents: Vec3 },
    /// Capped cylinder with axis +y, centred at the origin
    /// (y from `-height / 2` to `height / 2`).
    Cylinder { radius: f32, height: f32 },
    /// Cone with axis +y: base disk of `radius` at y = 0 (capped),
    /// apex at y = `height`.
    Cone { radius: f32, height: f32 },
    /// Flat shape in the xz plane through the origin, normal +y.
    Plane(PlaneKind),
    /// Triangle mesh loaded from a file.
    Mesh(Mesh),
    /// Constructive solid geometry: ray-traced only (raster mode draws
    /// nothing for it).
    Csg(Csg),
}

/// The outline of a [`Shape::Plane`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PlaneKind {
    /// Rectangle `[-half_size.x, half_size.x] x [-half_size.y, half_size.y]`
    /// in x and z.
    Quad { half_size: Vec2 },
    /// Disk of `radius` centred at the origin.
    Disk { radius: f32 },
}

impl Shape {
    /// Object-space axis-aligned bounding box `(min, max)`.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        match self {
            Shape::Sphere { radius } => (Vec3::splat(-radius), Vec3::splat(*radius)),
            Shape::Box { half_extents } => (-*half_extents, *half_extents),
            Shape::Cylinder { radius, height } => (
                Vec3::new(-radius, -height / 2.0, -radius),
                Vec3::new(*radius, height / 2.0, *radius),
            ),
            Shape::Cone { radius, height } => (
                Vec3::new(-radius, 0.0, -radius),
                Vec3::new(*radius, *height, *radius),
            ),
            Shape::Plane(PlaneKind::Quad { half_size }) => (
                Vec3::new(-half_size.x, 0.0, -half_size.y),
                Vec3::new(half_size.x, 0.0, half_size.y),
            ),
            Shape::Plane(PlaneKind::Disk { radius }) => (
                Vec3::new(-radius, 0.0, -radius),
                Vec3::new(*radius, 0.0, *radius),
            ),
            Shape::Mesh(mesh) => mesh.bounds(),
            Shape::Csg(csg) => csg.bounds(),
        }
    }

    /// Short lower-case name of the kind of shape (`"sphere"`, `"mesh"`, ...).
    pub fn kind_name(&self) -> &'static str {
        match self {
            Shape::Sphere { .. } => "sphere",
            Shape::Box { .. } => "box",
            Shape::Cylinder { .. } => "cylinder",
            Shape::Cone { .. } => "cone",
            Shape::Plane(PlaneKind::Quad { .. }) => "plane quad",
            Shape::Plane(PlaneKind::Disk { .. }) => "plane disk",
            Shape::Mesh(_) => "mesh",
            Shape::Csg(_) => "csg",
        }
    }

    /// Checks that sizes are finite and positive and that meshes are
    /// well formed.
    pub fn validate(&self) -> Result<(), String> {
        fn positive(what: &str, v: f32) -> Result<(), String> {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{what} must be positive, got {v}"))
            }
        }
        match self {
            Shape::Sphere { radius } => positive("sphere radius", *radius),
            Shape::Box { half_extents } => {
                positive("box half_extents.x", half_extents.x)?;
                positive("box half_extents.y", half_extents.y)?;
                positive("box half_extents.z", half_extents.z)
            }
            Shape::Cylinder { radius, height } => {
                positive("cylinder radius", *radius)?;
                positive("cylinder height", *height)
            }
            Shape::Cone { radius, height } => {
                positive("cone radius", *radius)?;
                positive("cone height", *height)
            }
            Shape::Plane(PlaneKind::Quad { half_size }) => {
                positive("plane half_size.x", half_size.x)?;
                positive("plane half_size.y", half_size.y)
            }
            Shape::Plane(PlaneKind::Disk { radius }) => positive("disk radius", *radius),
            Shape::Mesh(mesh) => mesh.validate(),
            Shape::Csg(csg) => csg.check(),
        }
    }
}
