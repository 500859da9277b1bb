//! The egui side panel: stats, views, render settings, camera, lights and
//! materials. Every widget edits the [`Model`]; the window applies the
//! model to the renderers on the same frame, so edits show at once.

use egui::{Color32, RichText, Ui};
use glam::Vec3;

use super::controller::NavMode;
use super::layout::Layout;
use super::model::Model;
use super::timing::PassTimes;
use crate::gpu::twins::MAX_OUTLINE_RADIUS;
use crate::render::{AccelChoice, RenderMode, Temporal, ToneMap, MAX_BOUNCES, MAX_SPP};
use crate::sampling::PixelPattern;
use crate::scene::{
    ApertureShape, Camera, Light, Material, Rim, ShadingModel, Toon, DEFAULT_TOON_BANDS,
    MAX_TOON_BANDS,
};
use crate::view::ViewSpec;

/// What the panel shows but does not edit.
pub struct PanelInfo<'a> {
    pub adapter: &'a str,
    pub backend: &'a str,
    /// The driver and its version (e.g. "llvmpipe Mesa 25.0.7 (LLVM 15.0.6)").
    pub driver: &'a str,
    pub frame_ms: f64,
    /// Samples accumulated in each shown view.
    pub samples: Vec<u32>,
    pub pass_times: Option<PassTimes>,
    /// False when the adapter has no timestamp queries.
    pub has_timer: bool,
    pub shader_dir: Option<String>,
    /// What rays walk in the first shown view ("driver" or "software"), and
    /// why the driver path is not used where it was asked for.
    pub accel: Option<(&'static str, Option<String>)>,
    /// Views whose change waits for its shaders to compile (they show the
    /// old state meanwhile).
    pub warming: usize,
    /// Per shown view, whether it waits for its first pipelines.
    pub compiling: Vec<bool>,
    /// egui's CPU ms per frame (smoothed).
    pub ui_ms: f64,
}

/// A combo box over `options`, named by `name`: one line per enum field.
pub fn enum_combo<T: Copy + PartialEq>(
    ui: &mut Ui,
    label: &str,
    value: &mut T,
    options: &[T],
    name: impl Fn(T) -> &'static str,
) -> bool {
    let mut changed = false;
    ui.horizontal(|ui| {
        ui.label(label);
        egui::ComboBox::from_id_salt(label)
            .selected_text(name(*value))
            .show_ui(ui, |ui| {
                for &o in options {
                    changed |= ui.selectable_value(value, o, name(o)).changed();
                }
            });
    });
    changed
}

fn vec3_ui(ui: &mut Ui, label: &str, v: &mut Vec3, speed: f32) -> bool {
    let mut changed = false;
    ui.horizontal(|ui| {
        ui.label(label);
        for c in [&mut v.x, &mut v.y, &mut v.z] {
            changed |= ui
                .add(egui::DragValue::new(c).speed(speed).max_decimals(3))
                .changed();
        }
    });
    changed
}

fn color_ui(ui: &mut Ui, label: &str, c: &mut Vec3) -> bool {
    let mut rgb = c.to_array();
    let changed = ui
        .horizontal(|ui| {
            ui.label(label);
            egui::color_picker::color_edit_button_rgb(ui, &mut rgb).changed()
        })
        .inner;
    if changed {
        *c = Vec3::from_array(rgb);
    }
    changed
}

fn slider(ui: &mut Ui, label: &str, v: &mut f32, range: std::ops::RangeInclusive<f32>) -> bool {
    ui.add(egui::Slider::new(v, range).text(label)).changed()
}

