//! Camera matrices for one sample: view, projection and sub-pixel jitter.

use glam::{Mat4, Vec2, Vec3};

use crate::scene::Camera;

/// View and jittered projection of one sample, and the depth range used.
#[derive(Debug, Clone, Copy)]
pub struct SampleCamera {
    pub view_from_world: Mat4,
    pub clip_from_world: Mat4,
    pub eye: Vec3,
    pub forward: Vec3,
}

/// Near and far planes that enclose a scene with these world bounds.
///
/// Both are view depths, distances along the view direction, and the
/// bounds' sphere (widened by 5%) lies between them. The near plane is the
/// sphere's nearest view depth, `dot(centre - eye, forward) - radius`, not
/// its nearest distance `|centre - eye| - radius`: for a scene off the view
/// axis the second is larger and the near plane would cut it (the kernel's
/// primary rays start on that plane). The far plane, the farthest distance,
/// is never nearer than the farthest view depth.
pub fn depth_range(camera: &Camera, bounds: (Vec3, Vec3)) -> (f32, f32) {
    let centre = (bounds.0 + bounds.1) * 0.5;
    let radius = ((bounds.1 - bounds.0) * 0.5).length().max(1e-3);
    let forward = (camera.target - camera.eye).normalize();
    let far = (camera.eye - centre).length() + radius * 1.05 + 1e-3;
    let near = ((centre - camera.eye).dot(forward) - radius * 1.05).max(far * 1e-4);
    (near, far)
}

/// The camera for one sample on an image of `size` pixels: `camera` is
/// already at the sample's shutter time; `offset` is the sub-pixel position
/// in [0, 1)^2 (0.5, 0.5 is the pixel centre) and `lens` the point on the
/// unit aperture.
///
/// Anti-aliasing: the rasterizer samples at pixel centres, so the image is
/// shifted by (0.5 - offset) pixels: the point (x + offset) then lands on
/// the centre. Depth of field, by the accumulation-buffer method: the eye
/// moves to `lens * aperture_radius` in the camera's right/up plane and the
/// projection is sheared (an NDC shift of lens / (F tan(fov/2))) so that the
/// plane at focus distance F projects where it did from the centre: it stays
/// sharp while nearer and farther points spread over the circle of confusion.
/// The trace pass unprojects through the same matrix, so its rays start on
/// the lens and pass through the same focal-plane points.
pub fn sample_camera(
    camera: &Camera,
    size: (u32, u32),
    offset: Vec2,
    lens: Vec2,
    depth: (f32, f32),
) -> SampleCamera {
    let (w, h) = (size.0 as f32, size.1 as f32);
    let forward = (camera.target - camera.eye).normalize();
    let right = forward.cross(camera.up).normalize();
    let up = right.cross(forward);
    let lens_world = lens * camera.aperture_radius;
    let eye = camera.eye + right * lens_world.x + up * lens_world.y;
    let view = glam::camera::rh::view::look_at_mat4(eye, eye + forward, camera.up);
    let tan_half = (camera.fov_y_deg.to_radians() * 0.5).tan();
    let proj = glam::camera::rh::proj::directx::perspective(
        camera.fov_y_deg.to_radians(),
        w / h,
        depth.0,
        depth.1,
    );
    let focus = camera.resolved_focus_distance();
    let shift_px = Vec2::splat(0.5) - offset;
    // Framebuffer x grows with NDC x, framebuffer y against NDC y.
    let shift_ndc = Vec3::new(
        2.0 * shift_px.x / w + lens_world.x / (focus * tan_half * (w / h)),
        -2.0 * shift_px.y / h + lens_world.y / (focus * tan_half),
        0.0,
    );
    SampleCamera {
        view_from_world: view,
        clip_from_world: Mat4::from_translation(shift_ndc) * proj * view,
        eye,
        forward,
    }
}

