//! Charts of benchmark results (plotters), for people who would rather look than read: bars
//! of medians, stacked bars of where a frame's time goes, lines of frame times along a walk,
//! and log–log lines of time against size.

use std::path::Path;

use anyhow::{anyhow, Result};
use plotters::coord::ranged1d::SegmentedCoord;
use plotters::coord::types::{RangedCoordf64, RangedCoordusize};
use plotters::prelude::*;

/// Fonts tried for labels (Debian's fonts-dejavu-core); without one the chart has no text.
const FONTS: [&str; 2] =
    ["/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf", "/usr/share/fonts/truetype/dejavu/DejaVuSansMono.ttf"];

fn register_font() -> bool {
    static ONCE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ONCE.get_or_init(|| {
        for f in FONTS {
            if let Ok(bytes) = std::fs::read(f) {
                // plotters keeps fonts for the whole run.
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return true;
                }
            }
        }
        false
    })
}

/// Colours of bars and lines, in order.
const PALETTE: [RGBColor; 9] = [
    RGBColor(76, 114, 176),
    RGBColor(221, 132, 82),
    RGBColor(85, 168, 104),
    RGBColor(196, 78, 82),
    RGBColor(129, 114, 179),
    RGBColor(147, 120, 96),
    RGBColor(218, 139, 195),
    RGBColor(140, 140, 140),
    RGBColor(204, 185, 116),
];

/// A horizontal bar chart: values along x, one segment per bar down y.
type BarAxes<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, SegmentedCoord<RangedCoordusize>>>;

/// The axes of a horizontal bar chart on `root`: values from 0 to `max` along x, one
/// segment per label down y (labels, caption and unit only when a font was found).
fn bar_axes<'a, 'b>(
    root: &'a DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>,
    path: &Path,
    title: &str,
    unit: &str,
    max: f64,
    labels: &[&str],
    text: bool,
) -> Result<BarAxes<'a, 'b>> {
    let e = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    let mut builder = ChartBuilder::on(root);
    builder.margin(16).x_label_area_size(if text { 40 } else { 10 }).y_label_area_size(if text { 120 } else { 10 });
    if text {
        builder.caption(title, ("sans-serif", 22));
    }
    let mut chart = builder.build_cartesian_2d(0.0..max, (0..labels.len()).into_segmented()).map_err(|x| e(&x))?;
    if text {
        chart
            .configure_mesh()
            .disable_y_mesh()
            .x_desc(unit)
            .y_label_formatter(&|s: &SegmentValue<usize>| match s {
                SegmentValue::CenterOf(i) | SegmentValue::Exact(i) => {
                    labels.get(*i).copied().unwrap_or_default().into()
                }
                SegmentValue::Last => String::new(),
            })
            .draw()
            .map_err(|x| e(&x))?;
    }
    Ok(chart)
}

/// One bar: label, value, and an optional error bar top (e.g. p95).
pub struct Bar {
    pub label: String,
    pub value: f64,
    pub high: Option<f64>,
}

/// Writes a horizontal bar chart PNG.
pub fn bar_chart(path: &Path, title: &str, unit: &str, bars: &[Bar]) -> Result<()> {
    let text = register_font();
    let h = 120 + 46 * bars.len() as u32;
    let root = BitMapBackend::new(path, (900, h)).into_drawing_area();
    let e = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let max = bars.iter().map(|b| b.high.unwrap_or(b.value).max(b.value)).fold(0.0, f64::max).max(1e-9) * 1.15;
    let labels: Vec<&str> = bars.iter().map(|b| b.label.as_str()).collect();
    let mut chart = bar_axes(&root, path, title, unit, max, &labels, text)?;
    chart
        .draw_series(bars.iter().enumerate().map(|(i, b)| {
            let c = PALETTE[i % PALETTE.len()];
            Rectangle::new([(0.0, SegmentValue::Exact(i)), (b.value, SegmentValue::Exact(i + 1))], c.filled())
        }))
        .map_err(|x| e(&x))?;
    chart
        .draw_series(bars.iter().enumerate().filter_map(|(i, b)| {
            b.high.map(|hi| {
                PathElement::new(
                    vec![(b.value, SegmentValue::CenterOf(i)), (hi, SegmentValue::CenterOf(i))],
                    BLACK.stroke_width(2),
                )
            })
        }))
        .map_err(|x| e(&x))?;
    if text {
        chart
            .draw_series(bars.iter().enumerate().map(|(i, b)| {
                Text::new(
                    format!("{:.2} {unit}", b.value),
                    (b.high.unwrap_or(b.value).max(b.value) + max * 0.01, SegmentValue::CenterOf(i)),
                    ("sans-serif", 15),
                )
            }))
            .map_err(|x| e(&x))?;
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

/// One stacked bar: label and its parts' values, in the order of the chart's part names.
pub struct Stack {
    pub label: String,
    pub parts: Vec<f64>,
}

/// Writes a horizontal stacked bar chart PNG: each bar its parts end to end, one colour per
/// part (named in the legend), the total written after it.
pub fn stacked_bar_chart(path: &Path, title: &str, unit: &str, names: &[&str], bars: &[Stack]) -> Result<()> {
    let text = register_font();
    let h = 150 + 46 * bars.len() as u32;
    let root = BitMapBackend::new(path, (900, h)).into_drawing_area();
    let e = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let total = |b: &Stack| b.parts.iter().sum::<f64>();
    let max = bars.iter().map(total).fold(0.0, f64::max).max(1e-9) * 1.2;
    let labels: Vec<&str> = bars.iter().map(|b| b.label.as_str()).collect();
    let mut chart = bar_axes(&root, path, title, unit, max, &labels, text)?;
    for (k, name) in names.iter().enumerate() {
        let c = PALETTE[k % PALETTE.len()];
        let series = chart
            .draw_series(bars.iter().enumerate().map(|(i, b)| {
                let start: f64 = b.parts.iter().take(k).sum();
                let end = start + b.parts.get(k).copied().unwrap_or(0.0);
                Rectangle::new([(start, SegmentValue::Exact(i)), (end, SegmentValue::Exact(i + 1))], c.filled())
            }))
            .map_err(|x| e(&x))?;
        if text {
            series.label(*name).legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 14, y + 6)], c.filled()));
        }
    }
    if text {
        chart
            .draw_series(bars.iter().enumerate().map(|(i, b)| {
                let t = total(b);
                Text::new(format!("{t:.2} {unit}"), (t + max * 0.01, SegmentValue::CenterOf(i)), ("sans-serif", 15))
            }))
            .map_err(|x| e(&x))?;
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|x| e(&x))?;
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

