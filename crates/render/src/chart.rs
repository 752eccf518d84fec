//! Log-log and linear line charts, and Pareto fronts.

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

use crate::error::{RenderError, Result};
use crate::text::{FAMILY, check_image_size, draw_err, ensure_fonts, format_log_tick, rgb_to_png, text_size};

/// One line of a [`loglog_chart`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points `(x, y)`, connected in the given order; both coordinates must
    /// be finite and positive.
    pub points: Vec<(f64, f64)>,
}

/// Label used for the Pareto points, in the legend and in errors.
const PARETO_LABEL: &str = "Pareto front";

/// Indices of the points not dominated by any other point when both
/// coordinates are to be minimized, sorted by x (then y, then index).
///
/// A point dominates another if it is no larger in both coordinates and
/// smaller in at least one; exact duplicates of a front point are all kept.
/// Points with a NaN or infinite coordinate are never on the front.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    pareto_front_with_margin(points, 0.0)
}

/// [`pareto_front`] where a point with a larger x must have a y at least `margin` (a
/// fraction) below the front's last point to join it, so that ties within measurement
/// noise do not all count as non-dominated.
pub fn pareto_front_with_margin(points: &[(f64, f64)], margin: f64) -> Vec<usize> {
    let mut order: Vec<usize> =
        (0..points.len()).filter(|&i| points[i].0.is_finite() && points[i].1.is_finite()).collect();
    order.sort_by(|&a, &b| {
        let (pa, pb) = (points[a], points[b]);
        pa.0.total_cmp(&pb.0).then(pa.1.total_cmp(&pb.1)).then(a.cmp(&b))
    });
    let mut front: Vec<usize> = Vec::new();
    for i in order {
        let p = points[i];
        match front.last() {
            None => front.push(i),
            Some(&last) => {
                let q = points[last];
                if p.1 < q.1 * (1.0 - margin) || p == q {
                    front.push(i);
                }
            }
        }
    }
    front
}

/// Smallest and largest coordinate a log axis accepts (beyond these the
/// axis arithmetic of plotters would overflow).
const LOG_LIMITS: (f64, f64) = (1e-100, 1e100);

/// Whether `v` can be drawn on a log axis of [`loglog_chart`]: finite, positive and within
/// `1e-100..=1e100`. Callers leave other values out of a chart (and say so).
pub fn log_drawable(v: f64) -> bool {
    (LOG_LIMITS.0..=LOG_LIMITS.1).contains(&v)
}

fn check_log_points(label: &str, points: &[(f64, f64)]) -> Result<()> {
    match points.iter().position(|&(x, y)| !(log_drawable(x) && log_drawable(y))) {
        Some(point) => Err(RenderError::NonPositiveLog {
            series: label.to_string(),
            point,
            x: points[point].0,
            y: points[point].1,
        }),
        None => Ok(()),
    }
}

/// Log-axis range around the data `[lo, hi]`: padded by 5 % of the data's
/// span in decades (at least 0.05 decade); widened to whole decades when that
/// would contain no power of ten (plotters labels only those and their
/// multiples).
fn log_axis_range(lo: f64, hi: f64) -> (f64, f64) {
    let (a, b) = (lo.log10(), hi.log10());
    let pad = (0.05 * (b - a)).max(0.05);
    let (a, b) = (a - pad, b + pad);
    let (a, b) = if a.ceil() <= b.floor() { (a, b) } else { (a.floor(), b.ceil()) };
    // Keep the axis arithmetic finite: at most 10 decades beyond the limits.
    let (a, b) = (a.max(LOG_LIMITS.0.log10() - 10.0), b.min(LOG_LIMITS.1.log10() + 10.0));
    (10f64.powf(a), 10f64.powf(b))
}

/// Whether the ticks of a log axis spanning `[lo, hi]` (all between 0.01
/// and 99999) get plain labels rather than `1e-3` style ones.
fn plain_axis(lo: f64, hi: f64) -> bool {
    lo >= 0.0099 && hi < 1e5
}

