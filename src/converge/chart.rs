//! The log-log convergence chart (RMSE against render seconds, one curve per method, and a 1/√t guide),
//! drawn with `plotters` to PNG and SVG. Text uses the bundled DejaVu Sans Mono (no system fonts needed).

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

/// Draws the chart of `curves` to `png` and `svg`.
pub fn draw_chart(curves: &[Curve], png: &Path, svg: &Path) -> Result<(), String> {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The bundled font is valid; a failure would only make text invisible.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES);
    });
    let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
        draw(&root, curves).map_err(|e| format!("{}: {e}", png.display()))?;
        root.present()
            .map_err(|e| format!("{}: {e}", png.display()))?;
    }
    image::RgbImage::from_raw(SIZE.0, SIZE.1, rgb)
        .ok_or("chart buffer size")?
        .save(png)
        .map_err(|e| format!("{}: {e}", png.display()))?;
    let root = SVGBackend::new(svg, SIZE).into_drawing_area();
    draw(&root, curves).map_err(|e| format!("{}: {e}", svg.display()))?;
    root.present()
        .map_err(|e| format!("{}: {e}", svg.display()))
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    curves: &[Curve],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let points = curves.iter().flat_map(|c| &c.points);
    let positive = |v: f64| v.is_finite() && v > 0.0;
    let (mut t0, mut t1, mut e0, mut e1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in points.filter(|p| positive(p.seconds) && positive(p.metrics.rmse)) {
        t0 = t0.min(p.seconds);
        t1 = t1.max(p.seconds);
        e0 = e0.min(p.metrics.rmse);
        e1 = e1.max(p.metrics.rmse);
    }
    if t0 > t1 {
        (t0, t1, e0, e1) = (1e-3, 1.0, 1e-3, 1.0);
    }
    let (t0, t1) = (t0 / 1.5, t1 * 1.5);
    let (e0, e1) = (e0 / 1.5, e1 * 1.5);
    let mut chart = ChartBuilder::on(root)
        .caption("RMSE vs render time", (FONT, 24))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(80)
        .build_cartesian_2d((t0..t1).log_scale(), (e0..e1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("render seconds")
        .y_desc("RMSE")
        .label_style((FONT, 14))
        .x_label_formatter(&|v| format!("{v:.3}"))
        .y_label_formatter(&|v| format!("{v:.1e}"))
        .draw()?;
    for (i, c) in curves.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        let data: Vec<(f64, f64)> = c
            .points
            .iter()
            .filter(|p| positive(p.seconds) && positive(p.metrics.rmse))
            .map(|p| (p.seconds, p.metrics.rmse))
            .collect();
        chart
            .draw_series(LineSeries::new(data.clone(), color.stroke_width(2)))?
            .label(c.method.name())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2)));
        chart.draw_series(data.into_iter().map(|p| Circle::new(p, 3, color.filled())))?;
    }
    // 1/√t guide through the first method's first checkpoint.
    if let Some(p) = curves.iter().find_map(|c| c.points.first()) {
        let guide = |t: f64| p.metrics.rmse * (p.seconds / t).sqrt();
        let grey = RGBColor(150, 150, 150);
        chart
            .draw_series(LineSeries::new(
                [(t0, guide(t0)), (t1, guide(t1))],
                grey.stroke_width(1),
            ))?
            .label("1/sqrt(t)")
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], grey.stroke_width(1)));
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}