/// The world-space ray through image point `pixel` (in pixels, y down, so
/// pixel centres are at i + 0.5): origin and unit direction. The CPU twin of
/// the raster projection, used by tests and picking.
pub fn primary_ray(camera: &Camera, size: (u32, u32), pixel: Vec2) -> (Vec3, Vec3) {
    let (w, h) = (size.0 as f32, size.1 as f32);
    let forward = (camera.target - camera.eye).normalize();
    let right = forward.cross(camera.up).normalize();
    let up = right.cross(forward);
    let tan_half = (camera.fov_y_deg.to_radians() * 0.5).tan();
    let ndc = Vec2::new(2.0 * pixel.x / w - 1.0, 1.0 - 2.0 * pixel.y / h);
    let dir = forward + right * ndc.x * tan_half * (w / h) + up * ndc.y * tan_half;
    (camera.eye, dir.normalize())
}

impl SampleCamera {
    /// The world ray through the centre of pixel (x, y) for this sample:
    /// the CPU twin of the trace pass's primary ray (the same unprojection
    /// through the inverse of `clip_from_world`). Origin and unit direction.
    pub fn pixel_ray(&self, size: (u32, u32), x: u32, y: u32) -> (Vec3, Vec3) {
        let world_from_clip = self.clip_from_world.as_dmat4().inverse();
        let ndc = glam::DVec2::new(
            (f64::from(x) + 0.5) / f64::from(size.0) * 2.0 - 1.0,
            1.0 - (f64::from(y) + 0.5) / f64::from(size.1) * 2.0,
        );
        let near = world_from_clip.project_point3(ndc.extend(0.0));
        let far = world_from_clip.project_point3(ndc.extend(1.0));
        (near.as_vec3(), (far - near).normalize().as_vec3())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every corner of the bounds lies between the near and far planes, as
    /// a view depth, for cameras that look at the bounds head on, from
    /// beside them and from inside them. The off-axis cameras are the
    /// case a distance-based near plane gets wrong: seen from 10 away and
    /// 25 degrees off the view axis, the cube's bounding sphere (radius
    /// sqrt 3) puts that plane at 10 - 1.05 sqrt 3 = 8.18, beyond the
    /// nearest corner's view depth, 7.73.
    #[test]
    fn the_depth_range_holds_the_bounds_off_the_view_axis() {
        let bounds = (Vec3::splat(-1.0), Vec3::splat(1.0));
        let corners = (0..8).map(|i| {
            Vec3::new(
                if i & 1 == 0 { -1.0 } else { 1.0 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -1.0 } else { 1.0 },
            )
        });
        let corners: Vec<Vec3> = corners.collect();
        for (eye, off_axis_deg) in [
            (Vec3::new(0.0, 0.0, 10.0), 0.0f32),
            (Vec3::new(0.0, 0.0, 10.0), 25.0),
            (Vec3::new(3.0, 4.0, 5.0), 60.0),
            (Vec3::new(0.0, 0.0, 3.0), 80.0),
            (Vec3::new(0.2, 0.1, 0.3), 30.0),
        ] {
            let to_centre = -eye.normalize();
            let turn = glam::Quat::from_axis_angle(Vec3::Y, off_axis_deg.to_radians());
            let forward = turn * to_centre;
            let camera = Camera {
                eye,
                target: eye + forward,
                up: Vec3::Y,
                fov_y_deg: 40.0,
                width: 64,
                height: 64,
                aperture_radius: 0.0,
                focus_distance: None,
                aperture: crate::scene::ApertureShape::Disk,
                shutter_open_s: 0.0,
                shutter_close_s: 0.0,
                eye_end: None,
                target_end: None,
            };
            let (near, far) = depth_range(&camera, bounds);
            assert!(
                0.0 < near && near < far,
                "{eye} {off_axis_deg}: {near} {far}"
            );
            for &c in &corners {
                let depth = (c - eye).dot(forward);
                if depth > 0.0 {
                    assert!(
                        near <= depth && depth <= far,
                        "eye {eye}, {off_axis_deg} degrees off axis: corner {c} at view depth {depth} outside [{near}, {far}]"
                    );
                }
            }
        }
    }
}
