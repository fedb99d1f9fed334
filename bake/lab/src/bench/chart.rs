//! The bench's chart: one panel per case, wall time against L2-UVP, drawn with plotters in a
//! font compiled into this crate.

use super::peers::PEER_TOOLS;
use super::{BenchError, Row, SolverKind};

/// DejaVu Sans (Bitstream Vera license, `bake/lab/assets/DejaVuSans-LICENSE.txt`), compiled in so charts
/// need no system fonts: plotters' `ab_glyph` backend draws only registered fonts.
static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
pub(super) const FONT_FAMILY: &str = "sans-serif";

pub(super) fn register_font() -> Result<(), BenchError> {
    static REGISTERED: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            plotters::style::register_font(FONT_FAMILY, plotters::style::FontStyle::Normal, FONT)
                .map_err(|_| "the bundled DejaVuSans.ttf is not a valid font".to_string())
        })
        .clone()
        .map_err(BenchError::Chart)
}

/// Series color of a solver.
fn solver_color(solver: &str) -> plotters::style::RGBColor {
    use plotters::style::RGBColor;
    match solver {
        "exact" => RGBColor(30, 30, 30),
        "sliced" => RGBColor(220, 110, 20),
        "pot_emd" => RGBColor(130, 130, 130),
        "pot_sinkhorn" => RGBColor(40, 160, 70),
        "geomloss" => RGBColor(170, 50, 160),
        "bsp_ot" => RGBColor(200, 40, 40),
        _ => RGBColor(40, 100, 200),
    }
}

/// Chart size in pixels per panel.
const PANEL: (u32, u32) = (520, 380);

/// The legend strip: the height of one line of entries, the margin at its left and right ends,
/// the width of a solver's entry and of a size's, and the gap between the two kinds.
const LEGEND_LINE: u32 = 44;
const LEGEND_MARGIN: i32 = 16;
const SOLVER_ENTRY: i32 = 120;
const SIZE_ENTRY: i32 = 110;
const SIZE_GAP: i32 = 20;

/// A drawing area of the chart's bitmap.
type Area<'a> =
    plotters::drawing::DrawingArea<plotters::backend::BitMapBackend<'a>, plotters::coord::Shift>;

fn chart_err(e: &dyn std::fmt::Display) -> BenchError {
    BenchError::Chart(e.to_string())
}

/// The chart as PNG bytes: one panel per case, wall time (log) against L2-UVP (log, [`Row::uvp`]),
/// a color per solver, a marker per n. Runs without a positive UVP (a failed run, or the exact
/// matching against itself) have no point.
pub fn chart_png(rows: &[Row]) -> Result<Vec<u8>, BenchError> {
    use plotters::prelude::*;
    register_font()?;
    let mut cases: Vec<&str> = Vec::new();
    for r in rows {
        if !cases.contains(&r.case.as_str()) {
            cases.push(&r.case);
        }
    }
    let mut ns: Vec<usize> = rows.iter().map(|r| r.n).collect();
    ns.sort_unstable();
    ns.dedup();
    let mut solvers: Vec<&'static str> = Vec::new();
    let names = SolverKind::ALL
        .iter()
        .map(|k| k.name())
        .chain(PEER_TOOLS.iter().map(|p| p.0));
    for name in names {
        if rows.iter().any(|r| r.solver == name) {
            solvers.push(name);
        }
    }
    let cols = match cases.len() {
        0 | 1 => 1,
        2 | 4 => 2,
        _ => 3,
    };
    let panel_rows = cases.len().div_ceil(cols).max(1);
    let w = PANEL.0 * cols as u32;
    let (places, legend_height) = legend_layout(solvers.len(), ns.len(), w);
    let h = PANEL.1 * panel_rows as u32 + legend_height;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| chart_err(&e))?;
        let (grid, legend) = root.split_vertically(h - legend_height);
        let panels = grid.split_evenly((panel_rows, cols));
        for (case, area) in cases.iter().zip(panels.iter()) {
            draw_panel(area, rows, case, &ns, &solvers)?;
        }
        draw_legend(&legend, &places, &ns, &solvers)?;
        root.present().map_err(|e| chart_err(&e))?;
    }
    let mut png = Vec::new();
    {
        use image::ImageEncoder;
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(&buf, w, h, image::ExtendedColorType::Rgb8)
            .map_err(|e| chart_err(&e))?;
    }
    Ok(png)
}

