//! Line charts, PNG and SVG, with the DejaVu Sans font embedded (no system font needed).

use crate::error::{HarnessError, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

mod panel;

use panel::draw_panel;

/// One curve, or one marked x value.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text (for a [`Style::Vertical`] line: the text beside it).
    pub label: String,
    /// (x, y) points in data units (log axes take the raw values, not their logarithm); a
    /// [`Style::Vertical`] line is at the x of its one point (its y is not used).
    pub points: Vec<(f64, f64)>,
    /// How it is drawn.
    pub style: Style,
}

/// How a [`Series`] is drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Style {
    /// A line through the points.
    #[default]
    Line,
    /// A marker at each point (measured points).
    Markers,
    /// A dashed vertical line across the panel at one x (an event: a trip, a resonance),
    /// labelled beside its top, not in the legend.
    Vertical,
}

impl Series {
    /// A line series.
    pub fn line(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            label: label.into(),
            points,
            style: Style::Line,
        }
    }

    /// A marker series.
    pub fn markers(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            label: label.into(),
            points,
            style: Style::Markers,
        }
    }

    /// A labelled vertical line at `x` (data units).
    pub fn vertical(label: impl Into<String>, x: f64) -> Self {
        Self {
            label: label.into(),
            points: vec![(x, 0.0)],
            style: Style::Vertical,
        }
    }
}

/// One chart of a figure; the panels of a figure are stacked and share the x axis label.
#[derive(Clone, Debug, Default)]
pub struct Panel {
    /// Caption above the panel, wrapped to the panel's width (a newline starts a line).
    pub title: String,
    /// Y axis description with unit.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series>,
    /// Logarithmic x axis (base 10).
    pub log_x: bool,
    /// Logarithmic y axis (base 10).
    pub log_y: bool,
    /// Where the legend goes.
    pub legend: Legend,
}

/// Where a panel's legend goes. Every legend is drawn outside the plotting area, in a strip
/// of its own (the entries side by side, wrapped to the panel's width), so that it never
/// covers a curve.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Legend {
    /// Above the plot, under the title.
    #[default]
    Auto,
    /// Above the plot, under the title (the same as [`Legend::Auto`]).
    UpperLeft,
    /// Below the plot, under the x axis.
    LowerLeft,
}

/// A figure: stacked panels.
#[derive(Clone, Debug, Default)]
pub struct Figure {
    /// X axis description with unit.
    pub x_label: String,
    /// The panels, top to bottom.
    pub panels: Vec<Panel>,
}

const FONT: &str = "sans-serif";

/// Registers the embedded DejaVu Sans once per process. Returns false if it failed, in
/// which case charts are drawn without text rather than not at all.
fn fonts_ready() -> bool {
    static READY: OnceLock<bool> = OnceLock::new();
    *READY.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok()
    })
}

fn err(e: impl std::fmt::Debug) -> String {
    format!("{e:?}")
}

fn draw_figure<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    fig: &Figure,
) -> std::result::Result<(), String> {
    let text = fonts_ready();
    root.fill(&WHITE).map_err(err)?;
    let areas = root.split_evenly((fig.panels.len().max(1), 1));
    for (area, panel) in areas.iter().zip(fig.panels.iter()) {
        draw_panel(area, panel, &fig.x_label, text)?;
    }
    root.present().map_err(err)
}

/// Writes `stem.png` and `stem.svg`, 1000 pixels wide and 300 high per panel (at least
/// 480); returns the two paths.
pub fn save(fig: &Figure, stem: &Path) -> Result<(PathBuf, PathBuf)> {
    let height = (300 * fig.panels.len().max(1) as u32).max(480);
    save_sized(fig, stem, (1000, height))
}

/// [`save`] at `size` (width, height) in pixels: a square one for a map in the z-plane.
pub fn save_sized(fig: &Figure, stem: &Path, size: (u32, u32)) -> Result<(PathBuf, PathBuf)> {
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    // Drawn into an RGB buffer and encoded by `png` (plotters' own encoder would pull in the
    // whole `image` crate for one format).
    let mut rgb = vec![0_u8; 3 * size.0 as usize * size.1 as usize];
    draw_figure(
        BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area(),
        fig,
    )
    .and_then(|()| write_png(&png, size, &rgb))
    .map_err(|e| HarnessError::Plot(format!("{}: {e}", png.display())))?;
    draw_figure(SVGBackend::new(&svg, size).into_drawing_area(), fig)
        .map_err(|e| HarnessError::Plot(format!("{}: {e}", svg.display())))?;
    Ok((png, svg))
}

