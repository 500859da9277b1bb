//! The camera controller: plain functions from input deltas to a new
//! [`Camera`], and the table that maps mouse buttons and modifiers to
//! gestures. No window types here, so all of it is unit-tested.
//!
//! Orbit follows three.js OrbitControls: a drag across the full viewport
//! height turns the camera by a full turn; a pan moves eye and target by the
//! same vector so that the point under the cursor at the target's depth
//! stays under it; the wheel and middle drag dolly toward the target.
//! Fly: the right mouse button looks around (eye fixed), W/A/S/D/Q/E move.
//! `up` is the world's up axis (the scene camera's `up` when loaded); the
//! camera's own `up` is set to it after each gesture.

use std::f32::consts::PI;

use glam::{Quat, Vec2, Vec3};

use crate::scene::Camera;

/// Closest angle (radians) between the view direction and the up axis:
/// orbiting never goes over the pole.
pub const MIN_POLAR: f32 = 1e-3;
/// Smallest eye-target distance a dolly leaves.
pub const MIN_DISTANCE: f32 = 1e-4;
/// Framing leaves this much room around the scene's bounding sphere.
pub const FRAME_MARGIN: f32 = 1.05;

/// How the mouse drives the camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NavMode {
    /// Turn around the target (three.js OrbitControls).
    #[default]
    Orbit,
    /// Look around from the eye with the right button, move with W/A/S/D/Q/E.
    Fly,
}

/// What a drag does to the camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Gesture {
    Orbit,
    Pan,
    Zoom,
    Look,
}

/// The mouse button that is dragging.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DragButton {
    Left,
    Right,
    Middle,
}

/// Modifier keys held during a drag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Mods {
    pub shift: bool,
    pub ctrl: bool,
    pub alt: bool,
}

/// The gesture for a drag with `button` and `mods` held.
///
/// - Left: orbit; Shift or Ctrl + left: pan (three.js); Blender's
///   emulate-3-button combinations: Alt + left orbit, Alt + Shift + left
///   pan, Alt + Ctrl + left zoom.
/// - Right: pan (orbit mode) or look (fly mode).
/// - Middle: zoom (three.js); Blender: Shift + middle pan, Ctrl + middle zoom.
pub fn drag_gesture(mode: NavMode, button: DragButton, mods: Mods) -> Gesture {
    match button {
        DragButton::Left => {
            if mods.alt && mods.ctrl {
                Gesture::Zoom
            } else if mods.shift || mods.ctrl {
                Gesture::Pan
            } else {
                Gesture::Orbit
            }
        }
        DragButton::Right => match mode {
            NavMode::Orbit => Gesture::Pan,
            NavMode::Fly => Gesture::Look,
        },
        DragButton::Middle => {
            if mods.shift {
                Gesture::Pan
            } else {
                Gesture::Zoom
            }
        }
    }
}

fn unit_up(up: Vec3) -> Vec3 {
    up.try_normalize().unwrap_or(Vec3::Y)
}

/// A unit vector perpendicular to `axis`, preferring the one toward `hint`.
fn perpendicular(axis: Vec3, hint: Vec3) -> Vec3 {
    let h = hint - axis * hint.dot(axis);
    h.try_normalize()
        .unwrap_or_else(|| axis.any_orthonormal_vector())
}

/// The angle between `v` and `up`, accurate near 0 and PI (unlike acos).
pub fn polar_angle(v: Vec3, up: Vec3) -> f32 {
    v.cross(up).length().atan2(v.dot(up))
}