/// The panel of one case: its runs' (seconds, L2-UVP) points, a series per size and solver.
fn draw_panel(
    area: &Area<'_>,
    rows: &[Row],
    case: &str,
    ns: &[usize],
    solvers: &[&'static str],
) -> Result<(), BenchError> {
    use plotters::prelude::*;
    let measured: Vec<(&Row, f64, f64)> = rows
        .iter()
        .filter(|r| r.case == *case)
        .filter_map(|r| {
            let y = r.uvp()?;
            (r.seconds > 0.0 && y >= 0.0 && y.is_finite()).then_some((r, r.seconds, y))
        })
        .collect();
    // A log axis has no 0: runs that reproduce the reference exactly sit on a floor below the
    // smallest positive value, and the caption says so.
    let min_positive = measured
        .iter()
        .map(|p| p.2)
        .filter(|&y| y > 0.0)
        .fold(f64::INFINITY, f64::min);
    let floor = if min_positive.is_finite() {
        min_positive / 4.0
    } else {
        1e-3
    };
    let has_zero = measured.iter().any(|p| p.2 == 0.0);
    let pts: Vec<(&Row, f64, f64)> = measured
        .into_iter()
        .map(|(r, x, y)| (r, x, if y > 0.0 { y } else { floor }))
        .collect();
    let reference = if rows
        .iter()
        .any(|r| r.case == *case && r.uvp_closed_form.is_some())
    {
        "closed form"
    } else {
        "exact"
    };
    let (x0, x1) = log_range(pts.iter().map(|p| p.1));
    let (y0, y1) = log_range(pts.iter().map(|p| p.2));
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!(
                "{case}: L2-UVP vs {reference}{}",
                if has_zero { " (bottom: 0)" } else { "" }
            ),
            (FONT_FAMILY, 17).into_font(),
        )
        .margin(8)
        .x_label_area_size(34)
        .y_label_area_size(56)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(|e| chart_err(&e))?;
    chart
        .configure_mesh()
        .x_desc("seconds")
        .y_desc("L2-UVP (%)")
        .label_style((FONT_FAMILY, 12).into_font())
        .axis_desc_style((FONT_FAMILY, 13).into_font())
        .x_label_formatter(&|v| format_tick(*v))
        .y_label_formatter(&|v| format_tick(*v))
        .draw()
        .map_err(|e| chart_err(&e))?;
    for (ni, &n) in ns.iter().enumerate() {
        for &solver in solvers {
            let color = solver_color(solver);
            let series: Vec<(f64, f64)> = pts
                .iter()
                .filter(|p| p.0.n == n && p.0.solver == solver)
                .map(|p| (p.1, p.2))
                .collect();
            let style = ShapeStyle::from(&color).filled();
            let stroke = ShapeStyle::from(&color).stroke_width(2);
            let drawn = match ni % 4 {
                0 => chart.draw_series(series.iter().map(|&c| Circle::new(c, 4, style))),
                1 => chart.draw_series(series.iter().map(|&c| TriangleMarker::new(c, 6, style))),
                2 => chart.draw_series(series.iter().map(|&c| Cross::new(c, 5, stroke))),
                _ => chart.draw_series(
                    series
                        .iter()
                        .map(|&c| EmptyElement::at(c) + Rectangle::new([(-4, -4), (4, 4)], style)),
                ),
            };
            drawn.map_err(|e| chart_err(&e))?;
        }
    }
    Ok(())
}

