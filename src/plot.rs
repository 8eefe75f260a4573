//! A small line-plot writer for PNG files: axes with ticks and numbers, a title, axis
//! labels, a legend, one polyline per series. Text uses a built-in 5x7 pixel font (no
//! system fonts needed, so plots come out the same on every machine).

use std::path::Path;

/// One curve.
pub struct Series<'a> {
    /// Legend text.
    pub label: &'a str,
    /// RGB colour.
    pub colour: [u8; 3],
    /// Points `(x, y)`; non-finite points break the line.
    pub points: Vec<(f64, f64)>,
}

/// A plot's texts.
pub struct Labels<'a> {
    /// Title above the plot.
    pub title: &'a str,
    /// Horizontal axis.
    pub x: &'a str,
    /// Vertical axis.
    pub y: &'a str,
}

const W: usize = 900;
const H: usize = 560;
const LEFT: usize = 90;
const RIGHT: usize = 30;
const TOP: usize = 50;
const BOTTOM: usize = 70;

struct Canvas {
    px: Vec<u8>,
}

impl Canvas {
    fn set(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < W && (y as usize) < H {
            let i = (y as usize * W + x as usize) * 3;
            self.px[i..i + 3].copy_from_slice(&c);
        }
    }

    fn line(&mut self, (x0, y0): (f64, f64), (x1, y1): (f64, f64), c: [u8; 3], thick: bool) {
        let n = ((x1 - x0).abs().max((y1 - y0).abs()).ceil() as usize).max(1);
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let (x, y) = (x0 + t * (x1 - x0), y0 + t * (y1 - y0));
            let (xi, yi) = (x.round() as i64, y.round() as i64);
            self.set(xi, yi, c);
            if thick {
                self.set(xi + 1, yi, c);
                self.set(xi, yi + 1, c);
            }
        }
    }

    /// Draws `text` with its left edge at `x` and top at `y`, `scale` pixels per font
    /// pixel; returns the width drawn.
    fn text(&mut self, x: i64, y: i64, text: &str, scale: i64, c: [u8; 3]) -> i64 {
        let mut cx = x;
        for ch in text.chars() {
            let g = glyph(ch);
            for (row, bits) in g.iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) != 0 {
                        for dy in 0..scale {
                            for dx in 0..scale {
                                self.set(cx + col * scale + dx, y + row as i64 * scale + dy, c);
                            }
                        }
                    }
                }
            }
            cx += 6 * scale;
        }
        cx - x
    }
}

fn text_width(text: &str, scale: i64) -> i64 {
    text.chars().count() as i64 * 6 * scale
}

/// About five round tick values covering `[lo, hi]`.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = (hi - lo).max(1e-300);
    let raw = span / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let mut v = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while v <= hi + 1e-9 * span {
        out.push(if v.abs() < 1e-12 * span { 0.0 } else { v });
        v += step;
    }
    out
}

/// Tick positions: on a log axis (values are log10) the 1, 2, 5 multiples of the decades
/// in range, only the decades when there are more than 8 of those, or the linear ticks of
/// the exponents when fewer than 2 fall in range.
fn axis_ticks(lo: f64, hi: f64, log: bool) -> Vec<f64> {
    if !log {
        return ticks(lo, hi);
    }
    let decades: Vec<f64> = (lo.floor() as i64..=hi.ceil() as i64)
        .map(|k| k as f64)
        .filter(|&k| k >= lo && k <= hi)
        .collect();
    if decades.len() > 8 {
        let step = (decades.len() as f64 / 6.0).ceil() as usize;
        return decades.into_iter().step_by(step).collect();
    }
    let fine: Vec<f64> = (lo.floor() as i64..=hi.ceil() as i64)
        .flat_map(|k| [1.0f64, 2.0, 5.0].map(|m| k as f64 + m.log10()))
        .filter(|&t| t >= lo && t <= hi)
        .collect();
    if fine.len() > 8 {
        decades
    } else if fine.len() >= 2 {
        fine
    } else {
        ticks(lo, hi)
    }
}