/// Turns `offset` (from the pivot) by `yaw` about `up` and changes its
/// angle from `up` by `pitch`, keeping that angle in [MIN_POLAR, PI - MIN_POLAR].
/// `hint` picks the direction to leave the pole in when `offset` lies on it.
fn turn(offset: Vec3, up: Vec3, yaw: f32, pitch: f32, hint: Vec3) -> Vec3 {
    let r = offset.length();
    if r == 0.0 {
        return offset;
    }
    let dir = Quat::from_axis_angle(up, yaw) * (offset / r);
    let polar = polar_angle(dir, up);
    let new_polar = (polar + pitch).clamp(MIN_POLAR, PI - MIN_POLAR);
    let horizontal = perpendicular(up, dir + hint * 1e-6);
    (up * new_polar.cos() + horizontal * new_polar.sin()) * r
}

/// Left drag by `delta_px` over a viewport `viewport_h_px` tall: turns the
/// eye around the target, keeping their distance. Dragging right moves the
/// camera left (the scene follows the cursor); dragging down raises it.
pub fn orbit(cam: &Camera, up: Vec3, delta_px: Vec2, viewport_h_px: f32) -> Camera {
    let up = unit_up(up);
    let h = viewport_h_px.max(1.0);
    let yaw = -2.0 * PI * delta_px.x / h;
    let pitch = -2.0 * PI * delta_px.y / h;
    let offset = cam.eye - cam.target;
    // Leaving a pole (top view), go toward the side the screen's bottom shows.
    let hint = -cam.up;
    Camera {
        eye: cam.target + turn(offset, up, yaw, pitch, hint),
        up,
        ..cam.clone()
    }
}

/// Camera axes: (forward, right, screen up), unit length.
pub fn basis(cam: &Camera, up: Vec3) -> (Vec3, Vec3, Vec3) {
    let forward = (cam.target - cam.eye)
        .try_normalize()
        .unwrap_or(Vec3::NEG_Z);
    let right = forward
        .cross(unit_up(up))
        .try_normalize()
        .unwrap_or_else(|| forward.any_orthonormal_vector());
    (forward, right, right.cross(forward))
}

/// Right drag (or Shift + left) by `delta_px`: moves eye and target by the
/// same vector, so that a point at the target's depth follows the cursor.
pub fn pan(cam: &Camera, up: Vec3, delta_px: Vec2, viewport_h_px: f32) -> Camera {
    let (_, right, screen_up) = basis(cam, up);
    let distance = cam.eye.distance(cam.target);
    let world_per_px =
        2.0 * distance * (cam.fov_y_deg.to_radians() * 0.5).tan() / viewport_h_px.max(1.0);
    let shift = (-right * delta_px.x + screen_up * delta_px.y) * world_per_px;
    Camera {
        eye: cam.eye + shift,
        target: cam.target + shift,
        up: unit_up(up),
        ..cam.clone()
    }
}

/// Moves the eye toward the target (`factor` < 1) or away (> 1) along the
/// view direction; the target stays.
pub fn dolly(cam: &Camera, factor: f32) -> Camera {
    let offset = cam.eye - cam.target;
    let r = offset.length();
    if r == 0.0 || !factor.is_finite() || factor <= 0.0 {
        return cam.clone();
    }
    let new_r = (r * factor).max(MIN_DISTANCE);
    Camera {
        eye: cam.target + offset * (new_r / r),
        ..cam.clone()
    }
}

/// The dolly factor of `lines` wheel steps: up (positive) zooms in.
pub fn wheel_zoom_factor(lines: f32) -> f32 {
    0.9f32.powf(lines)
}

/// The dolly factor of a zoom drag by `dy_px`: dragging down moves away,
/// by a factor of 2 per viewport height.
pub fn drag_zoom_factor(dy_px: f32, viewport_h_px: f32) -> f32 {
    2f32.powf(dy_px / viewport_h_px.max(1.0) * 2.0)
}

