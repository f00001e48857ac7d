//! Line charts, PNG and SVG, with the DejaVu Sans font embedded (no system font needed).

use crate::error::{HarnessError, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

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

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(90, 90, 90),
];

fn color(i: usize) -> RGBColor {
    PALETTE.get(i % PALETTE.len()).copied().unwrap_or(BLACK)
}

fn map(v: f64, log: bool) -> Option<f64> {
    if log {
        (v > 0.0 && v.is_finite()).then(|| v.log10())
    } else {
        v.is_finite().then_some(v)
    }
}

fn bounds(panel: &Panel) -> ((f64, f64), (f64, f64)) {
    let mut xr = (f64::INFINITY, f64::NEG_INFINITY);
    let mut yr = (f64::INFINITY, f64::NEG_INFINITY);
    for s in &panel.series {
        for &(x, y) in &s.points {
            let x = map(x, panel.log_x);
            if s.style == Style::Vertical {
                // A marked x widens the x range only.
                if let Some(x) = x {
                    xr = (xr.0.min(x), xr.1.max(x));
                }
            } else if let (Some(x), Some(y)) = (x, map(y, panel.log_y)) {
                xr = (xr.0.min(x), xr.1.max(x));
                yr = (yr.0.min(y), yr.1.max(y));
            }
        }
    }
    let fix = |r: (f64, f64)| {
        if !r.0.is_finite() || !r.1.is_finite() {
            (0.0, 1.0)
        } else if (r.1 - r.0).abs() < 1e-12 {
            (r.0 - 0.5, r.1 + 0.5)
        } else {
            let pad = 0.05 * (r.1 - r.0);
            (r.0 - pad, r.1 + pad)
        }
    };
    let x = if xr.0.is_finite() && xr.1 > xr.0 {
        xr
    } else {
        fix(xr)
    };
    (x, fix(yr))
}

/// `v` with two significant digits, without trailing zeros.
fn sig2(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.1e}");
    }
    let digits = (1 - a.log10().floor() as i32).max(0) as usize;
    let text = format!("{v:.digits$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

fn tick_label(v: f64, log: bool) -> String {
    if log {
        sig2(10f64.powf(v))
    } else {
        let a = v.abs();
        if a < 1e-12 {
            // A tick at zero computed as a rounding residue (−2.2e-16).
            "0".into()
        } else if !(1e-3..1e4).contains(&a) {
            format!("{v:.1e}")
        } else {
            format!("{}", (v * 1000.0).round() / 1000.0)
        }
    }
}

fn err(e: impl std::fmt::Debug) -> String {
    format!("{e:?}")
}

/// Font size of panel titles, and of legend and tick labels (pixels).
const TITLE_SIZE: u32 = 18;
const LABEL_SIZE: u32 = 13;
/// Height of a title line and of a legend row (pixels).
const TITLE_LINE: u32 = 22;
const LEGEND_ROW: u32 = 20;
/// Margin around a panel's chart, and the width of its y axis labels (pixels).
const MARGIN: u32 = 12;
const Y_LABEL_AREA: u32 = 64;
/// Colour of vertical event lines and their labels.
const VERTICAL: RGBColor = RGBColor(60, 60, 60);

/// `text` broken into lines no wider than `width` by `measure`: at each newline, and at
/// spaces (a word wider than that stands alone on its line).
pub(crate) fn wrap(text: &str, width: u32, measure: impl Fn(&str) -> u32) -> Vec<String> {
    let mut lines = Vec::new();
    for paragraph in text.lines() {
        let mut line = String::new();
        for word in paragraph.split(' ').filter(|w| !w.is_empty()) {
            let joined = format!("{line} {word}");
            if line.is_empty() {
                line = word.to_string();
            } else if measure(&joined) <= width {
                line = joined;
            } else {
                lines.push(std::mem::replace(&mut line, word.to_string()));
            }
        }
        if !line.is_empty() {
            lines.push(line);
        }
    }
    lines
}

/// Width of `text` at `size` on `area` (pixels); an estimate from its length when the
/// backend cannot measure it.
fn text_width<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, text: &str, size: u32) -> u32 {
    let style = TextStyle::from((FONT, size).into_font());
    area.estimate_text_size(text, &style).map_or_else(
        |_| (text.chars().count() as u32).saturating_mul(size) * 6 / 10,
        |(w, _)| w,
    )
}

/// The legend's entries (series index, x offset from the strip's left edge), row by row,
/// wrapped to `width`; vertical lines carry their own labels and have no entry.
fn legend_rows<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    width: u32,
) -> Vec<Vec<(usize, u32)>> {
    let mut rows: Vec<Vec<(usize, u32)>> = Vec::new();
    let mut row = Vec::new();
    let mut x = 0;
    for (i, s) in panel.series.iter().enumerate() {
        if s.style == Style::Vertical || s.label.is_empty() {
            continue;
        }
        let w = 24 + text_width(area, &s.label, LABEL_SIZE) + 18;
        if x > 0 && x + w > width {
            rows.push(std::mem::take(&mut row));
            x = 0;
        }
        row.push((i, x));
        x += w;
    }
    if !row.is_empty() {
        rows.push(row);
    }
    rows
}