/// The whole panel.
pub fn side_panel(ui: &mut Ui, model: &mut Model, info: &PanelInfo) {
    stats_ui(ui, model, info);
    if let Some(err) = model.error.clone() {
        ui.separator();
        ui.label(RichText::new(err).color(Color32::from_rgb(255, 110, 100)));
        if ui.small_button("dismiss").clicked() {
            model.error = None;
        }
    }
    if let Some(status) = &model.status {
        ui.label(RichText::new(status).small());
    }
    ui.separator();
    ui.horizontal_wrapped(|ui| {
        if ui
            .button("Screenshot")
            .on_hover_text("Saves the window (F12)")
            .clicked()
        {
            model.requests.screenshot = true;
        }
        if ui
            .button("Save views")
            .on_hover_text("Saves each view's image")
            .clicked()
        {
            model.requests.save_views = true;
        }
        if ui.button("Frame all").on_hover_text("F or Home").clicked() {
            model.requests.frame_all = true;
        }
    });
    ui.horizontal(|ui| {
        ui.checkbox(&mut model.vsync, "vsync");
        ui.add(egui::Slider::new(&mut model.samples_per_frame, 1..=16).text("samples/frame"));
    });
    egui::ScrollArea::vertical().show(ui, |ui| {
        egui::CollapsingHeader::new("Views")
            .default_open(true)
            .show(ui, |ui| views_ui(ui, model));
        egui::CollapsingHeader::new("Render settings")
            .default_open(true)
            .show(ui, |ui| settings_ui(ui, model));
        egui::CollapsingHeader::new("Camera")
            .default_open(true)
            .show(ui, |ui| camera_ui(ui, model));
        egui::CollapsingHeader::new("Lights").show(ui, |ui| lights_ui(ui, model));
        egui::CollapsingHeader::new("Materials").show(ui, |ui| materials_ui(ui, model));
        egui::CollapsingHeader::new("Controls").show(ui, |ui| {
            for (what, how) in super::CONTROLS {
                ui.label(format!("{what}: {how}"));
            }
        });
    });
}

fn stats_ui(ui: &mut Ui, model: &Model, info: &PanelInfo) {
    ui.heading("celray");
    let fps = if info.frame_ms > 0.0 {
        1000.0 / info.frame_ms
    } else {
        0.0
    };
    let samples: Vec<String> = info.samples.iter().map(u32::to_string).collect();
    ui.label(format!("{} ({})", info.adapter, info.backend));
    ui.label(format!("driver: {}", info.driver));
    ui.label(format!(
        "{:.1} ms  {:.0} fps  {} / {} spp",
        info.frame_ms,
        fps,
        samples.join(", "),
        model.settings.spp
    ));
    match (&info.pass_times, info.has_timer) {
        (Some(t), _) => {
            ui.label(
                RichText::new(format!(
                    "GPU: raster {:.2}  trace {:.2}  outline+accum {:.2}  resolve {:.2}  copy {:.2}  egui {:.2} ms",
                    t.raster_ms, t.trace_ms, t.accumulate_ms, t.resolve_ms, t.copy_ms, t.egui_ms
                ))
                .small(),
            );
        }
        (None, true) if info.compiling.contains(&true) => {
            ui.label(RichText::new("GPU: (no passes yet: the views' shaders compile)").small());
        }
        (None, true) => {
            ui.label(RichText::new("GPU: (converged, no passes to time)").small());
        }
        (None, false) => {
            ui.label(RichText::new("GPU pass times: no timestamp queries here").small());
        }
    }
    ui.label(RichText::new(format!("window CPU: egui {:.2} ms", info.ui_ms)).small());
    let file = model
        .scene_path
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| "built-in default scene".into());
    ui.label(RichText::new(format!("scene: {file}")).small());
    if let Some((used, notice)) = &info.accel {
        ui.label(RichText::new(format!("rays walk: {used} structures")).small());
        if let Some(n) = notice {
            ui.label(RichText::new(n).small().color(Color32::YELLOW));
        }
    }
    if info.warming > 0 {
        ui.label(
            RichText::new(format!(
                "compiling shaders ({} view{}); each view shows its last image meanwhile",
                info.warming,
                if info.warming == 1 { "" } else { "s" }
            ))
            .small()
            .color(Color32::YELLOW),
        );
    }
    if let Some(dir) = &info.shader_dir {
        ui.label(RichText::new(format!("shaders: {dir} (watched)")).small());
    }
}

fn view_kind_name(k: u8) -> &'static str {
    match k {
        0 => "scene materials",
        1 => "blinn-phong",
        _ => "toon",
    }
}