/// Writes a line chart PNG: one named series of (x, y) points per line, with a legend.
pub fn line_chart(
    path: &Path,
    title: &str,
    x_unit: &str,
    y_unit: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> Result<()> {
    let text = register_font();
    let root = BitMapBackend::new(path, (900, 480)).into_drawing_area();
    let e = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let points = series.iter().flat_map(|s| s.1.iter());
    let (x0, x1, y1) =
        points.fold((f64::INFINITY, f64::NEG_INFINITY, 0.0f64), |(a, b, c), p| (a.min(p.0), b.max(p.0), c.max(p.1)));
    let (x0, x1) = if x0 <= x1 { (x0, x1.max(x0 + 1.0)) } else { (0.0, 1.0) };
    let y1 = y1.max(1e-9) * 1.1;
    let mut builder = ChartBuilder::on(&root);
    builder.margin(16).x_label_area_size(if text { 40 } else { 10 }).y_label_area_size(if text { 60 } else { 10 });
    if text {
        builder.caption(title, ("sans-serif", 22));
    }
    let mut chart = builder.build_cartesian_2d(x0..x1, 0.0..y1).map_err(|x| e(&x))?;
    if text {
        chart.configure_mesh().x_desc(x_unit).y_desc(y_unit).draw().map_err(|x| e(&x))?;
    }
    for (i, (name, pts)) in series.iter().enumerate() {
        let c = PALETTE[i % PALETTE.len()];
        let drawn = chart.draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2))).map_err(|x| e(&x))?;
        if text {
            drawn
                .label(name.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        }
    }
    if text && !series.is_empty() {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 15))
            .draw()
            .map_err(|x| e(&x))?;
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

/// One line of a line chart: a label and its (x, y) points, in x order.
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

/// Writes a line chart PNG with logarithmic x and y axes, one line (with point markers) per
/// series and a legend. Points that are not positive are left out (a log axis has no place
/// for them).
pub fn log_log_chart(path: &Path, title: &str, x_desc: &str, y_desc: &str, series: &[Series]) -> Result<()> {
    let text = register_font();
    let root = BitMapBackend::new(path, (1000, 700)).into_drawing_area();
    let e = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let pts = || series.iter().flat_map(|s| s.points.iter().copied()).filter(|&(x, y)| x > 0.0 && y > 0.0);
    let range = |f: fn((f64, f64)) -> f64| {
        let (lo, hi) = pts().map(f).fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
        if lo.is_finite() {
            (lo / 1.5, hi * 1.5)
        } else {
            (1.0, 10.0)
        }
    };
    let ((x0, x1), (y0, y1)) = (range(|p| p.0), range(|p| p.1));
    let mut builder = ChartBuilder::on(&root);
    builder.margin(20).x_label_area_size(if text { 45 } else { 10 }).y_label_area_size(if text { 70 } else { 10 });
    if text {
        builder.caption(title, ("sans-serif", 22));
    }
    let mut chart = builder.build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale()).map_err(|x| e(&x))?;
    if text {
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| if *v >= 10.0 { format!("{v:.0}") } else { format!("{v:.2}") })
            .draw()
            .map_err(|x| e(&x))?;
    }
    for (i, s) in series.iter().enumerate() {
        let c = PALETTE[i % PALETTE.len()];
        let points: Vec<(f64, f64)> = s.points.iter().copied().filter(|&(x, y)| x > 0.0 && y > 0.0).collect();
        let drawn = chart.draw_series(LineSeries::new(points.clone(), c.stroke_width(2))).map_err(|x| e(&x))?;
        if text {
            drawn
                .label(s.label.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        }
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, c.filled()))).map_err(|x| e(&x))?;
    }
    if text {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 16))
            .draw()
            .map_err(|x| e(&x))?;
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}
