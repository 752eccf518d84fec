//! Shaded, scalar-colored surface panels with a shared color bar.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::HPos;
use tiny_skia::{Color, FillRule, Paint, PathBuilder, Pixmap, Rect, Transform};

use crate::error::{RenderError, Result};
use crate::text::{
    check_image_size, draw_text_line, draw_text_vertical, ensure_fonts, format_ticks, rgb_to_png, text_color,
    text_size,
};

/// One surface to draw: a triangle mesh with one scalar value per vertex.
#[derive(Debug, Clone, PartialEq)]
pub struct Surface<'a> {
    /// Vertex positions.
    pub positions: &'a [[f64; 3]],
    /// Triangles as indices into `positions`.
    pub triangles: &'a [[u32; 3]],
    /// One value per vertex; each face is colored by the mean of its three
    /// vertex values.
    pub scalar: &'a [f64],
    /// Title drawn above the panel.
    pub title: String,
}

/// Color map used for the scalar field.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Colormap {
    /// Perceptually uniform purple → green → yellow (the default).
    #[default]
    Viridis,
    /// Google's Turbo rainbow: dark blue → green → red.
    Turbo,
    /// Perceptually uniform blue → magenta → yellow.
    Plasma,
    /// Perceptually uniform black → red → pale yellow.
    Inferno,
    /// Color-vision-deficiency friendly blue → yellow.
    Cividis,
}

impl Colormap {
    fn gradient(self) -> colorous::Gradient {
        match self {
            Colormap::Viridis => colorous::VIRIDIS,
            Colormap::Turbo => colorous::TURBO,
            Colormap::Plasma => colorous::PLASMA,
            Colormap::Inferno => colorous::INFERNO,
            Colormap::Cividis => colorous::CIVIDIS,
        }
    }

    /// The color at `t` in `[0, 1]` (clamped; NaN gives the low end).
    pub fn eval(self, t: f64) -> [u8; 3] {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        self.gradient().eval_continuous(t).into_array()
    }
}

/// Camera and look of [`render_surfaces`].
#[derive(Debug, Clone, PartialEq)]
pub struct ViewOptions {
    /// Width in pixels of one panel.
    pub width: u32,
    /// Height in pixels of one panel, title band included; also the height
    /// of the whole image.
    pub height: u32,
    /// Direction the (orthographic) camera looks along, in model
    /// coordinates. Need not be normalized. Default: a 3/4 view from the
    /// `+x, +y, +z` side, `(-1, -0.6, -1.6)` normalized.
    pub view_dir: [f64; 3],
    /// Model direction that appears upwards on screen (default `+y`). If it
    /// is parallel to `view_dir` another axis is used instead.
    pub up: [f64; 3],
    /// Color map of the scalar (default [`Colormap::Viridis`]).
    pub colormap: Colormap,
    /// Name of the scalar, written along the color bar (may be empty).
    pub scalar_label: String,
    /// Background color, RGB (default white). Text is drawn dark on light
    /// backgrounds and light on dark ones.
    pub background: [u8; 3],
    /// With a color here, a NaN scalar marks a vertex without a value: a face takes the
    /// mean of its vertices that have one, and this color when none has (default `None`:
    /// a NaN scalar is an error).
    pub no_value: Option<[u8; 3]>,
}

