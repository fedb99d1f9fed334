//! Charts of the barycenter sweeps, drawn like the solver bench's (same font, same axes code).

use super::{AccuracyRow, ResolutionRow, PROXIES, RESOLUTIONS};
use crate::bench::chart::{format_tick, register_font, FONT_FAMILY};
use crate::bench::BenchError;
use plotters::prelude::*;

const PANEL: (u32, u32) = (620, 380);

fn err(e: &dyn std::fmt::Display) -> BenchError {
    BenchError::Chart(e.to_string())
}

fn color(i: usize) -> RGBColor {
    [
        RGBColor(40, 100, 200),
        RGBColor(220, 110, 20),
        RGBColor(120, 60, 160),
        RGBColor(30, 150, 70),
        RGBColor(200, 30, 40),
        RGBColor(30, 30, 30),
    ][i % 6]
}

fn encode(buf: &[u8], w: u32, h: u32) -> Result<Vec<u8>, BenchError> {
    use image::ImageEncoder;
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(buf, w, h, image::ExtendedColorType::Rgb8)
        .map_err(|e| err(&e))?;
    Ok(png)
}

/// Per case, two panels: the W2 gap to the truth (% of the scale) and the objective excess (%)
/// over the sweep's weights (x: the sweep's index; vertices first, then edges, then interior), a
/// series per proxy.
pub fn accuracy_png(rows: &[AccuracyRow]) -> Result<Vec<u8>, BenchError> {
    register_font()?;
    let mut cases: Vec<&str> = Vec::new();
    for r in rows {
        if !cases.contains(&r.case.as_str()) {
            cases.push(&r.case);
        }
    }
    let (w, h) = (PANEL.0 * 2, PANEL.1 * cases.len().max(1) as u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let panels = root.split_evenly((cases.len().max(1), 2));
        for (ci, case) in cases.iter().enumerate() {
            for (pi, metric) in ["W2 gap / scale (%)", "objective excess (%)"]
                .iter()
                .enumerate()
            {
                let area = &panels[ci * 2 + pi];
                let series: Vec<(usize, Vec<(f64, f64)>)> = PROXIES
                    .iter()
                    .enumerate()
                    .map(|(i, p)| {
                        let pts = rows
                            .iter()
                            .filter(|r| r.case == *case && r.proxy == *p)
                            .enumerate()
                            .filter_map(|(x, r)| {
                                let y = if pi == 0 { Some(r.w2_gap) } else { r.excess };
                                y.map(|y| (x as f64, 100.0 * y))
                            })
                            .collect();
                        (i, pts)
                    })
                    .collect();
                let ymax = series
                    .iter()
                    .flat_map(|s| s.1.iter().map(|p| p.1))
                    .fold(1e-6f64, f64::max)
                    * 1.1;
                let xmax = series
                    .iter()
                    .flat_map(|s| s.1.iter().map(|p| p.0))
                    .fold(1.0f64, f64::max);
                let mut chart = ChartBuilder::on(area)
                    .caption(format!("{case}: {metric}"), (FONT_FAMILY, 17).into_font())
                    .margin(8)
                    .x_label_area_size(34)
                    .y_label_area_size(56)
                    .build_cartesian_2d(-0.5..xmax + 0.5, 0.0..ymax)
                    .map_err(|e| err(&e))?;
                chart
                    .configure_mesh()
                    .x_desc("weights (sweep index: vertices, edges, interior)")
                    .y_desc(*metric)
                    .label_style((FONT_FAMILY, 12).into_font())
                    .axis_desc_style((FONT_FAMILY, 13).into_font())
                    .y_label_formatter(&|v| format_tick(*v))
                    .draw()
                    .map_err(|e| err(&e))?;
                for (i, pts) in &series {
                    let c = color(*i);
                    chart
                        .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
                        .map_err(|e| err(&e))?
                        .label(PROXIES[*i])
                        .legend(move |(x, y)| {
                            Rectangle::new([(x, y - 5), (x + 16, y + 5)], c.filled())
                        });
                    chart
                        .draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))
                        .map_err(|e| err(&e))?;
                }
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .label_font((FONT_FAMILY, 12).into_font())
                    .draw()
                    .map_err(|e| err(&e))?;
            }
        }
        root.present().map_err(|e| err(&e))?;
    }
    encode(&buf, w, h)
}

/// The rendered blend's relative L1 error against samples per pixel (log–log), a series per
/// output resolution.
pub fn resolution_png(rows: &[ResolutionRow]) -> Result<Vec<u8>, BenchError> {
    register_font()?;
    let (w, h) = PANEL;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let xs = rows.iter().map(|r| r.samples_per_pixel);
        let (x0, x1) = xs.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        let ys = rows.iter().map(|r| r.l1);
        let (y0, y1) = ys.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        let (x0, x1) = if x0.is_finite() {
            (x0 / 1.5, x1 * 1.5)
        } else {
            (0.1, 10.0)
        };
        let (y0, y1) = if y0.is_finite() {
            (y0 / 1.5, y1 * 1.5)
        } else {
            (0.01, 1.0)
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "2-way blend: relative L1 of the render vs samples per pixel",
                (FONT_FAMILY, 16).into_font(),
            )
            .margin(8)
            .x_label_area_size(34)
            .y_label_area_size(56)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("n / R² (samples per pixel)")
            .y_desc("relative L1")
            .label_style((FONT_FAMILY, 12).into_font())
            .axis_desc_style((FONT_FAMILY, 13).into_font())
            .x_label_formatter(&|v| format_tick(*v))
            .y_label_formatter(&|v| format_tick(*v))
            .draw()
            .map_err(|e| err(&e))?;
        for (i, &r) in RESOLUTIONS.iter().enumerate() {
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|x| x.resolution == r)
                .map(|x| (x.samples_per_pixel, x.l1))
                .collect();
            let c = color(i);
            chart
                .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
                .map_err(|e| err(&e))?
                .label(format!("{r}²"))
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 16, y + 5)], c.filled()));
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))
                .map_err(|e| err(&e))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((FONT_FAMILY, 12).into_font())
            .draw()
            .map_err(|e| err(&e))?;
        root.present().map_err(|e| err(&e))?;
    }
    encode(&buf, w, h)
}