/// Where each legend entry goes, in its strip: the solvers' entries, then the sizes' (after a
/// gap), each as the (x, y) of its middle-left point, wrapped onto a new line where the next entry
/// would pass the chart's right edge (a single panel is narrower than seven tools' names); and the
/// strip's height.
pub(super) fn legend_layout(solvers: usize, sizes: usize, width: u32) -> (Vec<(i32, i32)>, u32) {
    let right = (width as i32 - LEGEND_MARGIN).max(LEGEND_MARGIN + SOLVER_ENTRY);
    let (mut x, mut line) = (LEGEND_MARGIN, 0i32);
    let mut places = Vec::with_capacity(solvers + sizes);
    let entries = (0..solvers)
        .map(|_| (0, SOLVER_ENTRY))
        .chain((0..sizes).map(|k| {
            let gap = if k == 0 && solvers > 0 { SIZE_GAP } else { 0 };
            (gap, SIZE_ENTRY)
        }));
    for (gap, entry) in entries {
        x += gap;
        if x > LEGEND_MARGIN && x + entry > right {
            (x, line) = (LEGEND_MARGIN, line + 1);
        }
        places.push((x, line * LEGEND_LINE as i32 + LEGEND_LINE as i32 / 2));
        x += entry;
    }
    (places, (line as u32 + 1) * LEGEND_LINE)
}

/// The legend strip: solver colors, then n markers, at the places [`legend_layout`] gave.
fn draw_legend(
    legend: &Area<'_>,
    places: &[(i32, i32)],
    ns: &[usize],
    solvers: &[&'static str],
) -> Result<(), BenchError> {
    use plotters::prelude::*;
    let font = (FONT_FAMILY, 15).into_font();
    let (solver_places, size_places) = places.split_at(solvers.len());
    for (&solver, &(x, y)) in solvers.iter().zip(solver_places) {
        let color = solver_color(solver);
        legend
            .draw(&Rectangle::new(
                [(x, y - 6), (x + 22, y + 6)],
                ShapeStyle::from(&color).filled(),
            ))
            .map_err(|e| chart_err(&e))?;
        legend
            .draw(&Text::new(solver, (x + 28, y - 8), font.clone()))
            .map_err(|e| chart_err(&e))?;
    }
    let black = ShapeStyle::from(&BLACK).filled();
    for (ni, (&n, &(x, y))) in ns.iter().zip(size_places).enumerate() {
        let c = (x + 6, y);
        let drawn = match ni % 4 {
            0 => legend.draw(&Circle::new(c, 4, black)),
            1 => legend.draw(&TriangleMarker::new(c, 6, black)),
            2 => legend.draw(&Cross::new(c, 5, ShapeStyle::from(&BLACK).stroke_width(2))),
            _ => legend.draw(&Rectangle::new(
                [(c.0 - 4, c.1 - 4), (c.0 + 4, c.1 + 4)],
                black,
            )),
        };
        drawn.map_err(|e| chart_err(&e))?;
        legend
            .draw(&Text::new(
                format!("n = {}", format_count(n)),
                (x + 16, y - 8),
                font.clone(),
            ))
            .map_err(|e| chart_err(&e))?;
    }
    Ok(())
}

/// A log axis range covering the values with a margin (a decade around 1 if there are none).
fn log_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !(lo.is_finite() && hi > 0.0) {
        return (0.1, 10.0);
    }
    let (lo, hi) = (lo / 1.6, hi * 1.6);
    if hi / lo < 10.0 {
        let mid = (lo * hi).sqrt();
        (mid / 10f64.sqrt(), mid * 10f64.sqrt())
    } else {
        (lo, hi)
    }
}

/// Tick labels: few significant digits, scientific outside [1e-3, 1e4).
pub(super) fn format_tick(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (1e-3..1e4).contains(&v.abs()) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.0e}")
    }
}

/// 1000 → "1K", 250000 → "250K", 1500 → "1500".
pub(super) fn format_count(n: usize) -> String {
    if n >= 1_000_000 && n.is_multiple_of(1_000_000) {
        format!("{}M", n / 1_000_000)
    } else if n >= 1000 && n.is_multiple_of(1000) {
        format!("{}K", n / 1000)
    } else {
        n.to_string()
    }
}