impl Default for ViewOptions {
    fn default() -> Self {
        let d: [f64; 3] = [-1.0, -0.6, -1.6];
        let n = norm(d);
        Self {
            width: 640,
            height: 640,
            view_dir: d.map(|c| c / n),
            up: [0.0, 1.0, 0.0],
            colormap: Colormap::Viridis,
            scalar_label: String::new(),
            background: [255, 255, 255],
            no_value: None,
        }
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Orthonormal camera frame: `right`, `up` on screen, `forward` into it.
struct Camera {
    right: [f64; 3],
    up: [f64; 3],
    forward: [f64; 3],
}

impl Camera {
    fn new(view_dir: [f64; 3], up: [f64; 3]) -> Result<Self> {
        let unit = |v: [f64; 3], what: &'static str| {
            let n = norm(v);
            if v.iter().all(|c| c.is_finite()) && n.is_finite() && n > 0.0 {
                Ok(v.map(|c| c / n))
            } else {
                Err(RenderError::InvalidView { what, value: v })
            }
        };
        let forward = unit(view_dir, "view_dir")?;
        let up = unit(up, "up")?;
        let mut right = cross(forward, up);
        if norm(right) < 1e-6 {
            // `up` is parallel to the view: use the model axis least aligned
            // with the view direction instead.
            let axis = (0..3).min_by(|&a, &b| forward[a].abs().total_cmp(&forward[b].abs())).unwrap_or(1);
            let mut alt = [0.0; 3];
            alt[axis] = 1.0;
            right = cross(forward, alt);
        }
        let n = norm(right);
        let right = right.map(|c| c / n);
        let up = cross(right, forward);
        Ok(Self { right, up, forward })
    }

    /// Screen x (right), screen y (up) and depth (larger = farther).
    fn project(&self, p: [f64; 3]) -> [f64; 3] {
        [dot(p, self.right), dot(p, self.up), dot(p, self.forward)]
    }
}

fn validate(index: usize, s: &Surface<'_>, allow_nan: bool) -> Result<()> {
    if s.positions.is_empty() {
        return Err(RenderError::EmptyInput {
            what: format!("panel {index} (\"{}\") has no vertices", s.title),
        });
    }
    if s.triangles.is_empty() {
        return Err(RenderError::EmptyInput {
            what: format!("panel {index} (\"{}\") has no triangles", s.title),
        });
    }
    if s.scalar.len() != s.positions.len() {
        return Err(RenderError::ScalarLength {
            panel: index,
            scalars: s.scalar.len(),
            vertices: s.positions.len(),
        });
    }
    if let Some((vertex, p)) = s.positions.iter().enumerate().find(|(_, p)| !p.iter().all(|c| c.is_finite()))
    {
        return Err(RenderError::NonFinitePosition { panel: index, vertex, position: *p });
    }
    if let Some((vertex, v)) =
        s.scalar.iter().enumerate().find(|(_, v)| !(v.is_finite() || allow_nan && v.is_nan()))
    {
        return Err(RenderError::NonFiniteScalar { panel: index, vertex, value: *v });
    }
    let n = s.positions.len();
    for (triangle, tri) in s.triangles.iter().enumerate() {
        if let Some(&bad) = tri.iter().find(|&&i| i as usize >= n) {
            return Err(RenderError::IndexOutOfRange { panel: index, triangle, index: bad, vertex_count: n });
        }
    }
    Ok(())
}

/// The range mapped onto the color map: the explicit one or the union of
/// all scalars, widened around its value when it is a single point.
/// Values at or above this many times the [`OUTLIER_QUANTILE`] quantile are outliers for
/// [`robust_range`].
pub const OUTLIER_FACTOR: f64 = 3.0;

/// The quantile of the nonzero magnitudes that [`robust_range`] compares the largest with.
pub const OUTLIER_QUANTILE: f64 = 0.95;

/// A color range `(0, q)` that keeps a few extreme values from darkening the whole
/// picture: `q` the [`OUTLIER_QUANTILE`] quantile of the nonzero magnitudes of `values`,
/// returned only when the largest is at least [`OUTLIER_FACTOR`] times `q` (values above it
/// are drawn at the top of the scale). `None`: the full range shows every value.
pub fn robust_range(values: &[f64]) -> Option<(f64, f64)> {
    let mut nonzero: Vec<f64> =
        values.iter().map(|v| v.abs()).filter(|v| *v > 0.0 && v.is_finite()).collect();
    if nonzero.len() < 2 {
        return None;
    }
    nonzero.sort_by(f64::total_cmp);
    let k = ((nonzero.len() - 1) as f64 * OUTLIER_QUANTILE).floor() as usize;
    let (quantile, largest) = (nonzero[k], nonzero[nonzero.len() - 1]);
    (largest >= OUTLIER_FACTOR * quantile).then_some((0.0, quantile))
}

fn color_range(panels: &[Surface<'_>], range: Option<(f64, f64)>) -> Result<(f64, f64)> {
    let (lo, hi) = match range {
        Some((lo, hi)) => {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(RenderError::InvalidRange { min: lo, max: hi });
            }
            (lo, hi)
        }
        None => panels
            .iter()
            .flat_map(|p| p.scalar.iter().copied())
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v))),
    };
    // Only vertices without a value: any range will do.
    let (lo, hi) = if lo <= hi { (lo, hi) } else { (0.0, 0.0) };
    if 0.5 * hi - 0.5 * lo > 0.5e-12 * lo.abs().max(hi.abs()) {
        Ok((lo, hi))
    } else {
        let mid = 0.5 * lo + 0.5 * hi;
        let half = if mid == 0.0 { 1.0 } else { 0.05 * mid.abs() };
        Ok((mid - half, mid + half))
    }
}

