//! Text rasterization for labels drawn into images: the built-in font
//! (Hack, from egui's default fonts) drawn by glyph coverage.

use ab_glyph::{Font, FontRef, PxScale, ScaleFont};

/// The built-in label font (Hack, shipped with egui's default fonts).
fn label_font() -> FontRef<'static> {
    FontRef::try_from_slice(epaint_default_fonts::HACK_REGULAR)
        .expect("the font compiled into epaint_default_fonts parses")
}

/// Draws `text` with its top-left corner at (`x`, `y`), `size_px` tall,
/// blending `color` over `image` by glyph coverage.
pub fn draw_text(
    image: &mut image::RgbaImage,
    x: f32,
    y: f32,
    size_px: f32,
    color: [u8; 3],
    text: &str,
) {
    let font = label_font();
    let scale = PxScale::from(size_px);
    let scaled = font.as_scaled(scale);
    let baseline = y + scaled.ascent();
    let mut caret = x;
    let mut previous = None;
    for ch in text.chars() {
        let id = scaled.glyph_id(ch);
        if let Some(prev) = previous {
            caret += scaled.kern(prev, id);
        }
        previous = Some(id);
        let glyph = id.with_scale_and_position(scale, ab_glyph::point(caret, baseline));
        caret += scaled.h_advance(id);
        let Some(outlined) = font.outline_glyph(glyph) else {
            continue;
        };
        let bounds = outlined.px_bounds();
        outlined.draw(|gx, gy, coverage| {
            let px = bounds.min.x as i64 + i64::from(gx);
            let py = bounds.min.y as i64 + i64::from(gy);
            if px < 0 || py < 0 || px >= i64::from(image.width()) || py >= i64::from(image.height())
            {
                return;
            }
            let p = image.get_pixel_mut(px as u32, py as u32);
            let a = coverage.clamp(0.0, 1.0);
            for c in 0..3 {
                p[c] = (f32::from(p[c]) * (1.0 - a) + f32::from(color[c]) * a).round() as u8;
            }
        });
    }
}

/// Width in pixels of `text` drawn `size_px` tall.
pub fn text_width(size_px: f32, text: &str) -> f32 {
    let font = label_font();
    let scaled = font.as_scaled(PxScale::from(size_px));
    text.chars()
        .map(|c| scaled.h_advance(scaled.glyph_id(c)))
        .sum()
}
