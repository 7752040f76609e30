//! The convergence plot: relative RMS error against seconds, log-log, one curve per method,
//! as SVG and PNG. Text uses the Noto Mono font shipped in `assets/fonts` (SIL OFL 1.1, see
//! `assets/fonts/NotoMono-LICENSE`), so no system fonts are needed.

use crate::CliError;
use lightbake::analysis::study::Study;
use plotters::coord::Shift;
use plotters::prelude::*;

/// The font, embedded.
static FONT: &[u8] = include_bytes!("../../../assets/fonts/NotoMono-Regular.ttf");

/// Plot size, pixels.
const SIZE: (u32, u32) = (1000, 680);

fn err(e: impl std::fmt::Display) -> String {
    format!("plot: {e}")
}

/// Registers the embedded font (once; later calls are no-ops).
fn register_font() -> Result<(), CliError> {
    static ONCE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *ONCE.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err("plot: the embedded font could not be read".into())
    }
}

/// Draws `study` onto `root`.
fn draw<DB: DrawingBackend>(study: &Study, root: &DrawingArea<DB, Shift>) -> Result<(), CliError>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(err)?;
    let pts = |c: &str| -> Vec<(f64, f64)> {
        study
            .curve(c)
            .iter()
            .filter(|r| r.seconds > 0.0 && r.measured > 0.0)
            .map(|r| (r.seconds, r.measured))
            .collect()
    };
    let all: Vec<(f64, f64)> = study.curves().iter().flat_map(|c| pts(c)).collect();
    if all.is_empty() {
        return Err("plot: no run has a positive time and error".into());
    }
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in &all {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    let mut chart = ChartBuilder::on(root)
        .caption(
            format!(
                "{}: error against run time ({} texels)",
                study.scene, study.texels
            ),
            ("sans-serif", 22),
        )
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(
            (x0 / 1.3..x1 * 1.3).log_scale(),
            (y0 / 1.5..y1 * 1.5).log_scale(),
        )
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("bake time (s)")
        .y_desc("relative RMS error")
        .label_style(("sans-serif", 14))
        .y_label_formatter(&|v| format!("{:.2}%", 100.0 * v))
        .x_label_formatter(&|v| format!("{v:.2}"))
        .draw()
        .map_err(err)?;
    for (i, c) in study.curves().iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        let p = pts(c);
        chart
            .draw_series(LineSeries::new(p.clone(), colour.stroke_width(2)))
            .map_err(err)?
            .label(c.to_string())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
        chart
            .draw_series(p.into_iter().map(|q| Circle::new(q, 3, colour.filled())))
            .map_err(err)?;
    }
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

/// Renders `study` as an SVG document and a PNG image (bytes).
pub fn render(study: &Study) -> Result<(Vec<u8>, Vec<u8>), CliError> {
    register_font()?;
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, SIZE).into_drawing_area();
        draw(study, &root)?;
    }
    let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
        draw(study, &root)?;
    }
    let image = image::RgbImage::from_raw(SIZE.0, SIZE.1, rgb)
        .ok_or_else(|| "plot: bitmap size mismatch".to_string())?;
    let mut png = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(err)?;
    Ok((text.into_bytes(), png))
}
