//! Small PNG line charts (RMSE vs spp, Pareto fronts, BRDF curves): several series,
//! axis ticks and labels, a legend, optional log axes.
//!
//! Drawn with `plotters` on its in-memory bitmap backend and encoded with `image`; text is
//! rasterised by `ab_glyph` from the DejaVu Sans file bundled in `assets/fonts/` (Bitstream
//! Vera licence, `assets/fonts/DejaVuSans-LICENSE.txt`), so no system font or fontconfig
//! is needed. Log axes plot `log10(v)` on a linear axis and label ticks with `10^k`
//! values; points that are not positive on a log axis (or not finite) are skipped,
//! counted and logged.
//!
//! ```no_run
//! use crate::plot::{LineChart, Scale, Series};
//! LineChart::new("RMSE vs samples")
//!     .x_label("samples per pixel").y_label("RMSE")
//!     .scales(Scale::Log, Scale::Log)
//!     .series(Series::new("uniform", vec![(1.0, 9.0), (10.0, 5.1), (100.0, 1.8)]))
//!     .save_png("rmse.png")?;
//! # Ok::<(), crate::plot::PlotError>(())
//! ```

use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";

/// Axis scale.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scale {
    Linear,
    /// Base-10 logarithmic; non-positive values are skipped.
    Log,
}

/// Where the legend box goes (inside the plot area).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Legend {
    UpperRight,
    UpperLeft,
    LowerRight,
    LowerLeft,
    /// No legend.
    Hidden,
}

/// One named polyline.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// (x, y) in data units, drawn in the given order.
    pub points: Vec<(f64, f64)>,
    /// Mark each point with a small circle.
    pub markers: bool,
    /// RGB colour; `None` picks from the palette by series index.
    pub color: Option<[u8; 3]>,
    /// Draw dashed (e.g. a normalised variant beside the original).
    pub dashed: bool,
}

impl Series {
    /// A solid line without markers, palette colour.
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series { name: name.into(), points, markers: false, color: None, dashed: false }
    }
    /// With point markers.
    pub fn with_markers(mut self) -> Self {
        self.markers = true;
        self
    }
    /// Dashed line.
    pub fn dashed(mut self) -> Self {
        self.dashed = true;
        self
    }
    /// Fixed colour.
    pub fn color(mut self, rgb: [u8; 3]) -> Self {
        self.color = Some(rgb);
        self
    }
}

/// Why a chart could not be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// No series had a single plottable point.
    #[error("chart `{title}`: no plottable points")]
    NoData { title: String },
    /// The embedded font could not be registered.
    #[error("plot font: {0}")]
    Font(String),
    /// The drawing backend failed.
    #[error("chart `{title}`: drawing failed: {msg}")]
    Draw { title: String, msg: String },
    /// Encoding or writing the PNG failed.
    #[error("writing chart to {path}: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
}

/// A line chart description; render with [`LineChart::render`] or [`LineChart::save_png`].
#[derive(Clone, Debug, PartialEq)]
pub struct LineChart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub x_scale: Scale,
    pub y_scale: Scale,
    /// Fixed axis ranges in data units (default: the data's bounds, padded).
    pub x_range: Option<(f64, f64)>,
    pub y_range: Option<(f64, f64)>,
    pub series: Vec<Series>,
    /// Image size in pixels.
    pub size: (u32, u32),
    /// Legend placement (default upper right).
    pub legend: Legend,
}

/// Palette (Tableau 10): distinguishable, print-safe.
const PALETTE: [[u8; 3]; 10] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
];

fn ensure_font() -> Result<(), PlotError> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).map_err(|_| "invalid embedded font".to_string())
    })
    .clone()
    .map_err(PlotError::Font)
}

fn to_axis(v: f64, s: Scale) -> Option<f64> {
    match s {
        Scale::Linear => v.is_finite().then_some(v),
        Scale::Log => (v > 0.0 && v.is_finite()).then(|| v.log10()),
    }
}

/// Tick label for an axis value (already in axis units).
fn tick_label(v: f64, s: Scale) -> String {
    let x = match s {
        Scale::Linear => v,
        Scale::Log => 10f64.powf(v),
    };
    let a = x.abs();
    if x == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{x:.0e}")
    } else if s == Scale::Log {
        // Three significant digits: 316, 31.6, 0.316.
        let digits = (2 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{x:.digits$}");
        let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { &s };
        s.to_string()
    } else {
        let s = format!("{x:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    }
}

fn range_of(vals: impl Iterator<Item = f64>, fixed: Option<(f64, f64)>, s: Scale) -> Option<(f64, f64)> {
    if let Some((a, b)) = fixed {
        let (a, b) = (to_axis(a, s)?, to_axis(b, s)?);
        return (b > a).then_some((a, b));
    }
    let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(v), h.max(v)));
    if !lo.is_finite() {
        return None;
    }
    let span = hi - lo;
    let pad = if span > 0.0 { 0.04 * span } else { 0.5f64.max(lo.abs() * 0.1) };
    Some((lo - pad, hi + pad))
}

