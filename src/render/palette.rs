//! The fixed qualitative palette of septa's pictures: the patches of
//! `preview.png` and the labels of contour SVGs get their colours from it,
//! by index, so the same index is the same colour everywhere.
//!
//! The first 20 colours are Tableau's 10 strong colours, then their 10
//! light companions (matplotlib's `tab20` reordered), so a few patches get
//! colours far apart; past 20, hues step by the golden angle at two
//! lightnesses. Deterministic: a colour depends only on its index.

/// The first 20 colours (RGB).
pub const PALETTE: [[u8; 3]; 20] = [
    [0x1f, 0x77, 0xb4],
    [0xff, 0x7f, 0x0e],
    [0x2c, 0xa0, 0x2c],
    [0xd6, 0x27, 0x28],
    [0x94, 0x67, 0xbd],
    [0x8c, 0x56, 0x4b],
    [0xe3, 0x77, 0xc2],
    [0x7f, 0x7f, 0x7f],
    [0xbc, 0xbd, 0x22],
    [0x17, 0xbe, 0xcf],
    [0xae, 0xc7, 0xe8],
    [0xff, 0xbb, 0x78],
    [0x98, 0xdf, 0x8a],
    [0xff, 0x98, 0x96],
    [0xc5, 0xb0, 0xd5],
    [0xc4, 0x9c, 0x94],
    [0xf7, 0xb6, 0xd2],
    [0xc7, 0xc7, 0xc7],
    [0xdb, 0xdb, 0x8d],
    [0x9e, 0xda, 0xe5],
];

/// Colour number `i` (RGB).
pub fn color(i: usize) -> [u8; 3] {
    if let Some(&c) = PALETTE.get(i) {
        return c;
    }
    let k = i - PALETTE.len();
    let hue = (k as f64 * 137.507_764) % 360.0;
    let lightness = if k % 2 == 0 { 0.45 } else { 0.65 };
    hsl(hue, 0.65, lightness)
}

/// Colour number `i` as `#rrggbb`.
pub fn hex(i: usize) -> String {
    let [r, g, b] = color(i);
    format!("#{r:02x}{g:02x}{b:02x}")
}

fn hsl(h: f64, s: f64, l: f64) -> [u8; 3] {
    let c = (1.0 - (2.0 * l - 1.0).abs()) * s;
    let hp = h / 60.0;
    let x = c * (1.0 - (hp % 2.0 - 1.0).abs());
    let (r, g, b) = match hp as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = l - c / 2.0;
    [r, g, b].map(|v| ((v + m) * 255.0).round().clamp(0.0, 255.0) as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_are_distinct_and_stable() {
        let all: Vec<[u8; 3]> = (0..200).map(color).collect();
        let mut unique = all.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), all.len());
        assert_eq!(color(0), [0x1f, 0x77, 0xb4]);
        assert_eq!(hex(1), "#ff7f0e");
        assert_eq!(color(57), color(57));
    }
}
