//! Line plots written as PNG files: axes with ticks and numbers, a title, axis labels, one
//! polyline per series and a legend in a panel right of the plot area (it never covers a
//! curve). Drawn with `plotters` into an RGB buffer; text uses DejaVu Sans, embedded in
//! the binary (`fonts/DejaVuSans.ttf`, licence in `fonts/LICENSE`), so plots come out the
//! same on every machine and need no system fonts.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// One curve.
pub struct Series<'a> {
    /// Legend text; series with an empty label are left out of the legend.
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

/// Axis scales and point markers.
#[derive(Debug, Clone, Copy, Default)]
pub struct Axes {
    /// Logarithmic horizontal axis (points with x <= 0 are left out).
    pub log_x: bool,
    /// Logarithmic vertical axis (points with y <= 0 are left out).
    pub log_y: bool,
    /// A dot at every point.
    pub markers: bool,
}

/// Width of every plot in pixels.
pub const WIDTH: u32 = 960;
/// Height of every plot in pixels.
pub const HEIGHT: u32 = 560;

/// The font family name the embedded font is registered under.
const FAMILY: &str = "DejaVu Sans";
/// DejaVu Sans 2.37 (Bitstream Vera licence with DejaVu's public-domain changes).
static FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");

/// Registers the embedded font with plotters (once per process).
fn register_font() -> std::io::Result<()> {
    static DONE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        // Also as "sans-serif", the family plotters falls back to for unstyled text.
        [FAMILY, "sans-serif"]
            .iter()
            .all(|name| plotters::style::register_font(name, FontStyle::Normal, FONT).is_ok())
    });
    if ok {
        Ok(())
    } else {
        Err(std::io::Error::other("the embedded font cannot be read"))
    }
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

/// Fainter grid lines of a log axis (values are log10): every integer multiple of the
/// decades in range, when there are not too many.
fn minor_ticks(lo: f64, hi: f64, log: bool) -> Vec<f64> {
    if !log || hi - lo > 6.0 {
        return Vec::new();
    }
    (lo.floor() as i64..=hi.ceil() as i64)
        .flat_map(|k| (1..10).map(move |m| k as f64 + (m as f64).log10()))
        .filter(|&t| t >= lo && t <= hi)
        .collect()
}

/// A linear axis over `range` (log10 values on a log axis) with our own grid lines: the
/// ticks of [`axis_ticks`] (numbered) and [`minor_ticks`] (faint).
struct Ticked {
    range: std::ops::Range<f64>,
    bold: Vec<f64>,
    light: Vec<f64>,
}

impl Ticked {
    fn new(range: std::ops::Range<f64>, log: bool) -> Ticked {
        Ticked {
            bold: axis_ticks(range.start, range.end, log),
            light: minor_ticks(range.start, range.end, log),
            range,
        }
    }
}

