//! The contact sheet: frames in a grid, each under a bar holding its label.

use super::text::draw_text;
use crate::capture::Frame;

/// Height in pixels of the label bar above each view on a contact sheet.
pub const LABEL_BAR_PX: u32 = 30;
const GAP_PX: u32 = 4;

/// Columns of a contact sheet of `n` views: one row up to 4, then a grid.
pub fn sheet_columns(n: usize) -> usize {
    if n <= 4 {
        n.max(1)
    } else {
        (n as f64).sqrt().ceil() as usize
    }
}

/// A contact sheet: each frame under a dark bar holding its label.
pub fn contact_sheet(frames: &[(String, &Frame)]) -> image::RgbaImage {
    let n = frames.len().max(1);
    let cols = sheet_columns(n) as u32;
    let rows = n.div_ceil(cols as usize) as u32;
    let (w, h) = frames
        .first()
        .map(|(_, f)| (f.width, f.height))
        .unwrap_or((1, 1));
    let cell_h = h + LABEL_BAR_PX;
    let sheet_w = cols * w + (cols + 1) * GAP_PX;
    let sheet_h = rows * cell_h + (rows + 1) * GAP_PX;
    let mut sheet = image::RgbaImage::from_pixel(sheet_w, sheet_h, image::Rgba([24, 24, 28, 255]));
    for (i, (label, frame)) in frames.iter().enumerate() {
        let (col, row) = (i as u32 % cols, i as u32 / cols);
        let x0 = GAP_PX + col * (w + GAP_PX);
        let y0 = GAP_PX + row * (cell_h + GAP_PX);
        draw_text(
            &mut sheet,
            x0 as f32 + 6.0,
            y0 as f32 + 6.0,
            18.0,
            [235, 235, 235],
            label,
        );
        let img = frame.to_rgba8();
        image::imageops::replace(
            &mut sheet,
            &img,
            i64::from(x0),
            i64::from(y0 + LABEL_BAR_PX),
        );
    }
    sheet
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_sheet_places_views_and_labels() {
        let red = Frame::flat(40, 20, [200, 0, 0]);
        let blue = Frame::flat(40, 20, [0, 0, 200]);
        let sheet = contact_sheet(&[("A".into(), &red), ("B".into(), &blue)]);
        assert_eq!(sheet.width(), 2 * 40 + 3 * GAP_PX);
        assert_eq!(sheet.height(), 20 + LABEL_BAR_PX + 2 * GAP_PX);
        let y = GAP_PX + LABEL_BAR_PX + 10;
        assert_eq!(sheet.get_pixel(GAP_PX + 20, y).0, [200, 0, 0, 255]);
        assert_eq!(sheet.get_pixel(2 * GAP_PX + 40 + 20, y).0, [0, 0, 200, 255]);
        // The label bar holds light text pixels.
        let bright = (GAP_PX..GAP_PX + LABEL_BAR_PX)
            .flat_map(|y| (GAP_PX..GAP_PX + 40).map(move |x| (x, y)))
            .filter(|&(x, y)| sheet.get_pixel(x, y).0[0] > 150)
            .count();
        assert!(bright > 5, "{bright} label pixels");
    }
}
