//! Bundled font, text drawing helpers, number formatting and PNG output.

use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{FontStyle, FontTransform, register_font};

use crate::error::{RenderError, Result};

/// DejaVu Sans, see `assets/LICENSE-DejaVu.txt`.
static FONT_BYTES: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// Family name under which the bundled font is registered with plotters.
pub(crate) const FAMILY: &str = "fibfluid-sans";

/// Registers the bundled font with plotters (once per process).
pub(crate) fn ensure_fonts() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        [FAMILY, "sans-serif"].iter().all(|name| register_font(name, FontStyle::Normal, FONT_BYTES).is_ok())
    });
    if ok { Ok(()) } else { Err(RenderError::Draw("the bundled font could not be loaded".into())) }
}

/// Maps any displayable drawing error into [`RenderError::Draw`].
pub(crate) fn draw_err<E: std::fmt::Display>(e: E) -> RenderError {
    RenderError::Draw(e.to_string())
}

/// Width and height in pixels of `text` at `size` in the bundled font.
pub(crate) fn text_size(text: &str, size: f64) -> Result<(u32, u32)> {
    if text.is_empty() {
        return Ok((0, 0));
    }
    (FAMILY, size).into_font().box_size(text).map_err(draw_err)
}

/// Fraction of the font size between the top of the layout box that plotters
/// uses for `VPos::Top` and the middle of the digits / capitals of the
/// bundled font (baseline at 0.5 em below the anchor, cap height 0.626 em).
const CAP_MIDDLE: f64 = 0.187;

/// Draws one line of text whose capitals are vertically centered on `y`.
pub(crate) fn draw_text_line<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    text: &str,
    (x, y): (i32, i32),
    size: f64,
    h_pos: HPos,
    color: RGBColor,
) -> Result<()> {
    if text.is_empty() {
        return Ok(());
    }
    let style = TextStyle::from((FAMILY, size).into_font()).color(&color).pos(Pos::new(h_pos, VPos::Top));
    let top = y - (CAP_MIDDLE * size).round() as i32;
    area.draw_text(text, &style, (x, top)).map_err(draw_err)
}

/// Draws text rotated to read bottom-to-top, centered on `(x, y)`
/// (horizontally the glyphs extend from about `x - 0.5 size` to `x + 0.1 size`).
pub(crate) fn draw_text_vertical<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    text: &str,
    (x, y): (i32, i32),
    size: f64,
    color: RGBColor,
) -> Result<()> {
    if text.is_empty() {
        return Ok(());
    }
    let style = TextStyle::from((FAMILY, size).into_font())
        .color(&color)
        .transform(FontTransform::Rotate270)
        .pos(Pos::new(HPos::Center, VPos::Center));
    area.draw_text(text, &style, (x, y)).map_err(draw_err)
}

/// Formats evenly spaced color-bar tick values as plain numbers: fixed point
/// for moderate magnitudes, `1.00e-3` style for very small or large ones.
/// Uses as few digits as keep neighbouring labels distinct and each label
/// within 1 % of a tick step of its value.
pub(crate) fn format_ticks(values: &[f64]) -> Vec<String> {
    let max_abs = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let step = values.windows(2).map(|w| (w[1] - w[0]).abs()).fold(f64::INFINITY, f64::min);
    let step = if step.is_finite() && step > 0.0 { step } else { max_abs.max(1.0) };
    let scientific = max_abs >= 1e5 || (max_abs > 0.0 && max_abs < 1e-2);
    let acceptable = |labels: &[String]| {
        labels.windows(2).all(|w| w[0] != w[1])
            && labels
                .iter()
                .zip(values)
                .all(|(s, v)| s.parse::<f64>().map(|p| (p - v).abs() <= 0.01 * step).unwrap_or(false))
    };
    let (first, last) = if scientific {
        (2usize, 10usize)
    } else {
        let d = (-step.log10().floor()).max(0.0) as usize;
        (d.min(12), 12)
    };
    let mut labels = Vec::new();
    for digits in first..=last {
        labels = values
            .iter()
            .map(|&v| {
                let v = if v == 0.0 { 0.0 } else { v };
                let s = if scientific { format!("{v:.digits$e}") } else { format!("{v:.digits$}") };
                strip_negative_zero(s)
            })
            .collect();
        if acceptable(&labels) {
            break;
        }
    }
    labels
}