/// Picks the corner of the plot where the legend box (a `fw` × `fh`
/// fraction of the plot) covers the fewest samples of the drawn lines and
/// points, given in normalized log coordinates (`[0, 1]²`, y up).
fn legend_corner(samples: &[(f64, f64)], fw: f64, fh: f64) -> SeriesLabelPosition {
    let corners = [
        (SeriesLabelPosition::UpperRight, true, true),
        (SeriesLabelPosition::UpperLeft, false, true),
        (SeriesLabelPosition::LowerRight, true, false),
        (SeriesLabelPosition::LowerLeft, false, false),
    ];
    let covered = |right: bool, upper: bool| {
        samples
            .iter()
            .filter(|&&(x, y)| {
                let in_x = if right { x >= 1.0 - fw } else { x <= fw };
                let in_y = if upper { y >= 1.0 - fh } else { y <= fh };
                in_x && in_y
            })
            .count()
    };
    corners
        .iter()
        .map(|(pos, right, upper)| (covered(*right, *upper), pos))
        .min_by_key(|(n, _)| *n)
        .map(|(_, pos)| pos.clone())
        .unwrap_or(SeriesLabelPosition::UpperRight)
}

/// Checks a requested image size: both sides non-zero and at most [`crate::MAX_PIXELS`].
fn chart_size(width: u32, height: u32) -> Result<(u32, u32)> {
    if width == 0 || height == 0 {
        return Err(RenderError::ZeroSize { width, height });
    }
    check_image_size(u64::from(width), u64::from(height))
}

/// Font sizes, line widths and legend geometry of a chart, scaled with the image's smaller
/// side.
struct ChartStyle {
    /// The image's smaller side, in pixels.
    min_side: f64,
    caption_size: f64,
    label_size: f64,
    line_w: u32,
    legend_margin: u32,
    legend_area: u32,
    /// Length of a line sample in the legend.
    sample_len: i32,
}

impl ChartStyle {
    fn new(w: u32, h: u32) -> Self {
        let min_side = f64::from(h.min(w));
        let label_size = (min_side * 0.03).clamp(10.0, 20.0);
        let legend_margin = (label_size * 0.6).round() as u32;
        let legend_area = (label_size * 2.2).round() as u32;
        Self {
            min_side,
            caption_size: (min_side * 0.045).clamp(13.0, 30.0),
            label_size,
            line_w: ((min_side / 300.0).round() as u32).clamp(1, 4),
            legend_margin,
            legend_area,
            sample_len: legend_area as i32 - legend_margin as i32 / 2,
        }
    }

    /// Radius of the round data markers: `fraction` of the smaller side, between 2 and
    /// `max` pixels.
    fn marker(&self, fraction: f64, max: f64) -> u32 {
        (self.min_side * fraction).round().clamp(2.0, max) as u32
    }
}

/// Color of the `k`-th series: Tableau 10, repeating.
fn series_color(k: usize) -> RGBColor {
    let c = colorous::TABLEAU10[k % colorous::TABLEAU10.len()];
    RGBColor(c.r, c.g, c.b)
}

type Root<'b> = DrawingArea<BitMapBackend<'b>, Shift>;

/// A chart with axes `X` × `Y` drawn on a bitmap.
type Chart<'a, 'b, X, Y> = ChartContext<'a, BitMapBackend<'b>, Cartesian2d<X, Y>>;

/// Lets `draw` paint on a white `w` × `h` bitmap and returns the picture as PNG bytes.
fn draw_png(w: u32, h: u32, draw: impl FnOnce(&Root<'_>) -> Result<()>) -> Result<Vec<u8>> {
    let mut rgb = vec![255u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        draw(&root)?;
        root.present().map_err(draw_err)?;
    }
    rgb_to_png(&rgb, w, h)
}

/// One axis of a chart: its description, its range (linear or log) and its tick labels.
struct Axis<'f, R> {
    label: &'f str,
    range: R,
    format: &'f dyn Fn(&f64) -> String,
}

