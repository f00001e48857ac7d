//! One panel of a [`Figure`](super::Figure): its scales (log or linear, the ranges its
//! series span, the tick labels), its layout (the title wrapped to its width, the legend
//! strip above or below the chart) and the drawing of its curves and event lines.

use super::{err, Legend, Panel, Style, FONT};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

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
pub(super) fn wrap(text: &str, width: u32, measure: impl Fn(&str) -> u32) -> Vec<String> {
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
pub(super) fn draw_panel<DB: DrawingBackend>(
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
    draw_title(&title_area, &title, width)?;
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
    draw_curves(&mut chart, panel)?;
    draw_verticals(&mut chart, panel, ((x0, x1), (y0, y1)), text)
}

/// A panel's chart, in data units (the logarithm on a log axis).
type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// The title's lines, each centred on the panel's `width`.
fn draw_title<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &[String],
    width: u32,
) -> std::result::Result<(), String> {
    let title_style = TextStyle::from((FONT, TITLE_SIZE).into_font());
    for (k, line) in title.iter().enumerate() {
        let x = width.saturating_sub(text_width(area, line, TITLE_SIZE)) / 2;
        area.draw_text(
            line,
            &title_style,
            (x as i32, (6 + k as u32 * TITLE_LINE) as i32),
        )
        .map_err(err)?;
    }
    Ok(())
}

/// The panel's curves: markers and lines, in the order of its series.
fn draw_curves<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    panel: &Panel,
) -> std::result::Result<(), String> {
    let (log_x, log_y) = (panel.log_x, panel.log_y);
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
    Ok(())
}

/// The event lines, over the curves, across the chart's `extent` ([`bounds`]); with `text`, their labels stacked from the top, each
/// on the side of its line away from the nearer edge.
fn draw_verticals<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    panel: &Panel,
    extent: ((f64, f64), (f64, f64)),
    text: bool,
) -> std::result::Result<(), String> {
    let ((x0, x1), (y0, y1)) = extent;
    let verticals = panel.series.iter().filter(|s| s.style == Style::Vertical);
    for (k, v) in verticals.enumerate() {
        let Some(x) = v.points.first().and_then(|&(x, _)| map(x, panel.log_x)) else {
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
