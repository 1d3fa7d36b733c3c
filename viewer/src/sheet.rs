//! Contact sheets: one PNG grid of offscreen renders, a row per baked file (a wedge's
//! variants) and a column per frame, each row under a label strip saying what it is, so an
//! artist compares variants by looking. Text is drawn with the 8×8 bitmap font of
//! `font8x8` at twice its size.

use crate::raster::Image;
use crate::source::ViewSource;
use crate::{initial_camera, render_frame, ViewerError, MAX_SCREENSHOT_SIDE};
use std::path::PathBuf;

/// One row of the sheet.
#[derive(Debug, Clone, PartialEq)]
pub struct SheetRow {
    pub file: PathBuf,
    pub label: String,
}

/// Height of a row's label strip, pixels.
pub const LABEL_HEIGHT: u32 = 22;
const LABEL_BACKGROUND: [u8; 3] = [24, 26, 30];
const LABEL_TEXT: [u8; 3] = [235, 235, 235];
const FRAME_TEXT: [u8; 3] = [250, 220, 120];

/// Renders every row's `frames` (1-based) at `cell` pixels each; rows that would make the
/// sheet taller than the largest image side are refused with the count that fits.
pub fn contact_sheet(
    rows: &[SheetRow],
    frames: &[usize],
    cell: (u32, u32),
) -> Result<Image, ViewerError> {
    let (cw, ch) = cell;
    let width = cw.saturating_mul(frames.len() as u32);
    let row_height = ch + LABEL_HEIGHT;
    let height = row_height.saturating_mul(rows.len() as u32);
    if rows.is_empty() || frames.is_empty() || cw == 0 || ch == 0 {
        return Err(ViewerError::Usage(
            "a contact sheet needs rows, frames and a cell size".into(),
        ));
    }
    if width > MAX_SCREENSHOT_SIDE || height > MAX_SCREENSHOT_SIDE {
        return Err(ViewerError::Usage(format!(
            "a contact sheet of {} rows × {} frames at {cw}x{ch} would be {width}x{height} \
             pixels; at most {MAX_SCREENSHOT_SIDE} a side ({} rows fit)",
            rows.len(),
            frames.len(),
            MAX_SCREENSHOT_SIDE / row_height
        )));
    }
    let mut sheet = Image::filled(width, height, LABEL_BACKGROUND);
    let registry = springbake_pipeline::default_registry();
    for (r, row) in rows.iter().enumerate() {
        let top = r as u32 * row_height;
        let mut source = ViewSource::open(&registry, &row.file)?;
        let camera = initial_camera(&source);
        // Twice the font's size when the label fits, else its own 8 pixels.
        let scale = if 4 + row.label.chars().count() as u32 * 16 <= width {
            2
        } else {
            1
        };
        let y = top + if scale == 2 { 3 } else { 7 };
        draw_text(&mut sheet, 4, y, &row.label, LABEL_TEXT, width - 4, scale);
        for (c, &frame) in frames.iter().enumerate() {
            let frame = frame.clamp(1, source.frame_count().max(1));
            let image = render_frame(&mut source, &row.file, &camera, frame, cell)?;
            let left = c as u32 * cw;
            blit(&mut sheet, &image, left, top + LABEL_HEIGHT);
            let text = format!("frame {frame}");
            let y = top + LABEL_HEIGHT + 4;
            draw_text(&mut sheet, left + 4, y, &text, FRAME_TEXT, left + cw, 2);
        }
    }
    Ok(sheet)
}

fn blit(dst: &mut Image, src: &Image, left: u32, top: u32) {
    for y in 0..src.height.min(dst.height.saturating_sub(top)) {
        let w = src.width.min(dst.width.saturating_sub(left)) as usize * 4;
        let from = (y * src.width) as usize * 4;
        let to = ((top + y) * dst.width + left) as usize * 4;
        dst.rgba[to..to + w].copy_from_slice(&src.rgba[from..from + w]);
    }
}

/// Draws `text` at (x, y) in the 8×8 font scaled `scale`×, clipped at `right`; characters
/// the font lacks are drawn as `?`.
pub fn draw_text(
    image: &mut Image,
    x: u32,
    y: u32,
    text: &str,
    rgb: [u8; 3],
    right: u32,
    scale: u32,
) {
    use font8x8::UnicodeFonts;
    let mut pen = x;
    for ch in text.chars() {
        if pen + 8 * scale > right.min(image.width) {
            break;
        }
        let glyph = font8x8::BASIC_FONTS
            .get(ch)
            .or_else(|| font8x8::BASIC_FONTS.get('?'))
            .unwrap_or([0; 8]);
        for (gy, bits) in glyph.iter().enumerate() {
            for gx in 0..8u32 {
                if bits & (1 << gx) == 0 {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        let (px, py) = (pen + gx * scale + dx, y + gy as u32 * scale + dy);
                        if px < image.width && py < image.height {
                            let i = (py * image.width + px) as usize * 4;
                            image.rgba[i..i + 3].copy_from_slice(&rgb);
                        }
                    }
                }
            }
        }
        pen += 8 * scale;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_drawn_in_its_colour_and_clipped() {
        let mut image = Image::filled(64, 20, [0, 0, 0]);
        draw_text(&mut image, 0, 0, "H", [255, 0, 0], 64, 2);
        let red = (0..16)
            .flat_map(|y| (0..16).map(move |x| (x, y)))
            .filter(|&(x, y)| image.pixel(x, y) == [255, 0, 0, 255])
            .count();
        assert!(red > 20, "{red} pixels of 'H'");
        let mut clipped = Image::filled(20, 20, [0, 0, 0]);
        draw_text(&mut clipped, 0, 0, "HHHH", [255, 0, 0], 20, 2);
        assert!((16..20).all(|x| clipped.pixel(x, 4) == [0, 0, 0, 255]));
    }
}