/// Fly mode, right drag by `delta_px`: turns the view about the eye (the
/// eye stays, the target moves on a sphere around it). Moving the cursor by
/// the viewport height turns by the vertical field of view.
pub fn look(cam: &Camera, up: Vec3, delta_px: Vec2, viewport_h_px: f32) -> Camera {
    let up = unit_up(up);
    let rad_per_px = cam.fov_y_deg.to_radians() / viewport_h_px.max(1.0);
    let yaw = -delta_px.x * rad_per_px;
    // The target's offset from the eye is the view direction: looking up
    // (cursor up, negative dy) lowers its angle from `up`.
    let pitch = delta_px.y * rad_per_px;
    let offset = cam.target - cam.eye;
    Camera {
        target: cam.eye + turn(offset, up, yaw, pitch, cam.up),
        up,
        ..cam.clone()
    }
}

/// Movement keys held in fly mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MoveKeys {
    pub forward: bool,
    pub back: bool,
    pub left: bool,
    pub right: bool,
    pub down: bool,
    pub up: bool,
    pub fast: bool,
}

impl MoveKeys {
    pub fn any(&self) -> bool {
        self.forward || self.back || self.left || self.right || self.down || self.up
    }
}

/// How much faster Shift moves in fly mode.
pub const FAST_FACTOR: f32 = 4.0;

/// Fly mode: moves eye and target by the same vector, `speed` world units
/// per second for `dt_s` seconds along the held keys' directions (W/S along
/// the view direction, A/D along the camera's right, Q/E along world up).
pub fn fly(cam: &Camera, up: Vec3, keys: MoveKeys, speed: f32, dt_s: f32) -> Camera {
    let (forward, right, _) = basis(cam, up);
    let axis = |pos: bool, neg: bool| f32::from(u8::from(pos)) - f32::from(u8::from(neg));
    let dir = forward * axis(keys.forward, keys.back)
        + right * axis(keys.right, keys.left)
        + unit_up(up) * axis(keys.up, keys.down);
    let Some(dir) = dir.try_normalize() else {
        return cam.clone();
    };
    let speed = if keys.fast {
        speed * FAST_FACTOR
    } else {
        speed
    };
    let step = dir * speed * dt_s;
    Camera {
        eye: cam.eye + step,
        target: cam.target + step,
        up: unit_up(up),
        ..cam.clone()
    }
}

/// The fly speed after `lines` wheel steps (up is faster).
pub fn fly_speed_after_wheel(speed: f32, lines: f32) -> f32 {
    (speed * 1.25f32.powf(lines)).clamp(1e-4, 1e6)
}

/// A fly speed that crosses the scene in about four seconds.
pub fn default_fly_speed(bounds: (Vec3, Vec3)) -> f32 {
    ((bounds.1 - bounds.0).length() * 0.25).max(0.1)
}

/// Centre and radius of the sphere around `bounds`.
fn bounding_sphere(bounds: (Vec3, Vec3)) -> (Vec3, f32) {
    let centre = (bounds.0 + bounds.1) * 0.5;
    let radius = ((bounds.1 - bounds.0) * 0.5).length().max(1e-2);
    (centre, radius)
}

/// The distance at which a sphere of `radius` fits the view of `cam` on an
/// image of `aspect` (width / height), with [`FRAME_MARGIN`].
fn fit_distance(cam: &Camera, aspect: f32, radius: f32) -> f32 {
    let half_v = cam.fov_y_deg.to_radians() * 0.5;
    let half_h = (half_v.tan() * aspect.max(1e-3)).atan();
    radius * FRAME_MARGIN / half_v.min(half_h).sin()
}

/// F / Home: keeps the view direction, moves the target to the centre of
/// `bounds` and the eye back until the whole bounding sphere is in view.
pub fn frame_bounds(cam: &Camera, up: Vec3, bounds: (Vec3, Vec3), aspect: f32) -> Camera {
    let (centre, radius) = bounding_sphere(bounds);
    let (forward, _, _) = basis(cam, up);
    let distance = fit_distance(cam, aspect, radius);
    Camera {
        eye: centre - forward * distance,
        target: centre,
        up: unit_up(up),
        ..cam.clone()
    }
}

