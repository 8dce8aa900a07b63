//! SVG plots for the benchmarks (plotters, SVG backend only: no fonts are loaded, text is left to
//! the SVG viewer). Two shapes: a grid of line-chart panels (one line per series) and a bar
//! chart.

use std::path::Path;

use anyhow::{anyhow, Result};
use plotters::coord::ranged1d::SegmentValue;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// Line colours, picked by [`Series::color`] (modulo their count).
pub const COLORS: [RGBColor; 8] = [
    RGBColor(214, 39, 40),   // red
    RGBColor(31, 119, 180),  // blue
    RGBColor(44, 160, 44),   // green
    RGBColor(148, 103, 189), // purple
    RGBColor(30, 30, 30),    // near black
    RGBColor(255, 127, 14),  // orange
    RGBColor(23, 190, 207),  // cyan
    RGBColor(140, 86, 75),   // brown
];

/// One line of a panel.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// `(x, y)` points in order of `x`.
    pub points: Vec<(f64, f64)>,
    /// Index into [`COLORS`].
    pub color: usize,
}

/// One chart of a grid.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Caption above the chart.
    pub title: String,
    /// Axis descriptions.
    pub x_desc: String,
    pub y_desc: String,
    /// Axis ranges. A series is drawn up to its first point outside `y_range` (a run that
    /// diverges is cut where it leaves the chart instead of flattening every other line). The
    /// legend sits in the upper left corner: leave room for it above the lines.
    pub x_range: (f64, f64),
    pub y_range: (f64, f64),
    /// The lines.
    pub series: Vec<Series>,
}

fn err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow!("plot: {e}")
}

/// Writes `panels` as a grid with `cols` columns (row-major) to an SVG file, each panel
/// `panel_size` pixels, under a common `title`.
pub fn line_grid(
    path: &Path,
    title: &str,
    panels: &[Panel],
    cols: usize,
    panel_size: (u32, u32),
) -> Result<()> {
    let cols = cols.max(1);
    let rows = panels.len().div_ceil(cols).max(1);
    let size = (panel_size.0 * cols as u32, panel_size.1 * rows as u32 + 40);
    let root = SVGBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 20)).map_err(err)?;
    let areas = root.split_evenly((rows, cols));
    for (panel, area) in panels.iter().zip(areas.iter()) {
        let (x0, x1) = widen(panel.x_range);
        let (y0, y1) = widen(panel.y_range);
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, ("sans-serif", 15))
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(panel.x_desc.as_str())
            .y_desc(panel.y_desc.as_str())
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(err)?;
        for s in &panel.series {
            let color = COLORS[s.color % COLORS.len()];
            let inside: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .take_while(|&(_, y)| y.is_finite() && y >= y0 && y <= y1)
                .collect();
            chart
                .draw_series(LineSeries::new(inside, color.stroke_width(1)))
                .map_err(err)?
                .label(s.label.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .label_font(("sans-serif", 11))
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

/// A bar chart of `bars` (label, value > 0) on a logarithmic axis, with the value printed above
/// each bar.
pub fn bars(path: &Path, title: &str, y_desc: &str, bars: &[(String, f64)]) -> Result<()> {
    let n = bars.len().max(1);
    let positive = bars.iter().map(|b| b.1).filter(|&v| v > 0.0);
    let hi = positive.clone().fold(0.0, f64::max);
    let lo = positive.fold(f64::INFINITY, f64::min);
    let (lo, hi) = if hi > 0.0 {
        (lo / 3.0, hi * 4.0)
    } else {
        (0.1, 10.0)
    };
    let root = SVGBackend::new(path, (150 * n as u32 + 100, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(64)
        // An integer range is inclusive here: n segments are 0..n-1.
        .build_cartesian_2d((0..n as i32 - 1).into_segmented(), (lo..hi).log_scale())
        .map_err(err)?;
    let labels: Vec<String> = bars.iter().map(|b| b.0.clone()).collect();
    let fmt = |v: &SegmentValue<i32>| match v {
        SegmentValue::CenterOf(i) | SegmentValue::Exact(i) => {
            labels.get(*i as usize).cloned().unwrap_or_default()
        }
        SegmentValue::Last => String::new(),
    };
    chart
        .configure_mesh()
        .disable_x_mesh()
        .y_desc(y_desc)
        .x_label_formatter(&fmt)
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(err)?;
    chart
        .draw_series(bars.iter().enumerate().map(|(i, b)| {
            let color = COLORS[i % COLORS.len()];
            let mut r = Rectangle::new(
                [
                    (SegmentValue::Exact(i as i32), lo),
                    (SegmentValue::Exact(i as i32 + 1), b.1.max(lo)),
                ],
                color.mix(0.8).filled(),
            );
            r.set_margin(0, 0, 24, 24);
            r
        }))
        .map_err(err)?;
    let above =
        TextStyle::from(("sans-serif", 13).into_font()).pos(Pos::new(HPos::Center, VPos::Bottom));
    chart
        .draw_series(bars.iter().enumerate().map(|(i, b)| {
            Text::new(
                format!("{:.1}", b.1),
                (SegmentValue::CenterOf(i as i32), b.1.max(lo) * 1.08),
                above.clone(),
            )
        }))
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

/// A non-empty range (plotters needs `lo < hi`).
fn widen((lo, hi): (f64, f64)) -> (f64, f64) {
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    if hi > lo {
        (lo, hi)
    } else {
        let d = if lo.abs() > 0.0 { lo.abs() * 0.1 } else { 1.0 };
        (lo - d, hi + d)
    }
}