fn views_ui(ui: &mut Ui, model: &mut Model) {
    enum_combo(ui, "layout", &mut model.layout, &Layout::ALL, Layout::name);
    if model.layout == Layout::Wipe {
        ui.add(egui::Slider::new(&mut model.wipe, 0.0..=1.0).text("wipe"));
    }
    for i in 0..model.layout.view_count() {
        let spec = &mut model.views[i];
        let mut kind: u8 = match &spec.shading {
            None => 0,
            Some(ShadingModel::BlinnPhong) => 1,
            Some(ShadingModel::Toon(_)) => 2,
        };
        let before = kind;
        ui.horizontal(|ui| {
            enum_combo(
                ui,
                &format!("view {}", i + 1),
                &mut kind,
                &[0, 1, 2],
                view_kind_name,
            );
            if let Some(ShadingModel::Toon(toon)) = &mut spec.shading {
                let mut bands = toon.bands();
                if ui
                    .add(egui::DragValue::new(&mut bands).range(1..=MAX_TOON_BANDS))
                    .on_hover_text("bands")
                    .changed()
                {
                    *toon = Toon::even(bands);
                }
            }
        });
        if kind != before {
            *spec = match kind {
                0 => ViewSpec::SCENE,
                1 => ViewSpec::with_model(ShadingModel::BlinnPhong),
                _ => ViewSpec::with_model(ShadingModel::Toon(Toon::even(DEFAULT_TOON_BANDS))),
            };
        }
    }
}

/// The render settings, one widget per field. (A `mode` field becomes one
/// more `enum_combo` line here.)
fn settings_ui(ui: &mut Ui, model: &mut Model) {
    let s = &mut model.settings;
    enum_combo(ui, "mode", &mut s.mode, &RenderMode::ALL, RenderMode::name);
    enum_combo(
        ui,
        "ray accel",
        &mut s.accel,
        &AccelChoice::ALL,
        AccelChoice::name,
    );
    ui.horizontal(|ui| {
        ui.label("reflection bounces");
        ui.add(egui::DragValue::new(&mut s.max_bounces).range(0..=MAX_BOUNCES));
    });
    ui.horizontal(|ui| {
        ui.label("sample target");
        ui.add(egui::DragValue::new(&mut s.spp).range(1..=MAX_SPP));
    });
    // off: one fresh sample per frame while the camera moves; reproject:
    // blend into the reprojected history (exact accumulation resumes when
    // the camera stops); blend: reprojected without rejection (ghosts).
    enum_combo(
        ui,
        "while moving",
        &mut s.temporal,
        &Temporal::ALL,
        Temporal::name,
    );
    enum_combo(
        ui,
        "pattern",
        &mut s.pattern,
        &PixelPattern::ALL,
        PixelPattern::name,
    );
    ui.horizontal(|ui| {
        ui.label("seed");
        ui.add(egui::DragValue::new(&mut s.seed));
    });
    enum_combo(
        ui,
        "tone map",
        &mut s.tone_map,
        &ToneMap::ALL,
        ToneMap::name,
    );
    ui.add(
        egui::Slider::new(&mut s.exposure, 0.01..=16.0)
            .logarithmic(true)
            .text("exposure"),
    );
}

fn aperture_kind(a: &ApertureShape) -> u8 {
    match a {
        ApertureShape::Disk => 0,
        ApertureShape::Square => 1,
        ApertureShape::Polygon { .. } => 2,
    }
}

fn camera_ui(ui: &mut Ui, model: &mut Model) {
    enum_combo(
        ui,
        "navigation",
        &mut model.nav,
        &[NavMode::Orbit, NavMode::Fly],
        |m| match m {
            NavMode::Orbit => "orbit",
            NavMode::Fly => "fly (Tab)",
        },
    );
    if model.nav == NavMode::Fly {
        ui.add(
            egui::Slider::new(&mut model.fly_speed, 0.01..=1000.0)
                .logarithmic(true)
                .text("fly speed (units/s)"),
        );
    }
    let c = &mut model.scene.camera;
    vec3_ui(ui, "eye", &mut c.eye, 0.02);
    vec3_ui(ui, "target", &mut c.target, 0.02);
    slider(ui, "fov y (deg)", &mut c.fov_y_deg, 1.0..=170.0);
    lens_ui(ui, c);
    shutter_ui(ui, c);
    color_ui(ui, "ambient", &mut model.scene.ambient);
    color_ui(ui, "background", &mut model.scene.background);
}