/// The chart of `root` over the axes `x` × `y`: caption, plot area, grid lines, tick
/// labels and axis descriptions.
fn chart_with_axes<'a, 'b, X, Y>(
    root: &'a Root<'b>,
    style: &ChartStyle,
    title: &str,
    x: Axis<'_, X>,
    y: Axis<'_, Y>,
) -> Result<Chart<'a, 'b, X::CoordDescType, Y::CoordDescType>>
where
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let label_size = style.label_size;
    let mut chart = ChartBuilder::on(root)
        .caption(title, (FAMILY, style.caption_size))
        .margin((label_size * 1.2) as u32)
        .x_label_area_size((label_size * 3.4) as u32)
        .y_label_area_size((label_size * 5.0) as u32)
        .build_cartesian_2d(x.range, y.range)
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .x_desc(x.label)
        .y_desc(y.label)
        .label_style((FAMILY, label_size))
        .axis_desc_style((FAMILY, label_size * 1.1))
        .x_label_formatter(x.format)
        .y_label_formatter(y.format)
        .bold_line_style(RGBColor(200, 200, 200))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(draw_err)?;
    Ok(chart)
}

/// Draws the legend box of the labelled series of `chart` at `position`.
fn draw_legend<'a, 'b: 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, CT>,
    style: &ChartStyle,
    position: SeriesLabelPosition,
) -> Result<()> {
    chart
        .configure_series_labels()
        .position(position)
        .margin(style.legend_margin)
        .legend_area_size(style.legend_area)
        .label_font((FAMILY, style.label_size))
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(120, 120, 120))
        .draw()
        .map_err(draw_err)
}

/// Smallest and largest x and y over all points of `series` and `pareto`.
///
/// Errors: [`RenderError::EmptyInput`] if there is no point at all.
fn data_bounds(series: &[Series], pareto: &[(f64, f64)]) -> Result<((f64, f64), (f64, f64))> {
    let all = series.iter().flat_map(|s| s.points.iter()).chain(pareto.iter());
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) =
        (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    let mut count = 0usize;
    for &(x, y) in all {
        count += 1;
        x_lo = x_lo.min(x);
        x_hi = x_hi.max(x);
        y_lo = y_lo.min(y);
        y_hi = y_hi.max(y);
    }
    if count == 0 {
        return Err(RenderError::EmptyInput { what: "the chart has no points".into() });
    }
    Ok(((x_lo, x_hi), (y_lo, y_hi)))
}

/// Draws a log-log chart and returns PNG bytes of `width` × `height`.
///
/// Each series is a line with round markers in its own color (Tableau 10,
/// repeating), listed in the legend. Points in `pareto` (in any order) are
/// drawn as large black rings joined, in order of x, by a thick dashed line
/// listed as "Pareto front". The axes span whole decades around all points.
///
/// # Errors
///
/// [`RenderError::ZeroSize`] / [`RenderError::ImageTooLarge`] for a bad
/// size, [`RenderError::EmptyInput`] if there is no point at all, and
/// [`RenderError::NonPositiveLog`] naming the series and the point index if
/// a coordinate is not finite and positive (or lies outside `1e-100..=1e100`).
pub fn loglog_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    pareto: &[(f64, f64)],
    width: u32,
    height: u32,
) -> Result<Vec<u8>> {
    let (w, h) = chart_size(width, height)?;
    for s in series {
        check_log_points(&s.label, &s.points)?;
    }
    check_log_points(PARETO_LABEL, pareto)?;
    let ((x_lo, x_hi), (y_lo, y_hi)) = data_bounds(series, pareto)?;
    let (x_lo, x_hi) = log_axis_range(x_lo, x_hi);
    let (y_lo, y_hi) = log_axis_range(y_lo, y_hi);
    let (x_plain, y_plain) = (plain_axis(x_lo, x_hi), plain_axis(y_lo, y_hi));
    ensure_fonts()?;

    let style = ChartStyle::new(w, h);
    let marker = style.marker(0.008, 6.0);
    let ring = (f64::from(marker) * 2.4).round() as u32;
    let legend = LegendBox::new(series, pareto, &style)?;

    draw_png(w, h, |root| {
        let x_fmt = |v: &f64| format_log_tick(*v, x_plain);
        let y_fmt = |v: &f64| format_log_tick(*v, y_plain);
        let mut chart = chart_with_axes(
            root,
            &style,
            title,
            Axis { label: x_label, range: (x_lo..x_hi).log_scale(), format: &x_fmt },
            Axis { label: y_label, range: (y_lo..y_hi).log_scale(), format: &y_fmt },
        )?;
        for (k, s) in series.iter().enumerate() {
            if !s.points.is_empty() {
                draw_marked_line(&mut chart, s, series_color(k), &style, marker)?;
            }
        }
        if !pareto.is_empty() {
            draw_pareto_front(&mut chart, pareto, &style, ring)?;
        }
        // Put the legend in the corner where it hides the least data.
        let (plot_w, plot_h) = chart.plotting_area().dim_in_pixel();
        let samples = log_line_samples(series, pareto, (x_lo, x_hi), (y_lo, y_hi));
        let corner = legend_corner(
            &samples,
            legend.width / f64::from(plot_w.max(1)),
            legend.height / f64::from(plot_h.max(1)),
        );
        draw_legend(&mut chart, &style, corner)
    })
}