impl LineChart {
    /// An empty 900×600 chart with linear axes.
    pub fn new(title: impl Into<String>) -> Self {
        LineChart {
            title: title.into(),
            x_label: String::new(),
            y_label: String::new(),
            x_scale: Scale::Linear,
            y_scale: Scale::Linear,
            x_range: None,
            y_range: None,
            series: Vec::new(),
            size: (900, 600),
            legend: Legend::UpperRight,
        }
    }
    pub fn x_label(mut self, s: impl Into<String>) -> Self {
        self.x_label = s.into();
        self
    }
    pub fn y_label(mut self, s: impl Into<String>) -> Self {
        self.y_label = s.into();
        self
    }
    /// Set both axis scales.
    pub fn scales(mut self, x: Scale, y: Scale) -> Self {
        self.x_scale = x;
        self.y_scale = y;
        self
    }
    pub fn x_range(mut self, lo: f64, hi: f64) -> Self {
        self.x_range = Some((lo, hi));
        self
    }
    pub fn y_range(mut self, lo: f64, hi: f64) -> Self {
        self.y_range = Some((lo, hi));
        self
    }
    pub fn size(mut self, w: u32, h: u32) -> Self {
        self.size = (w, h);
        self
    }
    pub fn legend(mut self, l: Legend) -> Self {
        self.legend = l;
        self
    }
    pub fn series(mut self, s: Series) -> Self {
        self.series.push(s);
        self
    }

    /// Points of each series in axis units, with the count of skipped points.
    fn axis_points(&self) -> (Vec<Vec<(f64, f64)>>, usize) {
        let mut skipped = 0;
        let pts = self
            .series
            .iter()
            .map(|s| {
                s.points
                    .iter()
                    .filter_map(|&(x, y)| {
                        let p = to_axis(x, self.x_scale).zip(to_axis(y, self.y_scale));
                        if p.is_none() {
                            skipped += 1;
                        }
                        p
                    })
                    .collect()
            })
            .collect();
        (pts, skipped)
    }

