//! Line charts, PNG and SVG, with the DejaVu Sans font embedded (no system font needed).

use crate::error::{HarnessError, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// One curve.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// (x, y) points in data units (log axes take the raw values, not their logarithm).
    pub points: Vec<(f64, f64)>,
    /// Draw markers instead of a line (measured points).
    pub markers: bool,
}

impl Series {
    /// A line series.
    pub fn line(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            label: label.into(),
            points,
            markers: false,
        }
    }

    /// A marker series.
    pub fn markers(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            label: label.into(),
            points,
            markers: true,
        }
    }
}

/// One chart of a figure; the panels of a figure are stacked and share the x axis label.
#[derive(Clone, Debug, Default)]
pub struct Panel {
    /// Caption above the panel.
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

/// Legend placement.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Legend {
    /// Upper right, or lower right on a logarithmic x axis (curves rising to the right).
    #[default]
    Auto,
    /// Upper left.
    UpperLeft,
    /// Lower left.
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
            if let (Some(x), Some(y)) = (map(x, panel.log_x), map(y, panel.log_y)) {
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

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    x_label: &str,
    text: bool,
) -> std::result::Result<(), String> {
    let ((x0, x1), (y0, y1)) = bounds(panel);
    let mut builder = ChartBuilder::on(area);
    builder.margin(12);
    if text {
        builder
            .caption(&panel.title, (FONT, 18))
            .x_label_area_size(38)
            .y_label_area_size(64);
    }
    let mut chart = builder
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| format!("{e:?}"))?;
    let (log_x, log_y) = (panel.log_x, panel.log_y);
    let fx = move |v: &f64| tick_label(*v, log_x);
    let fy = move |v: &f64| tick_label(*v, log_y);
    let mut mesh = chart.configure_mesh();
    mesh.x_label_formatter(&fx).y_label_formatter(&fy);
    if text {
        mesh.x_desc(x_label)
            .y_desc(&panel.y_label)
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 14));
    } else {
        mesh.disable_x_axis().disable_y_axis();
    }
    mesh.draw().map_err(|e| format!("{e:?}"))?;
    for (i, s) in panel.series.iter().enumerate() {
        let c = color(i);
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter_map(|&(x, y)| Some((map(x, log_x)?, map(y, log_y)?)))
            .collect();
        let anno = if s.markers {
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 4, c.filled())))
                .map_err(|e| format!("{e:?}"))?
        } else {
            chart
                .draw_series(LineSeries::new(pts, c.stroke_width(1)))
                .map_err(|e| format!("{e:?}"))?
        };
        if text {
            anno.label(s.label.clone()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(3))
            });
        }
    }
    if text {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.4))
            .label_font((FONT, 13))
            // Frequency and bandwidth charts rise to the upper right: keep the legend clear.
            .position(match panel.legend {
                Legend::UpperLeft => SeriesLabelPosition::UpperLeft,
                Legend::LowerLeft => SeriesLabelPosition::LowerLeft,
                Legend::Auto if panel.log_x => SeriesLabelPosition::LowerRight,
                Legend::Auto => SeriesLabelPosition::UpperRight,
            })
            .draw()
            .map_err(|e| format!("{e:?}"))?;
    }
    Ok(())
}

fn draw_figure<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    fig: &Figure,
) -> std::result::Result<(), String> {
    let text = fonts_ready();
    root.fill(&WHITE).map_err(|e| format!("{e:?}"))?;
    let areas = root.split_evenly((fig.panels.len().max(1), 1));
    for (area, panel) in areas.iter().zip(fig.panels.iter()) {
        draw_panel(area, panel, &fig.x_label, text)?;
    }
    root.present().map_err(|e| format!("{e:?}"))
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