/// Pixel size of the legend box of a [`loglog_chart`]: one entry per non-empty series and
/// one for a non-empty Pareto front.
struct LegendBox {
    width: f64,
    height: f64,
}

impl LegendBox {
    fn new(series: &[Series], pareto: &[(f64, f64)], style: &ChartStyle) -> Result<Self> {
        let mut entries: Vec<&str> =
            series.iter().filter(|s| !s.points.is_empty()).map(|s| s.label.as_str()).collect();
        if !pareto.is_empty() {
            entries.push(PARETO_LABEL);
        }
        let mut text_w = 0u32;
        for e in &entries {
            text_w = text_w.max(text_size(e, style.label_size)?.0);
        }
        Ok(Self {
            width: f64::from(text_w + style.legend_area + 2 * style.legend_margin + 10),
            height: entries.len() as f64 * style.label_size * 1.3 + f64::from(2 * style.legend_margin + 10),
        })
    }
}

/// Draws series `s` of a [`loglog_chart`] as a line with round markers, listed in the
/// legend.
fn draw_marked_line<'a, 'b: 'a, CT>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, CT>,
    s: &Series,
    color: RGBColor,
    style: &ChartStyle,
    marker: u32,
) -> Result<()>
where
    CT: CoordTranslate<From = (f64, f64)>,
{
    let (line_w, sample_len) = (style.line_w, style.sample_len);
    chart
        .draw_series(LineSeries::new(s.points.iter().copied(), color.stroke_width(line_w)))
        .map_err(draw_err)?
        .label(s.label.as_str())
        .legend(move |(x, y)| {
            EmptyElement::at((x, y))
                + PathElement::new(vec![(0, 0), (sample_len, 0)], color.stroke_width(line_w))
                + Circle::new((sample_len / 2, 0), marker, color.filled())
        });
    chart.draw_series(s.points.iter().map(|&p| Circle::new(p, marker, color.filled()))).map_err(draw_err)?;
    Ok(())
}

/// Draws the (non-empty) `pareto` points as black rings of radius `ring` joined, in order
/// of x, by a thick dashed line listed in the legend as [`PARETO_LABEL`].
fn draw_pareto_front<'a, 'b: 'a, CT>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, CT>,
    pareto: &[(f64, f64)],
    style: &ChartStyle,
    ring: u32,
) -> Result<()>
where
    CT: CoordTranslate<From = (f64, f64)>,
{
    let mut front = pareto.to_vec();
    front.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let stroke = BLACK.stroke_width(style.line_w + 1);
    let dash = (style.label_size * 0.6) as u32;
    let legend_ring = ring.min((style.label_size * 0.45) as u32);
    let sample_len = style.sample_len;
    chart
        .draw_series(DashedLineSeries::new(front.clone(), dash, dash * 2 / 3, stroke))
        .map_err(draw_err)?
        .label(PARETO_LABEL)
        .legend(move |(x, y)| {
            let r = legend_ring as i32;
            let mid = sample_len / 2;
            EmptyElement::at((x, y))
                + PathElement::new(vec![(0, 0), (mid - r - 1, 0)], stroke)
                + PathElement::new(vec![(mid + r + 1, 0), (sample_len, 0)], stroke)
                + Circle::new((mid, 0), legend_ring, BLACK.stroke_width(2))
        });
    chart
        .draw_series(front.iter().map(|&p| Circle::new(p, ring, BLACK.stroke_width(2))))
        .map_err(draw_err)?;
    Ok(())
}