impl Ranged for Ticked {
    type FormatOption = plotters::coord::ranged1d::DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let frac = (v - self.range.start) / (self.range.end - self.range.start);
        let length = (limit.1 - limit.0) as f64;
        limit.0 + (length * frac + 1e-3).floor().clamp(-1e6, 1e6) as i32
    }

    fn key_points<H: plotters::coord::ranged1d::KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.light.clone()
        } else {
            self.bold.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.range.clone()
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

/// Writes the series as a line plot to `path` (PNG, [`WIDTH`] x [`HEIGHT`]), linear axes.
pub fn line_plot(path: &Path, labels: &Labels, series: &[Series]) -> std::io::Result<()> {
    plot(path, labels, Axes::default(), series)
}

/// Writes the series as a line plot to `path` (PNG, [`WIDTH`] x [`HEIGHT`]) with the given
/// axes.
pub fn plot(path: &Path, labels: &Labels, axes: Axes, series: &[Series]) -> std::io::Result<()> {
    register_font()?;
    let mut px = vec![255u8; WIDTH as usize * HEIGHT as usize * 3];
    draw(&mut px, labels, axes, series).map_err(std::io::Error::other)?;
    let file = std::fs::File::create(path)?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), WIDTH, HEIGHT);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(std::io::Error::other)?;
    w.write_image_data(&px).map_err(std::io::Error::other)?;
    w.finish().map_err(std::io::Error::other)
}

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// Draws the plot into `px` (RGB, [`WIDTH`] x [`HEIGHT`]); the error is plotters' message.
fn draw(px: &mut [u8], labels: &Labels, axes: Axes, series: &[Series]) -> Result<(), String> {
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let tf = |v: f64, log: bool| {
        if !log {
            v
        } else if v > 0.0 {
            v.log10()
        } else {
            f64::NAN
        }
    };
    // Points in plotted coordinates (log10 on a log axis), cut into finite runs.
    let runs: Vec<Vec<Vec<(f64, f64)>>> = series
        .iter()
        .map(|s| {
            let mut runs = vec![Vec::new()];
            for p in &s.points {
                let q = (tf(p.0, axes.log_x), tf(p.1, axes.log_y));
                if q.0.is_finite() && q.1.is_finite() {
                    runs.last_mut().unwrap().push(q);
                } else if !runs.last().unwrap().is_empty() {
                    runs.push(Vec::new());
                }
            }
            runs.retain(|r| !r.is_empty());
            runs
        })
        .collect();
    let all: Vec<(f64, f64)> = runs.iter().flatten().flatten().copied().collect();
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

    let root = BitMapBackend::with_buffer(px, (WIDTH, HEIGHT)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root
        .margin(6, 0, 0, 0)
        .titled(labels.title, (FAMILY, 22).into_font().color(&BLACK))
        .map_err(|e| err(&e))?;
    let text = |size: f64| TextStyle::from((FAMILY, size).into_font()).color(&BLACK);

    // The legend panel: as wide as the longest label needs, right of the plot area.
    let legend: Vec<&Series> = series.iter().filter(|s| !s.label.is_empty()).collect();
    let legend_text = text(15.0);
    let widest = legend
        .iter()
        .map(|s| {
            root.estimate_text_size(s.label, &legend_text)
                .map(|(w, _)| w)
        })
        .try_fold(0u32, |m, w| w.map(|w| m.max(w)))
        .map_err(|e| err(&e))?;
    let legend_width = if legend.is_empty() {
        0
    } else {
        (widest + 70).clamp(120, WIDTH / 3)
    };
    let (plot_area, legend_area) = root.split_horizontally(root.dim_in_pixel().0 - legend_width);

    let mut chart = ChartBuilder::on(&plot_area)
        .margin(12)
        .x_label_area_size(52)
        .y_label_area_size(86)
        .build_cartesian_2d(
            Ticked::new(x0..x1, axes.log_x),
            Ticked::new(y0..y1, axes.log_y),
        )
        .map_err(|e| err(&e))?;
    let tick_label = |t: f64, log: bool| {
        if log {
            number(10f64.powf(t))
        } else {
            number(t)
        }
    };
    let x_label = |t: &f64| tick_label(*t, axes.log_x);
    let y_label = |t: &f64| tick_label(*t, axes.log_y);
    chart
        .configure_mesh()
        .x_desc(labels.x)
        .y_desc(labels.y)
        .label_style(text(14.0))
        .axis_desc_style(text(16.0))
        .x_label_formatter(&x_label)
        .y_label_formatter(&y_label)
        .bold_line_style(RGBColor(215, 215, 215).stroke_width(1))
        .light_line_style(RGBColor(238, 238, 238).stroke_width(1))
        .axis_style(BLACK.stroke_width(1))
        .draw()
        .map_err(|e| err(&e))?;
    if !axes.log_y && y0 < 0.0 && y1 > 0.0 {
        chart
            .draw_series(LineSeries::new(
                [(x0, 0.0), (x1, 0.0)],
                RGBColor(150, 150, 150),
            ))
            .map_err(|e| err(&e))?;
    }
    for (s, runs) in series.iter().zip(&runs) {
        let style = rgb(s.colour).stroke_width(2);
        for run in runs {
            chart
                .draw_series(LineSeries::new(run.iter().copied(), style))
                .map_err(|e| err(&e))?;
            if axes.markers || run.len() == 1 {
                chart
                    .draw_series(
                        run.iter()
                            .map(|&p| Circle::new(p, 3, rgb(s.colour).filled())),
                    )
                    .map_err(|e| err(&e))?;
            }
        }
    }
    // The plot area's border on top of the curves.
    let (xr, yr) = (chart.x_range(), chart.y_range());
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(xr.start, yr.start), (xr.end, yr.end)],
            BLACK.stroke_width(1),
        )))
        .map_err(|e| err(&e))?;
    if !legend.is_empty() {
        draw_legend(&legend_area, &legend, &legend_text, axes.markers).map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// The legend: one line (and dot) per labelled series with its text, in a framed box at
/// the top of `area`, aligned with the plot area's top.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    legend: &[&Series],
    text: &TextStyle,
    markers: bool,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    const ROW: i32 = 24;
    let (w, _) = area.dim_in_pixel();
    let (left, top) = (4, 12);
    let right = w as i32 - 10;
    let bottom = top + 10 + ROW * legend.len() as i32;
    area.draw(&Rectangle::new(
        [(left, top), (right, bottom)],
        WHITE.filled(),
    ))?;
    area.draw(&Rectangle::new(
        [(left, top), (right, bottom)],
        RGBColor(160, 160, 160).stroke_width(1),
    ))?;
    let anchored = text.pos(Pos::new(HPos::Left, VPos::Center));
    for (i, s) in legend.iter().enumerate() {
        let y = top + 5 + ROW / 2 + ROW * i as i32;
        let c = rgb(s.colour);
        area.draw(&PathElement::new(
            vec![(left + 10, y), (left + 38, y)],
            c.stroke_width(3),
        ))?;
        if markers {
            area.draw(&Circle::new((left + 24, y), 3, c.filled()))?;
        }
        area.draw(&Text::new(s.label.to_string(), (left + 46, y), &anchored))?;
    }
    Ok(())
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
    fn log_ticks_are_1_2_5_multiples_of_decades() {
        let t = axis_ticks(-3.1, -0.9, true);
        let v: Vec<String> = t.iter().map(|t| number(10f64.powf(*t))).collect();
        assert_eq!(
            v,
            ["0.001", "0.002", "0.005", "0.01", "0.02", "0.05", "0.1"]
        );
    }

    /// Decodes a PNG: (width, height, RGB pixels).
    fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
        let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size()];
        r.next_frame(&mut buf).unwrap();
        assert_eq!(r.info().color_type, png::ColorType::Rgb);
        (r.info().width, r.info().height, buf)
    }

    #[test]
    fn writes_a_png_with_the_curve_in_its_colour_and_text() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.png");
        let pts = (0..100)
            .map(|i| (i as f64, (i as f64 * 0.1).sin()))
            .collect();
        line_plot(
            &path,
            &Labels {
                title: "sine against angle",
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
        let (w, h, buf) = read_png(&path);
        assert_eq!((w, h), (WIDTH, HEIGHT));
        let red = buf.chunks(3).filter(|p| p == &[200, 30, 30]).count();
        assert!(red > 500, "only {red} curve pixels");
        // Text is antialiased: grey levels, not only black and white.
        let grey = buf
            .chunks(3)
            .filter(|p| p[0] == p[1] && p[1] == p[2] && (40..200).contains(&p[0]))
            .count();
        assert!(grey > 200, "only {grey} grey pixels of text");
    }

    /// The legend sits right of the plot area's frame: each series has its curve inside
    /// the frame and its legend line (and label text) outside it.
    #[test]
    fn the_legend_is_outside_the_plot_area() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("legend.png");
        let colours = [[10, 120, 200], [230, 120, 10]];
        let series: Vec<Series> = colours
            .iter()
            .enumerate()
            .map(|(k, &c)| Series {
                label: if k == 0 {
                    "rising curve"
                } else {
                    "falling curve"
                },
                colour: c,
                // Curves through the top right corner, where a legend inside would go.
                points: (1..=50)
                    .map(|i| {
                        let x = i as f64;
                        (x, if k == 0 { x * x } else { 2600.0 - x * x })
                    })
                    .collect(),
            })
            .collect();
        plot(
            &path,
            &Labels {
                title: "two curves",
                x: "x",
                y: "y",
            },
            Axes {
                log_x: true,
                log_y: true,
                markers: true,
            },
            &series,
        )
        .unwrap();
        let (w, h, buf) = read_png(&path);
        assert_eq!((w, h), (WIDTH, HEIGHT));
        let pixel = |x: u32, y: u32| {
            let i = 3 * (y * w + x) as usize;
            [buf[i], buf[i + 1], buf[i + 2]]
        };
        // The frame's right edge: the rightmost column that is black over a third of the
        // height.
        let frame_right = (0..w)
            .filter(|&x| (0..h).filter(|&y| pixel(x, y) == [0, 0, 0]).count() > h as usize / 3)
            .max()
            .unwrap();
        assert!(
            frame_right > w / 2 && frame_right < w - 100,
            "{frame_right}"
        );
        for c in colours {
            let (mut inside, mut outside) = (0, 0);
            for y in 0..h {
                for x in 0..w {
                    if pixel(x, y) == c {
                        if x < frame_right {
                            inside += 1;
                        } else {
                            outside += 1;
                        }
                    }
                }
            }
            assert!(inside > 300, "{c:?}: {inside} curve pixels");
            assert!(outside >= 60, "{c:?}: {outside} legend pixels");
        }
        let text = (frame_right + 1..w)
            .flat_map(|x| (0..h).map(move |y| (x, y)))
            .filter(|&(x, y)| pixel(x, y).iter().all(|&v| v < 120))
            .count();
        assert!(text > 100, "{text} dark legend text pixels");
    }

    #[test]
    fn empty_and_degenerate_series_still_make_a_plot() {
        let dir = tempfile::tempdir().unwrap();
        for (k, points) in [
            vec![],
            vec![(1.0, 2.0)],
            vec![(0.0, 1.0), (1.0, 1.0), (f64::NAN, 3.0), (2.0, 1.0)],
        ]
        .into_iter()
        .enumerate()
        {
            let path = dir.path().join(format!("{k}.png"));
            line_plot(
                &path,
                &Labels {
                    title: "t",
                    x: "x",
                    y: "y",
                },
                &[Series {
                    label: "",
                    colour: [0, 0, 200],
                    points,
                }],
            )
            .unwrap();
            assert_eq!(read_png(&path).0, WIDTH);
        }
    }
}
