//! Where the views go in the window: one view, two side by side, two under
//! a wipe line, or four in a grid. Rectangles are in egui points.

use egui::{Pos2, Rect, Vec2};

/// How the views share the area right of the panel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Layout {
    /// One view fills the area.
    #[default]
    Single,
    /// Two views side by side.
    Split,
    /// Two views on top of each other, a draggable vertical line between
    /// the left part of the first and the right part of the second.
    Wipe,
    /// Four views, two by two.
    Grid,
}

impl Layout {
    pub const ALL: [Layout; 4] = [Layout::Single, Layout::Split, Layout::Wipe, Layout::Grid];

    /// How many views the layout shows.
    pub fn view_count(self) -> usize {
        match self {
            Layout::Single => 1,
            Layout::Split | Layout::Wipe => 2,
            Layout::Grid => 4,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Layout::Single => "1 view",
            Layout::Split => "2 views, split",
            Layout::Wipe => "2 views, wipe",
            Layout::Grid => "4 views, grid",
        }
    }

    pub fn parse(text: &str) -> Option<Layout> {
        match text.trim().to_ascii_lowercase().as_str() {
            "single" | "1" => Some(Layout::Single),
            "split" | "2" => Some(Layout::Split),
            "wipe" => Some(Layout::Wipe),
            "grid" | "4" => Some(Layout::Grid),
            _ => None,
        }
    }

    /// The layout for `n` views given on the command line.
    pub fn for_count(n: usize) -> Layout {
        match n {
            0 | 1 => Layout::Single,
            2 => Layout::Split,
            _ => Layout::Grid,
        }
    }
}

/// Snaps a rectangle's corners to whole physical pixels.
pub fn snap(rect: Rect, pixels_per_point: f32) -> Rect {
    let s = |v: f32| (v * pixels_per_point).round() / pixels_per_point;
    Rect::from_min_max(
        Pos2::new(s(rect.min.x), s(rect.min.y)),
        Pos2::new(s(rect.max.x), s(rect.max.y)),
    )
}

/// The rectangle of each view in `area`, pixel-snapped. For [`Layout::Wipe`]
/// both views cover the whole area (the wipe line decides what shows).
pub fn view_rects(layout: Layout, area: Rect, pixels_per_point: f32) -> Vec<Rect> {
    let gap = 2.0;
    let half_w = (area.width() - gap) * 0.5;
    let half_h = (area.height() - gap) * 0.5;
    let rects = match layout {
        Layout::Single => vec![area],
        Layout::Wipe => vec![area, area],
        Layout::Split => vec![
            Rect::from_min_size(area.min, Vec2::new(half_w, area.height())),
            Rect::from_min_size(
                Pos2::new(area.min.x + half_w + gap, area.min.y),
                Vec2::new(half_w, area.height()),
            ),
        ],
        Layout::Grid => (0..4)
            .map(|i| {
                let (col, row) = ((i % 2) as f32, (i / 2) as f32);
                Rect::from_min_size(
                    Pos2::new(
                        area.min.x + col * (half_w + gap),
                        area.min.y + row * (half_h + gap),
                    ),
                    Vec2::new(half_w, half_h),
                )
            })
            .collect(),
    };
    rects
        .into_iter()
        .map(|r| snap(r, pixels_per_point))
        .collect()
}

/// Size in physical pixels of a view drawn in `rect` (at least 1 x 1).
pub fn pixel_size(rect: Rect, pixels_per_point: f32) -> (u32, u32) {
    let w = (rect.width() * pixels_per_point).round().max(1.0) as u32;
    let h = (rect.height() * pixels_per_point).round().max(1.0) as u32;
    (w, h)
}

/// The parts of a wipe: (left part of view 0, its uv), (right part of
/// view 1, its uv), with the line at `fraction` of the width.
pub fn wipe_parts(area: Rect, fraction: f32) -> [(Rect, Rect); 2] {
    let f = fraction.clamp(0.0, 1.0);
    let x = area.min.x + area.width() * f;
    [
        (
            Rect::from_min_max(area.min, Pos2::new(x, area.max.y)),
            Rect::from_min_max(Pos2::ZERO, Pos2::new(f, 1.0)),
        ),
        (
            Rect::from_min_max(Pos2::new(x, area.min.y), area.max),
            Rect::from_min_max(Pos2::new(f, 0.0), Pos2::new(1.0, 1.0)),
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_tile_the_area_without_overlap() {
        let area = Rect::from_min_size(Pos2::new(300.0, 0.0), Vec2::new(980.0, 720.0));
        for layout in Layout::ALL {
            let rects = view_rects(layout, area, 1.0);
            assert_eq!(rects.len(), layout.view_count());
            for r in &rects {
                assert!(area.expand(0.5).contains_rect(*r), "{layout:?} {r:?}");
                assert!(r.width() > 100.0 && r.height() > 100.0);
            }
            if layout != Layout::Wipe {
                for (i, a) in rects.iter().enumerate() {
                    for b in &rects[i + 1..] {
                        assert!(!a.shrink(0.5).intersects(b.shrink(0.5)), "{layout:?}");
                    }
                }
            }
        }
        // Grid views are all one size, so one camera gives one aspect.
        let grid = view_rects(Layout::Grid, area, 1.0);
        let sizes: Vec<(u32, u32)> = grid.iter().map(|r| pixel_size(*r, 1.0)).collect();
        assert!(sizes.windows(2).all(|w| w[0] == w[1]), "{sizes:?}");
        // At 2 pixels per point, the pixel size doubles.
        assert_eq!(pixel_size(area, 2.0), (1960, 1440));
    }

    #[test]
    fn wipe_parts_meet_at_the_line() {
        let area = Rect::from_min_size(Pos2::new(100.0, 10.0), Vec2::new(800.0, 600.0));
        let [(left, left_uv), (right, right_uv)] = wipe_parts(area, 0.25);
        assert_eq!(left.max.x, 300.0);
        assert_eq!(right.min.x, 300.0);
        assert_eq!(left.width() + right.width(), area.width());
        assert_eq!(left_uv.max.x, 0.25);
        assert_eq!(right_uv.min.x, 0.25);
        let [(all, _), (none, _)] = wipe_parts(area, 7.0);
        assert_eq!(all, area);
        assert_eq!(none.width(), 0.0);
    }
}