/// The numpad views (Blender's numbering, in a Y-up world whose front
/// faces +Z).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AxisView {
    /// Numpad 1: from +Z looking toward -Z.
    Front,
    /// Ctrl + numpad 1.
    Back,
    /// Numpad 3: from +X looking toward -X.
    Right,
    /// Ctrl + numpad 3.
    Left,
    /// Numpad 7: from above, front at the bottom of the screen.
    Top,
    /// Ctrl + numpad 7.
    Bottom,
}

impl AxisView {
    /// The view of numpad key `digit` (1, 3 or 7), the opposite with Ctrl.
    pub fn from_numpad(digit: u32, ctrl: bool) -> Option<AxisView> {
        Some(match (digit, ctrl) {
            (1, false) => AxisView::Front,
            (1, true) => AxisView::Back,
            (3, false) => AxisView::Right,
            (3, true) => AxisView::Left,
            (7, false) => AxisView::Top,
            (7, true) => AxisView::Bottom,
            _ => return None,
        })
    }

    /// Unit direction from the target to the eye. Top and bottom lean
    /// [`MIN_POLAR`] toward the front so that orbiting from them is defined.
    pub fn eye_direction(self) -> Vec3 {
        let (s, c) = MIN_POLAR.sin_cos();
        match self {
            AxisView::Front => Vec3::Z,
            AxisView::Back => Vec3::NEG_Z,
            AxisView::Right => Vec3::X,
            AxisView::Left => Vec3::NEG_X,
            AxisView::Top => Vec3::new(0.0, c, s),
            AxisView::Bottom => Vec3::new(0.0, -c, s),
        }
    }
}

/// Numpad 1/3/7: looks at the centre of `bounds` along an axis, from the
/// distance that frames them. The world up becomes +Y.
pub fn axis_view(cam: &Camera, view: AxisView, bounds: (Vec3, Vec3), aspect: f32) -> Camera {
    let (centre, radius) = bounding_sphere(bounds);
    let distance = fit_distance(cam, aspect, radius);
    Camera {
        eye: centre + view.eye_direction() * distance,
        target: centre,
        up: Vec3::Y,
        ..cam.clone()
    }
}