/// The thin lens: aperture size and shape, and where it focuses.
fn lens_ui(ui: &mut Ui, c: &mut Camera) {
    ui.add(
        egui::Slider::new(&mut c.aperture_radius, 0.0..=1.0)
            .text("aperture radius")
            .logarithmic(true)
            .smallest_positive(1e-4),
    );
    ui.horizontal(|ui| {
        let mut auto = c.focus_distance.is_none();
        if ui.checkbox(&mut auto, "focus at target").changed() {
            c.focus_distance = if auto {
                None
            } else {
                Some(c.eye.distance(c.target))
            };
        }
        if let Some(d) = &mut c.focus_distance {
            ui.add(
                egui::DragValue::new(d)
                    .speed(0.02)
                    .range(1e-3..=1e6)
                    .prefix("focus "),
            );
        }
    });
    let mut kind = aperture_kind(&c.aperture);
    if enum_combo(ui, "aperture", &mut kind, &[0, 1, 2], |k| match k {
        0 => "disk",
        1 => "square",
        _ => "polygon",
    }) {
        c.aperture = match kind {
            0 => ApertureShape::Disk,
            1 => ApertureShape::Square,
            _ => ApertureShape::Polygon {
                blades: 6,
                rotation_deg: 0.0,
            },
        };
    }
    if let ApertureShape::Polygon {
        blades,
        rotation_deg,
    } = &mut c.aperture
    {
        ui.horizontal(|ui| {
            ui.add(egui::DragValue::new(blades).range(3..=16).prefix("blades "));
            ui.add(
                egui::DragValue::new(rotation_deg)
                    .range(-360.0..=360.0)
                    .suffix(" deg"),
            );
        });
    }
}

/// The shutter interval that motion blur spreads samples over.
fn shutter_ui(ui: &mut Ui, c: &mut Camera) {
    ui.horizontal(|ui| {
        ui.label("shutter (s)");
        ui.add(
            egui::DragValue::new(&mut c.shutter_open_s)
                .speed(0.001)
                .range(0.0..=10.0)
                .prefix("open "),
        );
        let open = c.shutter_open_s;
        ui.add(
            egui::DragValue::new(&mut c.shutter_close_s)
                .speed(0.001)
                .range(open..=10.0)
                .prefix("close "),
        );
    });
}

fn lights_ui(ui: &mut Ui, model: &mut Model) {
    let mut remove = None;
    for (i, light) in model.scene.lights.iter_mut().enumerate() {
        ui.push_id(("light", i), |ui| {
            let (kind, color, intensity, cast_shadows) = match light {
                Light::Directional {
                    direction,
                    color,
                    intensity,
                    cast_shadows,
                } => {
                    ui.label(format!("{i}: directional"));
                    vec3_ui(ui, "direction", direction, 0.01);
                    ("directional", color, intensity, cast_shadows)
                }
                Light::Point {
                    position,
                    color,
                    intensity,
                    cast_shadows,
                } => {
                    ui.label(format!("{i}: point"));
                    vec3_ui(ui, "position", position, 0.02);
                    ("point", color, intensity, cast_shadows)
                }
            };
            let _ = kind;
            color_ui(ui, "color", color);
            ui.add(
                egui::Slider::new(intensity, 0.0..=20.0)
                    .logarithmic(true)
                    .smallest_positive(1e-3)
                    .text("intensity"),
            );
            ui.horizontal(|ui| {
                ui.checkbox(cast_shadows, "cast shadows");
                if ui.small_button("remove").clicked() {
                    remove = Some(i);
                }
            });
            ui.separator();
        });
    }
    if let Some(i) = remove {
        model.scene.lights.remove(i);
    }
    ui.horizontal(|ui| {
        if ui.button("+ directional").clicked() {
            model.scene.lights.push(Light::Directional {
                direction: Vec3::new(-0.5, -1.0, -0.6).normalize(),
                color: Vec3::ONE,
                intensity: 1.0,
                cast_shadows: true,
            });
        }
        if ui.button("+ point").clicked() {
            model.scene.lights.push(Light::Point {
                position: Vec3::new(0.0, 4.0, 3.0),
                color: Vec3::ONE,
                intensity: 0.5,
                cast_shadows: false,
            });
        }
    });
}

fn materials_ui(ui: &mut Ui, model: &mut Model) {
    let names = model.scene.material_names.clone();
    for (i, (m, name)) in model.scene.materials.iter_mut().zip(&names).enumerate() {
        egui::CollapsingHeader::new(name)
            .id_salt(("material", i))
            .show(ui, |ui| material_ui(ui, m));
    }
}

