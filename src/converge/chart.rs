//! Log-log charts drawn with `plotters` to PNG and SVG: the convergence chart (RMSE against render seconds, one
//! curve per method, and a 1/√t guide) and any other [`LogLogChart`] (the benches' charts). Text uses the bundled
//! DejaVu Sans Mono (no system fonts needed).

use super::summary::Curve;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

/// Chart size in pixels.
const SIZE: (u32, u32) = (900, 600);
/// The font family the chart's text uses, registered from the bundled file.
const FONT: &str = "sans-serif";
/// DejaVu Sans Mono (Bitstream Vera license, `assets/fonts/DejaVu-LICENSE.txt`).
const FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSansMono.ttf");

/// Curve colours, in method order.
const COLORS: [RGBColor; 7] = [
    RGBColor(0, 0, 0),
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// One curve of a log-log chart: a legend label and its (x, y) points.
#[derive(Clone, Debug)]
pub struct Series {
    /// The legend label.
    pub label: String,
    /// Points in drawing order; those with a non-positive or non-finite coordinate are left out.
    pub points: Vec<(f64, f64)>,
}

/// What a log-log chart shows: its caption, axis titles, curves, and an optional power-law guide line.
#[derive(Clone, Debug)]
pub struct LogLogChart {
    /// The caption above the plot.
    pub caption: String,
    /// The x-axis title.
    pub x_desc: String,
    /// The y-axis title.
    pub y_desc: String,
    /// The curves, coloured in order.
    pub series: Vec<Series>,
    /// A grey guide y ∝ x^exponent through the first series' first point, with its legend label.
    pub guide: Option<(f64, String)>,
    /// The corner the legend sits in (chosen where it hides no curve).
    pub legend: LegendCorner,
}

/// A corner of the plot area.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LegendCorner {
    /// Top left.
    #[cfg(any(test, feature = "testing"))]
    UpperLeft,
    /// Top right.
    UpperRight,
    /// Bottom left.
    #[cfg(any(test, feature = "testing"))]
    LowerLeft,
    /// Bottom right.
    #[cfg(any(test, feature = "testing"))]
    LowerRight,
}

/// Draws the convergence chart of `curves` (RMSE against seconds, with a 1/√t guide) to `png` and `svg`.
pub fn draw_chart(curves: &[Curve], png: &Path, svg: &Path) -> Result<(), ChartError> {
    let chart = LogLogChart {
        caption: "RMSE vs render time".into(),
        x_desc: "render seconds".into(),
        y_desc: "RMSE".into(),
        series: curves
            .iter()
            .map(|c| Series {
                label: c.method.name().into(),
                points: c
                    .points
                    .iter()
                    .map(|p| (p.seconds, p.metrics.rmse))
                    .collect(),
            })
            .collect(),
        guide: Some((-0.5, "1/sqrt(t)".into())),
        legend: LegendCorner::UpperRight,
    };
    draw_loglog_chart(&chart, png, svg)
}

/// A chart that could not be drawn or written.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct ChartError {
    /// The chart file.
    pub path: std::path::PathBuf,
    /// What the plotting or image library reported.
    pub message: String,
}

impl ChartError {
    fn new(path: &Path, message: impl std::fmt::Display) -> Self {
        Self {
            path: path.to_path_buf(),
            message: message.to_string(),
        }
    }
}

/// Draws `chart` to `png` and `svg`.
pub fn draw_loglog_chart(chart: &LogLogChart, png: &Path, svg: &Path) -> Result<(), ChartError> {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The bundled font is valid; a failure would only make text invisible.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES);
    });
    let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
        draw(&root, chart).map_err(|e| ChartError::new(png, e))?;
        root.present().map_err(|e| ChartError::new(png, e))?;
    }
    let mut encoded = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut encoded),
        &rgb,
        SIZE.0,
        SIZE.1,
        image::ExtendedColorType::Rgb8,
    )
    .map_err(|e| ChartError::new(png, e))?;
    crate::output::write_atomically(png, &encoded).map_err(|e| ChartError::new(png, e))?;
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, SIZE).into_drawing_area();
        draw(&root, chart).map_err(|e| ChartError::new(svg, e))?;
        root.present().map_err(|e| ChartError::new(svg, e))?;
    }
    crate::output::write_atomically(svg, text.as_bytes()).map_err(|e| ChartError::new(svg, e))
}

fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

/// Formats an axis label: plain decimals from 0.01 to 10⁴, scientific notation beyond.
fn axis_label(v: f64) -> String {
    if (1e-2..1e4).contains(&v.abs()) {
        format!("{v:.3}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_owned()
    } else {
        format!("{v:.1e}")
    }
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    spec: &LogLogChart,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let visible = |s: &Series| -> Vec<(f64, f64)> {
        s.points
            .iter()
            .copied()
            .filter(|&(x, y)| positive(x) && positive(y))
            .collect()
    };
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in spec.series.iter().flat_map(visible) {
        (x0, x1) = (x0.min(x), x1.max(x));
        (y0, y1) = (y0.min(y), y1.max(y));
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (1e-3, 1.0, 1e-3, 1.0);
    }
    let (x0, x1) = (x0 / 1.5, x1 * 1.5);
    let (y0, y1) = (y0 / 1.5, y1 * 1.5);
    let mut chart = ChartBuilder::on(root)
        .caption(&spec.caption, (FONT, 24))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(80)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc(&spec.x_desc)
        .y_desc(&spec.y_desc)
        .label_style((FONT, 14))
        .x_label_formatter(&|v| axis_label(*v))
        .y_label_formatter(&|v| axis_label(*v))
        .draw()?;
    for (i, s) in spec.series.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        let data = visible(s);
        chart
            .draw_series(LineSeries::new(data.clone(), color.stroke_width(2)))?
            .label(&s.label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2)));
        chart.draw_series(data.into_iter().map(|p| Circle::new(p, 3, color.filled())))?;
    }
    let anchor = spec.series.iter().find_map(|s| visible(s).first().copied());
    if let (Some((exponent, label)), Some((ax, ay))) = (&spec.guide, anchor) {
        let guide = |x: f64| ay * (x / ax).powf(*exponent);
        let grey = RGBColor(150, 150, 150);
        chart
            .draw_series(LineSeries::new(
                [(x0, guide(x0)), (x1, guide(x1))],
                grey.stroke_width(1),
            ))?
            .label(label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], grey.stroke_width(1)));
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(match spec.legend {
            #[cfg(any(test, feature = "testing"))]
            LegendCorner::UpperLeft => SeriesLabelPosition::UpperLeft,
            LegendCorner::UpperRight => SeriesLabelPosition::UpperRight,
            #[cfg(any(test, feature = "testing"))]
            LegendCorner::LowerLeft => SeriesLabelPosition::LowerLeft,
            #[cfg(any(test, feature = "testing"))]
            LegendCorner::LowerRight => SeriesLabelPosition::LowerRight,
        })
        .draw()?;
    Ok(())
}