/// Points along the drawn lines of a [`loglog_chart`] (the series and the Pareto front in
/// order of x), in normalized log coordinates of the axes `x` × `y`: every data point and
/// 15 samples inside each segment.
fn log_line_samples(
    series: &[Series],
    pareto: &[(f64, f64)],
    (x_lo, x_hi): (f64, f64),
    (y_lo, y_hi): (f64, f64),
) -> Vec<(f64, f64)> {
    let (lx, ly) = (x_lo.log10(), y_lo.log10());
    let (sx, sy) = (x_hi.log10() - lx, y_hi.log10() - ly);
    let norm = |(x, y): (f64, f64)| ((x.log10() - lx) / sx, (y.log10() - ly) / sy);
    let mut samples = Vec::new();
    let mut lines: Vec<Vec<(f64, f64)>> = series.iter().map(|s| s.points.clone()).collect();
    let mut front = pareto.to_vec();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    lines.push(front);
    for line in &lines {
        let pts: Vec<(f64, f64)> = line.iter().map(|&p| norm(p)).collect();
        samples.extend(pts.iter().copied());
        for seg in pts.windows(2) {
            for i in 1..16 {
                let t = f64::from(i) / 16.0;
                samples.push((seg[0].0 + t * (seg[1].0 - seg[0].0), seg[0].1 + t * (seg[1].1 - seg[0].1)));
            }
        }
    }
    samples
}

/// Linear axis range around the data `[lo, hi]`: padded by 5 % of the span (a unit
/// around a single value), and starting at 0 when `from_zero` and the data are
/// non-negative.
fn linear_axis_range(lo: f64, hi: f64, from_zero: bool) -> (f64, f64) {
    let span = hi - lo;
    let pad = if span > 0.0 { 0.05 * span } else { 0.5 * lo.abs().max(1.0) };
    let lo = if from_zero && lo >= 0.0 { 0.0 } else { lo - pad };
    (lo, hi + pad)
}