    /// Draw into an RGB image.
    ///
    /// # Errors
    /// [`PlotError::NoData`] if nothing is plottable; font or backend failures.
    pub fn render(&self) -> Result<image::RgbImage, PlotError> {
        ensure_font()?;
        let (pts, skipped) = self.axis_points();
        if skipped > 0 {
            tracing::warn!(chart = %self.title, skipped, "points not plottable (non-finite, or ≤ 0 on a log axis) were skipped");
        }
        let all = || pts.iter().flatten();
        let xr = range_of(all().map(|p| p.0), self.x_range, self.x_scale);
        let yr = range_of(all().map(|p| p.1), self.y_range, self.y_scale);
        let (Some((x0, x1)), Some((y0, y1))) = (xr, yr) else {
            return Err(PlotError::NoData { title: self.title.clone() });
        };
        let (w, h) = self.size;
        let mut buf = vec![255u8; (w * h * 3) as usize];
        let derr = |e: &dyn std::fmt::Display| PlotError::Draw { title: self.title.clone(), msg: e.to_string() };
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            root.fill(&WHITE).map_err(|e| derr(&e))?;
            let mut chart = ChartBuilder::on(&root)
                .caption(&self.title, (FAMILY, 22))
                .margin(12)
                .x_label_area_size(48)
                .y_label_area_size(72)
                .build_cartesian_2d(x0..x1, y0..y1)
                .map_err(|e| derr(&e))?;
            let (xs, ys) = (self.x_scale, self.y_scale);
            let xfmt = move |v: &f64| tick_label(*v, xs);
            let yfmt = move |v: &f64| tick_label(*v, ys);
            chart
                .configure_mesh()
                .x_desc(&self.x_label)
                .y_desc(&self.y_label)
                .x_label_formatter(&xfmt)
                .y_label_formatter(&yfmt)
                .label_style((FAMILY, 14))
                .axis_desc_style((FAMILY, 16))
                .light_line_style(RGBColor(235, 235, 235))
                .draw()
                .map_err(|e| derr(&e))?;
            for (i, (s, p)) in self.series.iter().zip(&pts).enumerate() {
                let [r, g, b] = s.color.unwrap_or(PALETTE[i % PALETTE.len()]);
                let col = RGBColor(r, g, b);
                let style = col.stroke_width(2);
                let anno = if s.dashed {
                    chart.draw_series(DashedLineSeries::new(p.iter().copied(), 8, 5, style)).map_err(|e| derr(&e))?
                } else {
                    chart.draw_series(LineSeries::new(p.iter().copied(), style)).map_err(|e| derr(&e))?
                };
                anno.label(s.name.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], col.stroke_width(2)));
                if s.markers {
                    chart.draw_series(p.iter().map(|&q| Circle::new(q, 3, col.filled()))).map_err(|e| derr(&e))?;
                }
            }
            let pos = match self.legend {
                Legend::UpperRight => Some(SeriesLabelPosition::UpperRight),
                Legend::UpperLeft => Some(SeriesLabelPosition::UpperLeft),
                Legend::LowerRight => Some(SeriesLabelPosition::LowerRight),
                Legend::LowerLeft => Some(SeriesLabelPosition::LowerLeft),
                Legend::Hidden => None,
            };
            if let Some(pos) = pos.filter(|_| self.series.iter().any(|s| !s.name.is_empty())) {
                chart
                    .configure_series_labels()
                    .label_font((FAMILY, 14))
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .position(pos)
                    .draw()
                    .map_err(|e| derr(&e))?;
            }
            root.present().map_err(|e| derr(&e))?;
        }
        Ok(image::RgbImage::from_raw(w, h, buf).expect("buffer sized w·h·3"))
    }

    /// Render and write a PNG.
    ///
    /// # Errors
    /// As [`LineChart::render`], plus [`PlotError::Write`] naming the path.
    pub fn save_png(&self, path: impl AsRef<Path>) -> Result<(), PlotError> {
        let img = self.render()?;
        img.save_with_format(path.as_ref(), image::ImageFormat::Png)
            .map_err(|source| PlotError::Write { path: path.as_ref().to_path_buf(), source })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows (mean) where a colour appears in the middle column band of the image.
    fn mean_row_of(img: &image::RgbImage, rgb: [u8; 3]) -> Option<f64> {
        let (w, h) = img.dimensions();
        let (mut sum, mut n) = (0.0, 0.0);
        for y in 0..h {
            for x in w / 3..w / 2 {
                if img.get_pixel(x, y).0 == rgb {
                    sum += f64::from(y);
                    n += 1.0;
                }
            }
        }
        (n > 0.0).then(|| sum / n)
    }

    #[test]
    fn log_axis_spaces_decades_evenly_and_linear_axis_spaces_values_evenly() {
        let (a, b, c) = ([200, 0, 0], [0, 200, 0], [0, 0, 200]);
        let flat = |v: f64| vec![(0.0, v), (1.0, v)];
        for (scale, vals) in [(Scale::Log, [1.0, 10.0, 100.0]), (Scale::Linear, [0.25, 0.5, 0.75])] {
            let img = LineChart::new("t")
                .scales(Scale::Linear, scale)
                .series(Series::new("", flat(vals[0])).color(a))
                .series(Series::new("", flat(vals[1])).color(b))
                .series(Series::new("", flat(vals[2])).color(c))
                .render()
                .unwrap();
            let (ra, rb, rc) =
                (mean_row_of(&img, a).unwrap(), mean_row_of(&img, b).unwrap(), mean_row_of(&img, c).unwrap());
            assert!(ra > rb && rb > rc, "larger values are higher up: {ra} {rb} {rc}");
            assert!(((ra - rb) - (rb - rc)).abs() <= 1.5, "{scale:?}: {ra} {rb} {rc}");
        }
    }

    #[test]
    fn text_is_drawn_and_png_round_trips() {
        let chart = LineChart::new("Title")
            .x_label("x")
            .y_label("y")
            .series(Series::new("legend", vec![(0.0, 1.0), (1.0, 2.0)]));
        let img = chart.render().unwrap();
        // Title area (top strip) holds dark anti-aliased glyph pixels only if text rendered.
        let dark = (0..30)
            .flat_map(|y| (0..img.width()).map(move |x| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0[0] < 100)
            .count();
        assert!(dark > 20, "no title glyphs drawn ({dark} dark pixels)");
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.png");
        chart.save_png(&p).unwrap();
        let back = image::open(&p).unwrap().to_rgb8();
        assert_eq!(back, img);
    }

    #[test]
    fn log_axis_skips_nonpositive_points_and_empty_chart_is_an_error() {
        let chart = LineChart::new("t")
            .scales(Scale::Linear, Scale::Log)
            .series(Series::new("s", vec![(0.0, 0.0), (1.0, -1.0)]));
        assert!(matches!(chart.render(), Err(PlotError::NoData { .. })));
        let (pts, skipped) = LineChart::new("t")
            .scales(Scale::Log, Scale::Linear)
            .series(Series::new("s", vec![(0.0, 1.0), (10.0, 2.0), (f64::NAN, 1.0)]))
            .axis_points();
        assert_eq!((pts[0].clone(), skipped), (vec![(1.0, 2.0)], 2));
    }

    #[test]
    fn tick_labels_read_as_data_values() {
        assert_eq!(tick_label(2.0, Scale::Log), "100");
        assert_eq!(tick_label(-1.0, Scale::Log), "0.1");
        assert_eq!(tick_label(0.25, Scale::Linear), "0.25");
        assert_eq!(tick_label(6.0, Scale::Log), "1e6");
        assert_eq!(tick_label(2.5, Scale::Log), "316");
        assert_eq!(tick_label(-0.5, Scale::Log), "0.316");
    }
}