/// Pixel layout shared by all panels.
struct Layout {
    title_size: f64,
    tick_size: f64,
    /// Height of the title band at the top of each panel.
    title_band: f64,
    /// Drawing rectangle of the mesh inside a panel: left, top, width, height.
    mesh_rect: [f64; 4],
}

impl Layout {
    fn new(width: u32, height: u32) -> Self {
        let (w, h) = (f64::from(width), f64::from(height));
        let title_size = (h * 0.04).clamp(12.0, 30.0);
        let tick_size = (h * 0.03).clamp(10.0, 22.0);
        let title_band = (title_size * 1.8).round();
        let margin = (0.04 * w.min(h)).round().max(1.0);
        let top = title_band + margin * 0.5;
        let mesh_w = (w - 2.0 * margin).max(1.0);
        let mesh_h = (h - top - margin).max(1.0);
        Self { title_size, tick_size, title_band, mesh_rect: [margin, top, mesh_w, mesh_h] }
    }
}

/// The color-bar strip right of the panels: its place, its size and its tick labels.
struct ColorBar {
    /// Tick labels from the low end (bottom) to the high end (top).
    tick_labels: Vec<String>,
    /// Width of the widest tick label.
    label_w: u32,
    pad: f64,
    /// Left edge of the bar.
    x: f64,
    /// Top edge of the bar.
    top: f64,
    bar_w: f64,
    bar_h: f64,
    tick_len: f64,
    /// Width reserved for the rotated scalar label (0 without one).
    scalar_band: f64,
}

impl ColorBar {
    /// The bar for the color range `lo..hi`, right of panels `panels_w` pixels wide in
    /// total.
    fn new(layout: &Layout, (lo, hi): (f64, f64), scalar_label: &str, panels_w: u64) -> Result<Self> {
        let tick_values: Vec<f64> = (0..5)
            .map(|k| {
                let f = f64::from(k) / 4.0;
                lo * (1.0 - f) + hi * f
            })
            .collect();
        let tick_labels = format_ticks(&tick_values);
        let mut label_w = 0u32;
        for label in &tick_labels {
            label_w = label_w.max(text_size(label, layout.tick_size)?.0);
        }
        let pad = (layout.tick_size * 0.8).round();
        let [_, my, _, mh] = layout.mesh_rect;
        Ok(Self {
            tick_labels,
            label_w,
            pad,
            x: panels_w as f64 + pad,
            top: my.round(),
            bar_w: (layout.tick_size * 1.2).round(),
            bar_h: mh.round().max(2.0),
            tick_len: (layout.tick_size * 0.35).round().max(3.0),
            scalar_band: if scalar_label.is_empty() { 0.0 } else { (layout.tick_size * 1.5).round() },
        })
    }

    /// Width of the whole strip: bar, ticks, labels and scalar label, with padding.
    fn strip_width(&self) -> f64 {
        2.0 * self.pad
            + self.bar_w
            + self.tick_len
            + 0.4 * self.pad
            + f64::from(self.label_w)
            + self.scalar_band
    }

    /// Pixel rows of the five ticks, from the bottom of the bar to its top.
    fn tick_rows(&self) -> Vec<f64> {
        (0..5)
            .map(|k| (self.top + self.bar_h - 1.0 - (self.bar_h - 1.0) * f64::from(k) / 4.0).round())
            .collect()
    }

    /// Left edge of the tick labels.
    fn label_x(&self) -> i32 {
        (self.x + self.bar_w + self.tick_len + 0.4 * self.pad).round() as i32
    }