fn number(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e4).contains(&a) {
        format!("{v:.1e}")
    } else {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Axis scales and point markers.
#[derive(Debug, Clone, Copy, Default)]
pub struct Axes {
    /// Logarithmic horizontal axis (points with x <= 0 are left out).
    pub log_x: bool,
    /// Logarithmic vertical axis (points with y <= 0 are left out).
    pub log_y: bool,
    /// A small square at every point.
    pub markers: bool,
}

/// Writes the series as a line plot to `path` (PNG, 900 x 560), linear axes.
pub fn line_plot(path: &Path, labels: &Labels, series: &[Series]) -> std::io::Result<()> {
    plot(path, labels, Axes::default(), series)
}

/// Writes the series as a line plot to `path` (PNG, 900 x 560) with the given axes.
pub fn plot(path: &Path, labels: &Labels, axes: Axes, series: &[Series]) -> std::io::Result<()> {
    let mut cv = Canvas {
        px: vec![255; W * H * 3],
    };
    let tf = |v: f64, log: bool| {
        if !log {
            v
        } else if v > 0.0 {
            v.log10()
        } else {
            f64::NAN
        }
    };
    let series: Vec<Series> = series
        .iter()
        .map(|s| Series {
            label: s.label,
            colour: s.colour,
            points: s
                .points
                .iter()
                .map(|p| (tf(p.0, axes.log_x), tf(p.1, axes.log_y)))
                .collect(),
        })
        .collect();
    let finite = |p: &&(f64, f64)| p.0.is_finite() && p.1.is_finite();
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().filter(finite).copied())
        .collect();
    let (mut x0, mut x1, mut y0, mut y1) = all.iter().fold(
        (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ),
        |(a, b, c, d), p| (a.min(p.0), b.max(p.0), c.min(p.1), d.max(p.1)),
    );
    if all.is_empty() {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    for (lo, hi) in [(&mut x0, &mut x1), (&mut y0, &mut y1)] {
        if *hi - *lo <= 1e-12 * lo.abs().max(hi.abs()).max(1e-300) {
            *lo -= 0.5 * lo.abs().max(1e-9);
            *hi += 0.5 * hi.abs().max(1e-9);
        }
        let pad = 0.04 * (*hi - *lo);
        *lo -= pad;
        *hi += pad;
    }
    let (pw, ph) = ((W - LEFT - RIGHT) as f64, (H - TOP - BOTTOM) as f64);
    let sx = |x: f64| LEFT as f64 + (x - x0) / (x1 - x0) * pw;
    let sy = |y: f64| TOP as f64 + (y1 - y) / (y1 - y0) * ph;
    let grey = [225, 225, 225];
    let black = [0, 0, 0];
    let label = |t: f64, log: bool| {
        if log {
            number(10f64.powf(t))
        } else {
            number(t)
        }
    };
    for t in axis_ticks(x0, x1, axes.log_x) {
        let x = sx(t);
        cv.line((x, TOP as f64), (x, (H - BOTTOM) as f64), grey, false);
        let s = label(t, axes.log_x);
        cv.text(
            x as i64 - text_width(&s, 2) / 2,
            (H - BOTTOM + 8) as i64,
            &s,
            2,
            black,
        );
    }
    for t in axis_ticks(y0, y1, axes.log_y) {
        let y = sy(t);
        cv.line((LEFT as f64, y), ((W - RIGHT) as f64, y), grey, false);
        let s = label(t, axes.log_y);
        cv.text(
            LEFT as i64 - 8 - text_width(&s, 2),
            y as i64 - 7,
            &s,
            2,
            black,
        );
    }
    if !axes.log_y && y0 < 0.0 && y1 > 0.0 {
        cv.line(
            (LEFT as f64, sy(0.0)),
            ((W - RIGHT) as f64, sy(0.0)),
            [150; 3],
            false,
        );
    }
    let (l, r, t, b) = (
        LEFT as f64,
        (W - RIGHT) as f64,
        TOP as f64,
        (H - BOTTOM) as f64,
    );
    for (p, q) in [
        ((l, t), (r, t)),
        ((r, t), (r, b)),
        ((r, b), (l, b)),
        ((l, b), (l, t)),
    ] {
        cv.line(p, q, black, false);
    }
    for s in &series {
        let mut last: Option<(f64, f64)> = None;
        for p in &s.points {
            if !(p.0.is_finite() && p.1.is_finite()) {
                last = None;
                continue;
            }
            let q = (sx(p.0), sy(p.1));
            if axes.markers {
                for d in -3..=3 {
                    for e in -3..=3 {
                        cv.set(q.0 as i64 + d, q.1 as i64 + e, s.colour);
                    }
                }
            }
            if let Some(a) = last {
                cv.line(a, q, s.colour, true);
            } else {
                cv.set(q.0 as i64, q.1 as i64, s.colour);
            }
            last = Some(q);
        }
    }
    cv.text(
        (W as i64 - text_width(labels.title, 2)) / 2,
        16,
        labels.title,
        2,
        black,
    );
    cv.text(
        (LEFT as i64 + (W - RIGHT) as i64 - text_width(labels.x, 2)) / 2,
        (H - 30) as i64,
        labels.x,
        2,
        black,
    );
    // The vertical axis label, written horizontally above the axis.
    cv.text(8, (TOP - 22) as i64, labels.y, 2, black);
    let mut ly = TOP as i64 + 10;
    for s in series.iter().filter(|s| !s.label.is_empty()) {
        let lx = (W - RIGHT) as i64 - 20 - text_width(s.label, 2) - 30;
        cv.line(
            (lx as f64, ly as f64 + 7.0),
            (lx as f64 + 22.0, ly as f64 + 7.0),
            s.colour,
            true,
        );
        cv.text(lx + 28, ly, s.label, 2, black);
        ly += 20;
    }
    let file = std::fs::File::create(path)?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), W as u32, H as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(std::io::Error::other)?;
    w.write_image_data(&cv.px).map_err(std::io::Error::other)?;
    w.finish().map_err(std::io::Error::other)
}

