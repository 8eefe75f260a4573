//! The fixed colours of the picture, as the 8-bit RGB values written to the image (the
//! render target is `Rgba8Unorm`, no sRGB conversion).
//!
//! Lit geometry (tissue, needle) is shaded: its pixels keep the hue of these colours and
//! scale in brightness from 35% (ambient only) up to full, plus a small white highlight.
//! The tissue is drawn with [`TISSUE_ALPHA`] over what lies behind it. Markers, the
//! background and the plot are flat: their pixels are exactly these values (except at
//! antialiased edges).

/// Background: a light grey-blue.
pub const BACKGROUND: [u8; 3] = [236, 239, 243];
/// Tissue surface: pink.
pub const TISSUE: [u8; 3] = [222, 118, 128];
/// Opacity of the tissue surface.
pub const TISSUE_ALPHA: f32 = 0.6;
/// Needle shaft and tip: steel blue.
pub const NEEDLE: [u8; 3] = [70, 110, 170];
/// Marker of a shaft node: orange.
pub const SHAFT_MARKER: [u8; 3] = [255, 128, 0];
/// Marker of the surface (entry) node: green.
pub const SURFACE_MARKER: [u8; 3] = [30, 200, 60];
/// Marker of the tip node: yellow.
pub const TIP_MARKER: [u8; 3] = [245, 215, 0];
/// Marker of an exit node (far surface): violet.
pub const EXIT_MARKER: [u8; 3] = [150, 60, 220];
/// Outline drawn around every marker: near black.
pub const MARKER_OUTLINE: [u8; 3] = [30, 30, 30];
/// Background of the force plot inset: white.
pub const PLOT_PANEL: [u8; 3] = [255, 255, 255];
/// Axes box of the plot: dark grey.
pub const PLOT_AXES: [u8; 3] = [70, 70, 70];
/// The zero-force line of the plot: light grey.
pub const PLOT_ZERO: [u8; 3] = [185, 185, 185];
/// The force against depth curve: blue.
pub const PLOT_CURVE: [u8; 3] = [31, 119, 180];
/// The latest sample on the curve: red.
pub const PLOT_CURRENT: [u8; 3] = [214, 39, 40];

/// Tissue colours of the regions after region 0 ([`TISSUE`]), in the order of the scene's
/// `[[region]]` tables, repeating: beige, yellow, dark red, brown, lilac, teal.
pub const REGIONS: [[u8; 3]; 6] = [
    [232, 196, 160],
    [238, 212, 110],
    [170, 52, 62],
    [150, 95, 70],
    [180, 140, 200],
    [90, 170, 160],
];

/// The tissue colour of region `r`: [`TISSUE`] for region 0 (nodes in no `[[region]]`).
pub fn region(r: u16) -> [u8; 3] {
    match r {
        0 => TISSUE,
        r => REGIONS[(r as usize - 1) % REGIONS.len()],
    }
}

/// An 8-bit colour as linear 0..1 floats with the given alpha.
pub fn rgba(c: [u8; 3], alpha: f32) -> [f32; 4] {
    [
        c[0] as f32 / 255.0,
        c[1] as f32 / 255.0,
        c[2] as f32 / 255.0,
        alpha,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_have_their_own_colours() {
        assert_eq!(region(0), TISSUE);
        let first: Vec<[u8; 3]> = (1..=6).map(region).collect();
        assert!(first.iter().all(|c| *c != TISSUE));
        assert_eq!(region(7), region(1));
    }
}