    /// Paints the gradient rows, the outline and the tick marks (in `fg`).
    fn paint(&self, pixmap: &mut Pixmap, colormap: Colormap, fg: RGBColor) {
        let mut paint = Paint { anti_alias: false, ..Paint::default() };
        let (x, top, w, h) = (self.x, self.top, self.bar_w, self.bar_h);
        let rows = h as u32;
        for row in 0..rows {
            let t = 1.0 - f64::from(row) / f64::from(rows - 1);
            let [r, g, b] = colormap.eval(t);
            paint.set_color_rgba8(r, g, b, 255);
            fill_rect(pixmap, &paint, x, top + f64::from(row), w, 1.0);
        }
        paint.set_color_rgba8(fg.0, fg.1, fg.2, 255);
        let line = 1.0;
        fill_rect(pixmap, &paint, x, top - line, w, line);
        fill_rect(pixmap, &paint, x, top + h, w, line);
        fill_rect(pixmap, &paint, x - line, top - line, line, h + 2.0);
        fill_rect(pixmap, &paint, x + w, top - line, line, h + 2.0);
        for y in self.tick_rows() {
            fill_rect(pixmap, &paint, x + w, y, self.tick_len, line);
        }
    }

    /// Writes the tick labels and, rotated beside them, `scalar_label`.
    fn draw_labels<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        tick_size: f64,
        scalar_label: &str,
        fg: RGBColor,
    ) -> Result<()> {
        let label_x = self.label_x();
        for (label, y) in self.tick_labels.iter().zip(self.tick_rows()) {
            draw_text_line(root, label, (label_x, y as i32), tick_size, HPos::Left, fg)?;
        }
        if !scalar_label.is_empty() {
            let x = label_x as f64 + f64::from(self.label_w) + 0.5 * self.scalar_band + 0.2 * tick_size;
            let y = self.top + 0.5 * self.bar_h;
            draw_text_vertical(root, scalar_label, (x.round() as i32, y.round() as i32), tick_size, fg)?;
        }
        Ok(())
    }
}

/// Where projected points land in a panel: the union of all panels' projections, centred
/// and scaled to fit the mesh rectangle.
struct Framing {
    center: [f64; 2],
    scale: f64,
    mesh_rect: [f64; 4],
}

impl Framing {
    fn fit(projected: &[Vec<[f64; 3]>], mesh_rect: [f64; 4]) -> Self {
        let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        let mut extent = 0.0f64;
        for q in projected.iter().flatten() {
            for k in 0..2 {
                min[k] = min[k].min(q[k]);
                max[k] = max[k].max(q[k]);
                extent = extent.max(q[k].abs());
            }
        }
        let [_, _, mw, mh] = mesh_rect;
        let tiny = 1e-12 * (1.0 + extent);
        let span = [(max[0] - min[0]).max(tiny), (max[1] - min[1]).max(tiny)];
        let scale = (mw / span[0]).min(mh / span[1]);
        let scale = if scale.is_finite() { scale } else { 1.0 };
        let center = [0.5 * (min[0] + max[0]), 0.5 * (min[1] + max[1])];
        Self { center, scale, mesh_rect }
    }

    /// Pixel position of the projected point `q` in the panel whose left edge is at `ox`.
    fn to_px(&self, ox: f64, q: [f64; 3]) -> (f32, f32) {
        let [mx, my, mw, mh] = self.mesh_rect;
        (
            (ox + mx + 0.5 * mw + (q[0] - self.center[0]) * self.scale) as f32,
            (my + 0.5 * mh - (q[1] - self.center[1]) * self.scale) as f32,
        )
    }
}

/// How a face is colored: the color map of its mean scalar over `lo..hi`, darkened by
/// two-sided Lambert shading.
struct Shading {
    /// Unit direction towards the light: from the camera, a bit from the upper left.
    light: [f64; 3],
    colormap: Colormap,
    lo: f64,
    hi: f64,
    /// The color of a face none of whose vertices has a value.
    no_value: [u8; 3],
}

impl Shading {
    fn new(camera: &Camera, colormap: Colormap, (lo, hi): (f64, f64), no_value: Option<[u8; 3]>) -> Self {
        let l: [f64; 3] =
            std::array::from_fn(|k| -camera.forward[k] + 0.45 * camera.up[k] - 0.3 * camera.right[k]);
        let n = norm(l);
        Self { light: l.map(|c| c / n), colormap, lo, hi, no_value: no_value.unwrap_or([160; 3]) }
    }

