//! The viewer's text overlay: lines of 8x8 glyphs (font8x8's public-domain ASCII set) over a
//! darkened box, so they stay readable on any image.

use font8x8::legacy::BASIC_LEGACY;

/// Pixels per text line (8 of glyph, 2 of spacing).
pub const LINE_HEIGHT: usize = 10;
const MARGIN: usize = 4;

/// A `0x00RRGGBB` colour.
pub const WHITE: u32 = 0x00FF_FFFF;
pub const YELLOW: u32 = 0x00FF_E060;
pub const RED: u32 = 0x00FF_7070;

/// Draws `lines` (text and colour) in the top-left corner of a `width x height` buffer of
/// `0x00RRGGBB` pixels: a box darkened to a quarter behind them, then the glyphs. Characters
/// outside ASCII are drawn as `?`; what does not fit is clipped.
pub fn draw(buffer: &mut [u32], width: usize, height: usize, lines: &[(String, u32)]) {
    if lines.is_empty() || width == 0 || buffer.len() < width * height {
        return;
    }
    let columns = lines.iter().map(|(t, _)| t.chars().count()).max().unwrap_or(0);
    let box_w = (2 * MARGIN + 8 * columns).min(width);
    let box_h = (2 * MARGIN + LINE_HEIGHT * lines.len()).min(height);
    for y in 0..box_h {
        for px in &mut buffer[y * width..y * width + box_w] {
            // Each channel to a quarter: shift right by two and mask off the bits shifted across.
            *px = (*px >> 2) & 0x003F_3F3F;
        }
    }
    for (row, (text, color)) in lines.iter().enumerate() {
        let y0 = MARGIN + row * LINE_HEIGHT;
        for (col, ch) in text.chars().enumerate() {
            let code = if ch.is_ascii() { ch as usize } else { '?' as usize };
            let glyph = BASIC_LEGACY[code];
            let x0 = MARGIN + col * 8;
            for (gy, bits) in glyph.iter().enumerate() {
                let y = y0 + gy;
                if y >= box_h {
                    break;
                }
                for gx in 0..8 {
                    let x = x0 + gx;
                    // font8x8 stores each row with its leftmost pixel in the lowest bit.
                    if x < box_w && bits >> gx & 1 != 0 {
                        buffer[y * width + x] = *color;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_drawn_over_a_darkened_box_and_clipped() {
        let (w, h) = (64, 20);
        let mut buf = vec![0x0080_8080u32; w * h];
        draw(&mut buf, w, h, &[("I".to_string(), WHITE), ("a very long line that is clipped".into(), RED)]);
        assert!(buf.contains(&WHITE), "a glyph pixel is white");
        assert!(buf.contains(&RED));
        assert_eq!(buf[(MARGIN - 1) * w + 2], 0x0020_2020, "the box darkens");
        assert_eq!(buf[(h - 1) * w + 1], 0x0020_2020, "the clipped box reaches the bottom");
        assert_eq!(buf[w - 1], 0x0020_2020, "the clipped box reaches the right edge");
        let mut untouched = vec![0x0080_8080u32; w * 40];
        draw(&mut untouched, w, 40, &[("x".into(), WHITE)]);
        assert_eq!(untouched[39 * w + 63], 0x0080_8080, "outside the box nothing changes");
    }
}