/// Writes an 8-bit RGB image of `size` (width, height) as a PNG file.
fn write_png(path: &Path, size: (u32, u32), rgb: &[u8]) -> std::result::Result<(), String> {
    let file = std::fs::File::create(path).map_err(|e| e.to_string())?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), size.0, size.1);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    // Per-row filter choice: plots are flat colour with thin lines, which it packs well.
    encoder.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(rgb).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::panel::wrap;
    use super::*;

    /// `fig` drawn as SVG text.
    fn svg(fig: &Figure, size: (u32, u32)) -> String {
        let mut s = String::new();
        draw_figure(
            SVGBackend::with_string(&mut s, size).into_drawing_area(),
            fig,
        )
        .unwrap();
        s
    }

    /// The `y` of the `<text>` element whose content is `label`.
    fn text_y(svg: &str, label: &str) -> f64 {
        let end = svg.find(&format!(">\n{label}\n</text>")).unwrap();
        let open = svg[..end].rfind("<text").unwrap();
        let y = &svg[open..end];
        let y = &y[y.find(" y=\"").unwrap() + 4..];
        y[..y.find('"').unwrap()].parse().unwrap()
    }

    /// The y pixel range of the polylines drawn `stroke-width="1"` in `color` (the curves;
    /// legend swatches are 3 wide).
    fn curve_y_range(svg: &str, color: &str) -> (f64, f64) {
        let mut range = (f64::INFINITY, f64::NEG_INFINITY);
        for line in svg.lines().filter(|l| {
            l.starts_with("<polyline")
                && l.contains(&format!("stroke=\"{color}\""))
                && l.contains("stroke-width=\"1\"")
        }) {
            let pts = &line[line.find("points=\"").unwrap() + 8..];
            for p in pts[..pts.find('"').unwrap()].split_whitespace() {
                let y: f64 = p.split(',').nth(1).unwrap().parse().unwrap();
                range = (range.0.min(y), range.1.max(y));
            }
        }
        range
    }

    #[test]
    fn wrap_keeps_every_line_within_the_width_and_breaks_at_newlines() {
        let measure = |t: &str| 8 * t.chars().count() as u32;
        let text = "overcurrent on table1: position loop 18.8500 rad/s, velocity loop \
                    94.2500 rad/s, AFB error from observer (Ka 0.4900 s)\nSpeed";
        let lines = wrap(text, 200, measure);
        assert!(lines.len() > 3, "{lines:?}");
        assert!(lines.iter().all(|l| measure(l) <= 200), "{lines:?}");
        assert_eq!(lines.last().map(String::as_str), Some("Speed"));
        assert_eq!(
            lines.join(" ").replace("Speed", "").trim(),
            text.replace("\nSpeed", "")
        );
        // A word wider than the width stands alone rather than being cut.
        assert_eq!(
            wrap("a bcdefghijkl m", 40, measure),
            ["a", "bcdefghijkl", "m"]
        );
    }

    #[test]
    fn the_legend_is_outside_the_curves_and_a_vertical_line_is_labelled() {
        // Curves that fill the whole plotting area, top to bottom and left to right.
        let saw: Vec<(f64, f64)> = (0..=200)
            .map(|k| (f64::from(k), f64::from(k % 2)))
            .collect();
        for legend in [Legend::Auto, Legend::LowerLeft] {
            let fig = Figure {
                x_label: "time (s)".into(),
                panels: vec![Panel {
                    title: "a title long enough to need two lines on a narrow figure, \
                            which it gets"
                        .into(),
                    y_label: "y".into(),
                    series: vec![
                        Series::line("first curve", saw.clone()),
                        Series::vertical("tripped: stall at 150.0000 s", 150.0),
                    ],
                    legend,
                    ..Panel::default()
                }],
            };
            let s = svg(&fig, (500, 400));
            let (top, bottom) = curve_y_range(&s, "#1F77B4");
            assert!(top < bottom, "{top} {bottom}");
            let y = text_y(&s, "first curve");
            // The label's box (its top at y, 13 px high) clear of the curves' span.
            assert!(
                y + 13.0 < top || y > bottom,
                "{legend:?}: legend at {y}, curves {top}..{bottom}"
            );
            assert!(s.contains(">\ntripped: stall at 150.0000 s\n</text>"));
            assert!(s.contains("stroke=\"#3C3C3C\""), "no vertical line");
        }
    }
}
