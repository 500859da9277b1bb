//! The view area of the window's UI: the views' images (where egui draws
//! them), their labels, the wipe line, and the camera gestures of pointer
//! input over the views (drags, wheel, clicks).

use egui::{Align2, Color32, FontId, Id, PointerButton, Pos2, Rect, Sense, Stroke};

use super::controller::{self, DragButton, Gesture, Mods, NavMode};
use super::layout::{self, Layout};
use super::model::Model;
use crate::view::settings_label;

/// What the view area's UI gave this frame.
#[derive(Clone)]
pub(super) struct ViewArea {
    /// Each shown view's rectangle, in points.
    pub rects: Vec<Rect>,
    /// A click (not a drag) on a view: its index and where, in [0, 1]^2
    /// over the view (y down).
    pub click: Option<(usize, glam::Vec2)>,
}

/// The view area: images, labels, the wipe line, and the camera gestures
/// of pointer input that egui did not take.
pub(super) fn views_ui(
    ui: &mut egui::Ui,
    area: Rect,
    model: &mut Model,
    textures: &[Option<egui::TextureId>],
    samples: &[u32],
    compiling: &[bool],
) -> ViewArea {
    let ppp = ui.ctx().pixels_per_point();
    let area = layout::snap(area, ppp);
    let rects = layout::view_rects(model.layout, area, ppp);
    // Camera gestures: only drags that start on the views and wheel turns
    // over them; a drag that starts on the panel or the wipe line is egui's.
    let response = ui.interact(area, Id::unique("celray views"), Sense::click_and_drag());
    let painter = ui.painter_at(area);
    draw_images(&painter, model, &rects, textures);
    draw_labels(&painter, model, &rects, samples, compiling);
    if model.layout == Layout::Wipe {
        wipe_line(ui, &painter, area, model);
    }
    camera_gestures(
        ui,
        &response,
        model,
        rects.first().map_or(1.0, |r| r.height()),
    );
    // A click (not a drag) on a view: the caller focuses the lens there.
    let click = response
        .clicked()
        .then(|| response.interact_pointer_pos())
        .flatten()
        .and_then(|pos| {
            let i = rects.iter().position(|r| r.contains(pos))?;
            let uv = (pos - rects[i].min) / rects[i].size();
            Some((i, glam::Vec2::new(uv.x, uv.y)))
        });
    ViewArea { rects, click }
}

/// The views' images, where egui draws them (`textures[i]` is view i's).
fn draw_images(
    painter: &egui::Painter,
    model: &Model,
    rects: &[Rect],
    textures: &[Option<egui::TextureId>],
) {
    let full_uv = Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0));
    if model.layout == Layout::Wipe {
        let parts = layout::wipe_parts(rects[0], model.wipe);
        for (i, (rect, uv)) in parts.iter().enumerate() {
            if let Some(id) = textures[i] {
                painter.image(id, *rect, *uv, Color32::WHITE);
            }
        }
    } else {
        for (i, rect) in rects.iter().enumerate() {
            if let Some(id) = textures[i] {
                painter.image(id, *rect, full_uv, Color32::WHITE);
            }
        }
    }
}

/// Each view's label: its name, samples and settings (or, before its first
/// image, that its shaders are compiling), on a dark box.
fn draw_labels(
    painter: &egui::Painter,
    model: &Model,
    rects: &[Rect],
    samples: &[u32],
    compiling: &[bool],
) {
    let settings = settings_label(&model.settings);
    for (i, rect) in rects.iter().enumerate() {
        let text = if compiling.get(i).copied().unwrap_or(false) {
            format!("{}  compiling shaders...", model.views[i].label())
        } else {
            format!(
                "{}  {} / {} spp  ({})",
                model.views[i].label(),
                samples.get(i).copied().unwrap_or(0),
                model.settings.spp,
                settings
            )
        };
        let right = model.layout == Layout::Wipe && i == 1;
        let (anchor, pos) = if right {
            (Align2::RIGHT_TOP, rect.right_top() + egui::vec2(-8.0, 8.0))
        } else {
            (Align2::LEFT_TOP, rect.left_top() + egui::vec2(8.0, 8.0))
        };
        let galley_rect = painter.text(
            pos,
            anchor,
            &text,
            FontId::proportional(13.0),
            Color32::TRANSPARENT,
        );
        painter.rect_filled(galley_rect.expand(4.0), 3.0, Color32::from_black_alpha(170));
        painter.text(
            pos,
            anchor,
            &text,
            FontId::proportional(13.0),
            Color32::WHITE,
        );
    }
}