/// The focus distance that puts the surface seen at `uv` (in [0, 1]^2 over
/// the view, y down) in focus: the view depth of the first hit of the
/// primary ray there; None over background. `closest_hit(origin, dir)` is
/// the distance along the ray to the scene's closest surface (the app asks
/// the view's renderer, [`crate::render::Renderer::pick`], which walks the
/// acceleration structure it already built).
pub fn focus_at(
    cam: &Camera,
    uv: Vec2,
    closest_hit: impl FnOnce(Vec3, Vec3) -> Option<f32>,
) -> Option<f32> {
    let size = (1000u32, ((1000.0 / cam.aspect()).round() as u32).max(1));
    let pixel = uv * Vec2::new(size.0 as f32, size.1 as f32);
    let (origin, dir) = crate::render::camera::primary_ray(cam, size, pixel);
    let t = closest_hit(origin, dir)?;
    Some(t * dir.dot((cam.target - cam.eye).normalize()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Mat4, Vec4Swizzles};

    fn camera() -> Camera {
        crate::scene::Scene::builtin_default().camera
    }

    fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
        (a - b).length() <= tol
    }

    const DELTAS: [Vec2; 6] = [
        Vec2::new(10.0, 0.0),
        Vec2::new(0.0, 25.0),
        Vec2::new(-300.0, 140.0),
        Vec2::new(1000.0, -2000.0),
        Vec2::new(3.5, -0.25),
        Vec2::new(-720.0, 720.0),
    ];

    #[test]
    fn orbit_keeps_target_and_distance_and_never_crosses_the_pole() {
        let mut cam = camera();
        let d0 = cam.eye.distance(cam.target);
        let target = cam.target;
        for _ in 0..20 {
            for d in DELTAS {
                cam = orbit(&cam, Vec3::Y, d, 720.0);
                assert_eq!(cam.target, target);
                let d1 = cam.eye.distance(cam.target);
                assert!((d1 - d0).abs() < 1e-4 * d0, "{d1} vs {d0}");
                let polar = polar_angle(cam.eye - cam.target, Vec3::Y);
                assert!(
                    (MIN_POLAR * 0.99..=PI - MIN_POLAR * 0.99).contains(&polar),
                    "{polar}"
                );
            }
        }
    }

    #[test]
    fn orbit_follows_three_js_directions() {
        let cam = camera(); // eye on +z of the target, looking toward -z
                            // Dragging right by the viewport height is a full turn: back home.
        let full = orbit(&cam, Vec3::Y, Vec2::new(720.0, 0.0), 720.0);
        assert!(close(full.eye, cam.eye, 1e-3));
        // A small drag right moves the camera to the left (-x).
        let right = orbit(&cam, Vec3::Y, Vec2::new(20.0, 0.0), 720.0);
        assert!(right.eye.x < cam.eye.x - 1e-3);
        // A drag down raises the camera.
        let down = orbit(&cam, Vec3::Y, Vec2::new(0.0, 20.0), 720.0);
        assert!(down.eye.y > cam.eye.y + 1e-3);
    }

    #[test]
    fn pan_moves_eye_and_target_by_the_same_vector() {
        let cam = camera();
        for d in DELTAS {
            let p = pan(&cam, Vec3::Y, d, 720.0);
            let de = p.eye - cam.eye;
            let dt = p.target - cam.target;
            assert!(close(de, dt, 1e-5), "{de} vs {dt}");
            // Perpendicular to the view direction.
            let forward = (cam.target - cam.eye).normalize();
            assert!(de.dot(forward).abs() < 1e-4 * de.length().max(1.0));
        }
        // A drag of the viewport's height moves the view by the height the
        // view spans at the target's depth: 2 d tan(fov / 2).
        let p = pan(&cam, Vec3::Y, Vec2::new(0.0, 720.0), 720.0);
        let span = 2.0 * cam.eye.distance(cam.target) * (cam.fov_y_deg.to_radians() / 2.0).tan();
        assert!(((p.eye - cam.eye).length() - span).abs() < 1e-3 * span);
        // Dragging down moves the camera up: the scene follows the cursor.
        assert!(p.eye.y > cam.eye.y);
    }

    #[test]
    fn dolly_keeps_target_and_direction() {
        let cam = camera();
        let dir = (cam.eye - cam.target).normalize();
        let d0 = cam.eye.distance(cam.target);
        let z = dolly(&cam, wheel_zoom_factor(3.0));
        assert_eq!(z.target, cam.target);
        assert!(close((z.eye - z.target).normalize(), dir, 1e-5));
        assert!((z.eye.distance(z.target) - d0 * 0.9f32.powi(3)).abs() < 1e-4);
        // Zooming in without end stops at MIN_DISTANCE, never crosses.
        let mut c = cam.clone();
        for _ in 0..1000 {
            c = dolly(&c, 0.5);
        }
        assert!(c.eye.distance(c.target) >= MIN_DISTANCE * 0.999);
        assert!(close((c.eye - c.target).normalize(), dir, 1e-3));
        // Dragging down (positive dy) moves away.
        assert!(drag_zoom_factor(10.0, 720.0) > 1.0 && drag_zoom_factor(-10.0, 720.0) < 1.0);
    }

    #[test]
    fn look_keeps_the_eye_and_turns_the_view() {
        let cam = camera();
        let l = look(&cam, Vec3::Y, Vec2::new(50.0, -30.0), 720.0);
        assert_eq!(l.eye, cam.eye);
        let d0 = cam.eye.distance(cam.target);
        assert!((l.eye.distance(l.target) - d0).abs() < 1e-4 * d0);
        // Cursor right looks right, cursor up looks up.
        let (_, right, _) = basis(&cam, Vec3::Y);
        assert!((l.target - cam.target).dot(right) > 0.0);
        assert!(l.target.y > cam.target.y);
    }

    #[test]
    fn fly_moves_eye_and_target_together_at_the_given_speed() {
        let cam = camera();
        let keys = MoveKeys {
            forward: true,
            ..Default::default()
        };
        let f = fly(&cam, Vec3::Y, keys, 2.0, 0.5);
        let forward = (cam.target - cam.eye).normalize();
        assert!(close(f.eye - cam.eye, forward, 1e-5));
        assert!(close(f.target - cam.target, forward, 1e-5));
        let fast = fly(&cam, Vec3::Y, MoveKeys { fast: true, ..keys }, 2.0, 0.5);
        assert!(((fast.eye - cam.eye).length() - FAST_FACTOR).abs() < 1e-4);
        let up = fly(
            &cam,
            Vec3::Y,
            MoveKeys {
                up: true,
                ..Default::default()
            },
            1.0,
            1.0,
        );
        assert!(close(up.eye - cam.eye, Vec3::Y, 1e-5));
        // Opposite keys cancel; no key, no move.
        let none = fly(
            &cam,
            Vec3::Y,
            MoveKeys {
                left: true,
                right: true,
                ..Default::default()
            },
            1.0,
            1.0,
        );
        assert_eq!(none.eye, cam.eye);
        assert!(fly_speed_after_wheel(1.0, 1.0) > 1.0 && fly_speed_after_wheel(1.0, -1.0) < 1.0);
    }

    /// Every corner of `bounds` inside the view frustum of `cam`.
    fn corners_in_view(cam: &Camera, bounds: (Vec3, Vec3), aspect: f32) -> bool {
        let view = glam::camera::rh::view::look_at_mat4(cam.eye, cam.target, cam.up);
        let proj = glam::camera::rh::proj::directx::perspective(
            cam.fov_y_deg.to_radians(),
            aspect,
            1e-3,
            1e4,
        );
        let m: Mat4 = proj * view;
        (0..8).all(|i| {
            let p = Vec3::new(
                if i & 1 == 0 { bounds.0.x } else { bounds.1.x },
                if i & 2 == 0 { bounds.0.y } else { bounds.1.y },
                if i & 4 == 0 { bounds.0.z } else { bounds.1.z },
            );
            let clip = m * p.extend(1.0);
            let ndc = clip.xyz() / clip.w;
            clip.w > 0.0 && ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0
        })
    }

    #[test]
    fn framing_puts_the_scene_bounds_inside_the_view_frustum() {
        let scene = crate::scene::Scene::builtin_default();
        let bounds = scene.bounds();
        // The default camera does not see the whole 80 m floor...
        assert!(!corners_in_view(&scene.camera, bounds, 16.0 / 9.0));
        for aspect in [16.0 / 9.0, 1.0, 0.4, 3.0] {
            for d in DELTAS {
                let cam = orbit(&scene.camera, Vec3::Y, d, 720.0);
                let framed = frame_bounds(&cam, Vec3::Y, bounds, aspect);
                assert!(corners_in_view(&framed, bounds, aspect), "aspect {aspect}");
                // ... the view direction is kept.
                let before = (cam.target - cam.eye).normalize();
                let after = (framed.target - framed.eye).normalize();
                assert!(close(before, after, 1e-4));
            }
        }
        // A small box far away is brought close: the framing is tight.
        let small = (Vec3::new(9.0, 0.0, 9.0), Vec3::new(10.0, 1.0, 10.0));
        let framed = frame_bounds(&scene.camera, Vec3::Y, small, 1.0);
        assert!(corners_in_view(&framed, small, 1.0));
        assert!(framed.eye.distance(framed.target) < 3.0);
    }

    #[test]
    fn numpad_views_look_along_the_axes_and_frame_the_scene() {
        let scene = crate::scene::Scene::builtin_default();
        let bounds = scene.bounds();
        let cases = [
            (1, false, Vec3::NEG_Z),
            (1, true, Vec3::Z),
            (3, false, Vec3::NEG_X),
            (3, true, Vec3::X),
            (7, false, Vec3::NEG_Y),
            (7, true, Vec3::Y),
        ];
        for (digit, ctrl, forward) in cases {
            let view = AxisView::from_numpad(digit, ctrl).unwrap();
            let cam = axis_view(&scene.camera, view, bounds, 16.0 / 9.0);
            let dir = (cam.target - cam.eye).normalize();
            assert!(dir.dot(forward) > 0.999, "{view:?}: {dir}");
            assert!(corners_in_view(&cam, bounds, 16.0 / 9.0), "{view:?}");
        }
        assert_eq!(AxisView::from_numpad(5, false), None);
        // Top view: the front (+z) is at the bottom of the screen.
        let top = axis_view(&scene.camera, AxisView::Top, bounds, 1.0);
        let (_, _, screen_up) = basis(&top, Vec3::Y);
        assert!(screen_up.dot(Vec3::NEG_Z) > 0.99, "{screen_up}");
        // Orbiting from the top view is well defined.
        let o = orbit(&top, Vec3::Y, Vec2::new(30.0, 30.0), 720.0);
        assert!(o.eye.is_finite());
    }

    #[test]
    fn gesture_table() {
        use DragButton::*;
        let none = Mods::default();
        let shift = Mods {
            shift: true,
            ..none
        };
        let ctrl = Mods { ctrl: true, ..none };
        let alt = Mods { alt: true, ..none };
        let alt_ctrl = Mods { ctrl: true, ..alt };
        let alt_shift = Mods { shift: true, ..alt };
        let o = NavMode::Orbit;
        assert_eq!(drag_gesture(o, Left, none), Gesture::Orbit);
        assert_eq!(drag_gesture(o, Left, shift), Gesture::Pan);
        assert_eq!(drag_gesture(o, Left, ctrl), Gesture::Pan);
        assert_eq!(drag_gesture(o, Left, alt), Gesture::Orbit);
        assert_eq!(drag_gesture(o, Left, alt_shift), Gesture::Pan);
        assert_eq!(drag_gesture(o, Left, alt_ctrl), Gesture::Zoom);
        assert_eq!(drag_gesture(o, Right, none), Gesture::Pan);
        assert_eq!(drag_gesture(NavMode::Fly, Right, none), Gesture::Look);
        assert_eq!(drag_gesture(o, Middle, none), Gesture::Zoom);
        assert_eq!(drag_gesture(o, Middle, shift), Gesture::Pan);
        assert_eq!(drag_gesture(o, Middle, ctrl), Gesture::Zoom);
    }

    #[test]
    fn click_focus_is_the_view_depth_of_the_surface_under_the_cursor() {
        let ron = r#"(version: 1,
            camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 100, height: 100),
            lights: [], materials: { "m": (base_color: (1.0, 1.0, 1.0), model: BlinnPhong) },
            shapes: { "ball": Sphere(radius: 1.0) },
            instances: [(shape: "ball", material: "m")],
        )"#;
        let scene =
            crate::scene::Scene::from_ron_str(ron, "t.ron", std::path::Path::new(".")).unwrap();
        // What Renderer::pick walks: the scene's acceleration structure.
        let accel = crate::accel::SceneAccel::build(&scene, &[0]).unwrap();
        let pick = |o, d| accel.closest_hit(o, d, 0.0, f32::MAX).hit.map(|h| h.t);
        // The centre of the view sees the sphere's front pole: depth 5 - 1.
        let f = focus_at(&scene.camera, Vec2::splat(0.5), pick).unwrap();
        assert!((f - 4.0).abs() < 1e-3, "{f}");
        // A corner sees only background.
        assert!(focus_at(&scene.camera, Vec2::new(0.02, 0.02), pick).is_none());
    }
}