/// 5x7 glyph rows (bit 4 = leftmost column). Unknown characters draw as a box.
fn glyph(c: char) -> [u8; 7] {
    let rows: [&str; 7] = match c {
        '0' => [
            ".###.", "#...#", "#..##", "#.#.#", "##..#", "#...#", ".###.",
        ],
        '1' => [
            "..#..", ".##..", "..#..", "..#..", "..#..", "..#..", ".###.",
        ],
        '2' => [
            ".###.", "#...#", "....#", "...#.", "..#..", ".#...", "#####",
        ],
        '3' => [
            "####.", "....#", "....#", ".###.", "....#", "....#", "####.",
        ],
        '4' => [
            "...#.", "..##.", ".#.#.", "#..#.", "#####", "...#.", "...#.",
        ],
        '5' => [
            "#####", "#....", "####.", "....#", "....#", "#...#", ".###.",
        ],
        '6' => [
            "..##.", ".#...", "#....", "####.", "#...#", "#...#", ".###.",
        ],
        '7' => [
            "#####", "....#", "...#.", "..#..", ".#...", ".#...", ".#...",
        ],
        '8' => [
            ".###.", "#...#", "#...#", ".###.", "#...#", "#...#", ".###.",
        ],
        '9' => [
            ".###.", "#...#", "#...#", ".####", "....#", "...#.", ".##..",
        ],
        '.' => [
            ".....", ".....", ".....", ".....", ".....", ".##..", ".##..",
        ],
        ',' => [
            ".....", ".....", ".....", ".....", ".##..", "..#..", ".#...",
        ],
        ':' => [
            ".....", ".##..", ".##..", ".....", ".##..", ".##..", ".....",
        ],
        '-' => [
            ".....", ".....", ".....", "#####", ".....", ".....", ".....",
        ],
        '+' => [
            ".....", "..#..", "..#..", "#####", "..#..", "..#..", ".....",
        ],
        '=' => [
            ".....", ".....", "#####", ".....", "#####", ".....", ".....",
        ],
        '(' => [
            "...#.", "..#..", ".#...", ".#...", ".#...", "..#..", "...#.",
        ],
        ')' => [
            ".#...", "..#..", "...#.", "...#.", "...#.", "..#..", ".#...",
        ],
        '/' => [
            "....#", "...#.", "...#.", "..#..", ".#...", ".#...", "#....",
        ],
        '%' => [
            "##..#", "##.#.", "...#.", "..#..", ".#...", ".#.##", "#..##",
        ],
        ' ' => [
            ".....", ".....", ".....", ".....", ".....", ".....", ".....",
        ],
        'a' => [
            ".....", ".....", ".###.", "....#", ".####", "#...#", ".####",
        ],
        'b' => [
            "#....", "#....", "####.", "#...#", "#...#", "#...#", "####.",
        ],
        'c' => [
            ".....", ".....", ".###.", "#....", "#....", "#...#", ".###.",
        ],
        'd' => [
            "....#", "....#", ".####", "#...#", "#...#", "#...#", ".####",
        ],
        'e' => [
            ".....", ".....", ".###.", "#...#", "#####", "#....", ".###.",
        ],
        'f' => [
            "..##.", ".#..#", ".#...", "###..", ".#...", ".#...", ".#...",
        ],
        'g' => [
            ".....", ".####", "#...#", "#...#", ".####", "....#", ".###.",
        ],
        'h' => [
            "#....", "#....", "#.##.", "##..#", "#...#", "#...#", "#...#",
        ],
        'i' => [
            "..#..", ".....", ".##..", "..#..", "..#..", "..#..", ".###.",
        ],
        'j' => [
            "...#.", ".....", "..##.", "...#.", "...#.", "#..#.", ".##..",
        ],
        'k' => [
            "#....", "#....", "#..#.", "#.#..", "##...", "#.#..", "#..#.",
        ],
        'l' => [
            ".##..", "..#..", "..#..", "..#..", "..#..", "..#..", ".###.",
        ],
        'm' => [
            ".....", ".....", "##.#.", "#.#.#", "#.#.#", "#...#", "#...#",
        ],
        'n' => [
            ".....", ".....", "#.##.", "##..#", "#...#", "#...#", "#...#",
        ],
        'o' => [
            ".....", ".....", ".###.", "#...#", "#...#", "#...#", ".###.",
        ],
        'p' => [
            ".....", ".....", "####.", "#...#", "####.", "#....", "#....",
        ],
        'q' => [
            ".....", ".....", ".####", "#...#", ".####", "....#", "....#",
        ],
        'r' => [
            ".....", ".....", "#.##.", "##..#", "#....", "#....", "#....",
        ],
        's' => [
            ".....", ".....", ".####", "#....", ".###.", "....#", "####.",
        ],
        't' => [
            ".#...", ".#...", "###..", ".#...", ".#...", ".#..#", "..##.",
        ],
        'u' => [
            ".....", ".....", "#...#", "#...#", "#...#", "#..##", ".##.#",
        ],
        'v' => [
            ".....", ".....", "#...#", "#...#", "#...#", ".#.#.", "..#..",
        ],
        'w' => [
            ".....", ".....", "#...#", "#...#", "#.#.#", "#.#.#", ".#.#.",
        ],
        'x' => [
            ".....", ".....", "#...#", ".#.#.", "..#..", ".#.#.", "#...#",
        ],
        'y' => [
            ".....", ".....", "#...#", "#...#", ".####", "....#", ".###.",
        ],
        'z' => [
            ".....", ".....", "#####", "...#.", "..#..", ".#...", "#####",
        ],
        'N' => [
            "#...#", "##..#", "#.#.#", "#..##", "#...#", "#...#", "#...#",
        ],
        'C' => [
            ".###.", "#...#", "#....", "#....", "#....", "#...#", ".###.",
        ],
        'G' => [
            ".###.", "#...#", "#....", "#.###", "#...#", "#...#", ".####",
        ],
        'P' => [
            "####.", "#...#", "#...#", "####.", "#....", "#....", "#....",
        ],
        'U' => [
            "#...#", "#...#", "#...#", "#...#", "#...#", "#...#", ".###.",
        ],
        'D' => [
            "###..", "#..#.", "#...#", "#...#", "#...#", "#..#.", "###..",
        ],
        'E' => [
            "#####", "#....", "#....", "####.", "#....", "#....", "#####",
        ],
        'B' => [
            "####.", "#...#", "#...#", "####.", "#...#", "#...#", "####.",
        ],
        'L' => [
            "#....", "#....", "#....", "#....", "#....", "#....", "#####",
        ],
        'S' => [
            ".####", "#....", "#....", ".###.", "....#", "....#", "####.",
        ],
        'M' => [
            "#...#", "##.##", "#.#.#", "#.#.#", "#...#", "#...#", "#...#",
        ],
        'H' => [
            "#...#", "#...#", "#...#", "#####", "#...#", "#...#", "#...#",
        ],
        'A' => [
            ".###.", "#...#", "#...#", "#####", "#...#", "#...#", "#...#",
        ],
        c if c.is_ascii_uppercase() => return glyph(c.to_ascii_lowercase()),
        _ => [
            "#####", "#...#", "#...#", "#...#", "#...#", "#...#", "#####",
        ],
    };
    rows.map(|r| r.bytes().fold(0u8, |acc, b| (acc << 1) | (b == b'#') as u8))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        assert_eq!(
            ticks(0.0, 1.0),
            vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]
        );
        let t = ticks(-0.013, 0.27);
        assert!(t.len() >= 3 && t[0] >= -0.013 && *t.last().unwrap() <= 0.27);
        assert!(t.contains(&0.0));
    }

    #[test]
    fn writes_a_png_with_the_curve_in_its_colour() {
        let dir = std::env::temp_dir().join(format!("needlesim_plot_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("p.png");
        let pts = (0..100)
            .map(|i| (i as f64, (i as f64 * 0.1).sin()))
            .collect();
        line_plot(
            &path,
            &Labels {
                title: "sine",
                x: "x",
                y: "y (N)",
            },
            &[Series {
                label: "sin",
                colour: [200, 30, 30],
                points: pts,
            }],
        )
        .unwrap();
        let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size()];
        r.next_frame(&mut buf).unwrap();
        assert_eq!((r.info().width, r.info().height), (W as u32, H as u32));
        let red = buf.chunks(3).filter(|p| p == &[200, 30, 30]).count();
        assert!(red > 500, "only {red} curve pixels");
        std::fs::remove_dir_all(&dir).ok();
    }
}