/// The wipe line: dragged to move the split between the two views.
fn wipe_line(ui: &mut egui::Ui, painter: &egui::Painter, area: Rect, model: &mut Model) {
    let x = area.min.x + area.width() * model.wipe;
    let handle = Rect::from_center_size(
        Pos2::new(x, area.center().y),
        egui::vec2(14.0, area.height()),
    );
    let wipe = ui
        .interact(handle, Id::unique("celray wipe line"), Sense::drag())
        .on_hover_cursor(egui::CursorIcon::ResizeHorizontal);
    if wipe.dragged() {
        model.wipe = (model.wipe + wipe.drag_delta().x / area.width().max(1.0)).clamp(0.0, 1.0);
    }
    let x = area.min.x + area.width() * model.wipe;
    painter.line_segment(
        [Pos2::new(x, area.min.y), Pos2::new(x, area.max.y)],
        Stroke::new(2.0, Color32::WHITE),
    );
    painter.circle_filled(Pos2::new(x, area.center().y), 7.0, Color32::WHITE);
}

fn camera_gestures(ui: &egui::Ui, response: &egui::Response, model: &mut Model, view_h: f32) {
    let (mods, lines) = ui.input(|i| {
        // Wheel steps, from the raw events (egui's own scroll delta is
        // smoothed and turned into zoom when Ctrl is held).
        let lines: f32 = i
            .raw
            .events
            .iter()
            .map(|e| match e {
                egui::Event::MouseWheel { unit, delta, .. } => match unit {
                    egui::MouseWheelUnit::Line => delta.y,
                    egui::MouseWheelUnit::Point => delta.y / 50.0,
                    egui::MouseWheelUnit::Page => delta.y * 10.0,
                },
                _ => 0.0,
            })
            .sum();
        (
            Mods {
                shift: i.modifiers.shift,
                ctrl: i.modifiers.ctrl || i.modifiers.command,
                alt: i.modifiers.alt,
            },
            lines,
        )
    });
    let up = model.world_up;
    let cam = &model.scene.camera;
    let delta = response.drag_delta();
    let d = glam::Vec2::new(delta.x, delta.y);
    let buttons = [
        (PointerButton::Primary, DragButton::Left),
        (PointerButton::Secondary, DragButton::Right),
        (PointerButton::Middle, DragButton::Middle),
    ];
    if d != glam::Vec2::ZERO {
        if let Some((_, button)) = buttons.iter().find(|(b, _)| response.dragged_by(*b)) {
            model.scene.camera = match controller::drag_gesture(model.nav, *button, mods) {
                Gesture::Orbit => controller::orbit(cam, up, d, view_h),
                Gesture::Pan => controller::pan(cam, up, d, view_h),
                Gesture::Zoom => controller::dolly(cam, controller::drag_zoom_factor(d.y, view_h)),
                Gesture::Look => controller::look(cam, up, d, view_h),
            };
        }
    }
    if response.hovered() && lines != 0.0 {
        match model.nav {
            NavMode::Orbit => {
                model.scene.camera =
                    controller::dolly(&model.scene.camera, controller::wheel_zoom_factor(lines))
            }
            NavMode::Fly => {
                model.fly_speed = controller::fly_speed_after_wheel(model.fly_speed, lines)
            }
        }
    }
}