/// A tick label of a linear axis: plain with trailing zeros trimmed (`200`, `0.25`), or
/// `1.5e-5` style for very small and very large magnitudes.
fn format_linear_tick(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || !v.is_finite() {
        return "0".into();
    }
    if !(1e-3..1e7).contains(&a) {
        return format!("{v:.2e}");
    }
    let s = format!("{v:.6}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Draws a chart with linear axes and returns PNG bytes of `width` × `height`: each
/// series a line in its own color (Tableau 10, repeating) with small markers when it has
/// few points, listed in a legend when there is more than one series. The y axis starts
/// at 0 when every y is non-negative (magnitudes).
///
/// # Errors
///
/// [`RenderError::ZeroSize`] / [`RenderError::ImageTooLarge`] for a bad size,
/// [`RenderError::EmptyInput`] if there is no point at all, and
/// [`RenderError::NonFinitePoint`] naming the series and the point if a coordinate is NaN
/// or infinite.
pub fn line_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    width: u32,
    height: u32,
) -> Result<Vec<u8>> {
    let (w, h) = chart_size(width, height)?;
    for s in series {
        if let Some(point) = s.points.iter().position(|(x, y)| !(x.is_finite() && y.is_finite())) {
            let (x, y) = s.points[point];
            return Err(RenderError::NonFinitePoint { series: s.label.clone(), point, x, y });
        }
    }
    let all: Vec<(f64, f64)> = series.iter().flat_map(|s| s.points.iter().copied()).collect();
    if all.is_empty() {
        return Err(RenderError::EmptyInput { what: "the chart has no points".into() });
    }
    let fold =
        |f: fn(&(f64, f64)) -> f64, init: f64, pick: fn(f64, f64) -> f64| all.iter().map(f).fold(init, pick);
    let (x_lo, x_hi) = (fold(|p| p.0, f64::INFINITY, f64::min), fold(|p| p.0, f64::NEG_INFINITY, f64::max));
    let (y_lo, y_hi) = (fold(|p| p.1, f64::INFINITY, f64::min), fold(|p| p.1, f64::NEG_INFINITY, f64::max));
    let (x_lo, x_hi) = if x_hi > x_lo { (x_lo, x_hi) } else { linear_axis_range(x_lo, x_hi, false) };
    let (y_lo, y_hi) = linear_axis_range(y_lo, y_hi, true);
    ensure_fonts()?;

    let style = ChartStyle::new(w, h);
    let marker = style.marker(0.006, 5.0);
    let (line_w, sample_len) = (style.line_w, style.sample_len);

    draw_png(w, h, |root| {
        let fmt = |v: &f64| format_linear_tick(*v);
        let x = Axis { label: x_label, range: x_lo..x_hi, format: &fmt };
        let y = Axis { label: y_label, range: y_lo..y_hi, format: &fmt };
        let mut chart = chart_with_axes(root, &style, title, x, y)?;
        let labelled = series.iter().filter(|s| !s.points.is_empty()).count() > 1;
        for (k, s) in series.iter().enumerate() {
            if s.points.is_empty() {
                continue;
            }
            let color = series_color(k);
            let drawn = chart
                .draw_series(LineSeries::new(s.points.iter().copied(), color.stroke_width(line_w)))
                .map_err(draw_err)?;
            if labelled {
                drawn.label(s.label.as_str()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + sample_len, y)], color.stroke_width(line_w))
                });
            }
            if s.points.len() <= 60 {
                chart
                    .draw_series(s.points.iter().map(|&p| Circle::new(p, marker, color.filled())))
                    .map_err(draw_err)?;
            }
        }
        if labelled {
            draw_legend(&mut chart, &style, SeriesLabelPosition::UpperRight)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_range_pads_and_keeps_a_power_of_ten() {
        let (lo, hi) = log_axis_range(8e-4, 0.9);
        assert!(lo < 8e-4 && lo > 5e-4, "{lo}");
        assert!(hi > 0.9 && hi <= 1.5, "{hi}");
        // No power of ten inside 2..5 after padding: whole decades.
        assert_eq!(log_axis_range(2.0, 5.0), (1.0, 10.0));
        // A single value still gives a non-empty range.
        let (lo, hi) = log_axis_range(3.0, 3.0);
        assert!(lo < 3.0 && hi > 3.0);
    }

    #[test]
    fn linear_range_pads_and_starts_magnitudes_at_zero() {
        assert_eq!(linear_axis_range(2.0, 12.0, true), (0.0, 12.5));
        assert_eq!(linear_axis_range(-2.0, 8.0, true), (-2.5, 8.5));
        let (lo, hi) = linear_axis_range(3.0, 3.0, false);
        assert!(lo < 3.0 && hi > 3.0);
    }

    #[test]
    fn linear_ticks_are_trimmed() {
        assert_eq!(format_linear_tick(200.0), "200");
        assert_eq!(format_linear_tick(0.25), "0.25");
        assert_eq!(format_linear_tick(-2.5), "-2.5");
        assert_eq!(format_linear_tick(0.0), "0");
        assert_eq!(format_linear_tick(2e-5), "2.00e-5");
    }

    #[test]
    fn line_chart_rejects_nan_and_draws_a_png() {
        let bad = [Series { label: "r".into(), points: vec![(0.0, 1.0), (1.0, f64::NAN)] }];
        assert!(matches!(
            line_chart("t", "x", "y", &bad, 200, 150),
            Err(RenderError::NonFinitePoint { point: 1, .. })
        ));
        let good = [Series { label: "r".into(), points: vec![(0.0, 0.0), (1.0, 2.0), (2.0, 0.0)] }];
        let png = line_chart("t", "frame", "|F|", &good, 240, 160).unwrap();
        assert_eq!(&png[1..4], b"PNG");
    }

    #[test]
    fn legend_avoids_the_crowded_corner() {
        // Data along the rising diagonal: upper right and lower left are busy.
        let diagonal: Vec<(f64, f64)> = (0..=100).map(|i| (i as f64 / 100.0, i as f64 / 100.0)).collect();
        let pos = legend_corner(&diagonal, 0.3, 0.3);
        assert!(matches!(pos, SeriesLabelPosition::UpperLeft | SeriesLabelPosition::LowerRight), "{pos:?}");
        // Empty plot: the default upper right.
        assert_eq!(legend_corner(&[], 0.3, 0.3), SeriesLabelPosition::UpperRight);
    }
}