/// Turns `-0.00` or `-0.00e0` into `0.00` / `0.00e0`.
fn strip_negative_zero(s: String) -> String {
    let mantissa = s.split('e').next().unwrap_or("");
    if s.starts_with('-') && mantissa[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// Formats a tick value of a logarithmic axis: plain (`0.25`, `300`) if
/// `plain`, else `2e-5` style.
pub(crate) fn format_log_tick(v: f64, plain: bool) -> String {
    if !(v.is_finite() && v > 0.0) {
        return String::new();
    }
    let mut e = v.log10().floor();
    let mut m = v / 10f64.powf(e);
    if m >= 9.9995 {
        m /= 10.0;
        e += 1.0;
    }
    let integral = (m - m.round()).abs() < 1e-3;
    let m_str = if integral { format!("{:.0}", m.round()) } else { format!("{m:.1}") };
    if plain {
        let decimals = ((-e).max(0.0) as usize) + usize::from(!integral);
        format!("{v:.decimals$}")
    } else {
        format!("{m_str}e{e}")
    }
}

/// Picks a text color that contrasts with `background`.
pub(crate) fn text_color(background: [u8; 3]) -> RGBColor {
    let [r, g, b] = background.map(f64::from);
    let luma = 0.299 * r + 0.587 * g + 0.114 * b;
    if luma > 128.0 { RGBColor(25, 25, 25) } else { RGBColor(235, 235, 235) }
}

/// Checks the size of a whole image against [`crate::MAX_PIXELS`].
pub(crate) fn check_image_size(width: u64, height: u64) -> Result<(u32, u32)> {
    let too_large = RenderError::ImageTooLarge { width, height };
    if width.saturating_mul(height) > crate::MAX_PIXELS {
        return Err(too_large);
    }
    match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) => Ok((w, h)),
        _ => Err(too_large),
    }
}

/// Encodes a tightly packed RGB buffer as PNG.
pub(crate) fn rgb_to_png(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>> {
    let mut rgba = Vec::with_capacity(rgb.len() / 3 * 4);
    for px in rgb.chunks_exact(3) {
        rgba.extend_from_slice(&[px[0], px[1], px[2], 255]);
    }
    let size = tiny_skia::IntSize::from_wh(width, height).ok_or(RenderError::ZeroSize { width, height })?;
    let pixmap = tiny_skia::Pixmap::from_vec(rgba, size)
        .ok_or_else(|| RenderError::Encode("pixel buffer has the wrong size".into()))?;
    pixmap.encode_png().map_err(|e| RenderError::Encode(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_plain_and_distinct() {
        assert_eq!(format_ticks(&[0.0, 0.25, 0.5, 0.75, 1.0]), ["0.00", "0.25", "0.50", "0.75", "1.00"]);
        assert_eq!(format_ticks(&[0.0, 25.0, 50.0, 75.0, 100.0]), ["0", "25", "50", "75", "100"]);
        assert_eq!(format_ticks(&[0.0, 0.001, 0.002]), ["0.00e0", "1.00e-3", "2.00e-3"]);
        assert_eq!(format_ticks(&[-1e-20, 1.0, 2.0]), ["0", "1", "2"]);
        assert_eq!(format_ticks(&[1e6, 2e6]), ["1.00e6", "2.00e6"]);
    }

    #[test]
    fn log_tick_labels() {
        assert_eq!(format_log_tick(1e-5, false), "1e-5");
        assert_eq!(format_log_tick(2e-5, false), "2e-5");
        assert_eq!(format_log_tick(1.0, false), "1e0");
        assert_eq!(format_log_tick(0.01, true), "0.01");
        assert_eq!(format_log_tick(0.25, true), "0.25");
        assert_eq!(format_log_tick(300.0, true), "300");
        assert_eq!(format_log_tick(1e4, false), "1e4");
        assert_eq!(format_log_tick(0.0, true), "");
    }
}