/// Draws the legend strip: for each entry a swatch (a line, or a marker) and its label.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    rows: &[Vec<(usize, u32)>],
    left: u32,
) -> std::result::Result<(), String> {
    let style = TextStyle::from((FONT, LABEL_SIZE).into_font());
    for (r, row) in rows.iter().enumerate() {
        let y = (r as u32 * LEGEND_ROW + LEGEND_ROW / 2) as i32;
        for &(i, x) in row {
            let Some(s) = panel.series.get(i) else {
                continue;
            };
            let (c, x) = (color(i), (left + x) as i32);
            if s.style == Style::Markers {
                area.draw(&Circle::new((x + 9, y), 4, c.filled()))
                    .map_err(err)?;
            } else {
                area.draw(&PathElement::new(
                    vec![(x, y), (x + 18, y)],
                    c.stroke_width(3),
                ))
                .map_err(err)?;
            }
            area.draw_text(&s.label, &style, (x + 24, y - 7))
                .map_err(err)?;
        }
    }
    Ok(())
}

/// One panel: its title (wrapped to the panel's width), its legend strip (above or below
/// the chart, see [`Legend`]), the chart, and its vertical event lines with their labels.
fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    x_label: &str,
    text: bool,
) -> std::result::Result<(), String> {
    let ((x0, x1), (y0, y1)) = bounds(panel);
    let (width, height) = area.dim_in_pixel();
    let inner = width.saturating_sub(2 * MARGIN);
    let (title, rows) = if text {
        let lines = wrap(&panel.title, inner, |t| text_width(area, t, TITLE_SIZE));
        let rows = legend_rows(area, panel, inner.saturating_sub(Y_LABEL_AREA));
        (lines, rows)
    } else {
        (Vec::new(), Vec::new())
    };
    let title_h = if title.is_empty() {
        0
    } else {
        title.len() as u32 * TITLE_LINE + 8
    };
    let legend_h = rows.len() as u32 * LEGEND_ROW;
    let (title_area, rest) = area.split_vertically(title_h);
    let title_style = TextStyle::from((FONT, TITLE_SIZE).into_font());
    for (k, line) in title.iter().enumerate() {
        let x = width.saturating_sub(text_width(area, line, TITLE_SIZE)) / 2;
        title_area
            .draw_text(
                line,
                &title_style,
                (x as i32, (6 + k as u32 * TITLE_LINE) as i32),
            )
            .map_err(err)?;
    }
    let rest_h = height.saturating_sub(title_h);
    let (chart_area, legend_area) = if panel.legend == Legend::LowerLeft {
        rest.split_vertically(rest_h.saturating_sub(legend_h + MARGIN / 2))
    } else {
        let (legend, chart) = rest.split_vertically(legend_h);
        (chart, legend)
    };
    draw_legend(&legend_area, panel, &rows, MARGIN + Y_LABEL_AREA)?;
    let mut builder = ChartBuilder::on(&chart_area);
    builder.margin(MARGIN);
    if title_h + legend_h > 0 {
        builder.margin_top(6);
    }
    if text {
        builder
            .x_label_area_size(38)
            .y_label_area_size(Y_LABEL_AREA);
    }
    let mut chart = builder.build_cartesian_2d(x0..x1, y0..y1).map_err(err)?;
    let (log_x, log_y) = (panel.log_x, panel.log_y);
    let fx = move |v: &f64| tick_label(*v, log_x);
    let fy = move |v: &f64| tick_label(*v, log_y);
    let mut mesh = chart.configure_mesh();
    mesh.x_label_formatter(&fx).y_label_formatter(&fy);
    if text {
        mesh.x_desc(x_label)
            .y_desc(&panel.y_label)
            .label_style((FONT, LABEL_SIZE))
            .axis_desc_style((FONT, 14));
    } else {
        mesh.disable_x_axis().disable_y_axis();
    }
    mesh.draw().map_err(err)?;
    for (i, s) in panel.series.iter().enumerate() {
        let c = color(i);
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter_map(|&(x, y)| Some((map(x, log_x)?, map(y, log_y)?)))
            .collect();
        match s.style {
            Style::Markers => {
                chart
                    .draw_series(pts.iter().map(|&p| Circle::new(p, 4, c.filled())))
                    .map_err(err)?;
            }
            Style::Line => {
                chart
                    .draw_series(LineSeries::new(pts, c.stroke_width(1)))
                    .map_err(err)?;
            }
            Style::Vertical => {}
        }
    }
    // Event lines last, over the curves; their labels stacked from the top, each on the
    // side of its line away from the nearer edge.
    let verticals = panel.series.iter().filter(|s| s.style == Style::Vertical);
    for (k, v) in verticals.enumerate() {
        let Some(x) = v.points.first().and_then(|&(x, _)| map(x, log_x)) else {
            continue;
        };
        chart
            .draw_series(DashedLineSeries::new(
                vec![(x, y0), (x, y1)],
                6,
                4,
                VERTICAL.stroke_width(2),
            ))
            .map_err(err)?;
        if text && !v.label.is_empty() {
            let right = x > (x0 + x1) / 2.0;
            let h = if right { HPos::Right } else { HPos::Left };
            let style = TextStyle::from((FONT, LABEL_SIZE).into_font())
                .color(&VERTICAL)
                .pos(Pos::new(h, VPos::Top));
            let dx = if right { -5 } else { 5 };
            let dy = 4 + 16 * k as i32;
            chart
                .plotting_area()
                .draw(&(EmptyElement::at((x, y1)) + Text::new(v.label.clone(), (dx, dy), style)))
                .map_err(err)?;
        }
    }
    Ok(())
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