/// Keeps toon thresholds strictly increasing inside (0, 1) after an edit of
/// threshold `edited`.
pub fn fix_thresholds(t: &mut [f32], edited: usize) {
    const STEP: f32 = 1e-3;
    let n = t.len();
    if n == 0 {
        return;
    }
    let lo = STEP * (edited as f32 + 1.0);
    let hi = 1.0 - STEP * (n - edited) as f32;
    t[edited] = t[edited].clamp(lo, hi);
    for j in (0..edited).rev() {
        t[j] = t[j].min(t[j + 1] - STEP);
    }
    for j in edited + 1..n {
        t[j] = t[j].max(t[j - 1] + STEP);
    }
}

fn material_ui(ui: &mut Ui, m: &mut Material) {
    if let Some(t) = &m.base_color_texture {
        ui.label(format!(
            "texture: {} ({}x{}; replaces the base colour)",
            t.texture.name(),
            t.texture.width,
            t.texture.height
        ))
        .on_hover_text(&t.texture.source);
    }
    if let Some(crate::scene::Pattern::Checker { size, .. }) = m.base_color_pattern {
        ui.label(format!("pattern: checker, {size} units"));
    }
    color_ui(ui, "base colour", &mut m.base_color);
    color_ui(ui, "specular colour", &mut m.specular_color);
    ui.add(
        egui::Slider::new(&mut m.shininess, 1.0..=1024.0)
            .logarithmic(true)
            .text("shininess"),
    );
    let mut toon = matches!(m.model, ShadingModel::Toon(_));
    ui.horizontal(|ui| {
        ui.label("model");
        let a = ui
            .selectable_value(&mut toon, false, "blinn-phong")
            .changed();
        let b = ui.selectable_value(&mut toon, true, "toon").changed();
        if a || b {
            m.model = if toon {
                ShadingModel::Toon(Toon::even(DEFAULT_TOON_BANDS))
            } else {
                ShadingModel::BlinnPhong
            };
        }
    });
    if let ShadingModel::Toon(t) = &mut m.model {
        toon_ui(ui, t);
    }
    color_ui(ui, "outline colour", &mut m.outline_color);
    let widest = MAX_OUTLINE_RADIUS as f32;
    slider(
        ui,
        "outline width (px)",
        &mut m.outline_width_px,
        0.0..=widest,
    );
    slider(ui, "reflectivity", &mut m.reflectivity, 0.0..=1.0);
    slider(ui, "roughness", &mut m.roughness, 0.0..=1.0);
}

/// A toon material's bands, their thresholds, the specular threshold and
/// the rim light.
fn toon_ui(ui: &mut Ui, t: &mut Toon) {
    let mut bands = t.bands();
    ui.horizontal(|ui| {
        ui.label("bands");
        if ui
            .add(egui::DragValue::new(&mut bands).range(1..=MAX_TOON_BANDS))
            .changed()
        {
            t.thresholds = Toon::even(bands).thresholds;
        }
    });
    let mut edited = None;
    ui.horizontal_wrapped(|ui| {
        ui.label("thresholds");
        for (j, v) in t.thresholds.iter_mut().enumerate() {
            if ui
                .add(egui::DragValue::new(v).speed(0.005).range(0.001..=0.999))
                .changed()
            {
                edited = Some(j);
            }
        }
    });
    if let Some(j) = edited {
        fix_thresholds(&mut t.thresholds, j);
    }
    slider(
        ui,
        "specular threshold",
        &mut t.specular_threshold,
        0.0..=1.0,
    );
    let mut rim = t.rim.is_some();
    if ui.checkbox(&mut rim, "rim light").changed() {
        t.rim = rim.then(|| Rim {
            color: Vec3::splat(0.3),
            threshold: 0.6,
        });
    }
    if let Some(r) = &mut t.rim {
        color_ui(ui, "rim colour", &mut r.color);
        slider(ui, "rim threshold", &mut r.threshold, 0.0..=1.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edited_thresholds_stay_strictly_increasing_inside_0_1() {
        let mut t = vec![0.25, 0.5, 0.75];
        t[1] = 0.9; // dragged past its neighbour
        fix_thresholds(&mut t, 1);
        assert!(t.windows(2).all(|w| w[0] < w[1]), "{t:?}");
        assert_eq!(t[1], 0.9);
        t[0] = 1.0;
        fix_thresholds(&mut t, 0);
        assert!(t.windows(2).all(|w| w[0] < w[1]) && t[2] < 1.0, "{t:?}");
        let toon = Toon {
            thresholds: t,
            specular_threshold: 0.5,
            rim: None,
        };
        assert!(toon.validate().is_ok());
    }
}