    /// The color of the face with vertices `[a, b, c]` of `panel`, or `None` if it is
    /// degenerate (covers no area).
    fn face_color(&self, panel: &Surface<'_>, [a, b, c]: [usize; 3]) -> Option<[u8; 3]> {
        let (pa, pb, pc) = (panel.positions[a], panel.positions[b], panel.positions[c]);
        // Edges scaled to unit size so huge or tiny meshes neither
        // overflow nor underflow.
        let (e1, e2) = (sub(pb, pa), sub(pc, pa));
        let m = e1.iter().chain(&e2).fold(0.0f64, |m, c| m.max(c.abs()));
        let normal = cross(e1.map(|c| c / m), e2.map(|c| c / m));
        let len = norm(normal);
        if !(len > 0.0 && len.is_finite()) {
            return None;
        }
        let lambert = (dot(normal, self.light) / len).abs();
        let shade = 0.3 + 0.7 * lambert;
        let values = [a, b, c].map(|v| panel.scalar[v]);
        let with_value = values.iter().filter(|v| !v.is_nan()).count();
        let rgb = if with_value == 0 {
            self.no_value
        } else {
            let mean = values.iter().filter(|v| !v.is_nan()).map(|v| v / with_value as f64).sum::<f64>();
            self.colormap.eval((0.5 * mean - 0.5 * self.lo) / (0.5 * self.hi - 0.5 * self.lo))
        };
        Some(rgb.map(|ch| (f64::from(ch) * shade).round().clamp(0.0, 255.0) as u8))
    }
}

/// Paints the faces of `panel` (vertices projected in `proj`) back to front into the panel
/// whose left edge is at `ox`.
fn paint_panel(
    pixmap: &mut Pixmap,
    panel: &Surface<'_>,
    proj: &[[f64; 3]],
    ox: f64,
    framing: &Framing,
    shading: &Shading,
) {
    let mut paint = Paint { anti_alias: false, ..Paint::default() };
    let mut faces: Vec<(f64, usize)> = panel
        .triangles
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let depth: f64 = t.iter().map(|&v| proj[v as usize][2]).sum();
            (depth, i)
        })
        .collect();
    // Back to front: farthest (largest depth) first.
    faces.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
    for &(_, fi) in &faces {
        let corners = panel.triangles[fi].map(|v| v as usize);
        let Some([cr, cg, cb]) = shading.face_color(panel, corners) else {
            continue;
        };
        paint.set_color_rgba8(cr, cg, cb, 255);
        let [(x0, y0), (x1, y1), (x2, y2)] = corners.map(|v| framing.to_px(ox, proj[v]));
        let mut pb = PathBuilder::with_capacity(4, 4);
        pb.move_to(x0, y0);
        pb.line_to(x1, y1);
        pb.line_to(x2, y2);
        pb.close();
        if let Some(path) = pb.finish() {
            pixmap.fill_path(&path, &paint, FillRule::Winding, Transform::identity(), None);
        }
    }
}

