//! Pictures joined into one.

use tiny_skia::{Color, Pixmap, PixmapPaint, Transform};

use crate::error::{RenderError, Result};
use crate::text::check_image_size;

/// Joins the PNG pictures `pngs` left to right, their tops aligned, on a white background
/// as tall as the tallest; returns PNG bytes.
///
/// # Errors
///
/// [`RenderError::EmptyInput`] without pictures, [`RenderError::Encode`] for bytes that
/// are not a PNG, [`RenderError::ImageTooLarge`] when the joined picture would be.
pub fn side_by_side(pngs: &[&[u8]]) -> Result<Vec<u8>> {
    if pngs.is_empty() {
        return Err(RenderError::EmptyInput { what: "no pictures to join".into() });
    }
    let pictures: Vec<Pixmap> = pngs
        .iter()
        .map(|p| Pixmap::decode_png(p).map_err(|e| RenderError::Encode(format!("not a PNG picture: {e}"))))
        .collect::<Result<_>>()?;
    let width: u64 = pictures.iter().map(|p| u64::from(p.width())).sum();
    let height = pictures.iter().map(Pixmap::height).max().unwrap_or(0);
    let (w, h) = check_image_size(width, u64::from(height))?;
    let mut joined =
        Pixmap::new(w, h).ok_or(RenderError::ImageTooLarge { width: u64::from(w), height: u64::from(h) })?;
    joined.fill(Color::WHITE);
    let mut x = 0;
    for p in &pictures {
        joined.draw_pixmap(x, 0, p.as_ref(), &PixmapPaint::default(), Transform::identity(), None);
        x += p.width() as i32;
    }
    joined.encode_png().map_err(|e| RenderError::Encode(e.to_string()))
}