/// Writes the panel titles and the color bar's labels onto `rgb`, a `size` RGB picture.
fn draw_text(
    rgb: &mut [u8],
    size: (u32, u32),
    panels: &[Surface<'_>],
    opts: &ViewOptions,
    layout: &Layout,
    bar: &ColorBar,
) -> Result<()> {
    let fg = text_color(opts.background);
    let root = BitMapBackend::with_buffer(rgb, size).into_drawing_area();
    let title_y = (layout.title_band * 0.55).round() as i32;
    for (pi, panel) in panels.iter().enumerate() {
        let cx = (f64::from(opts.width) * (pi as f64 + 0.5)).round() as i32;
        draw_text_line(&root, &panel.title, (cx, title_y), layout.title_size, HPos::Center, fg)?;
    }
    bar.draw_labels(&root, layout.tick_size, &opts.scalar_label, fg)?;
    root.present().map_err(crate::text::draw_err)
}

/// Renders `panels` side by side and returns PNG bytes.
///
/// All panels share one orthographic camera ([`ViewOptions::view_dir`],
/// [`ViewOptions::up`]) framed on the union of their screen-space bounding
/// boxes, so equal geometry appears at equal size and place. Each face is
/// flat Lambert shaded (two-sided, light from the camera's upper left) times
/// the color-map color of the mean of its vertex scalars (see
/// [`ViewOptions::no_value`] for vertices without one), and faces are
/// painted back to front. Each panel has its title above it; one color bar
/// on the right shows the color range with five plain-number tick labels
/// (min, max and three between) and [`ViewOptions::scalar_label`].
///
/// The color range is `range` if given (values outside are clamped),
/// otherwise the union of all panels' scalars. A single-valued range (e.g.
/// a constant scalar) is widened around its value, so the surface gets the
/// middle color of the map.
///
/// The image is `opts.height` pixels tall and `panels.len() * opts.width`
/// pixels plus the color-bar strip wide.
///
/// # Errors
///
/// [`RenderError::ZeroSize`], [`RenderError::EmptyInput`],
/// [`RenderError::ScalarLength`], [`RenderError::NonFinitePosition`],
/// [`RenderError::NonFiniteScalar`], [`RenderError::IndexOutOfRange`],
/// [`RenderError::InvalidRange`], [`RenderError::InvalidView`] and
/// [`RenderError::ImageTooLarge`] for bad input.
pub fn render_surfaces(
    panels: &[Surface<'_>],
    range: Option<(f64, f64)>,
    opts: &ViewOptions,
) -> Result<Vec<u8>> {
    if opts.width == 0 || opts.height == 0 {
        return Err(RenderError::ZeroSize { width: opts.width, height: opts.height });
    }
    if panels.is_empty() {
        return Err(RenderError::EmptyInput { what: "no surfaces to render".into() });
    }
    for (i, p) in panels.iter().enumerate() {
        validate(i, p, opts.no_value.is_some())?;
    }
    let range = color_range(panels, range)?;
    let camera = Camera::new(opts.view_dir, opts.up)?;
    ensure_fonts()?;

    let layout = Layout::new(opts.width, opts.height);
    let panels_w = u64::from(opts.width) * panels.len() as u64;
    let bar = ColorBar::new(&layout, range, &opts.scalar_label, panels_w)?;
    let (img_w, img_h) = check_image_size(panels_w + bar.strip_width() as u64, u64::from(opts.height))?;
    let mut pixmap = Pixmap::new(img_w, img_h)
        .ok_or(RenderError::ImageTooLarge { width: u64::from(img_w), height: u64::from(img_h) })?;
    let [br, bg, bb] = opts.background;
    pixmap.fill(Color::from_rgba8(br, bg, bb, 255));

    // Project every vertex once and frame the union of all panels.
    let projected: Vec<Vec<[f64; 3]>> =
        panels.iter().map(|p| p.positions.iter().map(|&x| camera.project(x)).collect()).collect();
    let framing = Framing::fit(&projected, layout.mesh_rect);
    let shading = Shading::new(&camera, opts.colormap, range, opts.no_value);
    for (pi, (panel, proj)) in panels.iter().zip(&projected).enumerate() {
        let ox = f64::from(opts.width) * pi as f64;
        paint_panel(&mut pixmap, panel, proj, ox, &framing, &shading);
    }
    bar.paint(&mut pixmap, opts.colormap, text_color(opts.background));

    // Text: drawn by plotters on an RGB copy of the picture.
    let mut rgb: Vec<u8> = Vec::with_capacity(img_w as usize * img_h as usize * 3);
    for px in pixmap.pixels() {
        rgb.extend_from_slice(&[px.red(), px.green(), px.blue()]);
    }
    drop(pixmap);
    draw_text(&mut rgb, (img_w, img_h), panels, opts, &layout, &bar)?;
    rgb_to_png(&rgb, img_w, img_h)
}

fn fill_rect(pixmap: &mut Pixmap, paint: &Paint<'_>, x: f64, y: f64, w: f64, h: f64) {
    if let Some(rect) = Rect::from_xywh(x as f32, y as f32, w as f32, h as f32) {
        pixmap.fill_rect(rect, paint, Transform::identity(), None);
    }
}
